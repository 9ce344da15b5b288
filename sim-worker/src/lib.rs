//! SADE-SIM's runtime roles (binary `sim-worker <role>`): the engine (`sadesim-engine`)
//! put to work with files, sockets, threads and processes. The world a run flies in is the
//! `sadesim-world` crate; the camera renderer `sadesim-render`. Modules:
//!
//! - `conduct`: one run around the engine's lockstep loop, for the local runner and the
//!   coordinator role alike (recorder, cameras, live view, airspace, the run's end);
//! - `transport`: the carriers of the shard protocol (in-process channels, binary frames
//!   over TCP) and the system wall clock;
//! - `shard_io`: a shard's MAVLink sockets and the thread that carries its queues to them;
//! - `airspace`: the airspace authority at run time, its HTTP API;
//! - `mavlink`: the MAVLink sockets (drone endpoints, uplink, the fleet router);
//! - `wind_field`: the urban wind field computed where files and processes are (OpenFOAM);
//! - `record`: the run folder's evidence (events, trajectory, MCAP, ULog, summary);
//! - `cameras`: onboard cameras rendered at exact simulated times;
//! - `view`: the live 3D view, replays and the camera frames over HTTP;
//! - `http_thread`: an axum server on a thread of its own;
//! - `roles`: `sim-worker <role>` entry points (assets, shard, coordinator, router,
//!   renderer, join, wait-release).

pub mod airspace;
pub mod cameras;
pub mod conduct;
pub mod http_thread;
pub mod mavlink;
pub mod record;
pub mod roles;
pub mod shard_io;
pub mod transport;
pub mod view;
pub mod wind_field;

#[cfg(test)]
mod fuzz_seeds;
