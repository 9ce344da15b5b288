//! The bytes of each recorded message, from one drone snapshot: protobuf for the
//! ground-truth streams (pose, `/tf`, velocity), JSON text for the others. Field names follow
//! [`super::protobuf::FILES`] and [`super::schemas`]; `ns` is simulated time since the run
//! start.

use sadesim_crds::geo::{Enu, GeoPoint};

use super::json::{self, COARSE, DEGREES, METRES};
use super::protobuf;
use crate::record::CameraStream;
use sadesim_engine::events::{Event, EventKind};
use sadesim_engine::protocol::{DroneSnapshot, EstimateDetail, GnssDetail};

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// `foxglove.PoseInFrame` (protobuf): the ground-truth pose in `world`.
pub fn pose(out: &mut Vec<u8>, ns: u64, s: &DroneSnapshot) {
    protobuf::timestamp(out, 1, ns);
    protobuf::bytes(out, 2, b"world");
    protobuf::message(out, 3, |b| {
        protobuf::vector3(b, 1, s.position_enu_m, protobuf::METRES_BITS);
        protobuf::quaternion(b, 2, s.attitude_wxyz);
    });
}

/// Appends one `foxglove.FrameTransform` `world` -> `child` (`drone/<name>`) to a
/// `foxglove.FrameTransforms` message (protobuf: the message is its repeated field 1, one
/// entry after another): the body frame (FLU) at the ground-truth pose.
pub fn transform(out: &mut Vec<u8>, ns: u64, child: &str, s: &DroneSnapshot) {
    protobuf::message(out, 1, |b| {
        protobuf::timestamp(b, 1, ns);
        protobuf::bytes(b, 2, b"world");
        protobuf::bytes(b, 3, child.as_bytes());
        protobuf::vector3(b, 4, s.position_enu_m, protobuf::METRES_BITS);
        protobuf::quaternion(b, 5, s.attitude_wxyz);
    });
}

/// `foxglove.CompressedImage` (protobuf): one camera frame as JPEG.
pub fn compressed_image(out: &mut Vec<u8>, ns: u64, frame_id: &str, jpeg: &[u8]) {
    protobuf::timestamp(out, 1, ns);
    protobuf::bytes(out, 2, jpeg);
    protobuf::bytes(out, 3, b"jpeg");
    protobuf::bytes(out, 4, frame_id.as_bytes());
}

/// `foxglove.RawImage` (protobuf): a depth frame, `16UC1` millimetres, little-endian.
pub fn depth_image(out: &mut Vec<u8>, ns: u64, frame_id: &str, camera: &CameraStream, depth_mm_le: &[u8]) {
    protobuf::timestamp(out, 1, ns);
    protobuf::fixed32(out, 2, camera.width);
    protobuf::fixed32(out, 3, camera.height);
    protobuf::bytes(out, 4, b"16UC1");
    protobuf::fixed32(out, 5, camera.width * 2);
    protobuf::bytes(out, 6, depth_mm_le);
    protobuf::bytes(out, 7, frame_id.as_bytes());
}

