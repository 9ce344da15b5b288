//! `GnssOutageFactor`: scheduled GNSS dropouts from the spec, per fleet group.

use sadesim_crds::environment::GnssDropout;

use super::sample::{EnvSample, EnvironmentFactor, SampleContext};

/// No GNSS for a drone inside any of its group's dropout windows `[start, start + duration)`
/// (simulated seconds). A dropout with no groups applies to every drone.
#[derive(Debug)]
pub struct GnssOutageFactor {
    /// Per shard drone (`SampleContext::drone`): its windows as (start_s, end_s).
    windows_s: Vec<Vec<(f64, f64)>>,
}

impl GnssOutageFactor {
    /// `group_of_drone[i]` is the fleet group of the shard's drone `i`.
    pub fn from_spec(dropouts: &[GnssDropout], group_of_drone: &[String]) -> Self {
        let windows_s = group_of_drone
            .iter()
            .map(|group| {
                dropouts
                    .iter()
                    .filter(|d| d.groups.is_empty() || d.groups.contains(group))
                    .map(|d| {
                        let start_s = seconds(d.start.into(), d.start.is_negative());
                        (start_s, start_s + seconds(d.duration.into(), d.duration.is_negative()))
                    })
                    .collect()
            })
            .collect();
        Self { windows_s }
    }

    /// True when the shard's drone `drone` has no GNSS at `time_s`.
    pub fn is_out(&self, drone: usize, time_s: f64) -> bool {
        self.windows_s.get(drone).is_some_and(|w| w.iter().any(|&(start, end)| (start..end).contains(&time_s)))
    }
}

/// A Kubernetes duration (magnitude and sign) as signed seconds.
fn seconds(magnitude: std::time::Duration, negative: bool) -> f64 {
    if negative { -magnitude.as_secs_f64() } else { magnitude.as_secs_f64() }
}

impl EnvironmentFactor for GnssOutageFactor {
    fn name(&self) -> &'static str {
        "gnss-outage"
    }

    fn apply(&mut self, ctx: &SampleContext, out: &mut EnvSample) {
        if self.is_out(ctx.drone, ctx.time_s) {
            out.gnss.available = false;
        }
    }
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use nalgebra::Vector3;
    use sadesim_crds::environment::{Environment as EnvSpec, Gnss};

    use super::*;
    use crate::env::Environment;

    fn dropout(start_s: u64, duration_s: u64, groups: &[&str]) -> GnssDropout {
        GnssDropout {
            start: Duration::from_secs(start_s).into(),
            duration: Duration::from_secs(duration_s).into(),
            groups: groups.iter().map(|g| g.to_string()).collect(),
        }
    }

    fn available(env: &mut Environment, drone: usize, time_s: f64) -> bool {
        let ctx = SampleContext {
            drone,
            position_enu_m: Vector3::zeros(),
            height_agl_m: 20.0,
            airspeed_mps: 0.0,
            time_s,
            dt_s: 0.01,
        };
        env.sample(&ctx).gnss.available
    }

    #[test]
    fn dropout_windows_apply_to_listed_groups_only() {
        let gnss = Gnss {
            constellation: None,
            rate_hz: None,
            horizontal_sigma_m: None,
            vertical_sigma_m: None,
            bias_walk_m_per_sqrt_s: None,
            bias: None,
            dropouts: vec![dropout(10, 5, &["survey"]), dropout(30, 2, &[])],
        };
        let spec = EnvSpec { wind: None, gnss: Some(gnss) };
        let groups = ["survey".to_string(), "delivery".to_string()];
        let mut env = Environment::from_spec(&spec, 1, &[0, 1], &groups, None);
        assert_eq!(env.factor_names(), vec!["gnss-outage"]);
        for (t, survey, delivery) in [
            (0.0, true, true),
            (9.99, true, true),
            (10.0, false, true),
            (14.99, false, true),
            (15.0, true, true),
            (29.99, true, true),
            (30.0, false, false),
            (31.5, false, false),
            (32.0, true, true),
        ] {
            assert_eq!(available(&mut env, 0, t), survey, "survey at {t}");
            assert_eq!(available(&mut env, 1, t), delivery, "delivery at {t}");
        }
    }
}
