//! What the cameras see: the world's triangles (ground and buildings from
//! `sadesim_world::mesh`) and flat ground markers, each triangle with its final colour.
//!
//! Shading is computed here, once, on the CPU in f64: each triangle gets one colour from its
//! albedo and a Lambert term with a fixed sun (flat face normals), so the GPU only copies
//! colours and the image depends on nothing but the geometry and the camera. There is no
//! texture: a marker is one flat square per cell, which draws exactly what a texture with
//! nearest-neighbour sampling would, with no sampler and no texture upload.

use sadesim_world::World;
use sadesim_world::mesh::{self, GROUND_SAMPLES, TriangleMesh};

use crate::error::{RenderError, Result};

/// Colour where a pixel sees nothing (above the horizon or beyond [`crate::FAR_M`]), RGB.
pub const SKY_RGB: [u8; 3] = [150, 190, 235];

/// The direction towards the sun, ENU, unit: from the south-east, about 54 degrees high. Fixed
/// so that frames depend on nothing but geometry and camera.
pub const SUN_DIRECTION_ENU: [f64; 3] = [0.303_045_763_365_663, -0.505_076_272_276_105, 0.808_122_035_641_768];

/// Light on a face that does not see the sun (sky light), as a fraction of full light.
const AMBIENT: f64 = 0.35;

/// Height of a marker above the point it is given at, metres: enough for the depth buffer to
/// put it over the ground it lies on, well below anything a camera's depth resolves.
pub const MARKER_LIFT_M: f64 = 0.005;

const GROUND_ALBEDO: [f64; 3] = [0.45, 0.50, 0.36];
const WALL_ALBEDO: [f64; 3] = [0.80, 0.76, 0.70];
const ROOF_ALBEDO: [f64; 3] = [0.55, 0.50, 0.50];
const MARKER_WHITE_ALBEDO: [f64; 3] = [1.0, 1.0, 1.0];
const MARKER_BLACK_ALBEDO: [f64; 3] = [0.04, 0.04, 0.04];

/// A flat square pattern lying on the ground: an ArUco fiducial ([`crate::aruco_4x4_50`]),
/// a landing pad, a checkerboard.
///
/// Layout: `cells` is `n * n` row-major, row 0 first. At `yaw_deg = 0`, seen from above
/// with north up, the pattern reads as printed: row 0 along the north edge, column 0 along
/// the west edge. `yaw_deg` turns it counter-clockwise seen from above (ENU, about +z).
#[derive(Clone, Debug, PartialEq)]
pub struct Marker {
    /// Centre of the square, ENU metres; z is the ground height under it (e.g.
    /// `World::ground_up_m`), the square is drawn [`MARKER_LIFT_M`] above. Flat ground is
    /// assumed under the square.
    pub center_enu_m: [f64; 3],
    /// Side of the whole square (border included), metres.
    pub size_m: f64,
    /// Rotation about up, degrees, counter-clockwise seen from above.
    pub yaw_deg: f64,
    /// `n * n` cells, row-major, `true` = white; the whole pattern, border included.
    pub cells: Vec<bool>,
}

impl Marker {
    /// Cells per side, `n`, when `cells` is a non-empty square.
    fn side(&self) -> Option<usize> {
        let n = self.cells.len().isqrt();
        (n > 0 && n * n == self.cells.len()).then_some(n)
    }

    /// The centre of cell (`row`, `col`) in the world, ENU metres, at the height the square
    /// is drawn: where a camera sees that cell ([`crate::CameraView::project`] it).
    pub fn cell_center_enu_m(&self, row: usize, col: usize) -> [f64; 3] {
        let n = self.side().unwrap_or(1) as f64;
        self.local_to_enu(col as f64 + 0.5, row as f64 + 0.5, n)
    }

    /// A point given in cell units (`x` columns from the west edge, `y` rows from the north
    /// edge, at yaw 0) in ENU metres.
    fn local_to_enu(&self, x_cells: f64, y_cells: f64, n: f64) -> [f64; 3] {
        let cell = self.size_m / n;
        let (east, north) = (-self.size_m / 2.0 + x_cells * cell, self.size_m / 2.0 - y_cells * cell);
        let (s, c) = self.yaw_deg.to_radians().sin_cos();
        let [e0, n0, u0] = self.center_enu_m;
        [e0 + c * east - s * north, n0 + s * east + c * north, u0 + MARKER_LIFT_M]
    }

