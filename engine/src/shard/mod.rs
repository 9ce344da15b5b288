//! A physics shard: owns the drones `[first, first + count)` of the plan, steps them in
//! sync windows, and reports their states and events at each window boundary (DESIGN §5).
//!
//! The shard is a pure core: it does no I/O. Its drones' MAVLink sessions exchange frames
//! through queues the shard owns ([`MavlinkQueues`]); the caller moves them to and from
//! the sockets through a [`MavlinkIo`] (`sim_worker::shard_io::ShardSockets`), called at fixed
//! points of [`Shard::advance_with`].

mod drone;
mod mavlink_io;
mod surroundings;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod urban_wind_tests;

use std::sync::Arc;

use sadesim_crds::fleet::HomePlacement;
use sadesim_crds::geo::LocalFrame;
use sadesim_crds::plan::RunPlan;

use crate::airspace::volume::ZoneVolume;
use crate::env::{EnvSample, Environment};
use crate::events::{CrashCause, Event};
use crate::pilot::scripted::{self, GroundHeight};
use crate::preset;
use crate::protocol::{FromShard, PROTOCOL_VERSION, ToShard};
use crate::sensors::SensorSuite;
use sadesim_world::World;

pub use crate::vehicle::ground::{CRASH_HORIZONTAL_MPS, CRASH_VERTICAL_MPS};
pub use drone::DroneSim;
pub use mavlink_io::{MavlinkIo, MavlinkQueues, NoMavlinkIo};
pub use surroundings::Surroundings;

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
    /// The sky and the plan disagree: the run names a GNSS constellation and no sky was
    /// given, or a sky was given to a run without one (a caller's bug; the roles load the
    /// sky with `sim_worker::roles::sky`).
    #[error("spec.environment.gnss.constellation is {0} but the shard was given {1}")]
    SkyMismatch(&'static str, &'static str),
    /// The urban wind field and the plan disagree (a caller's bug: `Surroundings::new`
    /// computes the field the run wants).
    #[error("the run {0} an urban wind field but the shard was given {1}")]
    WindMismatch(&'static str, &'static str),
    /// The field given lacks a sector the run's wind direction blends (a field loaded from
    /// a cache entry of fewer sectors, or a caller's bug).
    #[error(
        "the urban wind field has no sector {sector} ({direction_from_deg}°), which a wind from {wind_from_deg}° needs"
    )]
    WindSector { sector: u32, direction_from_deg: f64, wind_from_deg: f64 },
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
    drones: Vec<DroneSim>,
    /// The latest environment sample of each drone.
    env_samples: Vec<EnvSample>,
    /// Next physics step to simulate.
    step: u64,
    dt_s: f64,
    released: bool,
    /// Sim time of the next MAVLink exchange.
    next_mavlink_io_s: f64,
    /// Every drone's MAVLink queues (index = position in `drones`); empty without MAVLink.
    mavlink: Vec<MavlinkQueues>,
    /// The run's zones, for the geofences; empty when no drone of the shard has one.
    zones: Vec<ZoneVolume>,
}

/// Sim seconds between MAVLink socket rounds. Every round costs a datagram per peer for
/// each drone (reads only where the shard's readiness wait found data), so rounds as often
/// as the 10 ms windows would cost a shard more than its physics. Messages
/// are still built at their own rates (100 Hz ATTITUDE is 100 ATTITUDE messages a second,
/// each with its own timestamp), only sent in batches; 20 ms adds at most 20 ms of
/// latency, below what SDKs and ground stations notice (MAVSDK's offboard needs > 2 Hz
/// setpoints).
pub const MAVLINK_IO_PERIOD_S: f64 = 0.02;

/// The MAVLink system and component id of the routers' own frames (`sim_worker`'s router
/// registers with the drones with a HEARTBEAT from them while a ground station listens, or
/// a TCP health check connects): not the pilot, so they do not end a hold.
pub const ROUTER_SYSTEM_ID: u8 = 253;
pub const ROUTER_COMPONENT_ID: u8 = 240;

