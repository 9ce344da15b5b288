//! The OSM import on small files written here by a minimal PBF encoder (the real Helsinki
//! extract is checked against pyosmium in `tests/interop/test_osm.py`).

use std::io::Write;

use sadesim_crds::geo::{Enu, GeoPoint, LocalFrame};

use super::*;

const ORIGIN: GeoPoint = GeoPoint { latitude_deg: 60.17, longitude_deg: 24.95, altitude_msl_m: 10.0 };

fn frame() -> LocalFrame {
    LocalFrame::new(ORIGIN)
}

/// `[lat, lon]` of the ENU point `(e, n)`.
fn at(e: f64, n: f64) -> (f64, f64) {
    let p = frame().to_geodetic(Enu { east_m: e, north_m: n, up_m: 0.0 });
    (p.latitude_deg, p.longitude_deg)
}

// --- a minimal Protocol Buffers / PBF encoder ---------------------------------------------

fn varint(out: &mut Vec<u8>, mut v: u64) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

fn zz(v: i64) -> u64 {
    ((v << 1) ^ (v >> 63)) as u64
}

fn field_varint(out: &mut Vec<u8>, field: u32, v: u64) {
    varint(out, u64::from(field) << 3);
    varint(out, v);
}

fn field_bytes(out: &mut Vec<u8>, field: u32, bytes: &[u8]) {
    varint(out, (u64::from(field) << 3) | 2);
    varint(out, bytes.len() as u64);
    out.extend_from_slice(bytes);
}

fn field_packed(out: &mut Vec<u8>, field: u32, values: impl IntoIterator<Item = u64>) {
    let mut body = Vec::new();
    for v in values {
        varint(&mut body, v);
    }
    field_bytes(out, field, &body);
}

fn deltas(values: &[i64]) -> Vec<u64> {
    let mut last = 0;
    values
        .iter()
        .map(|&v| {
            let d = v - last;
            last = v;
            zz(d)
        })
        .collect()
}

type T<'a> = &'a [(&'a str, &'a str)];
/// A relation member: `(type: 0 node, 1 way, 2 relation, id, role)`.
type M<'a> = (u64, i64, &'a str);

/// One data block's content.
#[derive(Default)]
struct Data<'a> {
    nodes: Vec<(i64, (f64, f64))>,
    ways: Vec<(i64, T<'a>, Vec<i64>)>,
    relations: Vec<(i64, T<'a>, Vec<M<'a>>)>,
}

impl<'a> Data<'a> {
    /// A closed way around the ENU rectangle `[e0, e1] x [n0, n1]`, with nodes `first..`.
    fn rect_way(&mut self, way: i64, first: i64, [e0, n0, e1, n1]: [f64; 4], tags: T<'a>) {
        for (k, (e, n)) in [(e0, n0), (e1, n0), (e1, n1), (e0, n1)].into_iter().enumerate() {
            self.nodes.push((first + k as i64, at(e, n)));
        }
        self.ways.push((way, tags, vec![first, first + 1, first + 2, first + 3, first]));
    }
}

struct Strings(Vec<String>);

impl Strings {
    fn id(&mut self, s: &str) -> u64 {
        match self.0.iter().position(|x| x == s) {
            Some(i) => i as u64,
            None => {
                self.0.push(s.to_string());
                (self.0.len() - 1) as u64
            }
        }
    }
}

/// The fields ways and relations share: id 1, tag keys 2, tag values 3.
fn element(id: i64, tags: T, strings: &mut Strings) -> Vec<u8> {
    let mut e = Vec::new();
    field_varint(&mut e, 1, id as u64);
    field_packed(&mut e, 2, tags.iter().map(|t| strings.id(t.0)).collect::<Vec<_>>());
    field_packed(&mut e, 3, tags.iter().map(|t| strings.id(t.1)).collect::<Vec<_>>());
    e
}

