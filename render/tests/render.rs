//! Frames rendered on the GPU (lavapipe on CI: `tests/install-tools.sh` installs it) checked
//! against the geometry: depth, edges where `project()` puts them, markers, determinism.

use sadesim_render::{
    CameraModel, CameraPose, CameraView, Frame, Marker, Mount, RenderError, Renderer, Scene, aruco_4x4_50,
};

mod common;
use common::{BLOCK, is_sky, level_heading, luminance, world_of};

fn render_one(scene: &Scene, view: CameraView) -> Frame {
    let mut renderer = Renderer::new(scene).expect("a Vulkan adapter (install mesa-vulkan-drivers)");
    renderer.render(&[view]).expect("renders").pop().expect("one frame")
}

/// A level drone 20 m south of the block's south face (camera 0.1 m ahead of the body),
/// heading north: the camera looks straight at the face.
fn facing_the_block() -> (CameraView, f64) {
    let body = [0.0, BLOCK.south_m - 20.1, 6.0];
    let mount = Mount { offset_flu_m: [0.1, 0.0, 0.0], ..Mount::FORWARD };
    let pose = CameraPose::from_body(body, level_heading(90.0), &mount).expect("pose");
    let true_distance_m = BLOCK.south_m - pose.position_enu_m()[1];
    (CameraView { model: CameraModel::new(320, 240, 90.0).expect("model"), pose }, true_distance_m)
}

/// First and last column of row `v` that are not sky.
fn non_sky_span(frame: &Frame, v: u32) -> (u32, u32) {
    let cols: Vec<u32> = (0..frame.width).filter(|&u| !is_sky(frame, u, v)).collect();
    (*cols.first().expect("something on the row"), *cols.last().expect("something"))
}

#[test]
fn a_facade_20_m_ahead_is_20_m_deep_and_its_edges_are_where_project_puts_the_corners() {
    let scene = Scene::from_world(&world_of(&[BLOCK]));
    let (view, true_distance_m) = facing_the_block();
    assert!((true_distance_m - 20.0).abs() < 1e-9);
    let frame = render_one(&scene, view);
    let renderer_name = Renderer::new(&scene).expect("adapter").adapter_name().to_owned();
    assert!(!renderer_name.is_empty());

    // Centre depth: the face is perpendicular to the axis, so every facade pixel is z = 20 m.
    let (cu, cv) = (frame.width / 2, frame.height / 2);
    let depth = f64::from(frame.depth_at(cu, cv).expect("inside"));
    assert!((depth - true_distance_m).abs() / true_distance_m < 0.02, "{depth} m vs {true_distance_m} m");
    assert!((depth - true_distance_m).abs() < 1e-3, "exact up to f32: {depth} vs {true_distance_m}");

    // A row 3 m above the camera: sky | facade | sky.
    let eye_up_m = view.pose.position_enu_m()[2];
    let [_, v] = view.project([0.0, BLOCK.south_m, eye_up_m + 3.0]).expect("in front");
    let row = v.round() as u32;
    let (first, last) = non_sky_span(&frame, row);
    let [u_west, _] = view.project([BLOCK.west_m, BLOCK.south_m, eye_up_m + 3.0]).expect("in front");
    let [u_east, _] = view.project([BLOCK.east_m, BLOCK.south_m, eye_up_m + 3.0]).expect("in front");
    assert!((f64::from(first) - u_west).abs() <= 1.0, "west edge at {first}, projected {u_west}");
    assert!((f64::from(last) - u_east).abs() <= 1.0, "east edge at {last}, projected {u_east}");
    // The depth across the facade row is the same plane.
    for u in first + 1..last {
        let d = f64::from(frame.depth_at(u, row).expect("inside"));
        assert!((d - true_distance_m).abs() < 1e-3, "u {u}: {d}");
    }
    // Sky has no depth.
    assert_eq!(frame.depth_at(0, 0), Some(0.0));
}

