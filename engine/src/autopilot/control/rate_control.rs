//! Body rate control, PX4's `mc_rate_control`: rate error → torque.

use nalgebra::Vector3;

use super::control_allocation::Allocation;
use super::pid::Pid;

/// Body rate error → torque: `τ = J ⊙ α_sp + ω × Jω`, with `α_sp` from one PID per axis
/// (rad/s² per rad/s) and the gyroscopic term fed forward, so gains are airframe-free.
#[derive(Clone, Debug, PartialEq)]
pub struct RateController {
    pub roll: Pid,
    pub pitch: Pid,
    pub yaw: Pid,
    pub inertia_kg_m2: Vector3<f64>,
}

impl RateController {
    /// Torque setpoint, body N m.
    pub fn update(&mut self, rate_sp_body_rps: &Vector3<f64>, rate_body_rps: &Vector3<f64>, dt_s: f64) -> Vector3<f64> {
        let e = rate_sp_body_rps - rate_body_rps;
        let w = rate_body_rps;
        let alpha = Vector3::new(
            self.roll.update(e.x, w.x, dt_s),
            self.pitch.update(e.y, w.y, dt_s),
            self.yaw.update(e.z, w.z, dt_s),
        );
        let j = &self.inertia_kg_m2;
        j.component_mul(&alpha) + w.cross(&j.component_mul(w))
    }

    /// Stops the integrators winding up against the mixer: axes whose torque the mixer had
    /// to scale down (`scale < 1`) stop integrating in the direction of `torque_body_nm`.
    pub fn set_mixer_saturation(&mut self, torque_body_nm: &Vector3<f64>, allocation: &Allocation) {
        let flags = |tau: f64, scale: f64| (scale < 1.0 && tau > 0.0, scale < 1.0 && tau < 0.0);
        let (u, l) = flags(torque_body_nm.x, allocation.roll_pitch_scale);
        self.roll.set_downstream_saturation(u, l);
        let (u, l) = flags(torque_body_nm.y, allocation.roll_pitch_scale);
        self.pitch.set_downstream_saturation(u, l);
        let (u, l) = flags(torque_body_nm.z, allocation.yaw_scale);
        self.yaw.set_downstream_saturation(u, l);
    }

    pub fn reset(&mut self) {
        self.roll.reset();
        self.pitch.reset();
        self.yaw.reset();
    }
}