fn primitive_block(data: &Data) -> Vec<u8> {
    let mut strings = Strings(vec![String::new()]);
    let mut group = Vec::new();
    // Dense nodes, granularity 100 nanodegrees.
    let ids: Vec<i64> = data.nodes.iter().map(|n| n.0).collect();
    let lats: Vec<i64> = data.nodes.iter().map(|n| (n.1.0 * 1e7).round() as i64).collect();
    let lons: Vec<i64> = data.nodes.iter().map(|n| (n.1.1 * 1e7).round() as i64).collect();
    let mut dense = Vec::new();
    field_packed(&mut dense, 1, deltas(&ids));
    field_packed(&mut dense, 8, deltas(&lats));
    field_packed(&mut dense, 9, deltas(&lons));
    field_bytes(&mut group, 2, &dense);
    for (id, tags, refs) in &data.ways {
        let mut w = element(*id, tags, &mut strings);
        field_packed(&mut w, 8, deltas(refs));
        field_bytes(&mut group, 3, &w);
    }
    for (id, tags, members) in &data.relations {
        let mut r = element(*id, tags, &mut strings);
        field_packed(&mut r, 8, members.iter().map(|m| strings.id(m.2)).collect::<Vec<_>>());
        field_packed(&mut r, 9, deltas(&members.iter().map(|m| m.1).collect::<Vec<_>>()));
        field_packed(&mut r, 10, members.iter().map(|m| m.0).collect::<Vec<_>>());
        field_bytes(&mut group, 4, &r);
    }
    let mut table = Vec::new();
    for s in &strings.0 {
        field_bytes(&mut table, 1, s.as_bytes());
    }
    let mut block = Vec::new();
    field_bytes(&mut block, 1, &table);
    field_bytes(&mut block, 2, &group);
    block
}

fn blob(kind: &str, payload: &[u8], zlib: bool) -> Vec<u8> {
    let mut blob = Vec::new();
    if zlib {
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        z.write_all(payload).unwrap();
        field_varint(&mut blob, 2, payload.len() as u64);
        field_bytes(&mut blob, 3, &z.finish().unwrap());
    } else {
        field_bytes(&mut blob, 1, payload);
    }
    let mut header = Vec::new();
    field_bytes(&mut header, 1, kind.as_bytes());
    field_varint(&mut header, 3, blob.len() as u64);
    let mut out = (header.len() as u32).to_be_bytes().to_vec();
    out.extend(header);
    out.extend(blob);
    out
}

/// A file: header (bbox `[min_lon, min_lat, max_lon, max_lat]`, or the extent's square
/// plus a margin) and one zlib data block.
fn file_with(data: &Data, bbox: Option<[f64; 4]>) -> Vec<u8> {
    encode(data, bbox, true)
}

/// [`file_with`], the data block zlib-compressed or raw.
fn encode(data: &Data, bbox: Option<[f64; 4]>, zlib: bool) -> Vec<u8> {
    let [w, s, e, n] = bbox.unwrap_or_else(|| {
        let (s, w) = at(-2000.0, -2000.0);
        let (n, e) = at(2000.0, 2000.0);
        [w, s, e, n]
    });
    let mut header = Vec::new();
    let mut b = Vec::new();
    for (f, v) in [(1, w), (2, e), (3, n), (4, s)] {
        field_varint(&mut b, f, zz((v * 1e9).round() as i64));
    }
    field_bytes(&mut header, 1, &b);
    field_bytes(&mut header, 4, b"OsmSchema-V0.6");
    field_bytes(&mut header, 4, b"DenseNodes");
    let mut out = blob("OSMHeader", &header, false);
    out.extend(blob("OSMData", &primitive_block(data), zlib));
    out
}

fn file(data: &Data) -> Vec<u8> {
    file_with(data, None)
}

/// [`file`] with the data block stored raw instead of zlib-compressed (so a fuzzer's
/// mutations reach the block's fields instead of zlib's checksum).
fn file_raw(data: &Data) -> Vec<u8> {
    encode(data, None, false)
}

const EXTENT_M: f64 = 1000.0;

fn read(bytes: &[u8]) -> Result<OsmCity, OsmError> {
    read_pbf(bytes, &frame(), EXTENT_M)
}

// --- buildings ------------------------------------------------------------------------------

