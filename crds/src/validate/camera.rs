//! Onboard cameras and ground markers (`spec.fleet[].cameras`, `spec.world.markers`).

use std::collections::HashSet;

use super::Problems;
use super::world::WorldBounds;
use crate::run::SimulationRunSpec;

/// The largest image side (the renderer's limit).
const MAX_SIDE_PX: u64 = 4096;
/// The smallest image side.
const MIN_SIDE_PX: u64 = 16;

pub(super) fn check_cameras(spec: &SimulationRunSpec, bounds: Option<&WorldBounds>, p: &mut Problems) {
    let rendering = spec.rendering().enabled;
    let sharding = spec.sharding();
    let physics_hz = f64::from(spec.physics_rate_hz());
    // Frames are taken at window boundaries: the window rate must be a whole multiple of
    // a camera's rate.
    let window_hz = physics_hz / f64::from(sharding.sync_window_steps.max(1));
    let mut any_camera = false;
    for (i, g) in spec.fleet.iter().enumerate() {
        let mut names = HashSet::new();
        for (k, c) in g.cameras.iter().enumerate() {
            any_camera = true;
            let path = format!("spec.fleet[{i}].cameras[{k}]");
            p.dns_label(format!("{path}.name"), &c.name, 40);
            if !names.insert(c.name.as_str()) {
                p.add(format!("{path}.name"), format!("duplicate camera name {:?} in group {:?}", c.name, g.name));
            }
            p.range_int(format!("{path}.widthPx"), c.width_px.into(), MIN_SIDE_PX, MAX_SIDE_PX);
            p.range_int(format!("{path}.heightPx"), c.height_px.into(), MIN_SIDE_PX, MAX_SIDE_PX);
            p.range(format!("{path}.horizontalFovDeg"), c.horizontal_fov_deg, 1.0, 170.0);
            if p.range(format!("{path}.rateHz"), c.rate_hz, 0.01, window_hz) {
                let windows = window_hz / c.rate_hz;
                if (windows - windows.round()).abs() > 1e-9 {
                    p.add(
                        format!("{path}.rateHz"),
                        format!(
                            "{} Hz does not divide the {window_hz} Hz sync window rate: frames are taken at window boundaries (e.g. {window_hz}, {}, {} Hz)",
                            c.rate_hz,
                            window_hz / 2.0,
                            window_hz / 10.0
                        ),
                    );
                }
            }
            if let Some(record) = c.record_rate_hz
                && p.range(format!("{path}.recordRateHz"), record, 0.0, c.rate_hz)
                && record > 0.0
            {
                let frames = c.rate_hz / record;
                if (frames - frames.round()).abs() > 1e-9 {
                    p.add(
                        format!("{path}.recordRateHz"),
                        format!(
                            "{record} Hz does not divide the camera's rateHz ({} Hz): the recording takes every n-th rendered frame",
                            c.rate_hz
                        ),
                    );
                }
            }
            let m = &c.mount;
            for (field, v, limit) in [
                ("forwardM", m.forward_m, 10.0),
                ("leftM", m.left_m, 10.0),
                ("upM", m.up_m, 10.0),
                ("rollDeg", m.roll_deg, 180.0),
                ("pitchDeg", m.pitch_deg, 180.0),
                ("yawDeg", m.yaw_deg, 180.0),
            ] {
                p.range(format!("{path}.mount.{field}"), v, -limit, limit);
            }
        }
        if !g.cameras.is_empty() && !rendering {
            p.add(
                format!("spec.fleet[{i}].cameras"),
                "onboard cameras are rendered by the renderer: set spec.rendering.enabled to true",
            );
        }
    }
    let markers = &spec.world().markers;
    let mut names = HashSet::new();
    for (k, m) in markers.iter().enumerate() {
        let path = format!("spec.world.markers[{k}]");
        if m.name.is_empty() || m.name.len() > 63 {
            p.add(format!("{path}.name"), "must be 1 to 63 characters");
        }
        if !names.insert(m.name.as_str()) {
            p.add(format!("{path}.name"), format!("duplicate marker name {:?}", m.name));
        }
        p.range(format!("{path}.sizeM"), m.size_m, 0.1, 20.0);
        p.range(format!("{path}.yawDeg"), m.yaw_deg, -360.0, 360.0);
        p.range_int(format!("{path}.arucoId"), m.aruco_id.into(), 0, 49);
        if let Some(b) = bounds {
            b.check(p, &format!("{path}.position"), &m.position, m.size_m);
        }
    }
    if !markers.is_empty() && !any_camera {
        p.add("spec.world.markers", "only onboard cameras see markers: give a fleet group `cameras`");
    }
}
