//! Renders ArUco markers (OpenCV `DICT_4X4_50`, ids 0..=9) seen by a drone's downward camera
//! and writes one PNG per id, for a cross-check with OpenCV's detector:
//!
//! ```text
//! cargo run -p sadesim-render --example render_marker -- /tmp/markers
//! python3 -c 'import cv2, sys, glob
//! d = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50))
//! for p in sorted(glob.glob("/tmp/markers/marker_*.png")):
//!     print(p, d.detectMarkers(cv2.imread(p))[1].ravel().tolist())'
//! ```
//!
//! Each marker lies on flat ground, turned by a few degrees; the camera is 3 m above it,
//! pitched 10 degrees off the vertical, so the detector sees perspective, not a scan.

use sadesim_render::{CameraModel, CameraPose, CameraView, Marker, Mount, Renderer, Scene, aruco_4x4_50};
use sadesim_world::World;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::path::PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| "target/markers".to_owned()));
    std::fs::create_dir_all(&out)?;
    let world = World::of_buildings(100.0, vec![]);
    let markers: Vec<Marker> = (0..10)
        .map(|id| Marker {
            center_enu_m: [10.0 * id as f64, 0.0, 0.0],
            size_m: 0.8,
            yaw_deg: 7.0 * id as f64,
            cells: aruco_4x4_50(id).expect("ids 0..=9 exist"),
        })
        .collect();
    let mut renderer = Renderer::new(&Scene::with_markers(&world, &markers)?)?;
    println!("adapter: {}", renderer.adapter_name());
    let model = CameraModel::new(640, 480, 60.0)?;
    // Heading north, the camera 10 degrees short of straight down, 0.5 m south of the marker.
    let mount = Mount { pitch_deg: 80.0, ..Mount::DOWN };
    let views: Vec<CameraView> = markers
        .iter()
        .map(|m| {
            let [e, n, _] = m.center_enu_m;
            let attitude = [std::f64::consts::FRAC_1_SQRT_2, 0.0, 0.0, std::f64::consts::FRAC_1_SQRT_2];
            Ok(CameraView { model, pose: CameraPose::from_body([e, n - 0.5, 3.0], attitude, &mount)? })
        })
        .collect::<sadesim_render::Result<_>>()?;
    for (id, frame) in renderer.render(&views)?.iter().enumerate() {
        let path = out.join(format!("marker_{id}.png"));
        std::fs::write(&path, frame.rgb_png()?)?;
        println!("{id} {}", path.display());
    }
    Ok(())
}
