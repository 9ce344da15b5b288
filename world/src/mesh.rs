//! The world as triangle meshes, for every consumer that draws it: the bundle's glTF
//! (`world.glb`), the recording's `/world` scene (Foxglove `SceneUpdate`), renderers.
//!
//! Frame and units: world ENU metres (x east, y north, z up from the origin's ground), as
//! the rest of the library. Triangles wind counter-clockwise seen from outside the solid
//! (right-hand rule: the normal points out), so any viewer that culls back faces shows the
//! outside. A consumer in another frame applies a rotation (glTF's `x = e, y = u, z = -n`
//! is one), which keeps windings.

use crate::footprint::Point2;
use crate::map::World;

/// Ground samples per side of [`ground_mesh`]'s default grid: 64 cells, so a 4 km world is
/// drawn with 62.5 m cells (enough for the relief of a DEM resampled at >= 2 m to read as
/// terrain in a viewer, at 8 192 triangles).
pub const GROUND_SAMPLES: usize = 65;

/// Vertices and triangles of one mesh, world ENU metres.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriangleMesh {
    /// Vertex positions `[east, north, up]`, metres.
    pub positions_enu_m: Vec<[f64; 3]>,
    /// Vertex indices, three per triangle, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
}

impl TriangleMesh {
    /// True when the mesh has no triangle.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// Adds vertex `(e, n, u)`; returns its index.
    fn vertex(&mut self, e: f64, n: f64, u: f64) -> u32 {
        self.positions_enu_m.push([e, n, u]);
        (self.positions_enu_m.len() - 1) as u32
    }

    /// A convex polygon at height `u`, fan-triangulated, facing up (a roof) or down (a
    /// base). `ring` is counter-clockwise seen from above.
    fn cap(&mut self, ring: &[Point2], u: f64, up: bool) {
        let first = self.positions_enu_m.len() as u32;
        for p in ring {
            self.vertex(p[0], p[1], u);
        }
        for k in 1..ring.len().saturating_sub(1) as u32 {
            // Counter-clockwise from above is counter-clockwise seen from +z: a roof's
            // outside. A base's outside is below: the reverse order.
            let t = if up { [first, first + k, first + k + 1] } else { [first, first + k + 1, first + k] };
            self.triangles.push(t);
        }
    }

    /// One wall quad from `a` to `b` between heights `lo` and `hi`, facing right of a->b:
    /// outwards along a counter-clockwise outer ring, into the courtyard along a clockwise
    /// hole, the outside of the solid either way.
    fn wall(&mut self, a: Point2, b: Point2, lo: f64, hi: f64) {
        let i = [
            self.vertex(a[0], a[1], lo),
            self.vertex(b[0], b[1], lo),
            self.vertex(b[0], b[1], hi),
            self.vertex(a[0], a[1], hi),
        ];
        self.triangles.extend([[i[0], i[1], i[2]], [i[0], i[2], i[3]]]);
    }

    /// Smallest and largest coordinate per axis (`[e, n, u]`), `None` without vertices.
    pub fn bounds(&self) -> Option<([f64; 3], [f64; 3])> {
        let first = *self.positions_enu_m.first()?;
        Some(self.positions_enu_m.iter().fold((first, first), |(lo, hi), p| {
            (std::array::from_fn(|k| lo[k].min(p[k])), std::array::from_fn(|k| hi[k].max(p[k])))
        }))
    }
}

/// Every building as a closed solid: roof and base (the footprint's convex pieces,
/// fan-triangulated) and one quad per footprint edge, courtyard walls included. Vertices
/// are not shared between faces, so each face can be shaded flat.
pub fn buildings_mesh(world: &World) -> TriangleMesh {
    let mut mesh = TriangleMesh::default();
    for b in world.buildings() {
        let (lo, hi) = (b.base_up_m(), b.roof_up_m());
        let f = b.footprint();
        for piece in f.convex_pieces() {
            mesh.cap(&piece, hi, true);
            mesh.cap(&piece, lo, false);
        }
        for (a, c) in f.edges() {
            mesh.wall(a, c, lo, hi);
        }
    }
    mesh
}

