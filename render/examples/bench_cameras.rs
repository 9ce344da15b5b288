//! Frames per second of the renderer over a small city: 100 box buildings on a 10 x 10 grid,
//! 1, 8 and 32 cameras per `render` call at 160x120, 320x240 and 640x480 on flat ground
//! (1 and 8 on hills, where the ground keeps its grid), plus the cost of encoding one
//! 640x480 frame. Frames are rendered into reused buffers (`Renderer::render_into`), as a
//! simulator at camera rate would. Wall time, so run it on an idle machine:
//!
//! ```text
//! cargo run --release -p sadesim-render --example bench_cameras [seconds per case]
//! ```

use std::time::{Duration, Instant};

use sadesim_render::{CameraModel, CameraPose, CameraView, Frame, Mount, Renderer, Scene};
use sadesim_world::{Building, Footprint, GroundGrid, Terrain, World};

/// 100 buildings, 20 m x 20 m, on a 40 m grid, 12 to 47 m tall, on flat ground or on
/// gentle hills (which keep the ground's 65 x 65 grid: 8 192 more triangles).
fn city(hills: bool) -> World {
    let mut buildings = Vec::new();
    for j in 0..10 {
        for i in 0..10 {
            let (e, n) = (-200.0 + 40.0 * f64::from(i), -200.0 + 40.0 * f64::from(j));
            let ring = vec![[e, n], [e + 20.0, n], [e + 20.0, n + 20.0], [e, n + 20.0]];
            let height_m = 12.0 + f64::from((i * 7 + j * 13) % 36);
            buildings.push(Building::new(Footprint::new(ring, vec![]).expect("square"), 0.0, height_m).expect("tall"));
        }
    }
    if hills {
        let grid = GroundGrid::sample(300.0, 61, |e, n| 3.0 * (e / 80.0).sin() * (n / 110.0).cos());
        World::of_buildings_on(300.0, Terrain::from_grid(grid), buildings)
    } else {
        World::of_buildings(300.0, buildings)
    }
}

/// Viewpoints every case cycles through, so that all cases average the same images.
const VIEWPOINTS: usize = 32;

/// `VIEWPOINTS` drones at 40 m spread over the city (a sunflower spiral), each heading its
/// own way, cameras pitched 30 degrees down.
fn viewpoints(model: CameraModel) -> Vec<CameraView> {
    let mount = Mount { pitch_deg: 30.0, ..Mount::FORWARD };
    (0..VIEWPOINTS)
        .map(|k| {
            let a = k as f64 * 2.399_963; // the golden angle
            let r = 180.0 * ((k as f64 + 0.5) / VIEWPOINTS as f64).sqrt();
            let (s, c) = (a / 2.0).sin_cos();
            let pose = CameraPose::from_body([r * a.cos(), r * a.sin(), 40.0], [c, 0.0, 0.0, s], &mount);
            CameraView { model, pose: pose.expect("pose") }
        })
        .collect()
}

/// One way to turn a frame into bytes.
type Encoder = dyn Fn(&Frame) -> Vec<u8>;

fn timed(budget: Duration, mut f: impl FnMut()) -> (usize, Duration) {
    f(); // warm-up: first use of a resolution creates its textures and grows the buffers
    let start = Instant::now();
    let mut calls = 0;
    while calls < 3 || start.elapsed() < budget {
        f();
        calls += 1;
    }
    (calls, start.elapsed())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let seconds: f64 = std::env::args().nth(1).map(|s| s.parse()).transpose()?.unwrap_or(3.0);
    let budget = Duration::from_secs_f64(seconds);
    let flat = Scene::from_world(&city(false));
    let hills = Scene::from_world(&city(true));
    let mut renderer = Renderer::new(&flat)?;
    println!("adapter: {}", renderer.adapter_name());
    println!();
    println!("| ground | triangles | resolution | cameras per call | calls/s | frames/s | ms per call |");
    println!("|---|---:|---|---:|---:|---:|---:|");
    let sizes = [(160, 120), (320, 240), (640, 480)];
    for (name, scene, counts) in [("flat", &flat, &[1, 8, 32][..]), ("hills", &hills, &[1, 8][..])] {
        renderer.set_scene(scene)?;
        for (w, h) in sizes {
            let model = CameraModel::new(w, h, 90.0)?;
            for &n in counts {
                // Call i renders viewpoints i n .. i n + n (cyclic).
                let all = viewpoints(model);
                let (mut next, mut frames) = (0, Vec::new());
                let (calls, elapsed) = timed(budget, || {
                    let views: Vec<CameraView> = (0..n).map(|j| all[(next + j) % VIEWPOINTS]).collect();
                    next = (next + n) % VIEWPOINTS;
                    renderer.render_into(&views, &mut frames).expect("renders");
                });
                let per_call = elapsed.as_secs_f64() / calls as f64;
                let triangles = scene.triangle_count();
                println!(
                    "| {name} | {triangles} | {w}x{h} | {n} | {:.1} | {:.1} | {:.2} |",
                    1.0 / per_call,
                    n as f64 / per_call,
                    per_call * 1e3
                );
            }
        }
    }
    renderer.set_scene(&flat)?;

    let frame: Frame = renderer.render(&viewpoints(CameraModel::new(640, 480, 90.0)?)[..1])?.remove(0);
    println!();
    println!("| encoding one 640x480 frame | ms | bytes |");
    println!("|---|---:|---:|");
    let encoders: [(&str, &Encoder); 4] = [
        ("rgb_png", &|f| f.rgb_png().expect("png")),
        ("rgb_jpeg(85)", &|f| f.rgb_jpeg(85).expect("jpeg")),
        ("depth_png_mm", &|f| f.depth_png_mm().expect("png")),
        ("depth_f32_le", &|f| f.depth_f32_le()),
    ];
    for (name, encode) in encoders {
        let mut bytes = 0;
        let (calls, elapsed) = timed(budget / 3, || bytes = encode(&frame).len());
        println!("| {name} | {:.2} | {bytes} |", elapsed.as_secs_f64() * 1e3 / calls as f64);
    }
    Ok(())
}
