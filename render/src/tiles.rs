//! View-frustum culling: the scene's triangles grouped into square tiles of the ground
//! plane, each drawn only by the views whose frustum its bounding box touches.
//!
//! Why: lavapipe pays for every triangle of a draw, seen or not (`docs/performance.md`:
//! triangles cost more than pixels). A procedural city of 12 000 buildings is some 150 000
//! triangles, several milliseconds a view on 2 cores, while a drone's downward camera at 20-60 m sees
//! a few dozen buildings. What every engine does (three.js culls per object) we do per
//! tile, which keeps one vertex buffer and one draw per run of visible tiles.
//!
//! Frames: ENU metres, as the scene. A triangle belongs to the tile of its centroid; a
//! tile's box is the union of its triangles' boxes (the flat ground's two big triangles
//! give their tile a box over the whole world, so it is always drawn).

/// Side of a tile, metres: a few city blocks. Smaller tiles cull more finely but cost a
/// draw call each; at 100 m a downward camera at 60 m AGL (a 120 m footprint) draws 1-4.
pub const TILE_M: f64 = 100.0;

/// One tile: a run of vertices in the (sorted) vertex buffer and their bounding box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tile {
    pub first_vertex: u32,
    pub vertex_count: u32,
    pub min_enu_m: [f64; 3],
    pub max_enu_m: [f64; 3],
}

/// Sorts `vertices` (three per triangle) by tile, keeping the order of triangles within a
/// tile, and returns the tiles in buffer order.
pub fn tile<T: Copy>(vertices: &mut Vec<([f32; 3], T)>) -> Vec<Tile> {
    let triangles = vertices.len() / 3;
    let key = |t: usize| -> (i64, i64) {
        let c = (0..3).fold([0.0f64; 2], |acc, k| {
            let p = vertices[t * 3 + k].0;
            [acc[0] + f64::from(p[0]) / 3.0, acc[1] + f64::from(p[1]) / 3.0]
        });
        ((c[0] / TILE_M).floor() as i64, (c[1] / TILE_M).floor() as i64)
    };
    let mut order: Vec<((i64, i64), usize)> = (0..triangles).map(|t| (key(t), t)).collect();
    // Stable by construction: the triangle index breaks ties.
    order.sort_unstable();
    let mut sorted = Vec::with_capacity(vertices.len());
    let mut tiles: Vec<Tile> = Vec::new();
    let mut current = None;
    for (k, t) in order {
        if current != Some(k) {
            current = Some(k);
            tiles.push(Tile {
                first_vertex: sorted.len() as u32,
                vertex_count: 0,
                min_enu_m: [f64::INFINITY; 3],
                max_enu_m: [f64::NEG_INFINITY; 3],
            });
        }
        let tile = tiles.last_mut().expect("pushed above");
        for v in &vertices[t * 3..t * 3 + 3] {
            for axis in 0..3 {
                let x = f64::from(v.0[axis]);
                tile.min_enu_m[axis] = tile.min_enu_m[axis].min(x);
                tile.max_enu_m[axis] = tile.max_enu_m[axis].max(x);
            }
            sorted.push(*v);
        }
        tile.vertex_count += 3;
    }
    *vertices = sorted;
    tiles
}

/// The six planes `(a, b, c, d)` of a view's frustum in world coordinates, inside where
/// `a x + b y + c z + d >= 0`, from its clip-from-world matrix (column-major, wgpu clip
/// space: `-w <= x, y <= w`, `0 <= z <= w`), as Gribb and Hartmann extract them.
pub fn frustum_planes(clip_from_world: &[f32; 16]) -> [[f64; 4]; 6] {
    let row = |r: usize| -> [f64; 4] { std::array::from_fn(|c| f64::from(clip_from_world[c * 4 + r])) };
    let (x, y, z, w) = (row(0), row(1), row(2), row(3));
    let add = |a: [f64; 4], b: [f64; 4], s: f64| -> [f64; 4] { std::array::from_fn(|i| a[i] + s * b[i]) };
    [add(w, x, 1.0), add(w, x, -1.0), add(w, y, 1.0), add(w, y, -1.0), z, add(w, z, -1.0)]
}

