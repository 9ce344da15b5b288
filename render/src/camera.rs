//! Pinhole cameras: the model (resolution, field of view, intrinsics), the mount on a drone,
//! the pose in the world, projection of world points to pixels, and the calibration record.
//!
//! # Frames
//!
//! - World: ENU metres (x east, y north, z up), as `sadesim_world`.
//! - Body: FLU (x forward, y left, z up), attitude as the simulator's
//!   `DroneSnapshot.attitude_wxyz` (body FLU -> ENU, `[w, x, y, z]`).
//! - Optical: x right, y down, z forward along the optical axis, as ROS `*_optical_frame`
//!   (REP 103) and OpenCV. Depth is the optical z of the surface ([`crate::Frame`]).
//!
//! # Pixels
//!
//! Pixel `(u, v)`: u to the right, v down, the centre of the top-left pixel at `(0, 0)` and
//! pixel `(i, j)` covering `[i - 0.5, i + 0.5] x [j - 0.5, j + 0.5]`: OpenCV's and ROS
//! `CameraInfo`'s convention, so the [`CameraCalibration`] we publish means to those tools
//! what it means here. The optical axis goes through the centre of the image, so the
//! principal point is `cx = (width - 1) / 2`, `cy = (height - 1) / 2` (not `width / 2`,
//! which would be right for a convention with pixel centres at `i + 0.5`). [`CameraView::project`]
//! and the rendered image agree: the pixel whose centre a point projects nearest to is the
//! pixel that shows it (the GPU covers a pixel when its centre is inside a triangle).

use nalgebra::{Matrix3, Quaternion, Rotation3, Unit, UnitQuaternion, Vector3};

use crate::error::{RenderError, Result};

/// Largest width or height, pixels: far above any onboard camera we simulate, and small
/// enough that a frame (RGB + depth, 7 bytes a pixel, ~117 MB) stays a sane allocation.
pub const MAX_SIDE_PX: u32 = 4096;

/// Near clipping distance along the optical axis, metres: nothing closer is drawn (a drone's
/// own frame is not part of the scene; a camera 10 cm from a wall sees the wall).
pub const NEAR_M: f64 = 0.1;

/// Far clipping distance along the optical axis, metres: beyond it a pixel shows the sky
/// and has no depth. 2 km covers every world we fly in with margin for what a camera can
/// resolve; reversed-Z keeps the depth buffer exact at both ends.
pub const FAR_M: f64 = 2000.0;

/// A pinhole camera without distortion: resolution and horizontal field of view, square
/// pixels. Built only through [`CameraModel::new`], so every value of this type is valid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraModel {
    width: u32,
    height: u32,
    horizontal_fov_deg: f64,
}

/// The pinhole intrinsics, pixels, in the convention of the module doc (pixel centres at
/// integers): `u = fx * x / z + cx`, `v = fy * y / z + cy` for a point `(x, y, z)` in the
/// optical frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Intrinsics {
    /// Focal length along u, pixels: `(width / 2) / tan(hfov / 2)`.
    pub fx: f64,
    /// Focal length along v, pixels: equal to `fx` (square pixels).
    pub fy: f64,
    /// Principal point u, pixels: `(width - 1) / 2`, the image's centre.
    pub cx: f64,
    /// Principal point v, pixels: `(height - 1) / 2`.
    pub cy: f64,
}

/// The calibration of a camera exactly as Foxglove's `foxglove.CameraCalibration` (and ROS
/// `sensor_msgs/CameraInfo`) carry it, less the message's `timestamp` and `frame_id`, which
/// the publisher adds. Serialises to that schema's JSON field names (`D`, `K`, `R`, `P`).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct CameraCalibration {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// `plumb_bob` (OpenCV's radial-tangential model); with `D` empty: no distortion.
    pub distortion_model: String,
    /// Distortion coefficients: empty, the renderer is an ideal pinhole.
    #[serde(rename = "D")]
    pub d: Vec<f64>,
    /// Intrinsic matrix, 3x3 row-major: `[fx, 0, cx, 0, fy, cy, 0, 0, 1]`.
    #[serde(rename = "K")]
    pub k: [f64; 9],
    /// Rectification matrix, 3x3 row-major: identity (monocular, already rectified).
    #[serde(rename = "R")]
    pub r: [f64; 9],
    /// Projection matrix, 3x4 row-major: `[K | 0]` (monocular). A point `X` in the optical
    /// frame projects to `(p0 / p2, p1 / p2)` with `p = P * [X; 1]`.
    #[serde(rename = "P")]
    pub p: [f64; 12],
}

