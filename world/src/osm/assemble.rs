//! From OSM elements to the world's shapes: building prisms and open areas in world ENU
//! metres, clipped to the world's square.

use std::collections::HashMap;

use sadesim_crds::geo::LocalFrame;

use super::pbf::{MemberKind, RawOsm, RawRelation, RawWay, Tags};
use super::{DEFAULT_HEIGHT_M, STOREY_HEIGHT_M};
use super::{ElementId, HeightSource, OsmBuilding, OsmCity, OsmError, OsmOpenArea, OsmStats};
use crate::building::Building;
use crate::footprint::{Footprint, Point2, ring_contains, shoelace_m2};

/// Tag keys the assembly reads (the reader drops every other tag).
pub fn is_read_tag(key: &str) -> bool {
    matches!(
        key,
        "type"
            | "building"
            | "height"
            | "building:height"
            | "min_height"
            | "building:min_height"
            | "roof:height"
            | "building:levels"
            | "building:min_level"
            | "roof:levels"
            | "leisure"
            | "landuse"
            | "name"
    )
}

/// `leisure` values that make an open area (room for homes and takeoffs).
const OPEN_LEISURE: [&str; 6] = ["park", "garden", "common", "playground", "dog_park", "recreation_ground"];
/// `landuse` values that make an open area.
const OPEN_LANDUSE: [&str; 5] = ["grass", "meadow", "recreation_ground", "village_green", "park"];

fn tag<'a>(tags: &'a Tags, key: &str) -> Option<&'a str> {
    tags.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
}

/// What an area element is.
enum Role {
    Building,
    Open(String),
}

fn role_of(tags: &Tags) -> Option<Role> {
    if tag(tags, "building").is_some_and(|v| v != "no") {
        return Some(Role::Building);
    }
    if let Some(v) = tag(tags, "leisure").filter(|v| OPEN_LEISURE.contains(v)) {
        return Some(Role::Open(format!("leisure={v}")));
    }
    tag(tags, "landuse").filter(|v| OPEN_LANDUSE.contains(v)).map(|v| Role::Open(format!("landuse={v}")))
}

/// One polygon before clipping: outer ring and holes as node positions, degrees.
struct Polygon {
    outer: Vec<[f64; 2]>,
    holes: Vec<Vec<[f64; 2]>>,
}

/// Builds the city of `raw` within `extent_m` (half-width of the square) of the origin of
/// `frame`.
pub fn city(raw: &RawOsm, frame: &LocalFrame, extent_m: f64) -> Result<OsmCity, OsmError> {
    let mut stats = OsmStats::default();
    let mut buildings = Vec::new();
    let mut open_areas = Vec::new();
    let ways: HashMap<i64, &RawWay> = raw.ways.iter().map(|w| (w.id, w)).collect();
    let mut areas: Vec<(ElementId, &Tags, Role, Vec<Polygon>)> = Vec::new();

    for way in &raw.ways {
        let Some(role) = role_of(&way.tags) else { continue };
        let closed = way.refs.len() >= 4 && way.refs.first() == way.refs.last();
        if !closed {
            stats.skipped_open_ways += 1;
            continue;
        }
        match positions(&way.refs, raw) {
            Some(outer) => {
                areas.push((ElementId::Way(way.id), &way.tags, role, vec![Polygon { outer, holes: vec![] }]))
            }
            None => stats.skipped_incomplete += 1,
        }
    }
    for relation in &raw.relations {
        if tag(&relation.tags, "type") != Some("multipolygon") {
            continue;
        }
        let Some(role) = role_of(&relation.tags) else { continue };
        match multipolygon(relation, &ways, raw) {
            Some(polygons) => areas.push((ElementId::Relation(relation.id), &relation.tags, role, polygons)),
            None => stats.skipped_incomplete += 1,
        }
    }

    for (id, tags, role, polygons) in areas {
        let mut footprints = Vec::new();
        for polygon in polygons {
            let project = |ring: &[[f64; 2]]| -> Vec<Point2> {
                let plane: Vec<Point2> = ring
                    .iter()
                    .map(|&[lat, lon]| {
                        let (e, n) = frame.to_plane(lat, lon);
                        [e, n]
                    })
                    .collect();
                clip_to_square(&plane, extent_m)
            };
            let outer = project(&polygon.outer);
            if outer.len() < 3 {
                continue;
            }
            let holes: Vec<Vec<Point2>> =
                polygon.holes.iter().map(|h| project(h)).filter(|h| h.len() >= 3 && ring_area(h) > 0.0).collect();
            if ring_area(&outer) <= 0.0 {
                continue;
            }
            match Footprint::new(outer, holes) {
                Ok(f) => footprints.push(f),
                Err(_) => stats.skipped_invalid += 1,
            }
        }
        if footprints.is_empty() {
            continue;
        }
        match role {
            Role::Building => {
                let (base_m, height_m, source) = heights(id, tags)?;
                for footprint in footprints {
                    match Building::new(footprint, base_m, height_m - base_m) {
                        Ok(building) => {
                            stats.count(source);
                            buildings.push(OsmBuilding { id, building, height_source: source });
                        }
                        Err(_) => stats.skipped_invalid += 1,
                    }
                }
            }
            Role::Open(kind) => {
                let name = tag(tags, "name").map(str::to_string);
                for footprint in footprints {
                    open_areas.push(OsmOpenArea { id, kind: kind.clone(), name: name.clone(), footprint });
                }
            }
        }
    }
    stats.buildings = buildings.len();
    stats.open_areas = open_areas.len();
    if buildings.is_empty() {
        return Err(OsmError::NoBuildings { extent_m });
    }
    Ok(OsmCity { source_sha256: String::new(), buildings, open_areas, stats })
}