#[test]
fn a_building_way_becomes_a_prism_over_its_footprint_with_its_tagged_height() {
    let mut d = Data::default();
    d.rect_way(10, 100, [10.0, 20.0, 30.0, 35.0], &[("building", "yes"), ("height", "24.5")]);
    d.rect_way(11, 200, [100.0, 100.0, 110.0, 110.0], &[("highway", "service")]);
    let city = read(&file(&d)).unwrap();
    assert_eq!(city.buildings.len(), 1, "the service road is no building");
    let b = &city.buildings[0];
    assert_eq!(b.id, ElementId::Way(10));
    assert_eq!(b.height_source, HeightSource::Tagged);
    assert!((b.building.roof_up_m() - 24.5).abs() < 1e-9);
    assert_eq!(b.building.base_up_m(), 0.0);
    // 20 m x 15 m, through degrees at 1e-7 deg resolution (~1 cm).
    assert!((b.building.footprint_area_m2() - 300.0).abs() < 0.5, "{}", b.building.footprint_area_m2());
    assert!(b.building.footprint_contains(20.0, 27.0) && !b.building.footprint_contains(35.0, 27.0));
    assert_eq!(city.stats.heights_tagged, 1);
}

#[test]
fn heights_follow_the_documented_rules_and_are_counted() {
    let cases: [(T, f64, f64, HeightSource); 7] = [
        (&[("building", "yes"), ("building:height", "12 m")], 0.0, 12.0, HeightSource::Tagged),
        (&[("building", "yes"), ("height", "40'")], 0.0, 12.192, HeightSource::Tagged),
        (&[("building", "yes"), ("building:levels", "4")], 0.0, 12.0, HeightSource::Levels),
        (
            &[("building", "yes"), ("building:levels", "4"), ("roof:levels", "1"), ("roof:height", "2")],
            0.0,
            17.0,
            HeightSource::Levels,
        ),
        (&[("building", "yes"), ("height", "20"), ("min_height", "8")], 8.0, 20.0, HeightSource::Tagged),
        (&[("building", "yes"), ("height", "tall")], 0.0, DEFAULT_HEIGHT_M, HeightSource::Default),
        (&[("building", "house")], 0.0, DEFAULT_HEIGHT_M, HeightSource::Default),
    ];
    let mut d = Data::default();
    for (i, (tags, ..)) in cases.iter().enumerate() {
        let e = 50.0 * i as f64;
        d.rect_way(i as i64 + 1, 100 * (i as i64 + 1), [e, 0.0, e + 20.0, 20.0], tags);
    }
    let city = read(&file(&d)).unwrap();
    assert_eq!(city.buildings.len(), cases.len());
    for (b, (tags, base, roof, source)) in city.buildings.iter().zip(&cases) {
        assert!((b.building.base_up_m() - base).abs() < 1e-9, "{tags:?}: base {}", b.building.base_up_m());
        assert!((b.building.roof_up_m() - roof).abs() < 1e-9, "{tags:?}: roof {}", b.building.roof_up_m());
        assert_eq!(b.height_source, *source, "{tags:?}");
    }
    let s = &city.stats;
    assert_eq!((s.heights_tagged, s.heights_from_levels, s.heights_defaulted), (3, 2, 2));
}

#[test]
fn lengths_parse_in_metres_and_feet() {
    assert_eq!(parse_length_m("12"), Some(12.0));
    assert_eq!(parse_length_m(" 12.5 m"), Some(12.5));
    assert_eq!(parse_length_m("7m"), Some(7.0));
    assert!((parse_length_m("10 ft").unwrap() - 3.048).abs() < 1e-12);
    assert!((parse_length_m("40'6\"").unwrap() - (12.192 + 0.1524)).abs() < 1e-9);
    for bad in ["", "tall", "5;7", "NaN m", "inf"] {
        assert_eq!(parse_length_m(bad), None, "{bad:?}");
    }
}

