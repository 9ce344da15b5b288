//! Sensor models: IMU, barometer, magnetometer, GNSS receiver.
//!
//! Pure structs: each takes the truth (and the environment's `GnssCondition`) and returns a
//! noisy reading; time steps are passed in. Noise is seeded per drone from
//! `(seed, global drone index, Purpose::Sensors)` (IMU, barometer, magnetometer, each on its
//! own child stream) and `Purpose::Gnss` (receiver), so readings do not depend on sharding.

mod barometer;
mod gnss;
mod imu;
mod magnetometer;
mod noise;
mod suite;

pub use barometer::{
    BaroSample, Barometer, BarometerConfig, ISA_LAPSE_RATE_K_PER_M, ISA_SEA_LEVEL_PRESSURE_PA,
    ISA_SEA_LEVEL_TEMPERATURE_K, isa_pressure_pa, isa_temperature_k,
};
pub use gnss::{
    GPS_FIX_TYPE_2D_FIX, GPS_FIX_TYPE_3D_FIX, GPS_FIX_TYPE_NO_FIX, GnssConfig, GnssFix, GnssReceiver,
    MIN_SATELLITES_3D, SkyCounts,
};
pub use imu::{Imu, ImuConfig, ImuSample, STANDARD_GRAVITY_MPS2};
pub use magnetometer::{EarthField, MagSample, Magnetometer, MagnetometerConfig};
pub use suite::SensorSuite;