/// The node positions of `refs`, or `None` when a node is missing from the file (the
/// extract cut the element).
fn positions(refs: &[i64], raw: &RawOsm) -> Option<Vec<[f64; 2]>> {
    refs.iter().map(|r| raw.nodes.get(r).copied()).collect()
}

/// The polygons of a multipolygon relation: its `outer` (or unnamed) and `inner` member ways
/// joined end to end into closed rings, each inner ring given to the outer ring containing
/// it. `None` when a member way or node is missing or a ring does not close.
fn multipolygon(relation: &RawRelation, ways: &HashMap<i64, &RawWay>, raw: &RawOsm) -> Option<Vec<Polygon>> {
    let mut outer_ways = Vec::new();
    let mut inner_ways = Vec::new();
    for m in relation.members.iter().filter(|m| m.kind == MemberKind::Way) {
        let way = ways.get(&m.id)?;
        match m.role.as_str() {
            "inner" => inner_ways.push(way.refs.as_slice()),
            _ => outer_ways.push(way.refs.as_slice()),
        }
    }
    let outers: Vec<Vec<[f64; 2]>> =
        join_rings(&outer_ways)?.iter().map(|r| positions(r, raw)).collect::<Option<_>>()?;
    let inners: Vec<Vec<[f64; 2]>> =
        join_rings(&inner_ways)?.iter().map(|r| positions(r, raw)).collect::<Option<_>>()?;
    if outers.is_empty() {
        return None;
    }
    let mut polygons: Vec<Polygon> = outers.into_iter().map(|outer| Polygon { outer, holes: Vec::new() }).collect();
    for inner in inners {
        // The first outer ring holding the inner ring's first vertex.
        if let Some(p) = polygons.iter_mut().find(|p| ring_contains(&p.outer, inner[0])) {
            p.holes.push(inner);
        }
    }
    Some(polygons)
}

/// Joins way node lists into closed rings by their end nodes (reversing ways as needed).
/// `None` when some ways do not close into rings.
fn join_rings(ways: &[&[i64]]) -> Option<Vec<Vec<i64>>> {
    let mut left: Vec<Vec<i64>> = ways.iter().filter(|w| w.len() >= 2).map(|w| w.to_vec()).collect();
    let mut rings = Vec::new();
    while let Some(mut ring) = left.pop() {
        while ring.first() != ring.last() {
            let end = *ring.last()?;
            let next = left.iter().position(|w| w.first() == Some(&end) || w.last() == Some(&end))?;
            let mut way = left.swap_remove(next);
            if way.first() != Some(&end) {
                way.reverse();
            }
            ring.extend_from_slice(&way[1..]);
        }
        if ring.len() >= 4 {
            rings.push(ring);
        }
    }
    Some(rings)
}

/// Absolute area of a ring, m² (shoelace).
fn ring_area(ring: &[Point2]) -> f64 {
    shoelace_m2(ring).abs()
}

