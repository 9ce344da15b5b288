//! The SADE-SIM Kubernetes operator: reconciles `SimulationRun`s into Jobs, Pods, Services
//! and ConfigMaps (`k8s::children`), follows them through their lifecycle
//! (`k8s::controller`), and renders the same objects offline (`k8s::manifests`). It plans
//! runs with `sadesim-planner` and archives with `sadesim-evidence`, and links no
//! simulation engine (no physics, MAVLink or HTTP server crates: a test checks it).

pub mod args;
pub mod k8s;

pub use args::OperatorArgs;
