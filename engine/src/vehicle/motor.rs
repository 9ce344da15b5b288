//! A motor + rotor: first-order speed lag toward the commanded speed, thrust and reaction torque.
//!
//! # Command convention
//!
//! The command is a normalized `u ∈ [0, 1]` mapped **linearly to rotor speed**:
//! `ω_cmd = u · max_omega`. This is what PX4's Gazebo motor model does with its actuator
//! outputs, so thrust grows with `u²`. Real ESCs with a throttle curve are closer to
//! thrust-linear (PX4 compensates with `THR_MDL_FAC`); our mixer inverts the `u²` exactly
//! (`u = sqrt(T / k_f) / max_omega`), so either convention would fly the same.

use super::airframe::{Airframe, Spin};

/// One motor's constants (copied from the airframe) and its state.
#[derive(Clone, Debug, PartialEq)]
pub struct Motor {
    pub spin: Spin,
    /// `k_f`, N/(rad/s)².
    pub thrust_coeff_n_per_rad_s2: f64,
    /// `k_m`, m.
    pub torque_coeff_m: f64,
    pub max_omega_rad_s: f64,
    pub time_constant_up_s: f64,
    pub time_constant_down_s: f64,
    omega_rad_s: f64,
    command: f64,
    /// `([dt, τ_up, τ_down], 1 − e^{−dt/τ_up}, 1 − e^{−dt/τ_down})` of the last step: the
    /// physics step is fixed, so the two exponentials are computed once, not per motor per
    /// step (recomputed whenever dt or a time constant differs).
    lag: Option<([f64; 3], f64, f64)>,
}

impl Motor {
    /// The motor of `airframe.rotors[rotor_index]`, stopped.
    ///
    /// # Panics
    /// If `rotor_index` is out of range.
    pub fn new(airframe: &Airframe, rotor_index: usize) -> Self {
        Self {
            spin: airframe.rotors[rotor_index].spin,
            thrust_coeff_n_per_rad_s2: airframe.thrust_coeff_n_per_rad_s2,
            torque_coeff_m: airframe.torque_coeff_m,
            max_omega_rad_s: airframe.max_omega_rad_s,
            time_constant_up_s: airframe.motor_time_constant_up_s,
            time_constant_down_s: airframe.motor_time_constant_down_s,
            omega_rad_s: 0.0,
            command: 0.0,
            lag: None,
        }
    }

    /// All motors of an airframe, in rotor order, stopped.
    pub fn for_airframe(airframe: &Airframe) -> Vec<Self> {
        (0..airframe.rotors.len()).map(|i| Self::new(airframe, i)).collect()
    }

    /// Sets the speed directly (initial conditions, e.g. starting in hover), clamped to
    /// `[0, max_omega]`; the command follows so the motor stays there.
    pub fn set_omega(&mut self, omega_rad_s: f64) {
        self.omega_rad_s = omega_rad_s.clamp(0.0, self.max_omega_rad_s);
        self.command = self.omega_rad_s / self.max_omega_rad_s;
    }

    /// Advances the speed by `dt_s` toward `command · max_omega` (`command` clamped to [0, 1]).
    ///
    /// Exact discretisation of `τ dω/dt = ω_cmd − ω`, with `τ` the up or down time constant
    /// depending on the direction of the change, so the step is stable for any `dt_s`.
    pub fn step(&mut self, command: f64, dt_s: f64) {
        self.command = if command.is_finite() { command.clamp(0.0, 1.0) } else { 0.0 };
        let target = self.command * self.max_omega_rad_s;
        let alpha = |tau: f64| if tau > 0.0 { 1.0 - (-dt_s / tau).exp() } else { 1.0 };
        let key = [dt_s, self.time_constant_up_s, self.time_constant_down_s];
        let (up, down) = match self.lag {
            Some((k, up, down)) if k == key => (up, down),
            _ => {
                let (up, down) = (alpha(self.time_constant_up_s), alpha(self.time_constant_down_s));
                self.lag = Some((key, up, down));
                (up, down)
            }
        };
        let alpha = if target > self.omega_rad_s { up } else { down };
        self.omega_rad_s += (target - self.omega_rad_s) * alpha;
    }

    /// The last command, in [0, 1].
    pub fn command(&self) -> f64 {
        self.command
    }

    /// Rotor speed, rad/s (≥ 0; the spin direction is `spin`).
    pub fn omega_rad_s(&self) -> f64 {
        self.omega_rad_s
    }

    /// Thrust along body +z, N: `k_f ω²`.
    pub fn thrust_n(&self) -> f64 {
        self.thrust_coeff_n_per_rad_s2 * self.omega_rad_s * self.omega_rad_s
    }

    /// Reaction torque on the body about body +z, N m: `±k_m T` (sign from `Spin`).
    pub fn yaw_torque_nm(&self) -> f64 {
        self.spin.reaction_sign() * self.torque_coeff_m * self.thrust_n()
    }

    /// Mechanical shaft power, W: `|Q| ω`.
    pub fn mechanical_power_w(&self) -> f64 {
        self.torque_coeff_m * self.thrust_n() * self.omega_rad_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vehicle::airframe::preset;

    #[test]
    fn lag_reaches_63_percent_in_one_time_constant_each_way() {
        let a = preset("x500").unwrap();
        let mut m = Motor::new(&a, 0);
        let steps = 100;
        let dt = a.motor_time_constant_up_s / steps as f64;
        for _ in 0..steps {
            m.step(1.0, dt);
        }
        let up = m.omega_rad_s() / a.max_omega_rad_s;
        assert!((up - (1.0 - (-1.0f64).exp())).abs() < 1e-9, "{up}");

        m.set_omega(a.max_omega_rad_s);
        let dt = a.motor_time_constant_down_s / steps as f64;
        for _ in 0..steps {
            m.step(0.0, dt);
        }
        let down = 1.0 - m.omega_rad_s() / a.max_omega_rad_s;
        assert!((down - (1.0 - (-1.0f64).exp())).abs() < 1e-9, "{down}");
    }

    #[test]
    fn speeding_up_is_faster_than_slowing_down() {
        let a = preset("mini250").unwrap();
        let (mut up, mut down) = (Motor::new(&a, 0), Motor::new(&a, 0));
        down.set_omega(a.max_omega_rad_s);
        for _ in 0..10 {
            up.step(1.0, 1e-3);
            down.step(0.0, 1e-3);
        }
        assert!(up.omega_rad_s() > a.max_omega_rad_s - down.omega_rad_s());
    }

    #[test]
    fn thrust_and_reaction_torque_follow_spin() {
        let a = preset("x500").unwrap();
        let mut ccw = Motor::new(&a, 0);
        let mut cw = Motor::new(&a, 2);
        ccw.set_omega(500.0);
        cw.set_omega(500.0);
        let t = 8.54858e-6 * 500.0 * 500.0;
        assert!((ccw.thrust_n() - t).abs() < 1e-12);
        assert!((ccw.yaw_torque_nm() + 0.016 * t).abs() < 1e-12);
        assert!((cw.yaw_torque_nm() - 0.016 * t).abs() < 1e-12);
        assert!((ccw.mechanical_power_w() - 0.016 * t * 500.0).abs() < 1e-9);
    }

    #[test]
    fn command_is_clamped() {
        let a = preset("x500").unwrap();
        let mut m = Motor::new(&a, 0);
        m.step(7.0, 10.0);
        assert_eq!(m.command(), 1.0);
        assert!((m.omega_rad_s() - a.max_omega_rad_s).abs() < 1e-6);
        m.step(f64::NAN, 10.0);
        assert_eq!(m.command(), 0.0);
    }
}