/// The environment is sampled every this many physics steps (100 Hz at 1 kHz) and held in
/// between: wind gusts and GNSS conditions change over tenths of seconds (the Dryden
/// filters' bandwidth is V/L, well under 1 Hz at low altitude), while sampling them every
/// millisecond would cost a large share of the step for no change in the flight.
pub const ENV_SAMPLE_DIVIDER: u64 = 10;

impl Shard {
    /// Builds shard `index` of `plan` in its surroundings: the world, the sky when the run
    /// names a GNSS constellation (its drones then carry the ranging receiver), the urban
    /// wind field when it has wind among buildings.
    ///
    /// # Errors
    /// See [`ShardError`].
    pub fn new(plan: &RunPlan, index: u32, surroundings: &Surroundings) -> Result<Self, ShardError> {
        let Surroundings { world, sky, wind } = surroundings.clone();
        let shard = *plan.shards.get(index as usize).ok_or(ShardError::NoSuchShard(index))?;
        let spec = &plan.spec;
        let wants_sky = spec.environment().gnss.is_some_and(|g| g.constellation.is_some());
        match (wants_sky, &sky) {
            (true, None) => return Err(ShardError::SkyMismatch("set", "no sky")),
            (false, Some(_)) => return Err(ShardError::SkyMismatch("absent", "a sky")),
            _ => {}
        }
        match (crate::env::wants_urban_wind(spec, &world), &wind) {
            (true, None) => return Err(ShardError::WindMismatch("wants", "none")),
            (false, Some(_)) => return Err(ShardError::WindMismatch("does not want", "one")),
            _ => {}
        }
        if let (Some(field), Some(w)) = (&wind, spec.environment().wind) {
            let wind_from_deg = w.direction_from_deg;
            if let Some((sector, _)) =
                field.sectors_for(wind_from_deg).into_iter().find(|(k, _)| field.sector(*k).is_none())
            {
                let direction_from_deg = f64::from(sector) * field.sector_step_deg();
                return Err(ShardError::WindSector { sector, direction_from_deg, wind_from_deg });
            }
        }
        let frame = LocalFrame::new(spec.origin.geo());
        let env_spec = spec.environment();
        let planned = plan.shard_drones(&shard);
        let mut drones = Vec::with_capacity(planned.len());
        for d in planned {
            let group = &spec.fleet[d.group_index as usize];
            let preset =
                preset::Preset::named(&d.airframe).ok_or_else(|| ShardError::UnknownAirframe(d.airframe.clone()))?;
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
            // Return below the group's ceiling (the same tunables the parameter table reports).
            let navigator = crate::mavlink::params::plan::navigator_config(group);
            let sensors =
                SensorSuite::new(env_spec.gnss.as_ref(), sky.as_ref().map(|s| (s, &world)), plan.seed, d.index);
            let mut drone =
                DroneSim::new(d.clone(), preset, sensors, &world, navigator, spec.origin.altitude_msl_m, mission)?;
            if let Some(action) = group.geofence {
                drone.enable_geofence(action, spec.zones.len());
            }
            drones.push(drone);
        }
        let fenced = planned.iter().any(|d| spec.fleet[d.group_index as usize].geofence.is_some());
        let indices: Vec<u32> = planned.iter().map(|d| d.index).collect();
        let groups: Vec<String> = planned.iter().map(|d| d.group.clone()).collect();
        let env = Environment::from_spec(&env_spec, plan.seed, &indices, &groups, wind);
        Ok(Self {
            index,
            world,
            env,
            env_samples: vec![EnvSample::default(); drones.len()],
            drones,
            step: 0,
            dt_s: 1.0 / f64::from(plan.physics_rate_hz),
            released: false,
            next_mavlink_io_s: 0.0,
            mavlink: Vec::new(),
            zones: if fenced { spec.zones.iter().map(|z| ZoneVolume::new(z, &frame)).collect() } else { Vec::new() },
        })
    }

