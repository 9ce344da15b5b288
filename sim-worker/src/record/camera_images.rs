//! Onboard camera frames in the recording (issue 18): which cameras `recording.mcap`
//! holds, and the frames handed to it.
//!
//! The engine does not render: the local runner's cameras (`sadesim-render`) describe each
//! recorded camera once ([`CameraStream`], at [`super::Recorder::create`]) and hand over
//! the frames of a window ([`CameraImage`], [`super::Recorder::queue_images`]) before the
//! window itself, so the images are written with the window they were taken in.

/// One camera on one drone, as `recording.mcap` declares it.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraStream {
    /// The drone's global index.
    pub drone: u32,
    /// The camera's name in its fleet group.
    pub camera: String,
    /// Image size, pixels.
    pub width: u32,
    pub height: u32,
    /// Pinhole intrinsics, 3x3 row-major (`foxglove.CameraCalibration.K`), pixel centres
    /// at integer coordinates (OpenCV's and ROS's convention).
    pub k: [f64; 9],
    /// Projection, 3x4 row-major (`P = [K | 0]` for a monocular camera).
    pub p: [f64; 12],
    /// The optical frame's origin in the body frame (FLU), metres.
    pub mount_offset_flu_m: [f64; 3],
    /// The rotation of the optical frame (x right, y down, z forward) into the body frame
    /// (FLU), `[w, x, y, z]`.
    pub mount_optical_to_flu_wxyz: [f64; 4],
    /// Whether depth frames are recorded too.
    pub depth: bool,
}

/// One recorded frame of a [`CameraStream`].
#[derive(Clone, Debug, PartialEq)]
pub struct CameraImage {
    /// Index of the camera in the streams given to the recorder.
    pub stream: usize,
    /// Simulated time the frame shows, seconds since the run start.
    pub time_s: f64,
    /// The colour image, baseline JPEG.
    pub jpeg: Vec<u8>,
    /// The depth image, millimetres as little-endian `u16` row-major (`16UC1`, 0 = no
    /// hit), for depth cameras.
    pub depth_mm_le: Option<Vec<u8>>,
}

/// The optical frame of a camera in the recording's transform tree:
/// `drone/<drone name>/<camera>`, child of `drone/<drone name>`.
pub fn optical_frame(drone_name: &str, camera: &str) -> String {
    format!("drone/{drone_name}/{camera}")
}