    fn check(&self, index: usize) -> Result<usize> {
        let bad = |field: &str, expected: String| RenderError::InvalidMarker {
            field: format!("markers[{index}].{field}"),
            expected,
        };
        if !self.center_enu_m.iter().all(|v| v.is_finite()) {
            return Err(bad("center_enu_m", "finite ENU metres".to_owned()));
        }
        if !(self.size_m.is_finite() && self.size_m > 0.0) {
            return Err(bad("size_m", format!("a positive side in metres, got {}", self.size_m)));
        }
        if !self.yaw_deg.is_finite() {
            return Err(bad("yaw_deg", "finite degrees".to_owned()));
        }
        self.side().ok_or_else(|| bad("cells", format!("n * n cells (a non-empty square), got {}", self.cells.len())))
    }
}

/// One vertex as the GPU reads it: position ENU metres (f32) and the flat colour RGBA8.
pub(crate) const VERTEX_BYTES: u64 = 16;

/// The triangles of everything the cameras draw, with their colours, ready for the GPU.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Scene {
    /// Three vertices per triangle, not shared: `(position ENU m as f32, RGBA8)`.
    vertices: Vec<([f32; 3], [u8; 4])>,
}

impl Scene {
    /// The world's ground (a [`GROUND_SAMPLES`] grid, as the recording and the glTF draw
    /// it) and buildings, no markers.
    ///
    /// Flat ground (every grid height equal) is drawn as its one square, two triangles, the
    /// same plane with the same colour: the same pixels as the grid's 8 192 triangles, which
    /// would be 87 % of a 100-building city's triangles and cost lavapipe 1 ms a view
    /// (`docs/performance.md`).
    pub fn from_world(world: &World) -> Self {
        let mut scene = Self::default();
        let grid = mesh::ground_mesh(world, GROUND_SAMPLES);
        let flat = grid.positions_enu_m.windows(2).all(|w| w[0][2] == w[1][2]);
        let ground = if flat { mesh::ground_mesh(world, 2) } else { grid };
        scene.add_mesh(&ground, |_| GROUND_ALBEDO);
        scene.add_mesh(&mesh::buildings_mesh(world), |normal| if normal[2] > 0.5 { ROOF_ALBEDO } else { WALL_ALBEDO });
        scene
    }

    /// As [`Scene::from_world`], with `markers` on the ground.
    ///
    /// # Errors
    ///
    /// [`RenderError::InvalidMarker`] naming the marker and field (`markers[1].cells`) when
    /// a marker is not finite, has no positive size or its cells are not a square.
    pub fn with_markers(world: &World, markers: &[Marker]) -> Result<Self> {
        let mut scene = Self::from_world(world);
        for (i, marker) in markers.iter().enumerate() {
            scene.add_marker(i, marker)?;
        }
        Ok(scene)
    }

    /// Triangles in the scene.
    pub fn triangle_count(&self) -> usize {
        self.vertices.len() / 3
    }

    /// The vertex buffer's bytes, sorted by tile ([`crate::tiles`]), and the tiles: per
    /// vertex `x, y, z` f32 little-endian then `r, g, b, a`.
    pub(crate) fn tiled_vertex_bytes(&self) -> (Vec<u8>, Vec<crate::tiles::Tile>) {
        let mut vertices = self.vertices.clone();
        let tiles = crate::tiles::tile(&mut vertices);
        let mut out = Vec::with_capacity(vertices.len() * VERTEX_BYTES as usize);
        for (p, rgba) in &vertices {
            for c in p {
                out.extend_from_slice(&c.to_le_bytes());
            }
            out.extend_from_slice(rgba);
        }
        (out, tiles)
    }