#[test]
fn a_multipolygon_building_has_its_courtyard_as_a_hole_and_ways_join_into_rings() {
    let mut d = Data::default();
    // Outer 40 x 40 m from two open ways (one reversed), inner 10 x 10 m.
    let corners = [(0.0, 0.0), (40.0, 0.0), (40.0, 40.0), (0.0, 40.0)];
    for (k, (e, n)) in corners.into_iter().enumerate() {
        d.nodes.push((1 + k as i64, at(e, n)));
    }
    d.ways.push((101, &[], vec![1, 2, 3]));
    d.ways.push((102, &[], vec![1, 4, 3]));
    d.rect_way(103, 10, [15.0, 15.0, 25.0, 25.0], &[]);
    d.relations.push((
        7,
        &[("type", "multipolygon"), ("building", "yes"), ("building:levels", "5")],
        vec![(1, 101, "outer"), (1, 102, "outer"), (1, 103, "inner")],
    ));
    let city = read(&file(&d)).unwrap();
    assert_eq!(city.buildings.len(), 1);
    let b = &city.buildings[0];
    assert_eq!(b.id, ElementId::Relation(7));
    assert!((b.building.footprint_area_m2() - 1500.0).abs() < 1.0, "{}", b.building.footprint_area_m2());
    assert!(!b.building.footprint_contains(20.0, 20.0), "the courtyard is open");
    assert!(b.building.footprint_contains(5.0, 20.0));
    assert!((b.building.roof_up_m() - 15.0).abs() < 1e-9);
}

#[test]
fn buildings_are_clipped_to_the_world_square_and_those_outside_are_dropped() {
    let mut d = Data::default();
    d.rect_way(1, 100, [EXTENT_M - 10.0, 0.0, EXTENT_M + 30.0, 20.0], &[("building", "yes")]);
    d.rect_way(2, 200, [EXTENT_M + 50.0, 0.0, EXTENT_M + 80.0, 20.0], &[("building", "yes")]);
    d.rect_way(3, 300, [0.0, 0.0, 10.0, 10.0], &[("building", "yes")]);
    let city = read(&file(&d)).unwrap();
    assert_eq!(city.buildings.len(), 2, "the building wholly outside is dropped");
    let cut = &city.buildings[0].building;
    assert!((cut.footprint_area_m2() - 200.0).abs() < 0.5, "10 m of 40 m inside: {}", cut.footprint_area_m2());
    assert!(cut.max_corner().x <= EXTENT_M + 1e-6);
}

#[test]
fn parks_become_open_areas_with_their_names() {
    let mut d = Data::default();
    d.rect_way(1, 100, [0.0, 0.0, 10.0, 10.0], &[("building", "yes")]);
    d.rect_way(2, 200, [100.0, 100.0, 200.0, 180.0], &[("leisure", "park"), ("name", "Esplanadi")]);
    d.rect_way(3, 300, [300.0, 100.0, 320.0, 120.0], &[("landuse", "grass")]);
    d.rect_way(4, 400, [400.0, 100.0, 420.0, 120.0], &[("landuse", "industrial")]);
    let city = read(&file(&d)).unwrap();
    let kinds: Vec<(&str, Option<&str>)> =
        city.open_areas.iter().map(|a| (a.kind.as_str(), a.name.as_deref())).collect();
    assert_eq!(kinds, [("leisure=park", Some("Esplanadi")), ("landuse=grass", None)]);
    assert!((city.open_areas[0].footprint.area_m2() - 8000.0).abs() < 5.0);
    assert_eq!(city.stats.open_areas, 2);
}

#[test]
fn elements_cut_by_the_extract_are_skipped_and_counted() {
    let mut d = Data::default();
    d.rect_way(1, 100, [0.0, 0.0, 10.0, 10.0], &[("building", "yes")]);
    // A way whose nodes are not in the file, and a relation whose member way is not.
    d.ways.push((2, &[("building", "yes")], vec![900, 901, 902, 900]));
    d.relations.push((3, &[("type", "multipolygon"), ("building", "yes")], vec![(1, 999, "outer")]));
    // An open way tagged as a building.
    d.nodes.push((50, at(30.0, 30.0)));
    d.nodes.push((51, at(40.0, 30.0)));
    d.ways.push((4, &[("building", "yes")], vec![50, 51]));
    let city = read(&file(&d)).unwrap();
    assert_eq!(city.buildings.len(), 1);
    assert_eq!((city.stats.skipped_incomplete, city.stats.skipped_open_ways), (2, 1));
}

// --- building parts (Simple 3D Buildings) ---------------------------------------------------

