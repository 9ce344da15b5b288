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

/// Coordinator CPU seconds per simulated drone-second with `recording.mcap` or the ULogs
/// on: the recorder thread measured about 155 µs at the default rates (docs/performance.md,
/// "Recording cost"), plus the lockstep loop, the airspace monitor and the light files.
pub const COORDINATOR_CPU_S_PER_DRONE_S_RECORDING: f64 = 200e-6;
/// The same with both recordings off.
pub const COORDINATOR_CPU_S_PER_DRONE_S: f64 = 50e-6;

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
        coordinator: coordinator(spec, total, rtf),
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

/// The coordinator: a base for the lockstep loop and the airspace API, plus what recording
/// costs per simulated drone-second at the run's clock. Its recorder has a thread of its
/// own, beside the loop, so this CPU is what keeps it off the shards' critical path.
fn coordinator(spec: &SimulationRunSpec, drones: u32, rtf: f64) -> RoleResources {
    let recording = spec.recording();
    let per_drone_s = if recording.mcap || recording.ulog {
        COORDINATOR_CPU_S_PER_DRONE_S_RECORDING
    } else {
        COORDINATOR_CPU_S_PER_DRONE_S
    };
    let cores = f64::from(drones) * rtf * per_drone_s;
    RoleResources { cpu_millis: (250 + (cores * 1000.0).ceil() as u32).min(16_000), memory_mib: 128 + drones / 8 }
}

#[cfg(test)]
mod tests {
    use sadesim_crds::fixtures::RunBuilder;
    use sadesim_crds::run::{Clock, Recording};

    use super::*;

    fn coordinator_millis(drones: u32, factor: Option<f64>, recording: bool) -> u32 {
        let run = RunBuilder::test()
            .with_drones(drones)
            .with(|r| {
                if let Some(f) = factor {
                    r.spec.clock = Some(Clock { mode: ClockMode::Scaled, factor: Some(f) });
                }
                if !recording {
                    r.spec.recording = Some(Recording { mcap: false, ulog: false, ..Default::default() });
                }
            })
            .build();
        estimate(&run.spec, &[]).coordinator.cpu_millis
    }

    #[test]
    fn the_coordinator_requests_its_recorder_s_cpu_at_the_run_s_clock() {
        // 1000 drones in real time: 1000 drone-seconds per second x 200 µs = 200 millicores.
        assert_eq!(coordinator_millis(1000, None, true), 450);
        assert_eq!(coordinator_millis(1000, Some(4.0), true), 1050);
        assert_eq!(coordinator_millis(1000, None, false), 300);
        assert_eq!(coordinator_millis(4, None, true), 251);
    }
}
