//! Helpers shared by the integration tests.

use std::sync::Arc;

use sadesim_crds::SimulationRun;
use sadesim_crds::fleet::{Mission, MissionItem};
use sadesim_crds::geo::GeoPoint;
use sadesim_crds::plan::RunPlan;
use sadesim_engine::events::Event;
use sadesim_engine::protocol::{DroneSnapshot, FromShard, ToShard};
use sadesim_engine::shard::Shard;
use sadesim_world::{World, WorldInputs};

/// Plans a run that must be valid.
pub fn plan(run: &SimulationRun) -> RunPlan {
    sadesim_planner::plan(run).expect("a valid run")
}

/// Flies shard 0 of `run` for `seconds` of simulated time after a warm-up (until every
/// drone is ready, as the coordinator releases pilots), releasing the pilots then; returns every event and drone 0's true state at
/// every `sample_steps` physics steps.
pub fn fly(run: &SimulationRun, seconds: u64, sample_steps: u64) -> (Vec<Event>, Vec<DroneSnapshot>) {
    let plan = plan(run);
    let world = world(&plan);
    fly_in(&plan, world, None, seconds, sample_steps)
}

/// As [`fly`], for a planned run in a given world and GNSS sky.
pub fn fly_in(
    plan: &RunPlan,
    world: Arc<World>,
    sky: Option<Arc<sadesim_gnss::RunSky>>,
    seconds: u64,
    sample_steps: u64,
) -> (Vec<Event>, Vec<DroneSnapshot>) {
    let steps_per_s = u64::from(plan.physics_rate_hz);
    let mut shard =
        Shard::new(plan, 0, &sadesim_engine::shard::Surroundings::new(plan, world, sky)).expect("the shard builds");
    // Warm up as the coordinator does: pilots are released once every drone is ready (a
    // position estimate with a settled height, a few seconds of fixes), at least 0.3 s.
    let mut warm_up = steps_per_s * 3 / 10;
    let mut events = shard.advance(warm_up);
    while !shard.drones().iter().all(|d| d.is_ready() || d.is_crashed()) {
        assert!(warm_up < 60 * steps_per_s, "the drones are not ready after a minute");
        warm_up += steps_per_s / 10;
        events.extend(shard.advance(warm_up));
    }
    let mut track = Vec::new();
    for window in 1..=seconds * steps_per_s / sample_steps {
        let until_step = warm_up + window * sample_steps;
        let Some(FromShard::Advanced { drones, events: e, .. }) =
            shard.handle(ToShard::Advance { until_step, release_pilots: true, leases: None })
        else {
            panic!("the shard stopped")
        };
        events.extend(e);
        track.push(drones[0].clone());
    }
    (events, track)
}

/// Take off to `takeoff_agl_m`, fly to `to` (a ground point: only its latitude and
/// longitude count) at `agl_m`, hold `hold_s`, land there.
pub fn fly_to_and_land(to: GeoPoint, takeoff_agl_m: f64, agl_m: f64, hold_s: Option<f64>, speed_mps: f64) -> Mission {
    Mission {
        items: vec![
            MissionItem::Takeoff { altitude_agl_m: takeoff_agl_m },
            MissionItem::Waypoint {
                latitude_deg: to.latitude_deg,
                longitude_deg: to.longitude_deg,
                altitude_agl_m: agl_m,
                hold_s,
            },
            MissionItem::Land {},
        ],
        speed_mps: Some(speed_mps),
    }
}

/// A `spec.environment` written as its YAML/JSON document (`{"wind": {...}}`), as a user
/// writes it.
///
/// # Panics
/// When the document is not a valid environment.
pub fn environment(document: serde_json::Value) -> sadesim_crds::environment::Environment {
    serde_json::from_value(document).expect("a valid spec.environment")
}

/// The world a plan's shards share.
pub fn world(plan: &RunPlan) -> Arc<World> {
    Arc::new(World::generate(&WorldInputs::from_spec(&plan.spec, &[])))
}

/// Held by a test for as long as its run serves MAVLink endpoints (`RunOptions::mavlink`):
/// they bind fixed ports (UDP 14540+i and 24600+i on 127.0.0.1), so two such runs in one
/// test binary must not overlap. Every other test runs with `mavlink: false`.
pub fn mavlink_ports() -> std::sync::MutexGuard<'static, ()> {
    static PORTS: std::sync::Mutex<()> = std::sync::Mutex::new(());
    PORTS.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// The seeds a statistical flight test flies: ten noise realizations (sensor noise,
/// turbulence, the procedural city and the homes all follow the seed).
///
/// A tolerance held by one realization is partly the luck of that seed: any change to how
/// random numbers are drawn (a faster normal sampler, one draw more or less per step) gives
/// every test a new realization. Tests that judge flight accuracy against a tolerance judge
/// the median of these, so they test the autopilot, not the seed.
pub const SEEDS: [u64; 10] = [1, 2, 3, 4, 5, 6, 7, 8, 9, 10];

/// `f(seed)` for every seed of [`SEEDS`], each on a thread of its own (the flights are
/// independent), in the order of the seeds.
pub fn over_seeds<T: Send>(f: impl Fn(u64) -> T + Sync) -> Vec<T> {
    let f = &f;
    std::thread::scope(|s| {
        let handles: Vec<_> = SEEDS.iter().map(|&seed| s.spawn(move || f(seed))).collect();
        handles.into_iter().map(|h| h.join().expect("a flight panicked")).collect()
    })
}

/// The median of `values` (the mean of the middle two for an even count).
///
/// # Panics
/// On an empty slice or a NaN.
pub fn median(values: &[f64]) -> f64 {
    assert!(!values.is_empty(), "the median of nothing");
    let mut v = values.to_vec();
    v.sort_by(|a, b| a.partial_cmp(b).expect("no NaN"));
    let n = v.len();
    if n % 2 == 1 { v[n / 2] } else { (v[n / 2 - 1] + v[n / 2]) / 2.0 }
}

#[cfg(test)]
mod tests {
    use super::median;

    #[test]
    fn the_median_is_the_middle_value() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0, 3.0, 2.0]), 2.5);
        assert_eq!(median(&[0.5]), 0.5);
    }
}
