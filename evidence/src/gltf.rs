//! The world as glTF 2.0 binary (`.glb`) for renderers and 3D tools: one mesh of the
//! buildings (walls and roofs) and one of the ground over the world square.
//!
//! Frame: glTF is right-handed, Y up, metres; world ENU maps as `x = east`, `y = up`,
//! `z = -north` (a rotation, so windings are kept). The node
//! carries `extras.origin` (the run origin, WGS84 and MSL altitude) so tools can georeference
//! it. Triangles wind counter-clockwise seen from outside. No materials: viewers draw the
//! default grey.

use sadesim_crds::geo::GeoPoint;
use sadesim_world::World;
use serde_json::json;

/// Ground mesh samples per side.
const GROUND_SAMPLES: usize = 65;

/// Vertex positions and triangle indices of one mesh.
#[derive(Default)]
struct Mesh {
    positions: Vec<[f32; 3]>,
    indices: Vec<u32>,
}

impl Mesh {
    /// Adds ENU point `(e, n, u)`; returns its index.
    fn vertex(&mut self, e: f64, n: f64, u: f64) -> u32 {
        self.positions.push([e as f32, u as f32, -n as f32]);
        (self.positions.len() - 1) as u32
    }

    /// A convex polygon at height `u` facing up (or down), fan-triangulated. `ring` is
    /// counter-clockwise seen from above.
    fn cap(&mut self, ring: &[[f64; 2]], u: f64, up: bool) {
        let first = self.positions.len() as u32;
        for p in ring {
            self.vertex(p[0], p[1], u);
        }
        for k in 1..ring.len().saturating_sub(1) as u32 {
            // (e, n, u) -> (x, y, z) = (e, u, -n) is a rotation: counter-clockwise from
            // above in ENU stays counter-clockwise from +y.
            if up {
                self.indices.extend([first, first + k, first + k + 1]);
            } else {
                self.indices.extend([first, first + k + 1, first + k]);
            }
        }
    }

    /// One wall quad from `a` to `b` between heights `lo` and `hi`, facing right of a->b
    /// (outwards for a counter-clockwise outer ring, inwards into a courtyard for a
    /// clockwise hole).
    fn wall(&mut self, a: [f64; 2], b: [f64; 2], lo: f64, hi: f64) {
        let i = [
            self.vertex(a[0], a[1], lo),
            self.vertex(b[0], b[1], lo),
            self.vertex(b[0], b[1], hi),
            self.vertex(a[0], a[1], hi),
        ];
        self.indices.extend([i[0], i[1], i[2], i[0], i[2], i[3]]);
    }

    fn bounds(&self) -> ([f32; 3], [f32; 3]) {
        self.positions.iter().fold(([f32::MAX; 3], [f32::MIN; 3]), |(lo, hi), p| {
            (std::array::from_fn(|k| lo[k].min(p[k])), std::array::from_fn(|k| hi[k].max(p[k])))
        })
    }
}

fn buildings_mesh(world: &World) -> Mesh {
    let mut mesh = Mesh::default();
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

fn ground_mesh(world: &World) -> Mesh {
    let mut mesh = Mesh::default();
    let half = world.extent_m();
    let n = GROUND_SAMPLES;
    let step = 2.0 * half / (n - 1) as f64;
    for j in 0..n {
        for i in 0..n {
            let (e, north) = (-half + i as f64 * step, -half + j as f64 * step);
            mesh.vertex(e, north, world.ground_up_m(e, north));
        }
    }
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let at = |i: usize, j: usize| (j * n + i) as u32;
            // Counter-clockwise from above, as in `cap`.
            mesh.indices.extend([at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    mesh
}

/// The world as a `.glb` file: buildings and ground, origin in `extras`.
pub fn world_glb(world: &World, origin: GeoPoint) -> Vec<u8> {
    let meshes = [("buildings", buildings_mesh(world)), ("ground", ground_mesh(world))];
    let mut bin: Vec<u8> = Vec::new();
    let (mut views, mut accessors, mut gltf_meshes, mut nodes) = (vec![], vec![], vec![], vec![]);
    for (name, mesh) in meshes.iter().filter(|(_, m)| !m.indices.is_empty()) {
        let (min, max) = mesh.bounds();
        let pos_offset = bin.len();
        for p in &mesh.positions {
            for v in p {
                bin.extend_from_slice(&v.to_le_bytes());
            }
        }
        let idx_offset = bin.len();
        for i in &mesh.indices {
            bin.extend_from_slice(&i.to_le_bytes());
        }
        let (v, a) = (views.len(), accessors.len());
        views.push(
            json!({"buffer": 0, "byteOffset": pos_offset, "byteLength": idx_offset - pos_offset, "target": 34962}),
        );
        views.push(
            json!({"buffer": 0, "byteOffset": idx_offset, "byteLength": bin.len() - idx_offset, "target": 34963}),
        );
        accessors.push(json!({"bufferView": v, "componentType": 5126, "count": mesh.positions.len(), "type": "VEC3", "min": min, "max": max}));
        accessors
            .push(json!({"bufferView": v + 1, "componentType": 5125, "count": mesh.indices.len(), "type": "SCALAR"}));
        nodes.push(json!({"name": name, "mesh": gltf_meshes.len()}));
        gltf_meshes
            .push(json!({"name": name, "primitives": [{"attributes": {"POSITION": a}, "indices": a + 1, "mode": 4}]}));
    }
    let node_count = nodes.len();
    nodes.push(json!({
        "name": "world",
        "children": (0..node_count).collect::<Vec<_>>(),
        "extras": {"origin": {"latitudeDeg": origin.latitude_deg, "longitudeDeg": origin.longitude_deg, "altitudeMslM": origin.altitude_msl_m},
                   "frame": "x east, y up, z south (ENU metres from the origin)"},
    }));
    let doc = json!({
        "asset": {"version": "2.0", "generator": concat!("sadesim ", env!("CARGO_PKG_VERSION"))},
        "scene": 0,
        "scenes": [{"nodes": [node_count]}],
        "nodes": nodes,
        "meshes": gltf_meshes,
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": bin.len()}],
    });
    let mut json_chunk = serde_json::to_vec(&doc).expect("a glTF document always serializes");
    while !json_chunk.len().is_multiple_of(4) {
        json_chunk.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json_chunk.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json_chunk.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json_chunk);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}
