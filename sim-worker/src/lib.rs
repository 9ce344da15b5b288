//! SADE-SIM simulation engine and runtime roles (binary `sim-worker <role>`).
//!
//! The world a run flies in is the `sadesim-world` crate; GNSS geometry is `sadesim-gnss`,
//! the urban wind field `sadesim-wind`, the camera renderer `sadesim-render`. Modules are
//! named after the domain (DESIGN §6):
//!
//! - `vehicle`: airframe presets, motors, battery, the forces on a multirotor, rigid-body
//!   integration and ground contact;
//! - `env`: environment factors sampled at a drone's position and time (wind, urban wind,
//!   GNSS conditions), and OpenFOAM runs at the edge;
//! - `sensors`: IMU, barometer, magnetometer and GNSS receivers;
//! - `autopilot`: the built-in flight controller (estimator, navigator, cascaded control,
//!   geofence, failsafes);
//! - `pilot`: scripted missions from the scenario;
//! - `shard`: a physics shard, the drones `[a, b)` stepped in sync windows (pure core);
//! - `coordinator`: the lockstep loop over the shards (clock, barrier, merged snapshot,
//!   pilot release, end of the run);
//! - `pacing`: how simulated time follows the wall clock;
//! - `conduct`: one run around the lockstep loop, for the local runner and the coordinator
//!   role alike (recorder, cameras, live view, airspace, the run's end);
//! - `protocol`: the shard <-> coordinator message set;
//! - `transport`: its carriers (in-process channels, binary frames over TCP);
//! - `events`: run events (the types live in `sadesim_crds::outcome::events`);
//! - `airspace`: zones as volumes, the airspace authority and its HTTP API, the
//!   compliance monitor, the verdict;
//! - `mavlink`: the MAVLink edge (framing, signing, the PX4 session, endpoints, router);
//! - `record`: the run folder's evidence (events, trajectory, MCAP, ULog, summary);
//! - `cameras`: onboard cameras rendered at exact simulated times;
//! - `view`: the live 3D view, replays and the camera frames over HTTP;
//! - `http_thread`: an axum server on a thread of its own;
//! - `roles`: `sim-worker <role>` entry points (assets, shard, coordinator, router,
//!   renderer, join, wait-release).
//!
//! Frames used everywhere in the engine: world **ENU** (x east, y north, z up, metres from
//! the run origin, see `sadesim_crds::geo`); body **FLU** (x forward, y left, z up).
//! MAVLink's NED/FRD appear only at the MAVLink edge.

pub mod airspace;
pub mod autopilot;
pub mod cameras;
pub mod conduct;
pub mod coordinator;
pub mod env;
pub mod events;
pub mod http_thread;
pub mod mavlink;
pub mod pacing;
pub mod pilot;
pub mod protocol;
pub mod record;
pub mod roles;
pub mod sensors;
pub mod shard;
pub mod transport;
pub mod vehicle;
pub mod view;
