//! Onboard cameras (`spec.fleet[].cameras`) and the ground markers they can see
//! (`spec.world.markers`), issue 18.
//!
//! Frames: a camera's mount is given in the drone's body frame FLU (x forward, y left, z
//! up, metres and degrees); the zero mount looks forward along body +x with the image's
//! top up. Rotations apply as yaw (about z), then pitch (about the new y), then roll: a
//! downward camera is `pitchDeg: 90`, the top of its image towards the drone's nose.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::fleet::LatLon;

/// One camera on every drone of a group.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct Camera {
    /// Camera name, unique in the group (DNS label): the frames are at
    /// `/cameras/<drone>/<name>/...`.
    #[schemars(length(min = 1, max = 40), pattern(r"^[a-z0-9]([-a-z0-9]*[a-z0-9])?$"))]
    pub name: String,
    /// Image width, pixels, 16..=4096.
    pub width_px: u32,
    /// Image height, pixels, 16..=4096.
    pub height_px: u32,
    /// Horizontal field of view, degrees, 1..=170 (pinhole, no distortion).
    pub horizontal_fov_deg: f64,
    /// Frames per simulated second. The sync window rate (physics rate / `syncWindowSteps`,
    /// 100 Hz by default) must be a whole multiple of it, so that every frame is taken at
    /// a window boundary: 100, 50, 25, 20, 10, 5, 2, 1 Hz by default.
    pub rate_hz: f64,
    /// Frames per simulated second written into `recording.mcap`
    /// (`/drones/<drone>/cameras/<name>/image`, `foxglove.CompressedImage` JPEG, with its
    /// `foxglove.CameraCalibration`, and `.../depth` as `foxglove.RawImage` `16UC1` for depth
    /// cameras). `rateHz` must be a whole multiple of it, so that every recorded frame is a
    /// rendered one; 0 records none. Default: 1 Hz, or `rateHz` when that is slower (images
    /// are most of a recording's bytes: 320x240 JPEG is about 15 kB a frame).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub record_rate_hz: Option<f64>,
    /// Where the camera sits on the drone and where it looks. Default: at the centre,
    /// looking forward.
    #[serde(default)]
    pub mount: CameraMount,
    /// Also render depth (metres along the optical axis; served as a 16-bit PNG in
    /// millimetres). Default false.
    #[serde(default)]
    pub depth: bool,
}

impl Camera {
    /// Frames per simulated second recorded into `recording.mcap` (`recordRateHz` or its
    /// default).
    pub fn record_rate_hz(&self) -> f64 {
        self.record_rate_hz.unwrap_or(self.rate_hz.min(1.0))
    }
}

/// A camera's pose on the drone, body frame FLU.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Default, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct CameraMount {
    /// Offset forward of the body origin, m.
    #[serde(default)]
    pub forward_m: f64,
    /// Offset left, m.
    #[serde(default)]
    pub left_m: f64,
    /// Offset up, m.
    #[serde(default)]
    pub up_m: f64,
    /// Roll about the camera's forward axis, degrees.
    #[serde(default)]
    pub roll_deg: f64,
    /// Pitch, degrees; +90 looks straight down.
    #[serde(default)]
    pub pitch_deg: f64,
    /// Yaw, degrees; +90 looks left.
    #[serde(default)]
    pub yaw_deg: f64,
}

/// A flat fiducial marker lying on the ground (for example a landing pad), seen by the
/// onboard cameras.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct GroundMarker {
    /// Marker name, unique in the world.
    #[schemars(length(min = 1, max = 63))]
    pub name: String,
    /// Centre of the marker, on the ground.
    pub position: LatLon,
    /// Side of the square marker, black border included, m, 0.1..=20.
    pub size_m: f64,
    /// Rotation counter-clockwise seen from above, degrees; 0 puts the marker's top edge
    /// to the north.
    #[serde(default)]
    pub yaw_deg: f64,
    /// The ArUco id in OpenCV's `DICT_4X4_50` dictionary, 0..=49.
    pub aruco_id: u32,
}
