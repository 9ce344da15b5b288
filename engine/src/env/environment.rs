//! `Environment`: the ordered list of factors of one shard, built from the run spec.

use std::fmt;
use std::sync::Arc;

use sadesim_crds::environment as spec;

use super::gnss_outage::GnssOutageFactor;
use super::sample::{EnvSample, EnvironmentFactor, SampleContext};
use super::wind::WindFactor;

/// The environment factors of one shard, applied in order at each sample.
pub struct Environment {
    factors: Vec<Box<dyn EnvironmentFactor>>,
}

impl Environment {
    /// Factors from the run spec for a shard's drones.
    ///
    /// `drone_global_indices[i]` and `group_of_drone[i]` describe the shard's drone `i`
    /// (`SampleContext::drone`). Random streams are keyed by the global index, so a drone's
    /// environment does not depend on which shard flies it (DESIGN §5).
    ///
    /// # Assumptions
    /// Both slices have the same length (the spec was validated and planned).
    pub fn from_spec(
        env: &spec::Environment,
        seed: u64,
        drone_global_indices: &[u32],
        group_of_drone: &[String],
        urban_wind: Option<Arc<sadesim_wind::UrbanWindField>>,
    ) -> Environment {
        debug_assert_eq!(drone_global_indices.len(), group_of_drone.len());
        let mut out = Environment::new();
        if let Some(wind) = &env.wind {
            out.push(Box::new(WindFactor::from_spec(wind, seed, drone_global_indices, urban_wind)));
        }
        if let Some(gnss) = &env.gnss
            && !gnss.dropouts.is_empty()
        {
            out.push(Box::new(GnssOutageFactor::from_spec(&gnss.dropouts, group_of_drone)));
        }
        out
    }

    /// No factors: calm air and open sky everywhere.
    pub fn new() -> Environment {
        Environment { factors: Vec::new() }
    }

    /// Appends a factor; it runs after the existing ones and may refine what they wrote.
    pub fn push(&mut self, factor: Box<dyn EnvironmentFactor>) {
        self.factors.push(factor);
    }

    /// Names of the factors, in application order.
    pub fn factor_names(&self) -> Vec<&'static str> {
        self.factors.iter().map(|f| f.name()).collect()
    }

    /// The environment at one drone: the default sample refined by each factor in order.
    /// Call once per drone per physics step (factors step their filters with `ctx.dt_s`).
    pub fn sample(&mut self, ctx: &SampleContext) -> EnvSample {
        let mut out = EnvSample::default();
        for factor in &mut self.factors {
            factor.apply(ctx, &mut out);
        }
        out
    }
}

impl Default for Environment {
    fn default() -> Self {
        Self::new()
    }
}

impl fmt::Debug for Environment {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Environment").field("factors", &self.factor_names()).finish()
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;
    use sadesim_crds::environment::{Turbulence, Wind};

    use super::*;

    fn spec() -> spec::Environment {
        let wind = Wind {
            speed_mps: 5.0,
            direction_from_deg: 225.0,
            reference_height_m: None,
            turbulence: Turbulence::Light,
            urban: None,
        };
        spec::Environment { wind: Some(wind), gnss: None }
    }

    fn series(env: &mut Environment, drone: usize, steps: u32, dt_s: f64) -> Vec<Vector3<f64>> {
        (0..steps)
            .map(|k| {
                let ctx = SampleContext {
                    drone,
                    position_enu_m: Vector3::new(0.0, 0.0, 30.0),
                    height_agl_m: 30.0,
                    airspeed_mps: 5.0,
                    time_s: f64::from(k) * dt_s,
                    dt_s,
                };
                env.sample(&ctx).wind_enu_mps
            })
            .collect()
    }

    fn groups(n: usize) -> Vec<String> {
        vec!["g".to_string(); n]
    }

    #[test]
    fn turbulence_is_reproducible_per_seed_and_drone_and_independent_of_sharding() {
        let mut shard_a = Environment::from_spec(&spec(), 42, &[5, 9], &groups(2), None);
        let mut shard_b = Environment::from_spec(&spec(), 42, &[9], &groups(1), None);
        let a9 = series(&mut shard_a, 1, 500, 0.1);
        assert_eq!(a9, series(&mut shard_b, 0, 500, 0.1), "drone 9 alone in a shard sees the same wind");
        let mut again = Environment::from_spec(&spec(), 42, &[5, 9], &groups(2), None);
        let a5 = series(&mut shard_a, 0, 500, 0.1);
        series(&mut again, 1, 500, 0.1);
        assert_eq!(a5, series(&mut again, 0, 500, 0.1));
        let mut other_seed = Environment::from_spec(&spec(), 43, &[5], &groups(1), None);
        assert_ne!(a5, series(&mut other_seed, 0, 500, 0.1));
    }

    #[test]
    fn different_drones_get_uncorrelated_gusts() {
        let mut env = Environment::from_spec(&spec(), 7, &[0, 1], &groups(2), None);
        // 1 s steps (the filters are exact at any step) over 20 000 s; vertical gusts
        // (L_w = 30 m, T = 6 s): ~1700 independent samples, so |correlation| of independent
        // streams is ~0.025 and stays well below 0.1.
        let a: Vec<f64> = series(&mut env, 0, 20_000, 1.0).iter().map(|w| w.z).collect();
        let b: Vec<f64> = series(&mut env, 1, 20_000, 1.0).iter().map(|w| w.z).collect();
        let dot = |x: &[f64], y: &[f64]| x.iter().zip(y).map(|(p, q)| p * q).sum::<f64>();
        let corr = dot(&a, &b) / (dot(&a, &a) * dot(&b, &b)).sqrt();
        eprintln!("vertical gust correlation between drones 0 and 1: {corr:.4}");
        assert!(corr.abs() < 0.1, "{corr}");
    }

    #[test]
    fn factors_follow_the_spec_and_debug_lists_them() {
        assert!(
            Environment::from_spec(&spec::Environment::default(), 1, &[0], &groups(1), None).factor_names().is_empty()
        );
        let env = Environment::from_spec(&spec(), 1, &[0], &groups(1), None);
        assert_eq!(env.factor_names(), vec!["wind"]);
        assert_eq!(format!("{env:?}"), r#"Environment { factors: ["wind"] }"#);
    }
}
