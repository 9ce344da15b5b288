//! `SensorSuite`: the four sensors of one drone, built from the run spec.

use std::sync::Arc;

use sadesim_crds::environment::Gnss;
use sadesim_gnss::RunSky;
use sadesim_world::World;

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
    /// Default IMU, barometer and magnetometer; the receiver from `spec.environment.gnss`:
    /// the ranging receiver in `world` under `sky` when the run has one, else the
    /// statistical receiver.
    pub fn new(
        gnss: Option<&Gnss>,
        sky: Option<(&Arc<RunSky>, &Arc<World>)>,
        seed: u64,
        drone_global_index: u32,
    ) -> Self {
        let config = GnssConfig::from_spec(gnss);
        Self {
            imu: Imu::new(ImuConfig::default(), seed, drone_global_index),
            barometer: Barometer::new(BarometerConfig::default(), seed, drone_global_index),
            magnetometer: Magnetometer::new(MagnetometerConfig::default(), seed, drone_global_index),
            gnss: match sky {
                Some((sky, world)) => {
                    GnssReceiver::ranging(config, seed, drone_global_index, sky.clone(), world.clone())
                }
                None => GnssReceiver::new(config, seed, drone_global_index),
            },
        }
    }
}