#[test]
fn pixel_centres_are_at_integers_so_an_edge_starts_at_the_next_whole_pixel() {
    // The camera slides east by a tenth of a pixel (at 20 m) per view: the facade's west
    // edge sweeps across a pixel. A pixel shows the facade when its centre is inside, so
    // with centres at integers the first facade column is exactly ceil(u_west) and the
    // last floor(u_east). A half-pixel slip in the convention fails half of these views.
    let scene = Scene::from_world(&world_of(&[BLOCK]));
    let (base, _) = facing_the_block();
    let metres_per_px = 20.0 / base.model.intrinsics().fx;
    let views: Vec<CameraView> = (0..10)
        .map(|k| {
            let [e, n, u] = base.pose.position_enu_m();
            let at = [e + 0.1 * f64::from(k) * metres_per_px, n, u];
            let pose = CameraPose::looking_at(at, [at[0], at[1] + 1.0, at[2]]).expect("pose");
            CameraView { pose, ..base }
        })
        .collect();
    let frames = Renderer::new(&scene).expect("adapter").render(&views).expect("renders");
    for (view, frame) in views.iter().zip(&frames) {
        let z = view.pose.position_enu_m()[2] + 3.0;
        let [_, v] = view.project([0.0, BLOCK.south_m, z]).expect("in front");
        let (first, last) = non_sky_span(frame, v.round() as u32);
        let [u_west, _] = view.project([BLOCK.west_m, BLOCK.south_m, z]).expect("in front");
        let [u_east, _] = view.project([BLOCK.east_m, BLOCK.south_m, z]).expect("in front");
        for (edge, want, got) in [("west", u_west.ceil(), first), ("east", u_east.floor(), last)] {
            let near_a_centre = (want - if edge == "west" { u_west } else { u_east }).abs() < 0.02;
            if !near_a_centre {
                assert_eq!(f64::from(got), want, "{edge} edge: projected {u_west} / {u_east}");
            }
        }
    }
}

#[test]
fn project_and_the_calibration_matrices_find_a_roof_corner_where_it_is_drawn() {
    let scene = Scene::from_world(&world_of(&[BLOCK]));
    // Off-centre, heading a little east of north, looking 5 degrees up.
    let body = [4.0, BLOCK.south_m - 25.0, 5.0];
    let mount = Mount { pitch_deg: -5.0, ..Mount::FORWARD };
    let pose = CameraPose::from_body(body, level_heading(80.0), &mount).expect("pose");
    let view = CameraView { model: CameraModel::new(320, 240, 90.0).expect("model"), pose };
    let frame = render_one(&scene, view);

    let corner = [BLOCK.west_m, BLOCK.south_m, BLOCK.height_m];
    let [u, v] = view.project(corner).expect("in front");
    assert!(u > 10.0 && u < 300.0 && v > 10.0 && v < 230.0, "corner in the image: {u} {v}");

    // The roof line: walking down a column 2 px inside the facade, the first non-sky pixel.
    let col = (u + 2.0).round() as u32;
    let top = (0..frame.height).find(|&r| !is_sky(&frame, col, r)).expect("facade below the sky");
    assert!((f64::from(top) - v).abs() <= 1.0, "roof line at row {top}, projected {v}");
    // The west edge: walking right along a row 2 px below the corner.
    let row = (v + 2.0).round() as u32;
    let left = (0..frame.width).find(|&c| !is_sky(&frame, c, row)).expect("facade right of the sky");
    assert!((f64::from(left) - u).abs() <= 1.0, "west edge at column {left}, projected {u}");

    // K and P reproduce the pixel from the corner in the optical frame.
    let cal = view.calibration();
    let x = pose.to_optical(corner);
    let k = cal.k;
    let kx = [0, 1, 2].map(|r| k[3 * r] * x[0] + k[3 * r + 1] * x[1] + k[3 * r + 2] * x[2]);
    let p = cal.p;
    let px = [0, 1, 2].map(|r| p[4 * r] * x[0] + p[4 * r + 1] * x[1] + p[4 * r + 2] * x[2] + p[4 * r + 3]);
    for h in [kx, px] {
        assert!((h[0] / h[2] - u).abs() < 1e-9 && (h[1] / h[2] - v).abs() < 1e-9, "{h:?} vs ({u}, {v})");
    }
}

