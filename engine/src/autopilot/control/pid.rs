//! One PID axis with anti-windup (copper-rs `PIDController` style): `update` returns the
//! output and keeps every term for logging.

/// Gains and limits of one PID axis (output units per error unit).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PidGains {
    pub kp: f64,
    /// Per second.
    pub ki: f64,
    /// Seconds; applied to the measurement's rate of change, not the error's.
    pub kd: f64,
    /// Bound on the integral term's contribution (output units).
    pub integral_limit: f64,
    /// Bound on `|output|`.
    pub output_limit: f64,
}

/// The terms of the last [`Pid::update`], for logging.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PidTerms {
    pub p: f64,
    pub i: f64,
    pub d: f64,
    pub output: f64,
}

/// `out = kp e + ki ∫e − kd d(measurement)/dt`, clamped to `±output_limit`.
///
/// Anti-windup: the integral term is clamped to `±integral_limit` and is not integrated
/// while the output is saturated in the direction the error pushes (conditional
/// integration), whether by `output_limit` or by a downstream stage that reported it with
/// [`Pid::set_downstream_saturation`]. Derivative on measurement: a setpoint step gives no
/// derivative kick.
#[derive(Clone, Debug, PartialEq)]
pub struct Pid {
    pub gains: PidGains,
    integral: f64,
    prev_measurement: Option<f64>,
    /// Downstream saturation (upper, lower) reported after the last step.
    saturated: (bool, bool),
    last: PidTerms,
}

impl Pid {
    pub fn new(gains: PidGains) -> Self {
        Self { gains, integral: 0.0, prev_measurement: None, saturated: (false, false), last: PidTerms::default() }
    }

    /// One step: `error = setpoint − measurement`; `dt_s > 0`.
    pub fn update(&mut self, error: f64, measurement: f64, dt_s: f64) -> f64 {
        let g = &self.gains;
        let p = g.kp * error;
        let d = match self.prev_measurement {
            Some(prev) if dt_s > 0.0 => -g.kd * (measurement - prev) / dt_s,
            _ => 0.0,
        };
        self.prev_measurement = Some(measurement);
        let unsaturated = p + self.integral + d;
        let (upper, lower) = self.saturated;
        let pushing_into_limit = ((upper || unsaturated >= g.output_limit) && error > 0.0)
            || ((lower || unsaturated <= -g.output_limit) && error < 0.0);
        if !pushing_into_limit {
            self.integral = (self.integral + g.ki * error * dt_s).clamp(-g.integral_limit, g.integral_limit);
        }
        let output = (p + self.integral + d).clamp(-g.output_limit, g.output_limit);
        self.last = PidTerms { p, i: self.integral, d, output };
        output
    }

    /// Tells the PID that what it drives could not deliver more (`upper`) or less (`lower`)
    /// than its last output, so the integral must not grow that way. Holds until changed.
    pub fn set_downstream_saturation(&mut self, upper: bool, lower: bool) {
        self.saturated = (upper, lower);
    }

    /// Forgets the integral, the previous measurement and any saturation.
    pub fn reset(&mut self) {
        self.integral = 0.0;
        self.prev_measurement = None;
        self.saturated = (false, false);
        self.last = PidTerms::default();
    }

    pub fn terms(&self) -> PidTerms {
        self.last
    }
}
