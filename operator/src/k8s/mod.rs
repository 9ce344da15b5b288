//! Kubernetes: what a SimulationRun becomes on a cluster (`children`, pure), the operator
//! that reconciles runs into those children (`controller`) and sweeps into runs (`sweep`),
//! and `sadesim manifests`.

pub mod children;
pub mod controller;
#[cfg(test)]
mod fake_api;
pub mod manifests;
pub mod sweep;
