//! SADE-SIM's simulation engine: everything that decides what happens in a run, as values
//! in and values out. It opens no file or socket, starts no thread or process and reads no
//! environment variable; the runtime roles (`sim-worker`) and the local runner (`sadesim`)
//! carry its messages and write what it reports. Modules are named after the domain
//! (DESIGN §6):
//!
//! - `vehicle`: airframes, motors, battery, the forces on a multirotor, rigid-body
//!   integration and ground contact;
//! - `env`: environment factors sampled at a drone's position and time (wind, urban wind,
//!   GNSS conditions);
//! - `sensors`: IMU, barometer, magnetometer and GNSS receivers;
//! - `autopilot`: the built-in flight controller (estimator, navigator, cascaded control,
//!   geofence, failsafes);
//! - `preset`: airframe presets, each a vehicle's physics with the controller gains and
//!   PX4 parameters it flies with;
//! - `pilot`: scripted missions from the scenario;
//! - `mavlink`: MAVLink without sockets (framing, signing, PX4 modes, the per-drone
//!   session, telemetry in MAVLink's frames);
//! - `airspace`: zones as volumes, the airspace authority's decisions, the compliance
//!   monitor, the verdict;
//! - `shard`: a physics shard, the drones `[a, b)` stepped in sync windows; its MAVLink
//!   frames wait in queues for the caller's sockets;
//! - `coordinator`: the lockstep loop over the shards (clock, barrier, merged snapshot,
//!   pilot release, end of the run) through the `ShardLink` and `WallClock` traits;
//! - `pacing`: how simulated time follows the wall clock;
//! - `protocol`: the shard <-> coordinator message set;
//! - `events`: run events (the types live in `sadesim_crds::outcome::events`);
//! - `fixtures`: test support, plans from fixture runs (feature `fixtures`).
//!
//! Frames used everywhere in the engine: world **ENU** (x east, y north, z up, metres from
//! the run origin, see `sadesim_crds::geo`); body **FLU** (x forward, y left, z up).
//! MAVLink's NED/FRD appear only in `mavlink`.

pub mod airspace;
pub mod autopilot;
pub mod coordinator;
pub mod env;
pub mod events;
#[cfg(any(test, feature = "fixtures"))]
pub mod fixtures;
pub mod mavlink;
pub mod pacing;
pub mod pilot;
pub mod preset;
pub mod protocol;
pub mod sensors;
pub mod shard;
pub mod vehicle;