/// Whether the box `min..max` may be inside the frustum: false only when it lies wholly
/// behind one plane (conservative: a box near a corner may pass and draw nothing).
pub fn box_visible(planes: &[[f64; 4]; 6], min: [f64; 3], max: [f64; 3]) -> bool {
    planes.iter().all(|[a, b, c, d]| {
        // The box's corner furthest along the plane's normal.
        let p = [
            if *a >= 0.0 { max[0] } else { min[0] },
            if *b >= 0.0 { max[1] } else { min[1] },
            if *c >= 0.0 { max[2] } else { min[2] },
        ];
        a * p[0] + b * p[1] + c * p[2] + d >= 0.0
    })
}

/// The vertex ranges a view draws: its visible tiles, neighbours in the buffer merged.
pub fn visible_ranges(tiles: &[Tile], planes: &[[f64; 4]; 6], out: &mut Vec<std::ops::Range<u32>>) {
    out.clear();
    for t in tiles.iter().filter(|t| box_visible(planes, t.min_enu_m, t.max_enu_m)) {
        let range = t.first_vertex..t.first_vertex + t.vertex_count;
        match out.last_mut() {
            Some(last) if last.end == range.start => last.end = range.end,
            _ => out.push(range),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{CameraModel, CameraPose, CameraView};

    fn triangle_at(e: f32, n: f32, id: u8) -> [([f32; 3], u8); 3] {
        [([e, n, 0.0], id), ([e + 1.0, n, 0.0], id), ([e, n + 1.0, 5.0], id)]
    }

    #[test]
    fn triangles_are_grouped_by_the_tile_of_their_centroid_keeping_their_order() {
        let mut v: Vec<_> = [triangle_at(250.0, 10.0, 0), triangle_at(10.0, 10.0, 1), triangle_at(260.0, 20.0, 2)]
            .into_iter()
            .flatten()
            .collect();
        let tiles = tile(&mut v);
        assert_eq!(tiles.len(), 2);
        assert_eq!((tiles[0].first_vertex, tiles[0].vertex_count), (0, 3), "tile (0, 0) first");
        assert_eq!((tiles[1].first_vertex, tiles[1].vertex_count), (3, 6));
        assert_eq!(v.iter().map(|p| p.1).collect::<Vec<_>>(), [1, 1, 1, 0, 0, 0, 2, 2, 2]);
        assert_eq!(tiles[1].min_enu_m, [250.0, 10.0, 0.0]);
        assert_eq!(tiles[1].max_enu_m, [261.0, 21.0, 5.0]);
    }

    #[test]
    fn a_downward_camera_keeps_the_box_below_it_and_culls_the_others() {
        let model = CameraModel::new(320, 240, 90.0).unwrap();
        let pose = CameraPose::looking_at([0.0, 0.0, 50.0], [0.0, 0.0, 0.0]).unwrap();
        let planes = frustum_planes(&CameraView { model, pose }.clip_from_world());
        assert!(box_visible(&planes, [-10.0, -10.0, 0.0], [10.0, 10.0, 20.0]));
        // 90° wide: the ground is seen to 50 m east and west, 37.5 m north and south.
        assert!(box_visible(&planes, [45.0, -5.0, 0.0], [55.0, 5.0, 1.0]));
        assert!(!box_visible(&planes, [60.0, -5.0, 0.0], [70.0, 5.0, 1.0]), "east of the image");
        assert!(!box_visible(&planes, [-5.0, 45.0, 0.0], [5.0, 55.0, 1.0]), "north of the image");
        assert!(!box_visible(&planes, [-5.0, -5.0, 60.0], [5.0, 5.0, 70.0]), "behind the camera");
        // A box spanning the whole world is always drawn.
        assert!(box_visible(&planes, [-1500.0, -1500.0, -5.0], [1500.0, 1500.0, 0.0]));
    }

    #[test]
    fn visible_neighbours_merge_into_one_draw() {
        let t = |first, min_e: f64| Tile {
            first_vertex: first,
            vertex_count: 3,
            min_enu_m: [min_e, 0.0, 0.0],
            max_enu_m: [min_e + 1.0, 1.0, 1.0],
        };
        let model = CameraModel::new(64, 64, 90.0).unwrap();
        let pose = CameraPose::looking_at([0.0, 0.0, 50.0], [0.0, 0.0, 0.0]).unwrap();
        let planes = frustum_planes(&CameraView { model, pose }.clip_from_world());
        let tiles = [t(0, 0.0), t(3, 10.0), t(6, 500.0), t(9, 20.0)];
        let mut ranges = Vec::new();
        visible_ranges(&tiles, &planes, &mut ranges);
        assert_eq!(ranges, [0..6, 9..12]);
    }
}