impl CameraModel {
    /// A camera of `width` x `height` pixels seeing `horizontal_fov_deg` degrees from the
    /// left edge of the image to the right edge.
    ///
    /// # Errors
    ///
    /// [`RenderError::InvalidCamera`] naming the field: `width` or `height` outside
    /// `1..=`[`MAX_SIDE_PX`], `horizontal_fov_deg` not strictly between 0 and 180 (a pinhole
    /// cannot see a half-space).
    pub fn new(width: u32, height: u32, horizontal_fov_deg: f64) -> Result<Self> {
        let side = |field: &'static str, value: u32| {
            if (1..=MAX_SIDE_PX).contains(&value) {
                Ok(())
            } else {
                Err(RenderError::InvalidCamera { field, value: value.to_string(), expected: "pixels, from 1 to 4096" })
            }
        };
        side("width", width)?;
        side("height", height)?;
        if !(horizontal_fov_deg.is_finite() && horizontal_fov_deg > 0.0 && horizontal_fov_deg < 180.0) {
            return Err(RenderError::InvalidCamera {
                field: "horizontal_fov_deg",
                value: horizontal_fov_deg.to_string(),
                expected: "degrees, strictly between 0 and 180",
            });
        }
        Ok(Self { width, height, horizontal_fov_deg })
    }

    /// Image width, pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Image height, pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Horizontal field of view, degrees, edge to edge.
    pub fn horizontal_fov_deg(&self) -> f64 {
        self.horizontal_fov_deg
    }

    /// Vertical field of view, degrees, edge to edge: `2 atan((height / 2) / fy)`.
    pub fn vertical_fov_deg(&self) -> f64 {
        let k = self.intrinsics();
        (2.0 * (f64::from(self.height) / 2.0 / k.fy).atan()).to_degrees()
    }

    /// The intrinsics (module doc: pixel centres at integers, so `cx = (width - 1) / 2`).
    /// The image's outer edges are at `u = -0.5` and `u = width - 0.5`, which `fx` puts at
    /// `+-hfov / 2`.
    pub fn intrinsics(&self) -> Intrinsics {
        let f = f64::from(self.width) / 2.0 / (self.horizontal_fov_deg.to_radians() / 2.0).tan();
        Intrinsics { fx: f, fy: f, cx: (f64::from(self.width) - 1.0) / 2.0, cy: (f64::from(self.height) - 1.0) / 2.0 }
    }

    /// The calibration record (`foxglove.CameraCalibration` fields), consistent with
    /// [`CameraModel::intrinsics`] and [`CameraView::project`].
    pub fn calibration(&self) -> CameraCalibration {
        let Intrinsics { fx, fy, cx, cy } = self.intrinsics();
        CameraCalibration {
            width: self.width,
            height: self.height,
            distortion_model: "plumb_bob".to_owned(),
            d: Vec::new(),
            k: [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0],
            r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            p: [fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0],
        }
    }
}

impl Intrinsics {
    /// The pixel `(u, v)` of a point in the optical frame (metres), `None` when it is
    /// closer than [`NEAR_M`] along the optical axis (behind the camera or clipped). The
    /// pixel may lie outside the image.
    pub fn project_optical(&self, point_optical_m: [f64; 3]) -> Option<[f64; 2]> {
        let [x, y, z] = point_optical_m;
        (z >= NEAR_M).then(|| [self.fx * x / z + self.cx, self.fy * y / z + self.cy])
    }
}

/// Where a camera sits on a drone and where it looks, relative to the body.
///
/// The camera's own axes before the optical convention are FLU like the body's, and the
/// zero mount looks forward along body +x with the image's top up. The rotation of those
/// axes relative to the body is `Rz(yaw) * Ry(pitch) * Rx(roll)` (yaw, then pitch, then roll
/// about the rotated axes), right-handed about the body's FLU axes as in ROS REP 103: so
/// **`pitch_deg = +90` looks straight down** (a rotation about +y, the left axis, tips the
/// forward axis down) with the top of the image towards body forward, `pitch_deg = -90`
/// looks up, `yaw_deg = +90` looks left.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Mount {
    /// The camera's optical centre from the body origin, body FLU metres.
    pub offset_flu_m: [f64; 3],
    /// Rotation about the camera's forward axis, degrees (positive: the camera's right side
    /// tips down, as a body's positive roll in FLU).
    pub roll_deg: f64,
    /// Rotation about the left axis, degrees; +90 looks down.
    pub pitch_deg: f64,
    /// Rotation about the up axis, degrees; +90 looks left.
    pub yaw_deg: f64,
}

