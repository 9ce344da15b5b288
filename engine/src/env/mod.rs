//! Environment factors sampled at (drone, position, time): wind, GNSS conditions.
//!
//! Physics and sensors see the environment only through [`Environment::sample`]; each
//! factor ([`EnvironmentFactor`]) refines the [`EnvSample`] in turn, so building-aware wind,
//! satellite visibility or fog plug in as new factors without touching physics.

mod dryden;
mod environment;
mod gnss_outage;
mod sample;
mod urban_wind;
mod wind;
mod wind_profile;

pub use dryden::{DrydenFilter, DrydenScales, M_PER_FT, MIN_AIRSPEED_MPS, MPS_PER_KT, wind_speed_at_20ft_mps};
pub use environment::Environment;
pub use gnss_outage::GnssOutageFactor;
pub use sample::{EnvSample, EnvironmentFactor, GnssCondition, SampleContext};
pub use urban_wind::{describe_urban_wind, urban_wind_field, wants_urban_wind};
pub use wind::WindFactor;
pub use wind_profile::{DEFAULT_REFERENCE_HEIGHT_M, MeanWind, URBAN_ROUGHNESS_LENGTH_M};
