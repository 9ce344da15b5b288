//! `WindFactor`: mean wind (the log profile, or the urban field around buildings) plus
//! per-drone Dryden turbulence, in world ENU.

use std::sync::Arc;

use nalgebra::Vector3;
use sadesim_crds::environment::{Turbulence, Wind};
use sadesim_crds::random::{Purpose, Rng};
use sadesim_wind::UrbanWindField;

use super::dryden::{DrydenFilter, DrydenScales, M_PER_FT, wind_speed_at_20ft_mps};
use super::sample::{EnvSample, EnvironmentFactor, SampleContext};
use super::wind_profile::MeanWind;

/// Turbulence ramps linearly from 0 at the roughness length z0 to full strength at the
/// bottom of the Dryden model's range (10 ft), metres: a landed drone sits in the roughness
/// sublayer, where the mean profile is 0 too.
const FULL_TURBULENCE_HEIGHT_M: f64 = 10.0 * M_PER_FT;

/// Mean wind with a log height profile plus Dryden turbulence (MIL-F-8785C low altitude),
/// one seeded filter per drone. Adds its wind to `EnvSample::wind_enu_mps`.
#[derive(Debug)]
pub struct WindFactor {
    mean: MeanWind,
    /// W20 (wind at 20 ft) setting the turbulence intensity, m/s; `None` = no turbulence.
    w20_mps: Option<f64>,
    /// Per shard drone, indexed by `SampleContext::drone`.
    drones: Vec<DroneGust>,
    /// The wind around the buildings, replacing the plain profile where it has cells.
    urban: Option<Arc<UrbanWindField>>,
    /// The mean wind at the field's reference height, m/s: what its factors multiply
    /// (computed once, not per sample).
    urban_reference_mps: f64,
}

/// In a wake the gusts grow: the turbulence scale is multiplied by `1 + deficit`, where the
/// deficit is the share of the undisturbed wind speed the buildings took away (0 in the
/// open, up to 1 in still air behind a block): urban canopies measure turbulence
/// intensities of 0.3-0.5 against 0.15-0.2 over open terrain (Roth 2000), about double.
const MAX_WAKE_TURBULENCE_GAIN: f64 = 1.0;

#[derive(Debug)]
struct DroneGust {
    filter: DrydenFilter,
    /// Time of the last filter step, s: sampling twice at one time does not step twice.
    stepped_at_s: f64,
    gust_enu_mps: Vector3<f64>,
}

impl WindFactor {
    /// From the spec's wind (urban roughness) for the shard's drones; each drone's filter
    /// draws from `(seed, global drone index, Purpose::Turbulence)`.
    /// `urban` is the run's field when it has one (`env::urban_wind_field`).
    pub fn from_spec(wind: &Wind, seed: u64, drone_global_indices: &[u32], urban: Option<Arc<UrbanWindField>>) -> Self {
        let mean = MeanWind::urban(wind.speed_mps, wind.direction_from_deg, wind.reference_height_m);
        let urban_reference_mps = urban.as_ref().map_or(0.0, |f| mean.speed_at_mps(f.profile.reference_height_m));
        Self { urban, urban_reference_mps, ..Self::new(mean, wind.turbulence, seed, drone_global_indices) }
    }

    pub fn new(mean: MeanWind, turbulence: Turbulence, seed: u64, drone_global_indices: &[u32]) -> Self {
        let drones = drone_global_indices
            .iter()
            .map(|&index| DroneGust {
                filter: DrydenFilter::new(Rng::stream(seed, u64::from(index), Purpose::Turbulence)),
                stepped_at_s: f64::NEG_INFINITY,
                gust_enu_mps: Vector3::zeros(),
            })
            .collect();
        Self { mean, w20_mps: wind_speed_at_20ft_mps(turbulence), drones, urban: None, urban_reference_mps: 0.0 }
    }

    /// Gust at the drone, world ENU, m/s; steps the drone's filter once per new `time_s`.
    fn gust_enu_mps(&mut self, ctx: &SampleContext) -> Vector3<f64> {
        let Some(w20_mps) = self.w20_mps else { return Vector3::zeros() };
        debug_assert!(ctx.drone < self.drones.len(), "drone {} not in this shard", ctx.drone);
        let Some(drone) = self.drones.get_mut(ctx.drone) else { return Vector3::zeros() };
        if ctx.time_s > drone.stepped_at_s {
            let scales = DrydenScales::low_altitude(ctx.height_agl_m, w20_mps);
            let gust_uvw = drone.filter.step(&scales, ctx.airspeed_mps, ctx.dt_s);
            // Mean-wind frame -> ENU: u downwind, v = up × u (to the left of the wind), w up.
            let u_hat = self.mean.downwind_enu();
            let w_hat = Vector3::z();
            let v_hat = w_hat.cross(&u_hat);
            let z0 = self.mean.roughness_length_m;
            let ramp = ((ctx.height_agl_m - z0) / (FULL_TURBULENCE_HEIGHT_M - z0).max(1e-3)).clamp(0.0, 1.0);
            drone.gust_enu_mps = ramp * (u_hat * gust_uvw.x + v_hat * gust_uvw.y + w_hat * gust_uvw.z);
            drone.stepped_at_s = ctx.time_s;
        }
        drone.gust_enu_mps
    }
}

impl WindFactor {
    /// The mean wind at the drone, world ENU, m/s, and the gain on its gusts: the profile
    /// and 1 in the open; among buildings the field's factor times the wind 10 m above open
    /// ground (the field's reference), and the wake gain.
    fn mean_and_gust_gain(&self, ctx: &SampleContext) -> (Vector3<f64>, f64) {
        let Some(field) = &self.urban else { return (self.mean.velocity_enu_mps(ctx.height_agl_m), 1.0) };
        let reference_mps = self.urban_reference_mps;
        let factor = field
            .factor_at(&ctx.position_enu_m, self.mean.direction_from_deg, ctx.height_agl_m)
            .expect("urban_wind_field computed the sectors of the run's direction");
        let free = field.profile.factor(ctx.height_agl_m);
        let deficit = if free > 0.0 { (1.0 - factor.norm() / free).clamp(0.0, 1.0) } else { 0.0 };
        (factor * reference_mps, 1.0 + MAX_WAKE_TURBULENCE_GAIN * deficit)
    }
}

impl EnvironmentFactor for WindFactor {
    fn name(&self) -> &'static str {
        "wind"
    }

    fn apply(&mut self, ctx: &SampleContext, out: &mut EnvSample) {
        let (mean, gust_gain) = self.mean_and_gust_gain(ctx);
        out.wind_enu_mps += mean + self.gust_enu_mps(ctx) * gust_gain;
    }
}

#[cfg(test)]
mod tests;