    /// Gives every drone of the shard a MAVLink session (PX4 SITL's identity: system id,
    /// parameters) and its queues; SYSTEM_TIME counts from `unix_epoch_at_start_us` (µs) at
    /// sim time 0. Opens no socket.
    pub fn enable_mavlink(&mut self, plan: &RunPlan, unix_epoch_at_start_us: u64) -> Result<(), ShardError> {
        use crate::mavlink::session::Session;
        use crate::mavlink::telemetry::VehicleIdentity;
        let frame = LocalFrame::new(plan.spec.origin.geo());
        for drone in &mut self.drones {
            let d = &drone.plan;
            let id =
                VehicleIdentity { system_id: d.system_id, frame, unix_epoch_at_start_us, uid: u64::from(d.index) + 1 };
            let params = crate::mavlink::params::plan::drone_table(plan, d)
                .ok_or_else(|| ShardError::UnknownAirframe(d.airframe.clone()))?;
            drone.attach_session(Session::new(id, params));
        }
        self.mavlink = (0..self.drones.len()).map(|_| MavlinkQueues::default()).collect();
        Ok(())
    }

    /// Every drone's MAVLink queues (index = position in [`Shard::drones`]); empty until
    /// [`Shard::enable_mavlink`].
    pub fn mavlink_queues(&mut self) -> &mut [MavlinkQueues] {
        &mut self.mavlink
    }

    /// The greeting sent when the shard is built.
    pub fn hello(&self) -> FromShard {
        FromShard::Hello { version: PROTOCOL_VERSION, shard: self.index, drones: self.drones.len() as u32 }
    }

    pub fn drones(&self) -> &[DroneSim] {
        &self.drones
    }

    /// Handles one coordinator message; `None` means the shard is done. MAVLink frames stay
    /// in their queues ([`NoMavlinkIo`]).
    pub fn handle(&mut self, msg: ToShard) -> Option<FromShard> {
        self.handle_with(msg, &mut NoMavlinkIo)
    }

    /// [`Shard::handle`], with `io` carrying the MAVLink queues ([`Shard::advance_with`]).
    pub fn handle_with(&mut self, msg: ToShard, io: &mut impl MavlinkIo) -> Option<FromShard> {
        match msg {
            ToShard::Advance { until_step, release_pilots, leases } => {
                if release_pilots {
                    self.released = true;
                }
                if let Some(leases) = leases {
                    self.set_leases(&leases);
                }
                let events = self.advance_with(until_step, io);
                Some(FromShard::Advanced {
                    shard: self.index,
                    step: self.step,
                    ready: self.drones.iter().all(|d| d.is_ready() || d.is_crashed()),
                    drones: self.drones.iter().map(DroneSim::snapshot).collect(),
                    events,
                })
            }
            ToShard::Hold { heartbeat } => Some(self.hold(heartbeat, io)),
            ToShard::Stop => None,
        }
    }

    /// A hold at the release ([`ToShard::Hold`]): nothing is simulated. What the drones'
    /// peers sent is read into the inbound queues, where the sessions find it at the next
    /// exchange (as if it had arrived just before it); with `heartbeat` every drone's
    /// HEARTBEAT at the held time leaves at once. Answers which drones have frames waiting
    /// from a peer other than a router's own ([`ROUTER_SYSTEM_ID`]).
    fn hold(&mut self, heartbeat: bool, io: &mut impl MavlinkIo) -> FromShard {
        if !self.mavlink.is_empty() {
            io.receive(&mut self.mavlink);
            if heartbeat {
                let t = self.step as f64 * self.dt_s;
                for (drone, queues) in self.drones.iter().zip(&mut self.mavlink) {
                    drone.mavlink_heartbeat(t, &mut queues.outbound);
                }
            }
            io.send(&mut self.mavlink, true);
        }
        let heard = self
            .drones
            .iter()
            .zip(&self.mavlink)
            .filter(|(_, q)| {
                q.inbound.iter().any(|f| {
                    (f.header.system_id, f.header.component_id) != (u32::from(ROUTER_SYSTEM_ID), ROUTER_COMPONENT_ID)
                })
            })
            .map(|(d, _)| d.plan.index)
            .collect();
        FromShard::Held { shard: self.index, heard }
    }

