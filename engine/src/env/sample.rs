//! What a factor is asked (`SampleContext`) and what it answers (`EnvSample`).

use nalgebra::Vector3;

/// Where and when the environment is sampled for one drone.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SampleContext {
    /// Index into the shard's drones (the order given to `Environment::from_spec`), not the
    /// global drone index.
    pub drone: usize,
    /// Position in world ENU, metres from the run origin.
    pub position_enu_m: Vector3<f64>,
    /// Height above ground level, metres.
    pub height_agl_m: f64,
    /// Speed of the drone relative to the air, m/s (drives the turbulence filters).
    pub airspeed_mps: f64,
    /// Simulated time, seconds.
    pub time_s: f64,
    /// Physics step, seconds: the time since the previous sample of this drone.
    pub dt_s: f64,
}

/// GNSS signal conditions at the drone's antenna, as seen by the receiver model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GnssCondition {
    /// False during an outage: the receiver reports no fix.
    pub available: bool,
    /// Multiplies the receiver's white noise; 1 = open sky, larger in urban canyons.
    pub sigma_scale: f64,
    /// Satellites used in the solution.
    pub satellites: u8,
    /// Horizontal dilution of precision, unitless.
    pub hdop: f64,
}

impl Default for GnssCondition {
    /// Open sky: a multi-constellation receiver typically tracks ~14 satellites, HDOP ~0.8.
    fn default() -> Self {
        Self { available: true, sigma_scale: 1.0, satellites: 14, hdop: 0.8 }
    }
}

/// The environment at one drone: refined in turn by each factor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnvSample {
    /// Air velocity (where the air moves to) in world ENU, m/s.
    pub wind_enu_mps: Vector3<f64>,
    pub gnss: GnssCondition,
}

impl Default for EnvSample {
    /// Calm air, open sky.
    fn default() -> Self {
        Self { wind_enu_mps: Vector3::zeros(), gnss: GnssCondition::default() }
    }
}

/// One environment factor (wind, GNSS outages, later building-aware wind, satellite
/// visibility, fog...). Factors run in order; each reads what earlier ones wrote in `out`
/// and refines it, so a new factor plugs in without touching physics or sensors.
///
/// # Assumptions
/// A factor may keep per-drone state (turbulence filters): the shard samples each drone
/// once per physics step with increasing `time_s`.
pub trait EnvironmentFactor: Send {
    /// Short stable name, for logs and `Debug`.
    fn name(&self) -> &'static str;
    /// Refines `out` for the drone and time in `ctx`.
    fn apply(&mut self, ctx: &SampleContext, out: &mut EnvSample);
}