    fn add_mesh(&mut self, mesh: &TriangleMesh, albedo: impl Fn([f64; 3]) -> [f64; 3]) {
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|i| mesh.positions_enu_m[i as usize]);
            let normal = unit_normal(a, b, c);
            self.push_triangle([a, b, c], shade(albedo(normal), normal));
        }
    }

    fn add_marker(&mut self, index: usize, marker: &Marker) -> Result<()> {
        let n = marker.check(index)?;
        // Every corner once, so neighbouring cells share bit-identical edges and the
        // rasteriser leaves neither gap nor overlap between them.
        let corners: Vec<[f64; 3]> = (0..=n)
            .flat_map(|row| (0..=n).map(move |col| (row, col)))
            .map(|(row, col)| marker.local_to_enu(col as f64, row as f64, n as f64))
            .collect();
        let at = |row: usize, col: usize| corners[row * (n + 1) + col];
        let up = [0.0, 0.0, 1.0];
        let (white, black) = (shade(MARKER_WHITE_ALBEDO, up), shade(MARKER_BLACK_ALBEDO, up));
        for row in 0..n {
            for col in 0..n {
                let rgba = if marker.cells[row * n + col] { white } else { black };
                // Rows run south, columns east: bottom-left -> bottom-right -> top-right turns
                // counter-clockwise seen from above, the face up.
                let (tl, tr, br, bl) = (at(row, col), at(row, col + 1), at(row + 1, col + 1), at(row + 1, col));
                self.push_triangle([bl, br, tr], rgba);
                self.push_triangle([bl, tr, tl], rgba);
            }
        }
        Ok(())
    }

    fn push_triangle(&mut self, corners: [[f64; 3]; 3], rgba: [u8; 4]) {
        for p in corners {
            self.vertices.push((p.map(|v| v as f32), rgba));
        }
    }
}

/// The outward unit normal of a counter-clockwise triangle (zero for a degenerate one).
fn unit_normal(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [f64; 3] {
    let (u, v) = ([b[0] - a[0], b[1] - a[1], b[2] - a[2]], [c[0] - a[0], c[1] - a[1], c[2] - a[2]]);
    let n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    if len > 0.0 { n.map(|x| x / len) } else { [0.0; 3] }
}

/// Lambert: `albedo * (ambient + (1 - ambient) * max(0, n . sun))`, as RGBA8.
fn shade(albedo: [f64; 3], normal: [f64; 3]) -> [u8; 4] {
    let sun = (0..3).map(|k| normal[k] * SUN_DIRECTION_ENU[k]).sum::<f64>().max(0.0);
    let light = AMBIENT + (1.0 - AMBIENT) * sun;
    let [r, g, b] = albedo.map(|a| (a * light * 255.0).round().clamp(0.0, 255.0) as u8);
    [r, g, b, 255]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sun_direction_is_a_unit_vector() {
        let n = SUN_DIRECTION_ENU.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!((n - 1.0).abs() < 1e-12, "{n}");
    }

    #[test]
    fn marker_row_zero_is_north_and_column_zero_west_at_yaw_zero() {
        let m = Marker { center_enu_m: [10.0, 20.0, 0.0], size_m: 6.0, yaw_deg: 0.0, cells: vec![true; 36] };
        let [e, n, u] = m.cell_center_enu_m(0, 0);
        assert!((e - 7.5).abs() < 1e-12 && (n - 22.5).abs() < 1e-12 && (u - MARKER_LIFT_M).abs() < 1e-12);
        // Turned 90 degrees counter-clockwise: row 0 now runs along the west edge.
        let m = Marker { yaw_deg: 90.0, ..m };
        let [e, n, _] = m.cell_center_enu_m(0, 0);
        assert!((e - 7.5).abs() < 1e-9 && (n - 17.5).abs() < 1e-9, "{e} {n}");
    }

    #[test]
    fn flat_ground_is_one_square_and_terrain_keeps_its_grid() {
        let flat = World::of_buildings(50.0, vec![]);
        assert_eq!(Scene::from_world(&flat).triangle_count(), 2);
        let grid = sadesim_world::GroundGrid::sample(50.0, 11, |e, n| 0.01 * e + 0.02 * n);
        let hills = World::of_buildings_on(50.0, sadesim_world::Terrain::from_grid(grid), vec![]);
        assert_eq!(Scene::from_world(&hills).triangle_count(), 2 * (GROUND_SAMPLES - 1).pow(2));
    }

    #[test]
    fn a_marker_is_two_triangles_per_cell() {
        let world = World::of_buildings(50.0, vec![]);
        let plain = Scene::from_world(&world).triangle_count();
        let m =
            Marker { center_enu_m: [0.0; 3], size_m: 1.0, yaw_deg: 0.0, cells: crate::aruco_4x4_50(3).expect("id") };
        let scene = Scene::with_markers(&world, &[m]).expect("valid");
        assert_eq!(scene.triangle_count() - plain, 72);
    }
}
