//! From OSM elements to the world's shapes: building prisms (outlines, or the parts that
//! replace them) and open areas in world ENU metres, clipped to the world's square.

use std::collections::HashMap;

use sadesim_crds::geo::LocalFrame;

use super::parts::{self, PlanePolygon};
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
            | "building:part"
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
    /// A building outline: `building` (not `no`), not a part.
    Building,
    /// `building:part` (not `no`), whether or not it is also tagged `building`: a prism of
    /// its own that replaces the outline it lies in ([`super::parts`]).
    Part,
    Open(String),
}

fn role_of(tags: &Tags) -> Option<Role> {
    if tag(tags, "building:part").is_some_and(|v| v != "no") {
        return Some(Role::Part);
    }
    if tag(tags, "building").is_some_and(|v| v != "no") {
        return Some(Role::Building);
    }
    if let Some(v) = tag(tags, "leisure").filter(|v| OPEN_LEISURE.contains(v)) {
        return Some(Role::Open(format!("leisure={v}")));
    }
    tag(tags, "landuse").filter(|v| OPEN_LANDUSE.contains(v)).map(|v| Role::Open(format!("landuse={v}")))
}

/// One polygon before projection: outer ring and holes as node positions, degrees.
struct Polygon {
    outer: Vec<[f64; 2]>,
    holes: Vec<Vec<[f64; 2]>>,
}

/// One area element, projected to the plane (not clipped yet).
struct Area<'a> {
    id: ElementId,
    tags: &'a Tags,
    role: Role,
    polygons: Vec<PlanePolygon>,
}

/// Builds the city of `raw` within `extent_m` (half-width of the square) of the origin of
/// `frame`.
pub fn city(raw: &RawOsm, frame: &LocalFrame, extent_m: f64) -> Result<OsmCity, OsmError> {
    let mut stats = OsmStats::default();
    let mut buildings = Vec::new();
    let mut open_areas = Vec::new();
    let ways: HashMap<i64, &RawWay> = raw.ways.iter().map(|w| (w.id, w)).collect();
    let mut areas: Vec<Area> = Vec::new();
    // The first element skipped as incomplete, for the error when no building is left.
    let mut first_incomplete: Option<String> = None;
    let mut skip = |stats: &mut OsmStats, id: ElementId, why: Incomplete| {
        stats.skipped_incomplete += 1;
        first_incomplete.get_or_insert_with(|| format!("{id}: {why}"));
    };
    let to_plane = |ring: &[[f64; 2]]| -> Vec<Point2> {
        ring.iter()
            .map(|&[lat, lon]| {
                let (e, n) = frame.to_plane(lat, lon);
                [e, n]
            })
            .collect()
    };
    let project = |polygons: Vec<Polygon>| -> Vec<PlanePolygon> {
        polygons
            .into_iter()
            .map(|p| PlanePolygon { outer: to_plane(&p.outer), holes: p.holes.iter().map(|h| to_plane(h)).collect() })
            .collect()
    };

    for way in &raw.ways {
        let Some(role) = role_of(&way.tags) else { continue };
        let closed = way.refs.len() >= 4 && way.refs.first() == way.refs.last();
        if !closed {
            stats.skipped_open_ways += 1;
            continue;
        }
        let id = ElementId::Way(way.id);
        match positions(&way.refs, raw) {
            Ok(outer) => areas.push(Area {
                id,
                tags: &way.tags,
                role,
                polygons: project(vec![Polygon { outer, holes: vec![] }]),
            }),
            Err(why) => skip(&mut stats, id, why),
        }
    }
    for relation in &raw.relations {
        if tag(&relation.tags, "type") != Some("multipolygon") {
            continue;
        }
        let Some(role) = role_of(&relation.tags) else { continue };
        let id = ElementId::Relation(relation.id);
        match multipolygon(relation, &ways, raw) {
            Ok(polygons) => areas.push(Area { id, tags: &relation.tags, role, polygons: project(polygons) }),
            Err(why) => skip(&mut stats, id, why),
        }
    }

    // Simple 3D Buildings: an outline holding a part's interior point is replaced by its
    // parts (decided on the whole extract, before clipping).
    let part_points: Vec<Point2> = areas
        .iter()
        .filter(|a| matches!(a.role, Role::Part))
        .filter_map(|a| parts::interior_point(&a.polygons))
        .collect();
    let outlines: Vec<usize> = (0..areas.len()).filter(|&k| matches!(areas[k].role, Role::Building)).collect();
    let held =
        parts::holding(&outlines.iter().map(|&k| areas[k].polygons.as_slice()).collect::<Vec<_>>(), &part_points);
    let mut replaced = vec![false; areas.len()];
    for (&k, held) in outlines.iter().zip(held) {
        replaced[k] = held;
    }

    for (area, replaced) in areas.into_iter().zip(replaced) {
        let mut footprints = Vec::new();
        for polygon in &area.polygons {
            let outer = clip_to_square(&polygon.outer, extent_m);
            if outer.len() < 3 {
                continue;
            }
            let holes: Vec<Vec<Point2>> = polygon
                .holes
                .iter()
                .map(|h| clip_to_square(h, extent_m))
                .filter(|h| h.len() >= 3 && ring_area(h) > 0.0)
                .collect();
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
        let id = area.id;
        match area.role {
            Role::Building if replaced => stats.outlines_replaced_by_parts += 1,
            role @ (Role::Building | Role::Part) => {
                let part = matches!(role, Role::Part);
                let (base_m, height_m, source) = heights(id, area.tags)?;
                for footprint in footprints {
                    match Building::new(footprint, base_m, height_m - base_m) {
                        Ok(building) => {
                            stats.count(source);
                            stats.parts += usize::from(part);
                            buildings.push(OsmBuilding { id, building, height_source: source, part });
                        }
                        Err(_) => stats.skipped_invalid += 1,
                    }
                }
            }
            Role::Open(kind) => {
                let name = tag(area.tags, "name").map(str::to_string);
                for footprint in footprints {
                    open_areas.push(OsmOpenArea { id, kind: kind.clone(), name: name.clone(), footprint });
                }
            }
        }
    }
    stats.buildings = buildings.len();
    stats.open_areas = open_areas.len();
    if buildings.is_empty() {
        let skipped = first_incomplete.map_or_else(String::new, |first| {
            let n = stats.skipped_incomplete;
            format!("; {n} area{} of the file skipped as incomplete, the first {first}", if n == 1 { "" } else { "s" })
        });
        return Err(OsmError::NoBuildings { extent_m, skipped });
    }
    Ok(OsmCity { source_sha256: String::new(), buildings, open_areas, stats })
}

/// Why an area element cannot be assembled from the file (usually: the extract cut it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Incomplete {
    Node(i64),
    Way(i64),
    /// The member ways do not join end to end into closed rings.
    Unclosed,
    /// A multipolygon without an outer ring.
    NoOuter,
}

