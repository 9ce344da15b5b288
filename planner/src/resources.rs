//! Resource estimate per role instance (Kubernetes requests; `sadesim plan` shows them).
//!
//! Physics cost scales with drone-steps per wall-clock second: drones x physicsRateHz x
//! real-time factor. `sadesim bench` measures well over 1 M drone-steps per core-second of
//! flight for the full per-drone stack with recordings (docs/performance.md, "Throughput by
//! fleet size"); we request for 250 000, which leaves headroom for slower cluster cores, the
//! ground phase, MAVLink and the recorder.

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

/// CPU seconds per onboard camera frame on Mesa's lavapipe (no GPU), fixed part: drawing
/// the tiles the view sees, readback and hand-over. Fitted to `sadesim bench --cameras` over
/// the procedural Chicago at 160x120, 320x240 and 640x480 (2 325, 833 and 290 frames/s on 2
/// cores, docs/performance.md): 0.5 ms + 21 ns per pixel is within 15 % of each.
pub const CAMERA_CPU_S_PER_FRAME: f64 = 0.5e-3;
/// CPU seconds per pixel of an onboard camera frame on lavapipe (rasterising, readback).
pub const CAMERA_CPU_S_PER_PIXEL: f64 = 21e-9;

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
/// With onboard cameras it also renders every frame (see [`camera_cores`]).
fn coordinator(spec: &SimulationRunSpec, drones: u32, rtf: f64) -> RoleResources {
    let recording = spec.recording();
    let per_drone_s = if recording.mcap || recording.ulog {
        COORDINATOR_CPU_S_PER_DRONE_S_RECORDING
    } else {
        COORDINATOR_CPU_S_PER_DRONE_S
    };
    let cores = f64::from(drones) * rtf * per_drone_s + camera_cores(spec, rtf);
    RoleResources {
        cpu_millis: (250 + (cores * 1000.0).ceil() as u32).min(16_000),
        memory_mib: 128 + drones / 8 + camera_memory_mib(spec),
    }
}

/// Cores the onboard cameras take at `rtf` when rendered on the CPU (lavapipe): frames per
/// wall-clock second times [`CAMERA_CPU_S_PER_FRAME`] + pixels x [`CAMERA_CPU_S_PER_PIXEL`].
/// On a GPU node (`spec.rendering.gpus`) the rasterising moves to the GPU, but the request
/// stays: readback and JPEG encoding remain on the CPU, and a pod that gets no GPU falls
/// back to lavapipe.
fn camera_cores(spec: &SimulationRunSpec, rtf: f64) -> f64 {
    spec.fleet
        .iter()
        .flat_map(|g| g.cameras.iter().map(move |c| (g.count, c)))
        .map(|(count, c)| {
            let pixels = f64::from(c.width_px) * f64::from(c.height_px);
            f64::from(count) * c.rate_hz * rtf * (CAMERA_CPU_S_PER_FRAME + pixels * CAMERA_CPU_S_PER_PIXEL)
        })
        .sum()
}

/// Mebibytes the onboard cameras add to the coordinator: lavapipe and the culled city
/// scene (256 MiB once), plus each camera's latest frame kept for pilots and the frame being
/// recorded (RGB8 and f32 depth, twice: 14 bytes a pixel).
fn camera_memory_mib(spec: &SimulationRunSpec) -> u32 {
    let cameras = spec.fleet.iter().flat_map(|g| g.cameras.iter().map(move |c| (g.count, c)));
    let bytes: u64 =
        cameras.clone().map(|(n, c)| u64::from(n) * u64::from(c.width_px) * u64::from(c.height_px) * 14).sum();
    match cameras.count() {
        0 => 0,
        _ => 256 + u32::try_from(bytes >> 20).unwrap_or(u32::MAX - 256).min(u32::MAX - 256),
    }
}

#[cfg(test)]
mod tests {
    use sadesim_crds::fixtures::{RunBuilder, down_camera};
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

    #[test]
    fn the_coordinator_requests_the_cpu_and_memory_its_cameras_render_with() {
        use sadesim_crds::camera::Camera;
        let camera = |width_px, height_px, rate_hz| Camera { width_px, height_px, rate_hz, ..down_camera() };
        let with = |cameras: Vec<Camera>, factor: Option<f64>| {
            let run = RunBuilder::test()
                .with_drones(32)
                .with(|r| {
                    r.spec.fleet[0].cameras = cameras.clone();
                    r.spec.clock = factor.map(|f| Clock { mode: ClockMode::Scaled, factor: Some(f) });
                })
                .build();
            estimate(&run.spec, &[]).coordinator
        };
        let none = with(vec![], None);
        // 32 drones x 10 Hz x (0.5 ms + 76 800 px x 21 ns) = 0.676 cores; the measured 833
        // frames/s on 2 cores would give 0.77.
        let one = with(vec![camera(320, 240, 10.0)], None);
        assert_eq!(one.cpu_millis - none.cpu_millis, 676);
        // 32 x 320 x 240 x 14 B = 33 MiB of frames, plus lavapipe and the scene.
        assert_eq!(one.memory_mib - none.memory_mib, 256 + 32);
        // Twice the clock, twice the frames per wall-clock second.
        let fast = with(vec![camera(320, 240, 10.0)], Some(2.0)).cpu_millis - with(vec![], Some(2.0)).cpu_millis;
        assert_eq!(fast, 1352);
        // A second, larger camera adds its own frames.
        let two = with(vec![camera(320, 240, 10.0), camera(640, 480, 5.0)], None);
        assert!(two.cpu_millis > one.cpu_millis + 1000, "{two:?}");
        // The request is bounded like every role's.
        assert_eq!(with(vec![camera(4096, 4096, 100.0)], None).cpu_millis, 16_000);
    }
}