impl Mount {
    /// At the body origin, looking forward along body +x.
    pub const FORWARD: Mount = Mount { offset_flu_m: [0.0; 3], roll_deg: 0.0, pitch_deg: 0.0, yaw_deg: 0.0 };

    /// At the body origin, looking straight down, the top of the image towards body forward.
    pub const DOWN: Mount = Mount { offset_flu_m: [0.0; 3], roll_deg: 0.0, pitch_deg: 90.0, yaw_deg: 0.0 };

    /// The camera's FLU axes in the body frame: `Rz(yaw) * Ry(pitch) * Rx(roll)`.
    fn body_from_camera_flu(&self) -> Rotation3<f64> {
        Rotation3::from_euler_angles(self.roll_deg.to_radians(), self.pitch_deg.to_radians(), self.yaw_deg.to_radians())
    }
}

/// The optical frame's axes in a FLU frame: optical x (right) = -y, optical y (down) = -z,
/// optical z (forward) = +x. Columns are the optical axes.
fn flu_from_optical() -> Rotation3<f64> {
    Rotation3::from_matrix_unchecked(Matrix3::new(0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0))
}

/// Where a camera is and where it looks: the optical centre in the world and the rotation
/// of the optical frame into ENU. Built by [`CameraPose::from_body`] or
/// [`CameraPose::looking_at`], which refuse non-finite input, so every pose is usable.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraPose {
    position_enu_m: Vector3<f64>,
    optical_to_enu: UnitQuaternion<f64>,
}

impl CameraPose {
    /// The pose of a camera mounted on a drone at `body_position_enu_m` (ENU metres) with
    /// attitude `body_flu_to_enu_wxyz` (the rotation of body FLU axes into ENU, as
    /// `DroneSnapshot.attitude_wxyz`; normalised here).
    ///
    /// # Errors
    ///
    /// [`RenderError::InvalidView`] naming the field when a value is not finite or the
    /// quaternion has (near) zero norm.
    pub fn from_body(body_position_enu_m: [f64; 3], body_flu_to_enu_wxyz: [f64; 4], mount: &Mount) -> Result<Self> {
        finite("body_position_enu_m", &body_position_enu_m)?;
        finite("body_flu_to_enu_wxyz", &body_flu_to_enu_wxyz)?;
        finite("mount.offset_flu_m", &mount.offset_flu_m)?;
        finite("mount.roll_deg/pitch_deg/yaw_deg", &[mount.roll_deg, mount.pitch_deg, mount.yaw_deg])?;
        let [w, x, y, z] = body_flu_to_enu_wxyz;
        let q = Quaternion::new(w, x, y, z);
        if q.norm() < 1e-9 {
            return Err(RenderError::InvalidView {
                field: "body_flu_to_enu_wxyz".to_owned(),
                expected: "a rotation quaternion (non-zero norm)",
            });
        }
        let enu_from_body = UnitQuaternion::from_quaternion(q);
        let optical = UnitQuaternion::from_rotation_matrix(&(mount.body_from_camera_flu() * flu_from_optical()));
        Ok(Self {
            position_enu_m: Vector3::from(body_position_enu_m) + enu_from_body * Vector3::from(mount.offset_flu_m),
            optical_to_enu: enu_from_body * optical,
        })
    }

    /// A camera at `position_enu_m` whose optical axis points at `target_enu_m`, the image's
    /// top towards up (or towards north when it looks straight up or down): handy for
    /// fixed cameras, tests and benchmarks.
    ///
    /// # Errors
    ///
    /// [`RenderError::InvalidView`] when a value is not finite or the two points coincide.
    pub fn looking_at(position_enu_m: [f64; 3], target_enu_m: [f64; 3]) -> Result<Self> {
        finite("position_enu_m", &position_enu_m)?;
        finite("target_enu_m", &target_enu_m)?;
        let forward = Vector3::from(target_enu_m) - Vector3::from(position_enu_m);
        let Some(z) = Unit::try_new(forward, 1e-9) else {
            return Err(RenderError::InvalidView {
                field: "target_enu_m".to_owned(),
                expected: "a point other than the camera's position",
            });
        };
        // Right = forward x up; straight up or down, "up" in the image is north instead.
        let x = Unit::try_new(z.cross(&Vector3::z()), 1e-9)
            .unwrap_or_else(|| Unit::new_normalize(z.cross(&Vector3::y())))
            .into_inner();
        let y = z.cross(&x);
        let r = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z.into_inner()]));
        Ok(Self {
            position_enu_m: Vector3::from(position_enu_m),
            optical_to_enu: UnitQuaternion::from_rotation_matrix(&r),
        })
    }

    /// The optical centre, ENU metres.
    pub fn position_enu_m(&self) -> [f64; 3] {
        self.position_enu_m.into()
    }

    /// The rotation of the optical frame (x right, y down, z forward) into ENU,
    /// `[w, x, y, z]`: what a recording's `/tf` publishes for the camera's optical frame.
    pub fn optical_to_enu_wxyz(&self) -> [f64; 4] {
        let q = self.optical_to_enu.quaternion();
        [q.w, q.i, q.j, q.k]
    }

    /// A world point (ENU metres) in the optical frame (metres): `R^T (p - t)`.
    pub fn to_optical(&self, point_enu_m: [f64; 3]) -> [f64; 3] {
        (self.optical_to_enu.inverse() * (Vector3::from(point_enu_m) - self.position_enu_m)).into()
    }

    /// The rotation matrix of the optical frame into ENU (columns: optical axes in ENU).
    pub(crate) fn enu_from_optical(&self) -> Matrix3<f64> {
        self.optical_to_enu.to_rotation_matrix().into_inner()
    }
}