impl std::fmt::Display for Incomplete {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Incomplete::Node(id) => write!(f, "node {id} is not in the file"),
            Incomplete::Way(id) => write!(f, "member way {id} is not in the file"),
            Incomplete::Unclosed => write!(f, "its member ways do not close into rings"),
            Incomplete::NoOuter => write!(f, "it has no outer ring"),
        }
    }
}

/// The node positions of `refs`; an error names the first node missing from the file (the
/// extract cut the element).
fn positions(refs: &[i64], raw: &RawOsm) -> Result<Vec<[f64; 2]>, Incomplete> {
    refs.iter().map(|r| raw.nodes.get(r).copied().ok_or(Incomplete::Node(*r))).collect()
}

/// The polygons of a multipolygon relation: its `outer` (or unnamed) and `inner` member ways
/// joined end to end into closed rings, each inner ring given to the outer ring containing
/// it. An error when a member way or node is missing or a ring does not close.
fn multipolygon(
    relation: &RawRelation,
    ways: &HashMap<i64, &RawWay>,
    raw: &RawOsm,
) -> Result<Vec<Polygon>, Incomplete> {
    let mut outer_ways = Vec::new();
    let mut inner_ways = Vec::new();
    for m in relation.members.iter().filter(|m| m.kind == MemberKind::Way) {
        let way = ways.get(&m.id).ok_or(Incomplete::Way(m.id))?;
        match m.role.as_str() {
            "inner" => inner_ways.push(way.refs.as_slice()),
            _ => outer_ways.push(way.refs.as_slice()),
        }
    }
    let rings = |ways: &[&[i64]]| -> Result<Vec<Vec<[f64; 2]>>, Incomplete> {
        join_rings(ways).ok_or(Incomplete::Unclosed)?.iter().map(|r| positions(r, raw)).collect()
    };
    let outers = rings(&outer_ways)?;
    let inners = rings(&inner_ways)?;
    if outers.is_empty() {
        return Err(Incomplete::NoOuter);
    }
    let mut polygons: Vec<Polygon> = outers.into_iter().map(|outer| Polygon { outer, holes: Vec::new() }).collect();
    for inner in inners {
        // The first outer ring holding the inner ring's first vertex.
        if let Some(p) = polygons.iter_mut().find(|p| ring_contains(&p.outer, inner[0])) {
            p.holes.push(inner);
        }
    }
    Ok(polygons)
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
