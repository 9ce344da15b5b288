//! The run's sky: every navigation satellite's position and velocity in the run's ENU frame
//! at a simulated time, from the constellation and the UTC instant of t = 0.
//!
//! Receivers of all drones fix on the same epochs (k / rate), so [`RunSky::at`] keeps the
//! last few epochs' states: SGP4 runs once per epoch per process, not once per drone.

use std::sync::{Arc, Mutex};

use nalgebra::Vector3;
use sadesim_crds::geo::{GeoPoint, LocalFrame};

use crate::orbits::Constellation;

/// Satellites this far below the origin's horizon are left out of an epoch, degrees: over
/// a city (a few kilometres) a satellite's elevation changes by hundredths of a degree, so
/// none of them rises above any receiver's mask.
const BELOW_HORIZON_MARGIN_DEG: f64 = 5.0;

/// Epochs kept: shards in one process may be a few epochs apart.
const CACHED_EPOCHS: usize = 8;

/// Half the time step of the central difference that gives velocities, s. Over 1 s a GNSS
/// orbit's velocity changes by ~0.5 m/s (centripetal 0.56 m/s²): the central difference's
/// error is ~0.1 mm/s.
const VELOCITY_HALF_STEP_S: f64 = 0.5;

/// One satellite at one epoch, in the run's ENU frame (metres, m/s).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SatelliteState {
    /// Index into the constellation's satellites (stable over the run).
    pub index: usize,
    pub position_enu_m: Vector3<f64>,
    /// Earth-fixed velocity, in the ENU axes.
    pub velocity_enu_mps: Vector3<f64>,
}

/// The constellation as seen from the run's origin over simulated time.
#[derive(Debug)]
pub struct RunSky {
    constellation: Constellation,
    frame: LocalFrame,
    /// UTC (UNIX seconds) of the run's t = 0.
    epoch_unix_s: f64,
    /// Satellites below this elevation are not tracked, degrees.
    mask_deg: f64,
    /// Recent epochs: (time bits, states).
    cache: Mutex<Vec<(u64, Arc<[SatelliteState]>)>>,
}

impl RunSky {
    /// The sky over `origin` with t = 0 at `epoch_unix_s` (UTC) and an elevation mask.
    pub fn new(constellation: Constellation, origin: GeoPoint, epoch_unix_s: f64, mask_deg: f64) -> Self {
        Self { constellation, frame: LocalFrame::new(origin), epoch_unix_s, mask_deg, cache: Mutex::new(Vec::new()) }
    }

    pub fn constellation(&self) -> &Constellation {
        &self.constellation
    }

    pub fn epoch_unix_s(&self) -> f64 {
        self.epoch_unix_s
    }

    pub fn mask_deg(&self) -> f64 {
        self.mask_deg
    }

    /// The satellites above (or just below) the origin's horizon at sim time `time_s`.
    /// The same `time_s` always gives the same states, cached or not.
    pub fn at(&self, time_s: f64) -> Arc<[SatelliteState]> {
        let key = time_s.to_bits();
        // A poisoned lock only means another thread panicked mid-insert; the cache is
        // still a list of complete entries.
        let mut cache = self.cache.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, states)) = cache.iter().find(|(k, _)| *k == key) {
            return states.clone();
        }
        let states: Arc<[SatelliteState]> = self.compute(time_s).into();
        if cache.len() == CACHED_EPOCHS {
            cache.remove(0);
        }
        cache.push((key, states.clone()));
        states
    }

    fn compute(&self, time_s: f64) -> Vec<SatelliteState> {
        let unix_s = self.epoch_unix_s + time_s;
        let h = VELOCITY_HALF_STEP_S;
        let now = self.constellation.positions(unix_s);
        let before = self.constellation.positions(unix_s - h);
        let after = self.constellation.positions(unix_s + h);
        let min_up = BELOW_HORIZON_MARGIN_DEG.to_radians().sin();
        now.iter()
            .filter_map(|p| {
                let enu = self.frame.ecef_to_enu(p.ecef);
                let position_enu_m = Vector3::new(enu.east_m, enu.north_m, enu.up_m);
                if position_enu_m.z / position_enu_m.norm() < -min_up {
                    return None;
                }
                let at = |list: &[crate::orbits::SatellitePosition]| list.iter().find(|q| q.index == p.index).copied();
                let (b, a) = (at(&before)?, at(&after)?);
                let d = |f: fn(&sadesim_crds::geo::Ecef) -> f64| (f(&a.ecef) - f(&b.ecef)) / (2.0 * h);
                let v = self.frame.rotate_to_enu(d(|e| e.x_m), d(|e| e.y_m), d(|e| e.z_m));
                Some(SatelliteState {
                    index: p.index,
                    position_enu_m,
                    velocity_enu_mps: Vector3::new(v.east_m, v.north_m, v.up_m),
                })
            })
            .collect()
    }
}
