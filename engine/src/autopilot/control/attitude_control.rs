//! Attitude control, PX4's `mc_att_control` `AttitudeControl`: attitude error → body rates.

use nalgebra::{Quaternion, UnitQuaternion, Vector3};

/// Quaternion attitude error → body rate setpoint (PX4 `AttitudeControl`).
///
/// First the shortest rotation that aligns the thrust axis (roll/pitch, "reduced
/// attitude"), then only `yaw_weight` of the remaining yaw rotation is mixed in, so a yaw
/// error never disturbs the thrust direction; the yaw gain is divided by the weight to
/// compensate. Error `e = 2 · sign(q_e.w) · imag(q_e)`, `q_e = q⁻¹ q_sp`, rates `K ⊙ e`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AttitudeController {
    pub gain_roll_pitch: f64,
    pub gain_yaw: f64,
    pub yaw_weight: f64,
    pub max_rate_roll_pitch_rad_s: f64,
    pub max_rate_yaw_rad_s: f64,
}

impl AttitudeController {
    /// Body rate setpoint, rad/s.
    pub fn update(&self, attitude_sp: &UnitQuaternion<f64>, attitude: &UnitQuaternion<f64>) -> Vector3<f64> {
        let (q, qd) = (attitude, attitude_sp);
        let e_z = q * Vector3::z();
        let e_z_d = qd * Vector3::z();
        // Antiparallel thrust axes: fall back to full attitude control (PX4 does the same).
        let qd_red = UnitQuaternion::rotation_between(&e_z, &e_z_d).map_or(*qd, |r| r * q);
        let mut q_mix = (qd_red.inverse() * qd).into_inner();
        if q_mix.w < 0.0 {
            q_mix = -q_mix;
        }
        let w = self.yaw_weight.clamp(0.0, 1.0);
        let half_yaw_cos = (w * q_mix.w.clamp(-1.0, 1.0).acos()).cos();
        let half_yaw_sin = (w * q_mix.k.clamp(-1.0, 1.0).asin()).sin();
        let yaw_part = UnitQuaternion::new_normalize(Quaternion::new(half_yaw_cos, 0.0, 0.0, half_yaw_sin));
        let qe = q.inverse() * (qd_red * yaw_part);
        let sign = if qe.w < 0.0 { -1.0 } else { 1.0 };
        let e = qe.imag() * (2.0 * sign);
        let k_yaw = if w > 1e-4 { self.gain_yaw / w } else { self.gain_yaw };
        let (rp, y) = (self.max_rate_roll_pitch_rad_s, self.max_rate_yaw_rad_s);
        Vector3::new(
            (self.gain_roll_pitch * e.x).clamp(-rp, rp),
            (self.gain_roll_pitch * e.y).clamp(-rp, rp),
            (k_yaw * e.z).clamp(-y, y),
        )
    }
}