fn prisms(city: &OsmCity) -> Vec<(ElementId, bool, f64, f64)> {
    city.buildings.iter().map(|b| (b.id, b.part, b.building.base_up_m(), b.building.roof_up_m())).collect()
}

#[test]
fn an_outline_with_parts_is_replaced_by_its_parts_with_their_own_heights() {
    let mut d = Data::default();
    // The outline: 40 x 20 m, 12 m. Inside: a 20 m-tall hall on the west half and a tower
    // floating from 15 m to 45 m over the east half (building:min_level 5).
    d.rect_way(1, 100, [0.0, 0.0, 40.0, 20.0], &[("building", "church"), ("height", "12")]);
    d.rect_way(2, 200, [0.0, 0.0, 20.0, 20.0], &[("building:part", "yes"), ("height", "20"), ("min_height", "0")]);
    d.rect_way(
        3,
        300,
        [25.0, 5.0, 35.0, 15.0],
        &[("building:part", "tower"), ("building:levels", "15"), ("building:min_level", "5")],
    );
    let city = read(&file(&d)).unwrap();
    assert_eq!(
        prisms(&city),
        [(ElementId::Way(2), true, 0.0, 20.0), (ElementId::Way(3), true, 15.0, 45.0)],
        "the outline is no prism of its own"
    );
    let s = &city.stats;
    assert_eq!((s.buildings, s.parts, s.outlines_replaced_by_parts), (2, 2, 1));
    assert_eq!((s.heights_tagged, s.heights_from_levels, s.heights_defaulted), (1, 1, 0), "one roof per prism");
}

#[test]
fn outlines_without_parts_stay_and_parts_outside_any_outline_are_buildings() {
    let mut d = Data::default();
    d.rect_way(1, 100, [0.0, 0.0, 20.0, 20.0], &[("building", "yes"), ("height", "10")]);
    // A part 100 m away from every outline, and a `building:part=no` inside the outline.
    d.rect_way(2, 200, [100.0, 0.0, 110.0, 10.0], &[("building:part", "yes"), ("height", "6")]);
    d.rect_way(3, 300, [5.0, 5.0, 10.0, 10.0], &[("building:part", "no"), ("height", "30")]);
    let city = read(&file(&d)).unwrap();
    assert_eq!(prisms(&city), [(ElementId::Way(1), false, 0.0, 10.0), (ElementId::Way(2), true, 0.0, 6.0)]);
    assert_eq!((city.stats.parts, city.stats.outlines_replaced_by_parts), (1, 0));
}

#[test]
fn a_part_belongs_to_the_outline_holding_its_interior_point_not_to_a_courtyard() {
    let mut d = Data::default();
    // A courtyard building (multipolygon) with a fountain part in the courtyard: the
    // outline stays. A part tagged building too is a part. A U-shaped part whose bounding
    // box centre is outside it still finds a point inside itself, in the second outline.
    let corners = [(0.0, 0.0), (40.0, 0.0), (40.0, 40.0), (0.0, 40.0)];
    for (k, (e, n)) in corners.into_iter().enumerate() {
        d.nodes.push((1 + k as i64, at(e, n)));
    }
    d.ways.push((101, &[], vec![1, 2, 3, 4, 1]));
    d.rect_way(102, 10, [10.0, 10.0, 30.0, 30.0], &[]);
    d.relations.push((7, &[("type", "multipolygon"), ("building", "yes")], vec![(1, 101, "outer"), (1, 102, "inner")]));
    d.rect_way(8, 20, [18.0, 18.0, 22.0, 22.0], &[("building:part", "yes"), ("building", "yes"), ("height", "3")]);
    d.rect_way(9, 30, [100.0, 0.0, 130.0, 30.0], &[("building", "yes")]);
    let u = [
        (100.0, 0.0),
        (130.0, 0.0),
        (130.0, 30.0),
        (120.0, 30.0),
        (120.0, 10.0),
        (110.0, 10.0),
        (110.0, 30.0),
        (100.0, 30.0),
    ];
    for (k, (e, n)) in u.into_iter().enumerate() {
        d.nodes.push((40 + k as i64, at(e, n)));
    }
    d.ways.push((10, &[("building:part", "yes"), ("height", "8")], vec![40, 41, 42, 43, 44, 45, 46, 47, 40]));
    let city = read(&file(&d)).unwrap();
    let ids: Vec<(ElementId, bool)> = city.buildings.iter().map(|b| (b.id, b.part)).collect();
    assert_eq!(ids, [(ElementId::Way(8), true), (ElementId::Way(10), true), (ElementId::Relation(7), false)]);
    assert_eq!(city.stats.outlines_replaced_by_parts, 1);
}

