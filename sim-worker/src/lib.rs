//! SADE-SIM simulation engine and runtime roles.
//!
//! Modules are named after the domain (DESIGN §6): `world` (ground, buildings), `env`
//! (environment factors: wind, GNSS), `vehicle` (airframes, motors, rigid bodies),
//! `sensors`, `autopilot` (the built-in flight controller), `shard` and `coordinator`
//! (lockstep time), `conduct` (one run around the lockstep loop, for the local runner and
//! the coordinator role alike), `pilot` (scripted missions).
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
