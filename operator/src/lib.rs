//! The SADE-SIM Kubernetes operator: reconciles `SimulationRun`s into Jobs, Pods, Services
//! and ConfigMaps, follows them through their lifecycle, and renders the same objects
//! offline. It plans runs with `sadesim-planner` over the world's files read by
//! `sadesim-sources`, archives with `sadesim-evidence`, and links no simulation engine (no
//! physics, MAVLink or HTTP server crates: a test checks it).
//!
//! - `k8s`: what a run becomes on a cluster (`k8s::children`, pure), the controller that
//!   reconciles runs into it (`k8s::controller`: read, decide, act; queue, leader election,
//!   metrics), and the offline manifests of `sadesim manifests` (`k8s::manifests`);
//! - `args`: the operator's flags (each also an environment variable the Helm chart sets)
//!   and their validated form.

pub mod args;
pub mod k8s;

pub use args::OperatorArgs;