#[test]
fn interior_points_are_those_geos_picks() {
    use super::parts::{PlanePolygon, interior_point};
    use crate::Point2;
    let poly = |outer: &[Point2], holes: &[&[Point2]]| PlanePolygon {
        outer: outer.to_vec(),
        holes: holes.iter().map(|h| h.to_vec()).collect(),
    };
    // shapely 2 / GEOS 3.14 `representative_point()` of the same shapes.
    let u = poly(
        &[[0.0, 0.0], [30.0, 0.0], [30.0, 30.0], [20.0, 30.0], [20.0, 10.0], [10.0, 10.0], [10.0, 30.0], [0.0, 30.0]],
        &[],
    );
    assert_eq!(interior_point(&[u]), Some([5.0, 20.0]));
    let courtyard = poly(
        &[[0.0, 0.0], [40.0, 0.0], [40.0, 40.0], [0.0, 40.0]],
        &[&[[5.0, 15.0], [35.0, 15.0], [35.0, 25.0], [5.0, 25.0]]],
    );
    assert_eq!(interior_point(&[courtyard]), Some([2.5, 20.0]));
    let two = [
        poly(&[[0.0, 0.0], [5.0, 0.0], [5.0, 50.0], [0.0, 50.0]], &[]),
        poly(&[[100.0, 0.0], [120.0, 0.0], [120.0, 7.0], [100.0, 7.0]], &[]),
    ];
    assert_eq!(interior_point(&two), Some([110.0, 3.5]), "the widest section of all polygons");
    assert_eq!(interior_point(&[poly(&[[0.0, 1.0], [5.0, 1.0], [9.0, 1.0]], &[])]), None, "no area");
}

#[test]
fn stacked_parts_are_all_solid_and_the_surface_is_the_highest_roof() {
    let mut d = Data::default();
    d.rect_way(1, 100, [0.0, 0.0, 40.0, 40.0], &[("building", "yes")]);
    d.rect_way(2, 200, [0.0, 0.0, 40.0, 40.0], &[("building:part", "yes"), ("height", "10")]);
    d.rect_way(3, 300, [10.0, 10.0, 30.0, 30.0], &[("building:part", "yes"), ("height", "60"), ("min_height", "10")]);
    let city = read(&file(&d)).unwrap();
    let spec = sadesim_crds::run::World {
        source: sadesim_crds::run::WorldSource::Osm,
        osm: Some(sadesim_crds::run::OsmExtract { file: "test.osm.pbf".into(), default_height_m: None }),
        extent_m: EXTENT_M,
        ..Default::default()
    };
    let inputs = crate::WorldInputs { origin: ORIGIN, world: spec, open_areas: Vec::new() };
    let world = crate::World::build(&inputs, &crate::WorldData { osm: Some(city), dem: None }).unwrap();
    assert_eq!(world.buildings().len(), 2);
    assert!((world.surface_up_m(20.0, 20.0) - 60.0).abs() < 1e-9, "the tower's roof, over the podium");
    assert!((world.surface_up_m(5.0, 5.0) - 10.0).abs() < 1e-9);
    for z in [5.0, 30.0, 59.0] {
        assert!(world.is_inside_building(nalgebra::Vector3::new(20.0, 20.0, z)), "solid at {z} m");
    }
    assert!(!world.is_inside_building(nalgebra::Vector3::new(5.0, 5.0, 30.0)), "beside the tower");
}

