//! The zones as a `foxglove.SceneUpdate`: one entity per zone in `world`, a prism drawn as
//! outlines (floor and ceiling loops, vertical edges), translucent walls and a label.
//!
//! # Caveats
//! AGL floors and ceilings are drawn over level ground at the origin's height (ENU up 0):
//! the recorder has no terrain. The compliance monitor itself uses the real terrain.

use sadesim_crds::geo::LocalFrame;
use sadesim_crds::plan::RunPlan;
use sadesim_crds::zones::{AltitudeReference, ZoneAltitude};
use serde_json::{Value, json};

use crate::airspace::volume::ZoneVolume;

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

/// The `/zones` message at time 0: every zone of `plan`.
pub fn zones_update(plan: &RunPlan) -> String {
    let frame = LocalFrame::new(plan.spec.origin.geo());
    let time = json!({"sec": 0, "nsec": 0});
    let entities: Vec<Value> = plan
        .spec
        .zones
        .iter()
        .map(|zone| {
            let v = ZoneVolume::new(zone, &frame);
            let (floor, ceiling) = v.vertical_limits_up_m(0.0);
            let n = v.polygon.len();
            let bottom: Vec<Value> = v.polygon.iter().map(|&(e, no)| point(e, no, floor)).collect();
            let top: Vec<Value> = v.polygon.iter().map(|&(e, no)| point(e, no, ceiling)).collect();
            let verticals: Vec<Value> =
                v.polygon.iter().flat_map(|&(e, no)| [point(e, no, floor), point(e, no, ceiling)]).collect();
            // Two triangles per wall: (a_floor, b_floor, b_ceiling), (a_floor, b_ceiling, a_ceiling).
            let walls: Vec<Value> = (0..n)
                .flat_map(|i| {
                    let (a, b) = (v.polygon[i], v.polygon[(i + 1) % n]);
                    [
                        point(a.0, a.1, floor),
                        point(b.0, b.1, floor),
                        point(b.0, b.1, ceiling),
                        point(a.0, a.1, floor),
                        point(b.0, b.1, ceiling),
                        point(a.0, a.1, ceiling),
                    ]
                })
                .collect();
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
                    "pose": {"position": point(centre.0, centre.1, ceiling), "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}},
                    "billboard": true, "font_size": 14.0, "scale_invariant": true, "color": edge,
                    "text": zone.name,
                }],
            })
        })
        .collect();
    json!({"deletions": [], "entities": entities}).to_string()
}