/// The ground over the world square as a regular grid of `samples` x `samples` heights
/// (`samples >= 2`), two triangles per cell, facing up.
pub fn ground_mesh(world: &World, samples: usize) -> TriangleMesh {
    let n = samples.max(2);
    let half = world.extent_m();
    let step = 2.0 * half / (n - 1) as f64;
    let mut mesh = TriangleMesh::default();
    for j in 0..n {
        for i in 0..n {
            let (e, north) = (-half + i as f64 * step, -half + j as f64 * step);
            mesh.vertex(e, north, world.ground_up_m(e, north));
        }
    }
    let at = |i: usize, j: usize| (j * n + i) as u32;
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            // (i, j) -> (i+1, j) -> (i+1, j+1) turns left seen from above: counter-clockwise.
            mesh.triangles.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            mesh.triangles.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    mesh
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;

    use super::*;
    use crate::footprint::Footprint;
    use crate::{Building, WorldInputs};

    fn normal(mesh: &TriangleMesh, t: [u32; 3]) -> Vector3<f64> {
        let p = |i: u32| Vector3::from(mesh.positions_enu_m[i as usize]);
        (p(t[1]) - p(t[0])).cross(&(p(t[2]) - p(t[0])))
    }

    /// Signed volume by the divergence theorem: positive when every face points out.
    fn volume_m3(mesh: &TriangleMesh) -> f64 {
        mesh.triangles
            .iter()
            .map(|t| {
                let p = |i: u32| Vector3::from(mesh.positions_enu_m[i as usize]);
                p(t[0]).dot(&p(t[1]).cross(&p(t[2]))) / 6.0
            })
            .sum()
    }

    fn courtyard_world() -> World {
        // A 40 m square block with a 10 m square courtyard, 12 m tall on flat ground.
        let outer = vec![[0.0, 0.0], [40.0, 0.0], [40.0, 40.0], [0.0, 40.0]];
        let hole = vec![[15.0, 15.0], [15.0, 25.0], [25.0, 25.0], [25.0, 15.0]];
        let building = Building::new(Footprint::new(outer, vec![hole]).expect("valid"), 0.0, 12.0).expect("tall");
        World::of_buildings(200.0, vec![building])
    }

    #[test]
    fn a_building_with_a_courtyard_is_a_closed_solid_facing_out() {
        let mesh = buildings_mesh(&courtyard_world());
        // Outward faces enclose the prism's volume exactly: (1600 - 100) m^2 x 12 m.
        assert!((volume_m3(&mesh) - 1500.0 * 12.0).abs() < 1e-6, "{}", volume_m3(&mesh));
        // A courtyard wall faces into the courtyard: the wall on x = 15 faces +x.
        let courtyard_wall = mesh
            .triangles
            .iter()
            .find(|t| t.iter().all(|&i| (mesh.positions_enu_m[i as usize][0] - 15.0).abs() < 1e-9))
            .expect("a wall on x = 15");
        assert!(normal(&mesh, *courtyard_wall).x > 0.0);
        let ([_, _, lo], [_, _, hi]) = mesh.bounds().expect("vertices");
        assert_eq!((lo, hi), (0.0, 12.0));
    }

    #[test]
    fn the_ground_faces_up_and_follows_the_terrain() {
        let world =
            World::generate(&WorldInputs::from_spec(&sadesim_crds::fixtures::RunBuilder::test().build().spec, &[]));
        let mesh = ground_mesh(&world, 9);
        assert_eq!(mesh.positions_enu_m.len(), 81);
        assert_eq!(mesh.triangles.len(), 2 * 8 * 8);
        assert!(mesh.triangles.iter().all(|&t| normal(&mesh, t).z > 0.0));
        for p in &mesh.positions_enu_m {
            assert_eq!(p[2], world.ground_up_m(p[0], p[1]));
        }
        let ([e0, n0, _], [e1, n1, _]) = mesh.bounds().expect("vertices");
        assert_eq!((e0, n0, e1, n1), (-world.extent_m(), -world.extent_m(), world.extent_m(), world.extent_m()));
    }
}
