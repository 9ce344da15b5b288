//! SADE-SIM's `sadesim` binary as a library: the planner (pure `SimulationRun -> RunPlan`),
//! the CLI commands, and (later) the Kubernetes reconciler and the local runner.

pub mod archive;
pub mod assets;
pub mod bench;
pub mod cli;
pub mod k8s;

pub mod report;
pub mod runner;
