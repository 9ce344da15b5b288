//! SADE-SIM onboard cameras: RGB and depth frames of the world, rendered offscreen through a
//! real GPU API (wgpu on Vulkan; Mesa's lavapipe on machines without a GPU).
//!
//! A pure library for the simulator's camera sensors (`sim_worker::cameras` renders every
//! run's onboard cameras with it): the simulator builds a [`Scene`] from its
//! [`sadesim_world::World`] once, a [`Renderer`] once per process, and at each camera's
//! simulated instant calls [`Renderer::render`] with the [`CameraView`]s due (pose from the
//! drone's state through [`CameraPose::from_body`] and the camera's [`Mount`]). The renderer
//! reads no clock and keeps no state that changes a frame: the same scene and views give
//! the same bytes on the same adapter.
//!
//! - [`camera`]: pinhole models, mounts, poses, projection and the calibration record
//!   (frames, units and pixel convention);
//! - [`scene`]: what the cameras see: the world's triangles and flat ground markers;
//! - [`aruco`]: ArUco fiducials (OpenCV's `DICT_4X4_50`) for the markers;
//! - [`tiles`]: view-frustum culling over 100 m tiles of the ground plane;
//! - [`renderer`]: the GPU side (one wgpu device on Vulkan, offscreen targets, readback);
//! - [`frame`]: one rendered frame and its encodings (PNG, JPEG, 16-bit depth); depth is
//!   defined on [`Frame::depth_m`];
//! - [`error`]: the renderer's one error type.
//!
//! ```no_run
//! use sadesim_render::{CameraModel, CameraPose, CameraView, Mount, Renderer, Scene};
//! # fn run(world: &sadesim_world::World) -> sadesim_render::Result<()> {
//! let mut renderer = Renderer::new(&Scene::from_world(world))?;
//! let model = CameraModel::new(640, 480, 90.0)?;
//! let pose = CameraPose::from_body([0.0, 0.0, 30.0], [1.0, 0.0, 0.0, 0.0], &Mount::DOWN)?;
//! let frames = renderer.render(&[CameraView { model, pose }])?;
//! let png = frames[0].rgb_png()?;
//! # Ok(()) }
//! ```

pub mod aruco;
pub mod camera;
pub mod error;
pub mod frame;
pub mod renderer;
pub mod scene;
pub mod tiles;

pub use aruco::aruco_4x4_50;
pub use camera::{
    CameraCalibration, CameraModel, CameraPose, CameraView, FAR_M, Intrinsics, MAX_SIDE_PX, Mount, NEAR_M,
};
pub use error::{RenderError, Result};
pub use frame::Frame;
pub use renderer::Renderer;
pub use scene::{MARKER_LIFT_M, Marker, SKY_RGB, SUN_DIRECTION_ENU, Scene};
