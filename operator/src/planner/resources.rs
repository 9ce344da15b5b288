//! Resource estimate per role instance (Kubernetes requests; `sadesim plan` shows them).
//!
//! Physics cost scales with drone-steps per wall-clock second: drones x physicsRateHz x
//! real-time factor. `sadesim bench` measured ~360 000 drone-steps per core-second for the
//! full per-drone stack (docs/performance.md); we request for 250 000 to leave headroom for
//! slower cluster cores and for the MAVLink and recording work still to come.

use sadesim_crds::SimulationRunSpec;
use sadesim_crds::plan::{PlannedShard, ResourcePlan, RoleResources};
use sadesim_crds::run::ClockMode;

/// Drone-steps one core sustains per second with the full per-drone stack.
pub const DRONE_STEPS_PER_CORE_S: f64 = 250_000.0;

pub fn estimate(spec: &SimulationRunSpec, shards: &[PlannedShard]) -> ResourcePlan {
    let clock = spec.clock();
    // As-fast-as-possible runs take what they get; request as for real time.
    let rtf = match clock.mode {
        ClockMode::Scaled => clock.factor.unwrap_or(1.0),
        ClockMode::Realtime | ClockMode::AsFastAsPossible => 1.0,
    };
    let rate = f64::from(spec.physics_rate_hz());
    let shard = |drones: u32| {
        let cores = f64::from(drones) * rate * rtf / DRONE_STEPS_PER_CORE_S;
        RoleResources {
            cpu_millis: ((cores * 1000.0).ceil() as u32).clamp(250, 16_000),
            // World geometry (~64 MiB for a 6 km city) plus ~1 MiB per drone of state and
            // recording buffers.
            memory_mib: 128 + 64 + drones,
        }
    };
    let total = spec.total_drones() as u32;
    ResourcePlan {
        assets: RoleResources { cpu_millis: 1000, memory_mib: 1024 },
        shards: shards.iter().map(|s| shard(s.drone_count)).collect(),
        coordinator: RoleResources { cpu_millis: 250 + total / 10, memory_mib: 128 + total / 8 },
        router: RoleResources { cpu_millis: 100, memory_mib: 64 },
        renderer: spec.rendering().enabled.then_some(RoleResources { cpu_millis: 1000, memory_mib: 1024 }),
        pilot: spec.pilot.as_ref().map(|p| {
            p.resources.as_ref().map_or(RoleResources { cpu_millis: 500, memory_mib: 512 }, |r| RoleResources {
                cpu_millis: r.cpu_millis,
                memory_mib: r.memory_mib,
            })
        }),
    }
}
