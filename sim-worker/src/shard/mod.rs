//! A physics shard: owns the drones `[first, first + count)` of the plan, steps them in
//! sync windows, and reports their states and events at each window boundary (DESIGN §5).

mod drone;

use std::sync::Arc;

use sadesim_crds::fleet::HomePlacement;
use sadesim_crds::geo::LocalFrame;
use sadesim_crds::plan::RunPlan;

use crate::autopilot::navigator::NavigatorConfig;
use crate::env::{EnvSample, Environment};
use crate::events::Event;
use crate::physics::ContactWorld;
use crate::pilot::scripted::{self, GroundHeight};
use crate::protocol::{FromShard, PROTOCOL_VERSION, ToShard};
use crate::sensors::SensorSuite;
use crate::vehicle;
use crate::world::World;

pub use drone::{CRASH_HORIZONTAL_MPS, CRASH_VERTICAL_MPS, DroneSim};

/// Why a shard could not be built.
#[derive(Debug, thiserror::Error)]
pub enum ShardError {
    /// The plan has no such shard.
    #[error("shard {0} is not in the plan")]
    NoSuchShard(u32),
    /// The plan names an airframe this build does not know.
    #[error("unknown airframe {0:?}")]
    UnknownAirframe(String),
    /// The flight controller cannot be built for an airframe.
    #[error("failed to build the controller: {0}")]
    Control(#[from] crate::autopilot::control::ControlError),
}

impl GroundHeight for World {
    fn ground_up_m(&self, east_m: f64, north_m: f64) -> f64 {
        World::ground_up_m(self, east_m, north_m)
    }
}

/// One shard's simulation.
#[derive(Debug)]
pub struct Shard {
    index: u32,
    world: Arc<World>,
    env: Environment,
    contacts: ContactWorld,
    drones: Vec<DroneSim>,
    /// The latest environment sample of each drone.
    env_samples: Vec<EnvSample>,
    /// Next physics step to simulate.
    step: u64,
    dt_s: f64,
    released: bool,
}

/// The environment is sampled every this many physics steps (100 Hz at 1 kHz) and held in
/// between: wind gusts and GNSS conditions change over tenths of seconds (the Dryden
/// filters' bandwidth is V/L, well under 1 Hz at low altitude), while sampling them every
/// millisecond cost a fifth of the step time (docs/performance.md).
pub const ENV_SAMPLE_DIVIDER: u64 = 10;

impl Shard {
    /// Builds shard `index` of `plan` in `world`.
    ///
    /// # Errors
    /// See [`ShardError`].
    pub fn new(plan: &RunPlan, index: u32, world: Arc<World>) -> Result<Self, ShardError> {
        let shard = *plan.shards.get(index as usize).ok_or(ShardError::NoSuchShard(index))?;
        let spec = &plan.spec;
        let frame = LocalFrame::new(spec.origin.geo());
        let env_spec = spec.environment();
        let planned = plan.shard_drones(&shard);
        let mut drones = Vec::with_capacity(planned.len());
        for d in planned {
            let group = &spec.fleet[d.group_index as usize];
            let airframe =
                vehicle::preset(&d.airframe).ok_or_else(|| ShardError::UnknownAirframe(d.airframe.clone()))?;
            let home_en = nalgebra::Vector2::new(d.home.local.east_m, d.home.local.north_m);
            let home_area = match &group.homes {
                HomePlacement::RandomInArea(a) => Some(a),
                HomePlacement::Areas(list) => list.get(d.member as usize % list.len()),
                HomePlacement::Explicit(_) => None,
            };
            let mission = group
                .mission
                .as_ref()
                .map(|m| scripted::expand(m, &frame, world.as_ref(), home_en, home_area, plan.seed, d.index));
            // Return below the group's ceiling (PX4's 60 m default is above many groups' limits).
            let navigator = NavigatorConfig {
                rtl_altitude_m: (group.altitude.max_agl_m * 0.8).min(60.0),
                ..NavigatorConfig::default()
            };
            let sensors = SensorSuite::new(env_spec.gnss.as_ref(), plan.seed, d.index);
            drones.push(DroneSim::new(
                d.clone(),
                airframe,
                sensors,
                &world,
                navigator,
                spec.origin.altitude_msl_m,
                mission,
            )?);
        }
        let indices: Vec<u32> = planned.iter().map(|d| d.index).collect();
        let groups: Vec<String> = planned.iter().map(|d| d.group.clone()).collect();
        let env = Environment::from_spec(&env_spec, plan.seed, &indices, &groups);
        let balls: Vec<_> = drones.iter().map(|d| (d.position_enu_m(), d.radius_m)).collect();
        let contacts = ContactWorld::new(world.buildings(), &balls);
        Ok(Self {
            index,
            world,
            env,
            env_samples: vec![EnvSample::default(); drones.len()],
            contacts,
            drones,
            step: 0,
            dt_s: 1.0 / f64::from(plan.physics_rate_hz),
            released: false,
        })
    }

    /// The greeting sent when the shard is built.
    pub fn hello(&self) -> FromShard {
        FromShard::Hello { version: PROTOCOL_VERSION, shard: self.index, drones: self.drones.len() as u32 }
    }

    pub fn drones(&self) -> &[DroneSim] {
        &self.drones
    }

    /// Handles one coordinator message; `None` means the shard is done.
    pub fn handle(&mut self, msg: ToShard) -> Option<FromShard> {
        match msg {
            ToShard::Advance { until_step, release_pilots } => {
                if release_pilots {
                    self.released = true;
                }
                let events = self.advance(until_step);
                Some(FromShard::Advanced {
                    shard: self.index,
                    step: self.step,
                    ready: self.drones.iter().all(|d| d.is_ready() || d.is_crashed()),
                    drones: self.drones.iter().map(DroneSim::snapshot).collect(),
                    events,
                })
            }
            ToShard::Stop => None,
        }
    }

    /// Simulates up to (excluding) `until_step`, returning the events.
    pub fn advance(&mut self, until_step: u64) -> Vec<Event> {
        let mut events = Vec::new();
        while self.step < until_step {
            let t = self.step as f64 * self.dt_s;
            for (i, drone) in self.drones.iter_mut().enumerate() {
                if drone.is_crashed() {
                    continue;
                }
                if self.step.is_multiple_of(ENV_SAMPLE_DIVIDER) {
                    let env_dt_s = self.dt_s * ENV_SAMPLE_DIVIDER as f64;
                    self.env_samples[i] = self.env.sample(&drone.sample_context(i, t, env_dt_s));
                }
                drone.step(self.step + 1, t, self.dt_s, &self.env_samples[i], &self.world, self.released);
                self.contacts.set_position(i, &drone.position_enu_m());
            }
            self.contacts.step();
            // Times are step counts times dt, never sums, so they print the same everywhere.
            let t_end = (self.step + 1) as f64 * self.dt_s;
            for (i, drone) in self.drones.iter_mut().enumerate() {
                if !drone.is_crashed() && self.contacts.touches_building(i) {
                    let speed = drone.speed_mps();
                    drone.crash("building", speed);
                    self.contacts.disable(i);
                }
                let index = drone.plan.index;
                events.extend(drone.take_events().into_iter().map(|kind| Event {
                    time_s: t_end,
                    drone: Some(index),
                    kind,
                }));
            }
            self.step += 1;
        }
        events
    }
}
