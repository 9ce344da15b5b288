//! `SensorSuite`: the four sensors of one drone, built from the run spec.

use sadesim_crds::environment::Gnss;

use super::barometer::{Barometer, BarometerConfig};
use super::gnss::{GnssConfig, GnssReceiver};
use super::imu::{Imu, ImuConfig};
use super::magnetometer::{Magnetometer, MagnetometerConfig};

/// IMU, barometer, magnetometer and GNSS receiver of one drone, each with its own random
/// stream derived from `(seed, global drone index)`.
#[derive(Clone, Debug)]
pub struct SensorSuite {
    pub imu: Imu,
    pub barometer: Barometer,
    pub magnetometer: Magnetometer,
    pub gnss: GnssReceiver,
}

impl SensorSuite {
    /// Default IMU, barometer and magnetometer; the receiver from `spec.environment.gnss`.
    pub fn new(gnss: Option<&Gnss>, seed: u64, drone_global_index: u32) -> Self {
        Self {
            imu: Imu::new(ImuConfig::default(), seed, drone_global_index),
            barometer: Barometer::new(BarometerConfig::default(), seed, drone_global_index),
            magnetometer: Magnetometer::new(MagnetometerConfig::default(), seed, drone_global_index),
            gnss: GnssReceiver::new(GnssConfig::from_spec(gnss), seed, drone_global_index),
        }
    }
}