#[test]
fn the_same_views_render_the_same_bytes() {
    let scene = Scene::from_world(&world_of(&[BLOCK]));
    let (view, _) = facing_the_block();
    let other = CameraView {
        model: CameraModel::new(160, 120, 70.0).expect("model"),
        pose: CameraPose::looking_at([30.0, -10.0, 25.0], [0.0, 25.0, 5.0]).expect("pose"),
    };
    let mut renderer = Renderer::new(&scene).expect("adapter");
    let first = renderer.render(&[view, other, view]).expect("renders");
    let second = renderer.render(&[other, view]).expect("renders");
    let fresh = Renderer::new(&scene).expect("adapter").render(&[view]).expect("renders");
    let mut reused = first.clone();
    renderer.render_into(&[other, view], &mut reused).expect("renders");
    assert_eq!(reused, second, "into reused frames of other sizes");
    assert_eq!(first[0], first[2], "the same view twice in one call");
    assert_eq!(first[0], second[1], "across calls");
    assert_eq!(first[1], second[0], "across calls, another resolution");
    assert_eq!(first[0], fresh[0], "across renderers");
    assert_eq!(first[0].rgb_png().expect("png"), fresh[0].rgb_png().expect("png"));
    assert_eq!(first[0].depth_png_mm().expect("png"), fresh[0].depth_png_mm().expect("png"));
    assert_ne!(first[0], first[1]);
}

#[test]
fn a_downward_camera_sees_the_marker_cells_black_and_white() {
    let cells = aruco_4x4_50(7).expect("id 7");
    let marker = Marker { center_enu_m: [30.0, -20.0, 0.0], size_m: 1.2, yaw_deg: 20.0, cells: cells.clone() };
    let scene = Scene::with_markers(&world_of(&[BLOCK]), std::slice::from_ref(&marker)).expect("valid");
    // 4 m above, a little off the centre, heading 30 degrees.
    let pose = CameraPose::from_body([30.2, -20.1, 4.0], level_heading(30.0), &Mount::DOWN).expect("pose");
    let view = CameraView { model: CameraModel::new(320, 240, 60.0).expect("model"), pose };
    let frame = render_one(&scene, view);
    let depth = f64::from(frame.depth_at(160, 120).expect("inside"));
    assert!((depth - (4.0 - sadesim_render::MARKER_LIFT_M)).abs() < 1e-3, "{depth}");
    for row in 0..6 {
        for col in 0..6 {
            let [u, v] = view.project(marker.cell_center_enu_m(row, col)).expect("below the camera");
            let (u, v) = (u.round() as u32, v.round() as u32);
            let l = luminance(&frame, u, v);
            if cells[row * 6 + col] {
                assert!(l > 180.0, "cell ({row}, {col}) should be white: {l}");
            } else {
                assert!(l < 40.0, "cell ({row}, {col}) should be black: {l}");
            }
        }
    }
    // The ground around the marker is neither.
    let [u, v] = view.project([30.0 + 1.5, -20.0, 0.0]).expect("below");
    let l = luminance(&frame, u.round() as u32, v.round() as u32);
    assert!(l > 40.0 && l < 180.0, "ground {l}");
}