/// Sutherland–Hodgman clipping of a ring to the square `[-h, h]²` (convex clip window: the
/// result covers exactly the ring's area inside the square; a concave ring cut into
/// several pieces comes back as one ring joined along the square's edge, with zero-width
/// seams that add no area). The closing vertex, if any, is dropped.
fn clip_to_square(ring: &[Point2], h: f64) -> Vec<Point2> {
    let mut points: Vec<Point2> = ring.to_vec();
    if points.len() > 1 && points.first() == points.last() {
        points.pop();
    }
    if points.iter().all(|p| p[0].abs() <= h && p[1].abs() <= h) {
        return points;
    }
    // Each edge of the square: inside test and the intersection with a segment.
    let edges: [(usize, f64); 4] = [(0, -h), (0, h), (1, -h), (1, h)];
    for (axis, limit) in edges {
        let inside = |p: &Point2| if limit < 0.0 { p[axis] >= limit } else { p[axis] <= limit };
        let mut out = Vec::with_capacity(points.len() + 4);
        for i in 0..points.len() {
            let (a, b) = (points[i], points[(i + 1) % points.len()]);
            let cross = |a: Point2, b: Point2| {
                let t = (limit - a[axis]) / (b[axis] - a[axis]);
                [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]
            };
            match (inside(&a), inside(&b)) {
                (true, true) => out.push(b),
                (true, false) => out.push(cross(a, b)),
                (false, true) => {
                    out.push(cross(a, b));
                    out.push(b);
                }
                (false, false) => {}
            }
        }
        points = out;
        if points.is_empty() {
            break;
        }
    }
    points.dedup();
    points
}

/// Base and roof heights above the ground, metres, and where the roof height came from.
///
/// Roof: `height`, else `building:height`, else `building:levels` (+ `roof:levels`) x
/// [`STOREY_HEIGHT_M`] + `roof:height`, else [`DEFAULT_HEIGHT_M`]. Base: `min_height`,
/// else `building:min_height`, else `building:min_level` x [`STOREY_HEIGHT_M`], else 0.
fn heights(id: ElementId, tags: &Tags) -> Result<(f64, f64, HeightSource), OsmError> {
    let metres = |key: &str| -> Result<Option<f64>, OsmError> {
        let Some(text) = tag(tags, key) else { return Ok(None) };
        match parse_length_m(text) {
            Some(v) if v < 0.0 => Err(OsmError::Tag {
                element: id,
                key: key.into(),
                value: text.into(),
                expected: "a height >= 0".into(),
            }),
            Some(v) => Ok(Some(v)),
            // Unreadable values ("tall", "5;7") fall through to the next rule.
            None => Ok(None),
        }
    };
    let levels = |key: &str| -> Result<Option<f64>, OsmError> {
        let Some(text) = tag(tags, key) else { return Ok(None) };
        match text.trim().parse::<f64>() {
            Ok(v) if v.is_finite() && v < 0.0 => Err(OsmError::Tag {
                element: id,
                key: key.into(),
                value: text.into(),
                expected: "a number of storeys >= 0".into(),
            }),
            Ok(v) if v.is_finite() => Ok(Some(v)),
            _ => Ok(None),
        }
    };
    let base = match (metres("min_height")?, metres("building:min_height")?, levels("building:min_level")?) {
        (Some(m), _, _) | (None, Some(m), _) => m,
        (None, None, Some(l)) => l * STOREY_HEIGHT_M,
        _ => 0.0,
    };
    let (roof, source) = if let Some(h) = metres("height")? {
        (h, HeightSource::Tagged)
    } else if let Some(h) = metres("building:height")? {
        (h, HeightSource::Tagged)
    } else if let Some(l) = levels("building:levels")? {
        let roof_levels = levels("roof:levels")?.unwrap_or(0.0);
        ((l + roof_levels) * STOREY_HEIGHT_M + metres("roof:height")?.unwrap_or(0.0), HeightSource::Levels)
    } else {
        (DEFAULT_HEIGHT_M.max(base + STOREY_HEIGHT_M), HeightSource::Default)
    };
    Ok((base, roof, source))
}

/// A length in metres from an OSM value: `12`, `12.5`, `12 m`, `12m`; feet as `40'`, `40 ft`
/// or `40'6"`. `None` when it is none of these.
pub fn parse_length_m(text: &str) -> Option<f64> {
    let t = text.trim();
    let number = |s: &str| s.trim().parse::<f64>().ok().filter(|v| v.is_finite());
    if let Some(m) = t.strip_suffix('m').map(str::trim_end).and_then(number) {
        return Some(m);
    }
    if let Some(ft) = t.strip_suffix("ft").and_then(number) {
        return Some(ft * 0.3048);
    }
    if let Some((feet, rest)) = t.split_once('\'') {
        let inches = rest.trim().strip_suffix('"').map_or(Some(0.0), number)?;
        return Some(number(feet)? * 0.3048 + inches * 0.0254);
    }
    number(t)
}
