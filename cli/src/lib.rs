//! The `sadesim` command line as a library: the commands (`cli`), the local runner that
//! runs every role of a `SimulationRun` in one process or as child processes (`runner`),
//! and the benchmarks (`bench`). `sadesim operator` runs the Kubernetes operator of the
//! `sadesim-operator` crate.

pub mod bench;
pub mod cli;
pub mod runner;

#[cfg(test)]
mod report_tests;