#[test]
fn no_vulkan_driver_is_a_clear_error() {
    // The loader reads the driver list from the environment: run the probe below in a child
    // process (this crate forbids unsafe, so no `set_var` here) with no driver at all.
    let output = std::process::Command::new(std::env::current_exe().expect("test binary"))
        .args(["--ignored", "--exact", "probe_no_adapter", "--nocapture"])
        .env("VK_ICD_FILENAMES", "/nonexistent/icd.json")
        .env("VK_DRIVER_FILES", "/nonexistent/icd.json")
        .env("SADESIM_RENDER_PROBE", "1")
        .output()
        .expect("runs");
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(output.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&output.stderr));
    assert!(stdout.contains("mesa-vulkan-drivers"), "{stdout}");
}

#[test]
#[ignore = "run by no_vulkan_driver_is_a_clear_error with no Vulkan driver"]
fn probe_no_adapter() {
    if std::env::var_os("SADESIM_RENDER_PROBE").is_none() {
        return;
    }
    match Renderer::new(&Scene::default()) {
        Err(e @ RenderError::NoAdapter(_)) => println!("{e}"),
        other => panic!("expected NoAdapter, got {other:?}"),
    }
}

#[test]
fn an_empty_call_an_empty_scene_and_a_new_scene_are_fine() {
    let mut renderer = Renderer::new(&Scene::default()).expect("adapter");
    assert!(renderer.render(&[]).expect("nothing to do").is_empty());
    let (view, _) = facing_the_block();
    let frame = renderer.render(&[view]).expect("renders").pop().expect("one");
    assert!(frame.rgb.chunks(3).all(|p| p == sadesim_render::SKY_RGB));
    assert!(frame.depth_m.iter().all(|&d| d == 0.0));
    // The scene can change under the same renderer.
    let block = Scene::from_world(&world_of(&[BLOCK]));
    renderer.set_scene(&block).expect("fits");
    assert_eq!(renderer.render(&[view]).expect("renders"), [render_one(&block, view)]);
}

#[test]
fn the_renderer_can_move_to_a_sensor_thread() {
    fn send<T: Send>() {}
    send::<Renderer>();
    send::<Frame>();
}

#[test]
fn culling_draws_the_same_images_from_far_fewer_triangles() {
    use common::BoxBuilding;
    // A grid of 20 m blocks every 40 m over the whole 400 m world: 100 buildings in 16 tiles.
    let blocks: Vec<BoxBuilding> = (0..10)
        .flat_map(|i| (0..10).map(move |j| (f64::from(i) * 40.0 - 190.0, f64::from(j) * 40.0 - 190.0)))
        .map(|(w, s)| BoxBuilding { west_m: w, east_m: w + 20.0, south_m: s, north_m: s + 20.0, height_m: 12.0 })
        .collect();
    let scene = Scene::from_world(&world_of(&blocks));
    let model = CameraModel::new(160, 120, 90.0).expect("model");
    let views = [
        // Straight down from 40 m over a corner of four blocks: a few tiles.
        CameraView {
            model,
            pose: CameraPose::looking_at([-150.0, -150.0, 40.0], [-150.0, -150.0, 0.0]).expect("pose"),
        },
        // Across the whole city from its south-west corner: most tiles.
        CameraView { model, pose: CameraPose::looking_at([-210.0, -210.0, 30.0], [0.0, 0.0, 0.0]).expect("pose") },
    ];
    let mut renderer = Renderer::new(&scene).expect("adapter");
    let culled: Vec<Frame> = views.iter().map(|v| renderer.render(&[*v]).expect("renders").remove(0)).collect();
    let down_drawn = {
        renderer.render(&views[..1]).expect("renders");
        renderer.triangles_drawn()
    };
    renderer.set_culling(false);
    let everything = renderer.render(&views).expect("renders");
    assert_eq!(renderer.triangles_drawn(), 2 * scene.triangle_count() as u64);
    assert_eq!(culled, everything, "culling changes no pixel");
    assert!(
        down_drawn * 3 < scene.triangle_count() as u64,
        "the downward view drew {down_drawn} of {} triangles",
        scene.triangle_count()
    );
    assert!(culled[0].depth_at(80, 60).is_some_and(|d| d > 0.0), "it sees the ground or a roof");
}
