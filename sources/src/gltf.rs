//! The world as glTF 2.0 binary (`.glb`) for renderers and 3D tools: one mesh of the
//! buildings (walls and roofs) and one of the ground over the world square, both from
//! `sadesim_world::mesh`.
//!
//! Frame: glTF is right-handed, Y up, metres; world ENU maps as `x = east`, `y = up`,
//! `z = -north` (a rotation, so windings are kept). The node
//! carries `extras.origin` (the run origin, WGS84 and MSL altitude) so tools can georeference
//! it. Triangles wind counter-clockwise seen from outside. No materials: viewers draw the
//! default grey.

use sadesim_crds::geo::GeoPoint;
use sadesim_world::World;
use sadesim_world::mesh::{self, TriangleMesh};
use serde_json::json;

/// A mesh in glTF's frame: `f32` positions `(x, y, z) = (e, u, -n)` (a rotation of ENU, so
/// the mesh's outward windings stay outward) and flat indices.
struct GltfMesh {
    positions: Vec<[f32; 3]>,
    indices: Vec<u32>,
}

impl GltfMesh {
    fn of(mesh: &TriangleMesh) -> Self {
        let positions = mesh.positions_enu_m.iter().map(|&[e, n, u]| [e as f32, u as f32, -n as f32]).collect();
        Self { positions, indices: mesh.triangles.iter().flatten().copied().collect() }
    }

    /// Per-axis minimum and maximum (glTF requires them on position accessors).
    fn bounds(&self) -> ([f32; 3], [f32; 3]) {
        self.positions.iter().fold(([f32::MAX; 3], [f32::MIN; 3]), |(lo, hi), p| {
            (std::array::from_fn(|k| lo[k].min(p[k])), std::array::from_fn(|k| hi[k].max(p[k])))
        })
    }
}

/// The world as a `.glb` file: buildings and ground, origin in `extras`.
pub fn world_glb(world: &World, origin: GeoPoint) -> Vec<u8> {
    let meshes = [
        ("buildings", GltfMesh::of(&mesh::buildings_mesh(world))),
        ("ground", GltfMesh::of(&mesh::ground_mesh(world, mesh::GROUND_SAMPLES))),
    ];
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
