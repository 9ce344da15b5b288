//! Frames per second of the renderer over a small city: 100 box buildings on a 10 x 10 grid,
//! 1, 8 and 32 cameras per `render` call at 160x120, 320x240 and 640x480, plus the cost of
//! encoding one 640x480 frame. Wall time, so run it on an idle machine:
//!
//! ```text
//! cargo run --release -p sadesim-render --example bench_cameras [seconds per case]
//! ```

use std::time::{Duration, Instant};

use sadesim_render::{CameraModel, CameraPose, CameraView, Frame, Mount, Renderer, Scene};
use sadesim_world::{Building, Footprint, World};

/// 100 buildings, 20 m x 20 m, on a 40 m grid, 12 to 47 m tall.
fn city() -> World {
    let mut buildings = Vec::new();
    for j in 0..10 {
        for i in 0..10 {
            let (e, n) = (-200.0 + 40.0 * f64::from(i), -200.0 + 40.0 * f64::from(j));
            let ring = vec![[e, n], [e + 20.0, n], [e + 20.0, n + 20.0], [e, n + 20.0]];
            let height_m = 12.0 + f64::from((i * 7 + j * 13) % 36);
            buildings.push(Building::new(Footprint::new(ring, vec![]).expect("square"), 0.0, height_m).expect("tall"));
        }
    }
    World::of_buildings(300.0, buildings)
}

/// `n` drones at 40 m over the city, each heading its own way, cameras pitched 30 degrees down.
fn views(n: usize, model: CameraModel) -> Vec<CameraView> {
    let mount = Mount { pitch_deg: 30.0, ..Mount::FORWARD };
    (0..n)
        .map(|k| {
            let a = k as f64 * 2.399_963; // golden angle: spread positions and headings
            let position = [120.0 * a.cos() * (k as f64 / n as f64).sqrt(), 120.0 * a.sin(), 40.0];
            let (s, c) = (a / 2.0).sin_cos();
            CameraView { model, pose: CameraPose::from_body(position, [c, 0.0, 0.0, s], &mount).expect("pose") }
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
    let scene = Scene::from_world(&city());
    let mut renderer = Renderer::new(&scene)?;
    println!("adapter: {}", renderer.adapter_name());
    println!("scene: {} triangles", scene.triangle_count());
    println!();
    println!("| resolution | cameras per call | calls/s | frames/s | ms per call |");
    println!("|---|---:|---:|---:|---:|");
    for (w, h) in [(160, 120), (320, 240), (640, 480)] {
        let model = CameraModel::new(w, h, 90.0)?;
        for n in [1, 8, 32] {
            let views = views(n, model);
            let (calls, elapsed) = timed(budget, || {
                renderer.render(&views).expect("renders");
            });
            let per_call = elapsed.as_secs_f64() / calls as f64;
            println!("| {w}x{h} | {n} | {:.1} | {:.1} | {:.2} |", 1.0 / per_call, n as f64 / per_call, per_call * 1e3);
        }
    }

    let frame: Frame = renderer.render(&views(1, CameraModel::new(640, 480, 90.0)?))?.remove(0);
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
