//! `Environment`: the ordered list of factors of one shard, built from the run spec.

use std::fmt;

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
    ) -> Environment {
        debug_assert_eq!(drone_global_indices.len(), group_of_drone.len());
        let mut out = Environment::new();
        if let Some(wind) = &env.wind {
            out.push(Box::new(WindFactor::from_spec(wind, seed, drone_global_indices)));
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