/// `foxglove.CameraCalibration` (protobuf): the ideal pinhole of `camera` (no distortion,
/// `D` empty, `R` identity).
pub fn calibration(out: &mut Vec<u8>, ns: u64, frame_id: &str, camera: &CameraStream) {
    protobuf::timestamp(out, 1, ns);
    protobuf::fixed32(out, 2, camera.width);
    protobuf::fixed32(out, 3, camera.height);
    protobuf::bytes(out, 4, b"plumb_bob");
    protobuf::packed_doubles(out, 6, &camera.k);
    protobuf::packed_doubles(out, 7, &[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
    protobuf::packed_doubles(out, 8, &camera.p);
    protobuf::bytes(out, 9, frame_id.as_bytes());
}

/// Appends one `foxglove.FrameTransform` `drone/<name>` -> the camera's optical frame (its
/// mount, fixed on the body) to a `foxglove.FrameTransforms` message.
pub fn mount_transform(out: &mut Vec<u8>, ns: u64, parent: &str, child: &str, camera: &CameraStream) {
    protobuf::message(out, 1, |b| {
        protobuf::timestamp(b, 1, ns);
        protobuf::bytes(b, 2, parent.as_bytes());
        protobuf::bytes(b, 3, child.as_bytes());
        protobuf::vector3(b, 4, camera.mount_offset_flu_m, protobuf::METRES_BITS);
        protobuf::quaternion(b, 5, camera.mount_optical_to_flu_wxyz);
    });
}

/// `sadesim.Velocity` (protobuf): ground-truth linear velocity (ENU) and body rates (FLU).
pub fn velocity(out: &mut Vec<u8>, ns: u64, s: &DroneSnapshot) {
    protobuf::timestamp(out, 1, ns);
    protobuf::bytes(out, 2, b"world");
    protobuf::vector3(out, 3, s.velocity_enu_mps, protobuf::METRES_BITS);
    protobuf::vector3(out, 4, s.detail.rate_body_rps, protobuf::METRES_BITS);
}

/// Starts a JSON message: `{"timestamp":..`; the other members follow, each after a comma
/// ([`member`], [`json::members`]), and `}` closes it.
fn open(out: &mut Vec<u8>, ns: u64) {
    out.extend_from_slice(b"{\"timestamp\":");
    json::time(out, ns);
}

/// Appends `,"name":`, the key of a member after the timestamp.
fn member(out: &mut Vec<u8>, name: &str) {
    out.push(b',');
    json::key(out, name);
}

/// `sadesim.Estimate`: the estimator's output and its error against ground truth.
pub fn estimate(out: &mut Vec<u8>, ns: u64, e: &EstimateDetail, s: &DroneSnapshot) {
    let error = [
        e.position_enu_m[0] - s.position_enu_m[0],
        e.position_enu_m[1] - s.position_enu_m[1],
        e.position_enu_m[2] - s.position_enu_m[2],
    ];
    open(out, ns);
    member(out, "frame_id");
    json::string(out, "world");
    member(out, "position_enu_m");
    json::vector3(out, e.position_enu_m, METRES);
    member(out, "velocity_enu_mps");
    json::vector3(out, e.velocity_enu_mps, METRES);
    member(out, "orientation");
    json::quaternion(out, e.attitude_wxyz);
    member(out, "position_error_enu_m");
    json::vector3(out, error, METRES);
    json::numbers(out, &[("eph_m", e.eph_m), ("epv_m", e.epv_m)], METRES);
    out.push(b'}');
}

/// `sadesim.MotorCommands`: the first `motor_count` commands.
pub fn motors(out: &mut Vec<u8>, ns: u64, s: &DroneSnapshot) {
    open(out, ns);
    json::members(out, &[("armed", s.armed)], json::boolean);
    member(out, "commands");
    let count = usize::from(s.detail.motor_count).min(s.detail.motor_commands.len());
    json::array(out, s.detail.motor_commands[..count].iter().copied(), COARSE);
    out.push(b'}');
}

/// `sadesim.Battery`.
pub fn battery(out: &mut Vec<u8>, ns: u64, s: &DroneSnapshot) {
    open(out, ns);
    let d = &s.detail;
    json::numbers(
        out,
        &[
            ("voltage_v", d.battery_voltage_v),
            ("current_a", d.battery_current_a),
            ("consumed_mah", d.battery_consumed_mah),
            ("remaining", s.battery_remaining),
        ],
        COARSE,
    );
    out.push(b'}');
}

/// `sadesim.Status`: flight mode and state flags.
pub fn status(out: &mut Vec<u8>, ns: u64, s: &DroneSnapshot) {
    open(out, ns);
    member(out, "mode");
    json::string(out, s.mode.as_str());
    let flags =
        [("armed", s.armed), ("on_ground", s.on_ground), ("crashed", s.crashed), ("position_valid", s.position_valid)];
    json::members(out, &flags, json::boolean);
    json::numbers(out, &[("height_agl_m", s.height_agl_m)], METRES);
    out.push(b'}');
}

/// `sadesim.Wind`: the air velocity at the drone.
pub fn wind(out: &mut Vec<u8>, ns: u64, s: &DroneSnapshot) {
    open(out, ns);
    member(out, "frame_id");
    json::string(out, "world");
    member(out, "velocity_enu_mps");
    json::vector3(out, s.detail.wind_enu_mps, METRES);
    json::numbers(out, &[("speed_mps", norm(s.detail.wind_enu_mps))], METRES);
    out.push(b'}');
}

/// `foxglove.LocationFix` at `g` with a diagonal ENU covariance from 1-sigma horizontal and
/// vertical accuracies (`None`: unknown, covariance type 0).
pub fn location(out: &mut Vec<u8>, ns: u64, frame: &str, g: GeoPoint, sigma_m: Option<(f64, f64)>) {
    open(out, ns);
    member(out, "frame_id");
    json::string(out, frame);
    json::numbers(out, &[("latitude", g.latitude_deg), ("longitude", g.longitude_deg)], DEGREES);
    json::numbers(out, &[("altitude", g.altitude_msl_m)], METRES);
    let (covariance, covariance_type) = match sigma_m {
        Some((h, v)) => {
            let (hh, vv) = (h * h, v * v);
            ([hh, 0.0, 0.0, 0.0, hh, 0.0, 0.0, 0.0, vv], 2)
        }
        None => ([0.0; 9], 0),
    };
    member(out, "position_covariance");
    json::array(out, covariance, METRES);
    member(out, "position_covariance_type");
    json::uint(out, covariance_type);
    out.push(b'}');
}

/// `sadesim.GnssQuality` of the receiver output `g`; `truth_enu_m` is the true position at
/// the measurement time.
pub fn gnss_quality(out: &mut Vec<u8>, ns: u64, g: &GnssDetail, truth_enu_m: [f64; 3]) {
    open(out, ns);
    member(out, "fix_type");
    json::uint(out, u64::from(g.fix_type));
    member(out, "satellites_used");
    json::uint(out, u64::from(g.satellites));
    let opt = |v: Option<f64>| v.unwrap_or(f64::NAN);
    let fixed = g.fix_type >= 2;
    let [e, n, u] = g.position_enu_m;
    let horizontal = if fixed { (e - truth_enu_m[0]).hypot(n - truth_enu_m[1]) } else { f64::NAN };
    let vertical = if g.fix_type >= 3 { u - truth_enu_m[2] } else { f64::NAN };
    json::numbers(out, &[("hdop", opt(g.hdop)), ("vdop", opt(g.vdop))], COARSE);
    json::numbers(
        out,
        &[
            ("eph_m", opt(g.eph_m)),
            ("epv_m", opt(g.epv_m)),
            ("horizontal_error_m", horizontal),
            ("vertical_error_m", vertical),
        ],
        METRES,
    );
    let counts = g.sky.map(|k| [k.above_mask, k.line_of_sight, k.reflected].map(f64::from)).unwrap_or([f64::NAN; 3]);
    json::numbers(
        out,
        &[("satellites_above_mask", counts[0]), ("line_of_sight", counts[1]), ("reflected", counts[2])],
        0,
    );
    out.push(b'}');
}

/// The ENU position of a GNSS output.
pub fn gnss_enu(g: &GnssDetail) -> Enu {
    Enu::new(g.position_enu_m[0], g.position_enu_m[1], g.position_enu_m[2])
}

/// Foxglove log level of an event: WARNING for violations, unauthorized entries, crashes,
/// failsafes and refused commands or entries; ERROR for a failed run; INFO otherwise.
pub fn level(kind: &EventKind) -> u8 {
    match kind {
        EventKind::ViolationStarted { .. }
        | EventKind::Crashed { .. }
        | EventKind::Failsafe { .. }
        | EventKind::CommandRejected { .. }
        | EventKind::ZoneDenied { .. }
        | EventKind::ZoneEntered { authorized: false, .. } => 3,
        EventKind::RunEnded { reason } if reason.is_failure() => 4,
        _ => 2,
    }
}

/// `foxglove.Log` of one event: `message` is the event as in `events.jsonl`, `name` the
/// drone (or `run` for run-wide events).
pub fn log(out: &mut Vec<u8>, ns: u64, event: &Event, name: &str) {
    open(out, ns);
    member(out, "level");
    json::uint(out, u64::from(level(&event.kind)));
    let text = serde_json::to_string(event).unwrap_or_else(|e| format!("unserializable event: {e}"));
    json::members(out, &[("message", text.as_str()), ("name", name)], json::string);
    out.extend_from_slice(b",\"file\":\"\",\"line\":0}");
}