#[test]
fn the_scenario_default_height_replaces_only_the_import_default() {
    let mut d = Data::default();
    d.rect_way(1, 100, [0.0, 0.0, 20.0, 20.0], &[("building", "yes")]);
    d.rect_way(2, 200, [30.0, 0.0, 50.0, 20.0], &[("building", "yes"), ("height", "12")]);
    d.rect_way(3, 300, [60.0, 0.0, 80.0, 20.0], &[("building", "yes"), ("building:levels", "2")]);
    let city = read(&file(&d)).unwrap();
    let roofs = |default_height_m: Option<f64>| {
        let spec = sadesim_crds::run::World {
            source: sadesim_crds::run::WorldSource::Osm,
            osm: Some(sadesim_crds::run::OsmExtract { file: "test.osm.pbf".into(), default_height_m }),
            extent_m: EXTENT_M,
            ..Default::default()
        };
        let inputs = crate::WorldInputs { origin: ORIGIN, world: spec, open_areas: Vec::new() };
        let world = crate::World::build(&inputs, &crate::WorldData { osm: Some(city.clone()), dem: None }).unwrap();
        [10.0, 40.0, 70.0].map(|e| world.surface_up_m(e, 10.0))
    };
    assert_eq!(roofs(None), [DEFAULT_HEIGHT_M, 12.0, 6.0]);
    assert_eq!(roofs(Some(21.0)), [21.0, 12.0, 6.0], "tagged and levelled roofs keep their height");
}

// --- refused inputs -------------------------------------------------------------------------

fn one_building() -> Vec<u8> {
    let mut d = Data::default();
    d.rect_way(1, 100, [0.0, 0.0, 10.0, 10.0], &[("building", "yes")]);
    file(&d)
}

fn error(bytes: &[u8]) -> String {
    read(bytes).expect_err("refused").to_string()
}

#[test]
fn broken_files_are_refused_naming_the_byte_and_the_problem() {
    let good = one_building();
    assert!(read(&good).is_ok());
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("empty", vec![], "byte 0: empty file"),
        ("text", b"<?xml version='1.0'?><osm></osm>".to_vec(), "byte 0: not an OSM PBF file"),
        ("cut in the length", good[..2].to_vec(), "byte 0: truncated"),
        ("cut in the header", good[..10].to_vec(), "byte 0: truncated: the blob header needs"),
        ("cut in the data", good[..good.len() - 5].to_vec(), "truncated: the blob needs"),
        ("trailing garbage", [good.clone(), vec![0, 0, 0]].concat(), "truncated"),
    ];
    for (what, bytes, expected) in cases {
        let e = error(&bytes);
        assert!(e.contains(expected), "{what}: {e}");
    }
    // A flipped byte inside the compressed block: zlib's checksum catches it.
    let mut flipped = good.clone();
    let i = flipped.len() - 20;
    flipped[i] ^= 0x55;
    let e = error(&flipped);
    assert!(e.contains("zlib") || e.contains("blob payload byte"), "{e}");
}

#[test]
fn a_data_blob_first_or_an_unknown_required_feature_is_refused() {
    let data = blob("OSMData", &primitive_block(&Data::default()), false);
    assert!(error(&data).contains("the first blob is \"OSMData\", expected \"OSMHeader\""));
    let mut header = Vec::new();
    field_bytes(&mut header, 4, b"HistoricalInformation");
    let e = error(&blob("OSMHeader", &header, false));
    assert!(e.contains("requires feature \"HistoricalInformation\""), "{e}");
}

#[test]
fn an_extract_that_does_not_cover_the_world_is_refused_with_both_boxes() {
    let mut d = Data::default();
    d.rect_way(1, 100, [0.0, 0.0, 10.0, 10.0], &[("building", "yes")]);
    let (s, w) = at(-500.0, -500.0);
    let (n, e) = at(500.0, 500.0);
    let e = read_pbf(&file_with(&d, Some([w, s, e, n])), &frame(), EXTENT_M).unwrap_err();
    assert!(matches!(e, OsmError::NotCovering { .. }), "{e}");
    assert!(e.to_string().contains("world.extentM 1000 m"), "{e}");
}

#[test]
fn a_negative_height_is_refused_naming_the_element_and_tag() {
    let mut d = Data::default();
    d.rect_way(42, 100, [0.0, 0.0, 10.0, 10.0], &[("building", "yes"), ("height", "-5")]);
    assert_eq!(error(&file(&d)), "way 42: tag height=\"-5\": expected a height >= 0");
}