    /// The valid leases (`[drone, zone]`, global drone index), for the geofences.
    fn set_leases(&mut self, leases: &[[u32; 2]]) {
        for drone in &mut self.drones {
            let index = drone.plan.index;
            drone.set_permitted_zones(leases.iter().filter(|l| l[0] == index).map(|l| l[1] as usize));
        }
    }

    /// Simulates up to (excluding) `until_step`, returning the events; MAVLink frames stay
    /// in their queues ([`NoMavlinkIo`]).
    pub fn advance(&mut self, until_step: u64) -> Vec<Event> {
        self.advance_with(until_step, &mut NoMavlinkIo)
    }

    /// Simulates up to (excluding) `until_step`, returning the events. At the window's end
    /// the MAVLink sessions run, and `io` fills and drains their queues around them (see
    /// [`MavlinkIo`] for when).
    pub fn advance_with(&mut self, until_step: u64, io: &mut impl MavlinkIo) -> Vec<Event> {
        let mut events = Vec::new();
        let (first, dt_s, released) = (self.step, self.dt_s, self.released);
        // Drone by drone through the whole window, not step by step through every drone:
        // within a window the drones do not interact (each has its own environment
        // filters; the world is read-only; drone-drone contact and the geofence are judged
        // at the window's end), so the result is the same, and one drone's state stays in
        // the core's caches for the window's steps instead of the whole shard's state
        // (kilobytes per drone) streaming through them at every step.
        for (i, drone) in self.drones.iter_mut().enumerate() {
            let index = drone.plan.index;
            for step in first..until_step {
                if !drone.is_crashed() {
                    if step.is_multiple_of(ENV_SAMPLE_DIVIDER) {
                        let env_dt_s = dt_s * ENV_SAMPLE_DIVIDER as f64;
                        let t = step as f64 * dt_s;
                        self.env_samples[i] = self.env.sample(&drone.sample_context(i, t, env_dt_s));
                    }
                    drone.step(step + 1, step as f64 * dt_s, dt_s, &self.env_samples[i], &self.world, released);
                    // Building contact: the rotor disc's ball against the prisms (an exact
                    // query of the world; drones of other shards are not here, and
                    // drone-drone contact is judged on the merged snapshot, DESIGN §5).
                    if !drone.is_crashed() && drone.touches_building(&self.world) {
                        let speed = drone.speed_mps();
                        drone.crash(CrashCause::Building, speed);
                    }
                }
                // Times are step counts times dt, never sums, so they print the same
                // everywhere.
                if drone.has_events() {
                    let time_s = (step + 1) as f64 * dt_s;
                    events.extend(drone.take_events().into_iter().map(|kind| Event {
                        time_s,
                        drone: Some(index),
                        kind,
                    }));
                }
            }
        }
        // Step by step, in drone order within a step, as they happened: a stable sort by
        // time keeps each drone's own order and the shard's drone order.
        events.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
        self.step = self.step.max(until_step);
        // The geofence acts on the window's final state, before the pilot's next commands.
        if !self.zones.is_empty() {
            for drone in &mut self.drones {
                drone.check_geofence(self.step as f64 * self.dt_s, &self.zones, &self.world);
            }
        }
        // MAVLink at window ends: telemetry is built when due (its rates and timestamps
        // follow PX4's), and every MAVLINK_IO_PERIOD_S of sim time the sockets are read,
        // commands act, and everything queued leaves packed into datagrams.
        let t_end = self.step as f64 * self.dt_s;
        let exchange = t_end + 1e-9 >= self.next_mavlink_io_s;
        if exchange {
            self.next_mavlink_io_s = t_end + MAVLINK_IO_PERIOD_S;
            io.receive(&mut self.mavlink);
        }
        for (drone, queues) in self.drones.iter_mut().zip(&mut self.mavlink) {
            if exchange {
                drone.mavlink_exchange(t_end, queues);
            } else {
                drone.mavlink_collect(t_end, &mut queues.outbound);
            }
        }
        io.send(&mut self.mavlink, exchange);
        events
    }
}
