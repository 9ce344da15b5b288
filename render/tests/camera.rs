//! The camera model without a GPU: input checks, projection, calibration, mounts.

use sadesim_render::{CameraModel, CameraPose, CameraView, MAX_SIDE_PX, Marker, Mount, RenderError, Scene};

mod common;

fn refused_field(result: Result<CameraModel, RenderError>) -> (&'static str, String) {
    match result {
        Err(e @ RenderError::InvalidCamera { field, .. }) => (field, e.to_string()),
        other => panic!("expected InvalidCamera, got {other:?}"),
    }
}

#[test]
fn bad_sizes_and_fields_of_view_are_refused_naming_the_field() {
    for (width, height, fov, field) in [
        (0, 240, 90.0, "width"),
        (MAX_SIDE_PX + 1, 240, 90.0, "width"),
        (320, 0, 90.0, "height"),
        (320, 5000, 90.0, "height"),
        (320, 240, 0.0, "horizontal_fov_deg"),
        (320, 240, -10.0, "horizontal_fov_deg"),
        (320, 240, 180.0, "horizontal_fov_deg"),
        (320, 240, f64::NAN, "horizontal_fov_deg"),
        (320, 240, f64::INFINITY, "horizontal_fov_deg"),
    ] {
        let (got, message) = refused_field(CameraModel::new(width, height, fov));
        assert_eq!(got, field, "{width}x{height} at {fov} deg");
        assert!(message.contains(field), "{message}");
    }
    assert!(CameraModel::new(MAX_SIDE_PX, 1, 179.9).is_ok());
}

#[test]
fn bad_poses_and_markers_are_refused_naming_the_field() {
    let err = CameraPose::from_body([0.0, f64::NAN, 0.0], [1.0, 0.0, 0.0, 0.0], &Mount::FORWARD).expect_err("NaN");
    assert!(err.to_string().contains("body_position_enu_m"), "{err}");
    let err = CameraPose::from_body([0.0; 3], [0.0; 4], &Mount::FORWARD).expect_err("zero quaternion");
    assert!(err.to_string().contains("body_flu_to_enu_wxyz"), "{err}");
    let err = CameraPose::looking_at([1.0, 2.0, 3.0], [1.0, 2.0, 3.0]).expect_err("no direction");
    assert!(err.to_string().contains("target_enu_m"), "{err}");

    let world = common::world_of(&[]);
    let good = Marker { center_enu_m: [0.0; 3], size_m: 1.0, yaw_deg: 0.0, cells: vec![true; 36] };
    let err = Scene::with_markers(&world, &[good.clone(), Marker { cells: vec![true; 35], ..good.clone() }])
        .expect_err("not a square");
    assert!(err.to_string().contains("markers[1].cells"), "{err}");
    let err = Scene::with_markers(&world, &[Marker { size_m: 0.0, ..good }]).expect_err("no size");
    assert!(err.to_string().contains("markers[0].size_m"), "{err}");
}

#[test]
fn intrinsics_put_the_image_edges_at_half_the_field_of_view() {
    let model = CameraModel::new(640, 480, 90.0).expect("valid");
    let k = model.intrinsics();
    assert!((k.fx - 320.0).abs() < 1e-9 && k.fy == k.fx);
    assert_eq!((k.cx, k.cy), (319.5, 239.5));
    // tan(vfov / 2) = (480 / 2) / 320.
    assert!((model.vertical_fov_deg() - 2.0 * 0.75f64.atan().to_degrees()).abs() < 1e-9);
    // A point 45 degrees right of the axis lands on the right edge of the image, u = W - 0.5.
    let view = CameraView { model, pose: CameraPose::looking_at([0.0; 3], [1.0, 0.0, 0.0]).expect("pose") };
    let [u, v] = view.project([10.0, -10.0, 0.0]).expect("in front");
    assert!((u - 639.5).abs() < 1e-9 && (v - 239.5).abs() < 1e-9, "{u} {v}");
    assert!(view.project([-1.0, 0.0, 0.0]).is_none(), "behind the camera");
}

#[test]
fn mounts_follow_the_documented_axes() {
    // A level drone heading north (body x = north, y = west).
    let q = common::level_heading(90.0);
    let pose = |mount: Mount| CameraPose::from_body([0.0, 0.0, 10.0], q, &mount).expect("pose");
    let axis_of = |pose: CameraPose, p: [f64; 3]| pose.to_optical(p);
    // Forward: optical z north, x (right) east, y (down) down.
    let fwd = pose(Mount::FORWARD);
    assert_close(axis_of(fwd, [0.0, 5.0, 10.0]), [0.0, 0.0, 5.0]);
    assert_close(axis_of(fwd, [5.0, 0.0, 10.0]), [5.0, 0.0, 0.0]);
    assert_close(axis_of(fwd, [0.0, 0.0, 5.0]), [0.0, 5.0, 0.0]);
    // Down (pitch +90): optical z down, the image's top (-y) towards body forward (north).
    let down = pose(Mount::DOWN);
    assert_close(axis_of(down, [0.0, 0.0, 5.0]), [0.0, 0.0, 5.0]);
    assert_close(axis_of(down, [0.0, 5.0, 10.0]), [0.0, -5.0, 0.0]);
    assert_close(axis_of(down, [5.0, 0.0, 10.0]), [5.0, 0.0, 0.0]);
    // Yaw +90 looks left (west); the offset is in body FLU (1 m forward = 1 m north).
    let left = pose(Mount { yaw_deg: 90.0, offset_flu_m: [1.0, 0.0, 0.0], ..Mount::FORWARD });
    assert_close(left.position_enu_m(), [0.0, 1.0, 10.0]);
    assert_close(axis_of(left, [-5.0, 1.0, 10.0]), [0.0, 0.0, 5.0]);
}

#[test]
fn calibration_matches_foxglove_camera_calibration() {
    let model = CameraModel::new(320, 240, 60.0).expect("valid");
    let json = serde_json::to_value(model.calibration()).expect("serialises");
    let k = model.intrinsics();
    assert_eq!(json["width"], 320);
    assert_eq!(json["height"], 240);
    assert_eq!(json["distortion_model"], "plumb_bob");
    assert_eq!(json["D"], serde_json::json!([]));
    assert_eq!(json["K"], serde_json::json!([k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0]));
    assert_eq!(json["R"], serde_json::json!([1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]));
    assert_eq!(json["P"], serde_json::json!([k.fx, 0.0, k.cx, 0.0, 0.0, k.fy, k.cy, 0.0, 0.0, 0.0, 1.0, 0.0]));
}

fn assert_close(got: [f64; 3], want: [f64; 3]) {
    assert!((0..3).all(|k| (got[k] - want[k]).abs() < 1e-9), "{got:?} != {want:?}");
}
