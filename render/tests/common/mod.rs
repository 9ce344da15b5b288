//! Small worlds and helpers shared by the renderer's tests.

#![allow(dead_code)]

use sadesim_render::{Frame, SKY_RGB};
use sadesim_world::{Building, Footprint, World};

/// One box building: `[west, east] x [south, north]` metres, `height_m` tall on flat ground.
pub struct BoxBuilding {
    pub west_m: f64,
    pub east_m: f64,
    pub south_m: f64,
    pub north_m: f64,
    pub height_m: f64,
}

/// The test block: 20 m wide (east-west), 10 m deep, 15 m tall, its south face at y = 20 m.
pub const BLOCK: BoxBuilding =
    BoxBuilding { west_m: -10.0, east_m: 10.0, south_m: 20.0, north_m: 30.0, height_m: 15.0 };

/// A 400 m world with `buildings` on flat ground at 0 m.
pub fn world_of(buildings: &[BoxBuilding]) -> World {
    let buildings = buildings
        .iter()
        .map(|b| {
            let ring = vec![[b.west_m, b.south_m], [b.east_m, b.south_m], [b.east_m, b.north_m], [b.west_m, b.north_m]];
            Building::new(Footprint::new(ring, vec![]).expect("a rectangle"), 0.0, b.height_m).expect("tall enough")
        })
        .collect();
    World::of_buildings(200.0, buildings)
}

/// Body FLU -> ENU for a level drone heading `yaw_deg` counter-clockwise from east, `[w, x, y, z]`.
pub fn level_heading(yaw_deg: f64) -> [f64; 4] {
    let half = yaw_deg.to_radians() / 2.0;
    [half.cos(), 0.0, 0.0, half.sin()]
}

pub fn is_sky(frame: &Frame, u: u32, v: u32) -> bool {
    frame.rgb_at(u, v) == Some(SKY_RGB)
}

/// Mean of the three channels.
pub fn luminance(frame: &Frame, u: u32, v: u32) -> f64 {
    let [r, g, b] = frame.rgb_at(u, v).expect("inside the image");
    (f64::from(r) + f64::from(g) + f64::from(b)) / 3.0
}
