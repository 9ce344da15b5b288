//! The `sadesim` command line as a library; the binary is flags and an exit code.
//!
//! - `cli`: the commands (`validate`, `plan`, `run`, `report`, `view`, `assets`, `archive`,
//!   `gnss`, ...): flags and glue over the other crates;
//! - `runner`: the local runner of `sadesim run`, every role of a `SimulationRun` in one
//!   process (shards as threads) or as `sim-worker` child processes (`--processes`), and the
//!   pilot's supervision;
//! - `sweep`: `sadesim sweep`, a `SimulationSweep`'s runs in parallel, resumable, and its
//!   report;
//! - `bench`: `sadesim bench`, drone-steps per second of the full per-drone stack.
//!
//! `sadesim operator` runs the Kubernetes operator of the `sadesim-operator` crate.

pub mod bench;
pub mod cli;
pub mod runner;
pub mod sweep;

#[cfg(test)]
mod report_tests;
