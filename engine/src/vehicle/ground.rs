//! Landing gear on the terrain: a touchdown below the crash speeds rests the drone level on
//! its gear; faster is a crash. Frames: world ENU (up is +z), heights in metres.

use nalgebra::{UnitQuaternion, Vector3};

use crate::vehicle::RigidState;
use crate::vehicle::yaw_of;

/// Touchdown faster than this (m/s, downward) is a crash, not a landing.
pub const CRASH_VERTICAL_MPS: f64 = 3.0;
/// Touching the ground faster than this horizontally (m/s) is a crash.
pub const CRASH_HORIZONTAL_MPS: f64 = 4.0;
/// Landing-gear height: body origin (centre of mass) above the ground at rest, m.
pub const GEAR_HEIGHT_M: f64 = 0.1;
/// Hysteresis of lift-off: a resting drone counts as airborne once its body origin is this
/// far above its rest height, m (so gear chatter on the ground is not a take-off).
pub const LIFT_OFF_MARGIN_M: f64 = 0.02;

/// What the ground did to the drone in one step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GroundContact {
    /// Resting on its gear (after this step).
    pub on_ground: bool,
    /// Body origin above the ground under it, m (`GEAR_HEIGHT_M` at rest).
    pub height_agl_m: f64,
    /// The drone hit the ground at this speed (m/s, the whole velocity's norm): a crash.
    pub crash_speed_mps: Option<f64>,
}

/// Checks the body against the ground at `ground_up_m` (ENU up of the terrain under the
/// drone, m), given whether it was resting (`on_ground`) before the step. A landing puts the
/// state on its gear, level at its yaw and at rest; a crash and free flight leave it as it
/// is.
pub fn ground_contact(state: &mut RigidState, ground_up_m: f64, on_ground: bool) -> GroundContact {
    let p = state.position_enu_m;
    let floor = ground_up_m + GEAR_HEIGHT_M;
    let height_agl_m = p.z - floor + GEAR_HEIGHT_M;
    if p.z > floor {
        let on_ground = on_ground && p.z <= floor + LIFT_OFF_MARGIN_M;
        return GroundContact { on_ground, height_agl_m, crash_speed_mps: None };
    }
    let v = state.velocity_enu_mps;
    let horizontal = v.xy().norm();
    if !on_ground && (-v.z > CRASH_VERTICAL_MPS || horizontal > CRASH_HORIZONTAL_MPS) {
        return GroundContact { on_ground, height_agl_m, crash_speed_mps: Some(v.norm()) };
    }
    state.position_enu_m.z = floor;
    state.velocity_enu_mps = Vector3::zeros();
    state.rate_body_rps = Vector3::zeros();
    state.attitude = UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_of(&state.attitude));
    GroundContact { on_ground: true, height_agl_m: GEAR_HEIGHT_M, crash_speed_mps: None }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Falling at `velocity` with the body origin `above_floor_m` over its rest height on
    /// ground 12 m up.
    fn falling(velocity: Vector3<f64>, above_floor_m: f64) -> RigidState {
        let mut s = RigidState::at_rest(Vector3::new(5.0, -3.0, 12.0 + GEAR_HEIGHT_M + above_floor_m));
        s.velocity_enu_mps = velocity;
        s.rate_body_rps = Vector3::new(0.3, -0.2, 0.1);
        s.attitude = UnitQuaternion::from_euler_angles(0.2, -0.1, 1.0);
        s
    }

    #[test]
    fn a_slow_touchdown_rests_the_drone_level_on_its_gear_keeping_its_yaw() {
        let mut s = falling(Vector3::new(1.0, 0.5, -1.0), -0.01);
        let c = ground_contact(&mut s, 12.0, false);
        assert_eq!(c, GroundContact { on_ground: true, height_agl_m: GEAR_HEIGHT_M, crash_speed_mps: None });
        assert_eq!(s.position_enu_m, Vector3::new(5.0, -3.0, 12.0 + GEAR_HEIGHT_M));
        assert_eq!((s.velocity_enu_mps, s.rate_body_rps), (Vector3::zeros(), Vector3::zeros()));
        let (roll, pitch, yaw) = s.attitude.euler_angles();
        assert!(roll.abs() < 1e-12 && pitch.abs() < 1e-12, "{roll} {pitch}");
        assert!((yaw - yaw_of(&falling(Vector3::zeros(), 0.0).attitude)).abs() < 1e-12);
    }

    #[test]
    fn hitting_the_ground_faster_than_the_crash_speeds_is_a_crash_and_leaves_the_state() {
        for v in
            [Vector3::new(0.0, 0.0, -(CRASH_VERTICAL_MPS + 0.1)), Vector3::new(CRASH_HORIZONTAL_MPS + 0.1, 0.0, -0.5)]
        {
            let mut s = falling(v, -0.05);
            let before = s;
            let c = ground_contact(&mut s, 12.0, false);
            assert_eq!(c.crash_speed_mps, Some(v.norm()), "{v:?}");
            assert!(!c.on_ground);
            assert!((c.height_agl_m - (GEAR_HEIGHT_M - 0.05)).abs() < 1e-9);
            assert_eq!(s, before);
        }
    }

    #[test]
    fn a_resting_drone_is_not_crashed_by_a_fast_velocity_it_has_not_flown() {
        // Already on the ground (a motor spin-up kick): held on its gear, no crash.
        let mut s = falling(Vector3::new(0.0, 0.0, -5.0), -0.001);
        let c = ground_contact(&mut s, 12.0, true);
        assert_eq!((c.on_ground, c.crash_speed_mps), (true, None));
    }

    #[test]
    fn lift_off_counts_only_past_the_margin() {
        let mut s = falling(Vector3::new(0.0, 0.0, 0.5), LIFT_OFF_MARGIN_M / 2.0);
        assert!(ground_contact(&mut s, 12.0, true).on_ground);
        let mut s = falling(Vector3::new(0.0, 0.0, 0.5), LIFT_OFF_MARGIN_M * 2.0);
        let c = ground_contact(&mut s, 12.0, true);
        assert!(!c.on_ground);
        assert!((c.height_agl_m - (GEAR_HEIGHT_M + LIFT_OFF_MARGIN_M * 2.0)).abs() < 1e-9);
        // Airborne stays airborne just above the floor.
        let mut s = falling(Vector3::new(0.0, 0.0, -0.5), LIFT_OFF_MARGIN_M / 2.0);
        assert!(!ground_contact(&mut s, 12.0, false).on_ground);
    }
}