fn finite(field: &str, values: &[f64]) -> Result<()> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(RenderError::InvalidView { field: field.to_owned(), expected: "finite numbers" })
    }
}

/// One camera to render: its model and where it is. Rendering a view gives one
/// [`crate::Frame`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraView {
    /// Resolution and field of view.
    pub model: CameraModel,
    /// Position and orientation in the world.
    pub pose: CameraPose,
}

impl CameraView {
    /// The pixel `(u, v)` (module doc: pixel centres at integers, v down) where the world
    /// point `point_enu_m` appears, `None` when it is closer than [`NEAR_M`] along the
    /// optical axis (behind the camera). The pixel may lie outside the image; visibility
    /// (occlusion) is not checked.
    pub fn project(&self, point_enu_m: [f64; 3]) -> Option<[f64; 2]> {
        self.model.intrinsics().project_optical(self.pose.to_optical(point_enu_m))
    }

    /// The calibration record of [`CameraModel::calibration`].
    pub fn calibration(&self) -> CameraCalibration {
        self.model.calibration()
    }

    /// The matrix from world ENU (homogeneous, metres) to the GPU's clip space, column-major
    /// for WGSL. The GPU's framebuffer has pixel centres at `i + 0.5` and NDC y up, so a
    /// pixel `u` of our convention is framebuffer `u + 0.5`:
    ///
    /// - `x_ndc = 2 (u + 0.5) / W - 1 = (2 fx x + (2 (cx + 0.5) - W) z) / (W z)`,
    /// - `y_ndc = 1 - 2 (v + 0.5) / H = (-2 fy y + (H - 2 (cy + 0.5)) z) / (H z)`,
    /// - reversed Z with a far plane: `z_ndc = n (f - z) / (z (f - n))`, 1 at the near
    ///   plane, 0 at the far one (floats are densest near 0, where the distant geometry is),
    /// - `w = z`, the optical depth (what the fragment shader writes as depth).
    pub(crate) fn clip_from_world(&self) -> [f32; 16] {
        let Intrinsics { fx, fy, cx, cy } = self.model.intrinsics();
        let (w, h) = (f64::from(self.model.width), f64::from(self.model.height));
        let (n, f) = (NEAR_M, FAR_M);
        // Rows of the projection acting on optical (x, y, z, 1).
        let proj = [
            [2.0 * fx / w, 0.0, 2.0 * (cx + 0.5) / w - 1.0, 0.0],
            [0.0, -2.0 * fy / h, 1.0 - 2.0 * (cy + 0.5) / h, 0.0],
            [0.0, 0.0, -n / (f - n), n * f / (f - n)],
            [0.0, 0.0, 1.0, 0.0],
        ];
        // View: optical = R^T p - R^T t, as a 3x4 [R^T | -R^T t].
        let rt = self.pose.enu_from_optical().transpose();
        let t = -(rt * self.pose.position_enu_m);
        let view = |row: usize, col: usize| if col < 3 { rt[(row, col)] } else { t[row] };
        let mut out = [0.0f32; 16];
        for row in 0..4 {
            for col in 0..4 {
                // (proj * [view; 0 0 0 1])[row][col]
                let mut sum = (0..3).map(|k| proj[row][k] * view(k, col)).sum::<f64>();
                if col == 3 {
                    sum += proj[row][3];
                }
                out[col * 4 + row] = sum as f32;
            }
        }
        out
    }
}