#[test]
fn no_building_in_the_extent_is_an_error_not_an_empty_city() {
    let mut d = Data::default();
    d.rect_way(1, 100, [0.0, 0.0, 10.0, 10.0], &[("leisure", "park")]);
    assert!(error(&file(&d)).starts_with("no building within world.extentM 1000 m"));
}

#[test]
fn a_city_left_empty_by_incomplete_elements_names_the_first_and_what_is_missing() {
    let mut d = Data::default();
    d.rect_way(1, 100, [0.0, 0.0, 10.0, 10.0], &[]);
    d.relations.push((3, &[("type", "multipolygon"), ("building", "yes")], vec![(1, 1, "outer"), (1, 999, "inner")]));
    d.ways.push((4, &[("building", "yes")], vec![900, 901, 902, 900]));
    assert_eq!(
        error(&file(&d)),
        "no building within world.extentM 1000 m of the origin: check spec.origin (is it inside the extract?) and \
         the extent; 2 areas of the file skipped as incomplete, the first way 4: node 900 is not in the file"
    );
    d.ways.pop();
    assert!(error(&file(&d)).ends_with(
        "; 1 area of the file skipped as incomplete, the first relation 3: member way 999 is not in the file"
    ));
}

#[test]
fn the_fuzz_seeds_are_valid_extracts() {
    // The seed corpus of fuzz/fuzz_targets/pbf.rs (same origin and extent): buildings with
    // each height rule, a courtyard multipolygon, parts, a park; zlib and raw data blocks.
    let mut d = Data::default();
    d.rect_way(1, 100, [0.0, 0.0, 20.0, 10.0], &[("building", "yes"), ("height", "24.5")]);
    d.rect_way(2, 200, [30.0, 0.0, 50.0, 20.0], &[("building", "yes"), ("building:levels", "4"), ("roof:height", "2")]);
    d.rect_way(3, 300, [60.0, 0.0, 100.0, 20.0], &[("building", "church")]);
    d.rect_way(4, 400, [60.0, 0.0, 80.0, 20.0], &[("building:part", "yes"), ("height", "30"), ("min_height", "5")]);
    d.rect_way(5, 500, [100.0, 100.0, 200.0, 180.0], &[("leisure", "park"), ("name", "Esplanadi")]);
    let corners = [(0.0, 50.0), (40.0, 50.0), (40.0, 90.0), (0.0, 90.0)];
    for (k, (e, n)) in corners.into_iter().enumerate() {
        d.nodes.push((600 + k as i64, at(e, n)));
    }
    d.ways.push((6, &[], vec![600, 601, 602]));
    d.ways.push((7, &[], vec![600, 603, 602]));
    d.rect_way(8, 700, [15.0, 65.0, 25.0, 75.0], &[]);
    d.relations.push((
        9,
        &[("type", "multipolygon"), ("building", "yes"), ("building:min_level", "1"), ("height", "12 m")],
        vec![(1, 6, "outer"), (1, 7, "outer"), (1, 8, "inner")],
    ));
    let mut one = Data::default();
    one.rect_way(1, 100, [0.0, 0.0, 10.0, 10.0], &[("building", "yes")]);
    let seeds = [("city-raw.osm.pbf", file_raw(&d)), ("city.osm.pbf", file(&d)), ("one-raw.osm.pbf", file_raw(&one))];
    for (name, bytes) in &seeds {
        let city = read(bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(!city.buildings.is_empty() && (city.stats.parts == 0 || city.stats.outlines_replaced_by_parts == 1));
    }
    let (raw, zlib) = (read(&seeds[0].1).unwrap(), read(&seeds[1].1).unwrap());
    assert_eq!((raw.buildings, raw.stats), (zlib.buildings, zlib.stats), "raw or zlib: the same city");
    crate::fuzz::write_seeds("pbf", &seeds);
}

#[test]
fn arbitrary_bytes_never_panic() {
    // A cheap deterministic fuzz: every prefix and many byte flips of a valid file.
    let good = one_building();
    for n in 0..good.len() {
        let _ = read(&good[..n]);
    }
    for bytes in crate::fuzz::mutations(&good, 2000, 0x2545_f491_4f6c_dd1d, |r| r as usize) {
        let _ = read(&bytes);
    }
}
