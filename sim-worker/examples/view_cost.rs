//! What the live view costs the coordinator per window, at 32 and 1 000 drones:
//!
//!   cargo run --release -p sim-worker --example view_cost
//!
//! The coordinator pays for turning a window into a frame (the JSON of every drone's pose,
//! at most 25 times a wall second) and for each event; browsers cost it nothing (they read
//! the feed from the server's own thread). Prints the cost of one frame, the cost of a
//! throttled window (what most windows cost), and the frame's size.

use std::time::Instant;

use sadesim_engine::events::FlightMode;
use sadesim_engine::protocol::{DroneDetail, DroneSnapshot};
use sim_worker::view::feed::{Pose, encode_frame};
use sim_worker::view::{Feed, Publisher};

fn drones(n: u32) -> Vec<DroneSnapshot> {
    (0..n)
        .map(|i| DroneSnapshot {
            index: i,
            position_enu_m: [f64::from(i) * 3.217, -f64::from(i) * 1.113, 31.4159 + f64::from(i % 7)],
            velocity_enu_mps: [1.0, 0.5, 0.0],
            attitude_wxyz: [0.9987, 0.0123, -0.0456, 0.0234],
            height_agl_m: 30.0,
            mode: FlightMode::Mission,
            armed: true,
            on_ground: false,
            crashed: false,
            battery_remaining: 0.9,
            position_valid: true,
            detail: DroneDetail::default(),
        })
        .collect()
}

fn main() {
    println!("| drones | frame (encode + publish) | throttled window | frame size |");
    println!("|---|---|---|---|");
    for n in [32u32, 1000] {
        let fleet = drones(n);
        let feed = Feed::new();
        let _browser = feed.subscribe();
        let reps = 2000;
        let started = Instant::now();
        let mut bytes = 0;
        for k in 0..reps {
            let poses: Vec<Pose> = fleet.iter().map(Pose::of).collect();
            let frame = encode_frame(f64::from(k) * 0.01, Some(1.0), &poses);
            bytes = frame.len();
            feed.publish_frame(frame.into());
        }
        let frame_us = started.elapsed().as_secs_f64() / f64::from(reps) * 1e6;
        // Windows inside the frame interval publish nothing but their events (none here).
        let mut publisher = Publisher::new(feed.clone());
        publisher.on_window(0.0, &fleet, &[]);
        let started = Instant::now();
        for k in 1..=reps {
            publisher.on_window(f64::from(k) * 0.01, &fleet, &[]);
        }
        let window_us = started.elapsed().as_secs_f64() / f64::from(reps) * 1e6;
        println!("| {n} | {frame_us:.1} µs | {window_us:.2} µs | {:.1} kB |", bytes as f64 / 1000.0);
    }
}
