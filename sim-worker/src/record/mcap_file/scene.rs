//! The static scene as `foxglove.SceneUpdate`s, in frame `world` (ENU metres):
//! - `/world`: the city, one entity `buildings` (every building as a closed solid) and
//!   one `ground` (the terrain over the world square), as triangle lists from
//!   `sadesim_world::mesh`, so Foxglove's 3D panel shows the drones among the buildings;
//! - `/zones`: one entity per zone, a prism drawn as outlines (floor and ceiling loops,
//!   vertical edges), translucent walls and a label. AGL floors and ceilings follow the
//!   ground under each corner (as the compliance monitor judges them).
//!
//! The city's coordinates are written to 1 cm: it is drawn, not measured, and the JSON
//! text is about half as long.

use sadesim_crds::geo::LocalFrame;
use sadesim_crds::plan::RunPlan;
use sadesim_crds::zones::{AltitudeReference, ZoneAltitude};
use sadesim_world::World;
use sadesim_world::mesh::{self, TriangleMesh};
use serde_json::{Value, json};

use super::json;
use sadesim_engine::airspace::volume::ZoneVolume;

fn point(e: f64, n: f64, u: f64) -> Value {
    json!({"x": e, "y": n, "z": u})
}

fn identity_pose() -> Value {
    json!({"position": point(0.0, 0.0, 0.0), "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}})
}

fn altitude_text(a: ZoneAltitude) -> String {
    let reference = match a.reference {
        AltitudeReference::Agl => "AGL",
        AltitudeReference::Msl => "MSL",
    };
    format!("{} m {reference}", a.height_m)
}

/// Decimals of the city's coordinates, metres: 1 cm.
const CITY_DECIMALS: usize = 2;

/// The `/world` message at time 0: the buildings and the ground of `world`. Written with
/// the streams' JSON writer (no `serde_json::Value` tree): the default procedural city has
/// some 300 000 vertices, which a value tree takes a second to build and write.
pub fn world_update(world: &World) -> Vec<u8> {
    let buildings = mesh::buildings_mesh(world);
    let ground = mesh::ground_mesh(world, mesh::GROUND_SAMPLES);
    let mut out = Vec::with_capacity(40 * (buildings.positions_enu_m.len() + ground.positions_enu_m.len()));
    out.extend_from_slice(br#"{"deletions":[],"entities":["#);
    if !buildings.is_empty() {
        let count = world.buildings().len().to_string();
        entity(&mut out, "buildings", &buildings, [0.62, 0.64, 0.68], &[("buildings", &count)]);
        out.push(b',');
    }
    entity(&mut out, "ground", &ground, [0.45, 0.52, 0.40], &[]);
    out.extend_from_slice(b"]}");
    out
}

/// Appends one `foxglove.SceneEntity` at time 0 in frame `world` holding `mesh` as one
/// opaque triangle list of colour `rgb`.
fn entity(out: &mut Vec<u8>, id: &str, mesh: &TriangleMesh, rgb: [f64; 3], metadata: &[(&str, &str)]) {
    let head = json!({
        "timestamp": {"sec": 0, "nsec": 0}, "frame_id": "world", "id": id,
        "lifetime": {"sec": 0, "nsec": 0}, "frame_locked": false,
        "metadata": metadata.iter().map(|(k, v)| json!({"key": k, "value": v})).collect::<Vec<_>>(),
        "arrows": [], "cubes": [], "spheres": [], "cylinders": [], "lines": [], "texts": [], "models": [],
    })
    .to_string();
    // The object without its closing brace, then the triangles member.
    out.extend_from_slice(&head.as_bytes()[..head.len() - 1]);
    out.extend_from_slice(b",\"triangles\":[{\"pose\":");
    out.extend_from_slice(identity_pose().to_string().as_bytes());
    out.extend_from_slice(b",\"points\":[");
    for (i, &p) in mesh.positions_enu_m.iter().enumerate() {
        if i > 0 {
            out.push(b',');
        }
        json::vector3(out, p, CITY_DECIMALS);
    }
    out.extend_from_slice(b"],\"color\":");
    out.extend_from_slice(json!({"r": rgb[0], "g": rgb[1], "b": rgb[2], "a": 1.0}).to_string().as_bytes());
    out.extend_from_slice(b",\"colors\":[],\"indices\":[");
    for (i, &v) in mesh.triangles.iter().flatten().enumerate() {
        if i > 0 {
            out.push(b',');
        }
        json::uint(out, u64::from(v));
    }
    out.extend_from_slice(b"]}]}");
}

/// The `/zones` message at time 0: every zone of `plan`, AGL limits over `world`'s ground.
pub fn zones_update(plan: &RunPlan, world: &World) -> String {
    let frame = LocalFrame::new(plan.spec.origin.geo());
    let time = json!({"sec": 0, "nsec": 0});
    let entities: Vec<Value> = plan
        .spec
        .zones
        .iter()
        .map(|zone| {
            let v = ZoneVolume::new(zone, &frame);
            // Floor and ceiling at each corner, over the ground there.
            let limits: Vec<(f64, f64, f64, f64)> = v
                .polygon
                .iter()
                .map(|&(e, no)| {
                    let (floor, ceiling) = v.vertical_limits_up_m(world.ground_up_m(e, no));
                    (e, no, floor, ceiling)
                })
                .collect();
            let n = limits.len();
            let bottom: Vec<Value> = limits.iter().map(|&(e, no, floor, _)| point(e, no, floor)).collect();
            let top: Vec<Value> = limits.iter().map(|&(e, no, _, ceiling)| point(e, no, ceiling)).collect();
            let verticals: Vec<Value> =
                limits.iter().flat_map(|&(e, no, floor, ceiling)| [point(e, no, floor), point(e, no, ceiling)]).collect();
            // Two triangles per wall: (a_floor, b_floor, b_ceiling), (a_floor, b_ceiling, a_ceiling).
            let walls: Vec<Value> = (0..n)
                .flat_map(|i| {
                    let (a, b) = (limits[i], limits[(i + 1) % n]);
                    [
                        point(a.0, a.1, a.2),
                        point(b.0, b.1, b.2),
                        point(b.0, b.1, b.3),
                        point(a.0, a.1, a.2),
                        point(b.0, b.1, b.3),
                        point(a.0, a.1, a.3),
                    ]
                })
                .collect();
            let label_up_m = limits.iter().map(|l| l.3).fold(f64::NEG_INFINITY, f64::max);
            let (sum_e, sum_n) = v.polygon.iter().fold((0.0, 0.0), |(se, sn), &(e, no)| (se + e, sn + no));
            let centre = (sum_e / n.max(1) as f64, sum_n / n.max(1) as f64);
            let edge = json!({"r": 0.9, "g": 0.2, "b": 0.1, "a": 1.0});
            let fill = json!({"r": 0.9, "g": 0.2, "b": 0.1, "a": 0.15});
            let line = |kind: u8, points: Vec<Value>| {
                json!({"type": kind, "pose": identity_pose(), "thickness": 2.0, "scale_invariant": true,
                       "points": points, "color": edge, "colors": [], "indices": []})
            };
            let until = if v.active_until_s.is_finite() { format!("{} s", v.active_until_s) } else { "end".into() };
            json!({
                "timestamp": time,
                "frame_id": "world",
                "id": format!("zone/{}", zone.name),
                "lifetime": {"sec": 0, "nsec": 0},
                "frame_locked": false,
                "metadata": [
                    {"key": "zone", "value": zone.name},
                    {"key": "floor", "value": altitude_text(zone.floor())},
                    {"key": "ceiling", "value": altitude_text(zone.ceiling)},
                    {"key": "active", "value": format!("{} s to {until}", v.active_from_s)},
                    {"key": "authorizedOperators", "value": zone.policy.authorized_operators.join(",")},
                ],
                "arrows": [], "cubes": [], "spheres": [], "cylinders": [], "models": [],
                "lines": [line(1, bottom), line(1, top), line(2, verticals)],
                "triangles": [{"pose": identity_pose(), "points": walls, "color": fill, "colors": [], "indices": []}],
                "texts": [{
                    "pose": {"position": point(centre.0, centre.1, label_up_m), "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}},
                    "billboard": true, "font_size": 14.0, "scale_invariant": true, "color": edge,
                    "text": zone.name,
                }],
            })
        })
        .collect();
    json!({"deletions": [], "entities": entities}).to_string()
}

/// The `/markers` message at time 0 (`None` without markers): one entity per ground marker
/// of `spec.world.markers` (`marker/<name>`), a thin dark square lying on the ground at
/// its centre (`world.ground_up_m` there, where the cameras see it), turned by its yaw,
/// with its ArUco id as metadata: a marker's pose is a known 3-D point to check a camera
/// against.
pub fn markers_update(plan: &RunPlan, world: &World) -> Option<String> {
    let markers = &plan.spec.world().markers;
    if markers.is_empty() {
        return None;
    }
    let frame = LocalFrame::new(plan.spec.origin.geo());
    let entities: Vec<Value> = markers
        .iter()
        .map(|m| {
            let (e, n) = frame.to_plane(m.position.latitude_deg, m.position.longitude_deg);
            let half_yaw = m.yaw_deg.to_radians() / 2.0;
            json!({
                "timestamp": {"sec": 0, "nsec": 0},
                "frame_id": "world",
                "id": format!("marker/{}", m.name),
                "lifetime": {"sec": 0, "nsec": 0},
                "frame_locked": false,
                "metadata": [
                    {"key": "marker", "value": m.name},
                    {"key": "arucoId", "value": m.aruco_id.to_string()},
                    {"key": "dictionary", "value": "DICT_4X4_50"},
                ],
                "arrows": [], "spheres": [], "cylinders": [], "lines": [], "triangles": [], "texts": [], "models": [],
                "cubes": [{
                    "pose": {
                        "position": point(e, n, world.ground_up_m(e, n)),
                        "orientation": {"x": 0.0, "y": 0.0, "z": half_yaw.sin(), "w": half_yaw.cos()},
                    },
                    "size": point(m.size_m, m.size_m, 0.01),
                    "color": {"r": 0.1, "g": 0.1, "b": 0.1, "a": 1.0},
                }],
            })
        })
        .collect();
    Some(json!({"deletions": [], "entities": entities}).to_string())
}
