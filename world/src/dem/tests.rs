//! DEMs written here by a minimal TIFF writer (GDAL-written GeoTIFFs are checked against
//! GDAL itself in `tests/interop/test_dem.py`).

use std::io::Write;

use sadesim_crds::geo::{GeoPoint, LocalFrame};

use super::*;

/// What the test TIFF holds.
struct Spec {
    width: u32,
    height: u32,
    /// Row-major values.
    values: Vec<f64>,
    /// 16-bit signed integers instead of 32-bit floats.
    int16: bool,
    big_endian: bool,
    /// Deflate, with horizontal differencing for integers.
    deflate: bool,
    /// `(pixel scale x, y, tiepoint x, y)` of pixel (0, 0)'s top-left corner.
    geo: Option<[f64; 4]>,
    /// GeographicTypeGeoKey or ProjectedCSTypeGeoKey value.
    epsg: u16,
    nodata: Option<&'static str>,
    compression: Option<u16>,
}

impl Spec {
    fn plane(width: u32, height: u32, geo: [f64; 4], f: impl Fn(f64, f64) -> f64) -> Self {
        let mut values = Vec::new();
        for j in 0..height {
            for i in 0..width {
                // The value of an area pixel sits at its centre.
                let x = geo[2] + (f64::from(i) + 0.5) * geo[0];
                let y = geo[3] - (f64::from(j) + 0.5) * geo[1];
                values.push(f(x, y));
            }
        }
        Self {
            width,
            height,
            values,
            int16: false,
            big_endian: false,
            deflate: false,
            geo: Some(geo),
            epsg: 4326,
            nodata: None,
            compression: None,
        }
    }

    fn write(&self) -> Vec<u8> {
        let le = !self.big_endian;
        let u16b = |v: u16| if le { v.to_le_bytes() } else { v.to_be_bytes() };
        let u32b = |v: u32| if le { v.to_le_bytes() } else { v.to_be_bytes() };
        let f64b = |v: f64| if le { v.to_le_bytes() } else { v.to_be_bytes() };
        // Pixel data.
        let mut data = Vec::new();
        for row in self.values.chunks(self.width as usize) {
            let mut prev = 0i16;
            for &v in row {
                if self.int16 {
                    let q = v.round() as i16;
                    let stored = if self.deflate { q.wrapping_sub(prev) } else { q };
                    prev = q;
                    data.extend_from_slice(&u16b(stored as u16));
                } else {
                    data.extend_from_slice(&u32b((v as f32).to_bits()));
                }
            }
        }
        if self.deflate {
            let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
            z.write_all(&data).unwrap();
            data = z.finish().unwrap();
        }
        // Layout: header, data, out-of-line values, IFD.
        let mut out = if le { b"II*\0".to_vec() } else { b"MM\0*".to_vec() };
        out.extend_from_slice(&[0; 4]);
        let data_at = out.len() as u32;
        out.extend_from_slice(&data);
        let mut entries: Vec<(u16, u16, u32, Vec<u8>)> = Vec::new();
        let short = |tag: u16, v: u16| (tag, 3u16, 1u32, u16b(v).to_vec());
        let long = |tag: u16, v: u32| (tag, 4u16, 1u32, u32b(v).to_vec());
        entries.push(long(256, self.width));
        entries.push(long(257, self.height));
        entries.push(short(258, if self.int16 { 16 } else { 32 }));
        entries.push(short(259, self.compression.unwrap_or(if self.deflate { 8 } else { 1 })));
        entries.push(long(273, data_at));
        entries.push(short(277, 1));
        entries.push(long(278, self.height));
        entries.push(long(279, data.len() as u32));
        if self.deflate && self.int16 {
            entries.push(short(317, 2));
        }
        entries.push(short(339, if self.int16 { 2 } else { 3 }));
        if let Some([sx, sy, tx, ty]) = self.geo {
            let doubles = |v: &[f64]| v.iter().flat_map(|&d| f64b(d)).collect::<Vec<u8>>();
            entries.push((33550, 12, 3, doubles(&[sx, sy, 0.0])));
            entries.push((33922, 12, 6, doubles(&[0.0, 0.0, 0.0, tx, ty, 0.0])));
            let geographic = self.epsg < 32000 && self.epsg != 3857;
            let (model, key) = if geographic { (2u16, 2048u16) } else { (1, 3072) };
            let keys: Vec<u16> = vec![1, 1, 0, 2, 1024, 0, 1, model, key, 0, 1, self.epsg];
            entries.push((34735, 3, keys.len() as u32, keys.iter().flat_map(|&k| u16b(k)).collect()));
        }
        if let Some(nodata) = self.nodata {
            let mut text = nodata.as_bytes().to_vec();
            text.push(0);
            entries.push((42113, 2, text.len() as u32, text));
        }
        entries.sort_by_key(|e| e.0);
        let mut offsets = Vec::new();
        for e in &entries {
            if e.3.len() > 4 {
                offsets.push(Some(out.len() as u32));
                out.extend_from_slice(&e.3);
            } else {
                offsets.push(None);
            }
        }
        let ifd = out.len() as u32;
        out[4..8].copy_from_slice(&u32b(ifd));
        out.extend_from_slice(&u16b(entries.len() as u16));
        for (e, offset) in entries.iter().zip(offsets) {
            out.extend_from_slice(&u16b(e.0));
            out.extend_from_slice(&u16b(e.1));
            out.extend_from_slice(&u32b(e.2));
            match offset {
                Some(o) => out.extend_from_slice(&u32b(o)),
                None => {
                    let mut inline = e.3.clone();
                    inline.resize(4, 0);
                    out.extend_from_slice(&inline);
                }
            }
        }
        out.extend_from_slice(&[0; 4]);
        out
    }
}

const LAT0: f64 = 60.0;
const LON0: f64 = 24.0;

/// 0.1 deg x 0.05 deg at 0.001 deg pixels, z = 10 + 1000 (lon - 24) + 500 (lat - 60).
fn plane_tiff() -> Spec {
    Spec::plane(100, 50, [0.001, 0.001, LON0, LAT0 + 0.05], |lon, lat| {
        10.0 + 1000.0 * (lon - LON0) + 500.0 * (lat - LAT0)
    })
}

fn plane_z(lat: f64, lon: f64) -> f64 {
    10.0 + 1000.0 * (lon - LON0) + 500.0 * (lat - LAT0)
}

#[test]
fn a_geographic_float_geotiff_is_sampled_bilinearly_at_pixel_centres() {
    let dem = Dem::read(&plane_tiff().write(), "plane.tif").unwrap();
    assert_eq!(dem.crs(), Crs::Geographic);
    assert_eq!(dem.size(), (100, 50));
    for (lat, lon) in [(60.0205, 24.0305), (60.0123, 24.0777), (60.0005, 24.0005), (60.0495, 24.0995)] {
        let z = dem.elevation_m(lat, lon).unwrap();
        assert!((z - plane_z(lat, lon)).abs() < 1e-4, "{lat} {lon}: {z} vs {}", plane_z(lat, lon));
    }
    // Outside the pixel centres' hull: no elevation.
    assert_eq!(dem.elevation_m(60.0001, 24.05), None);
    assert_eq!(dem.elevation_m(60.02, 23.9), None);
}

#[test]
fn big_endian_int16_and_deflate_with_the_horizontal_predictor_read_the_same_grid() {
    let float = Dem::read(&plane_tiff().write(), "a.tif").unwrap();
    for (big_endian, deflate) in [(true, false), (false, true), (true, true)] {
        let mut spec = plane_tiff();
        spec.int16 = true;
        spec.big_endian = big_endian;
        spec.deflate = deflate;
        let dem = Dem::read(&spec.write(), "b.tif").unwrap();
        for (lat, lon) in [(60.0205, 24.0305), (60.0403, 24.0902)] {
            let (a, b) = (float.elevation_m(lat, lon).unwrap(), dem.elevation_m(lat, lon).unwrap());
            assert!((a - b).abs() <= 0.5, "{big_endian} {deflate}: {a} vs {b} (rounded to metres)");
        }
    }
}

#[test]
fn no_data_values_have_no_elevation() {
    let mut spec = plane_tiff();
    spec.values[25 * 100 + 50] = -9999.0;
    spec.nodata = Some("-9999");
    let dem = Dem::read(&spec.write(), "a.tif").unwrap();
    // Pixel (50, 25) is centred at lon 24.0505, lat 60.0245.
    assert_eq!(dem.elevation_m(60.0245, 24.0505), None);
    assert!(dem.elevation_m(60.0100, 24.0505).is_some());
}

#[test]
fn a_utm_geotiff_is_sampled_through_the_transverse_mercator_projection() {
    // UTM zone 35N around Helsinki, 10 m pixels, z = a plane in easting/northing.
    let (e0, n0) = utm_forward(60.17, 24.94, 35, true);
    let geo = [10.0, 10.0, (e0 - 1000.0).round(), (n0 + 1000.0).round()];
    let mut spec = Spec::plane(200, 200, geo, |x, y| 20.0 + 0.01 * (x - geo[2]) + 0.02 * (geo[3] - y));
    spec.epsg = 32635;
    let dem = Dem::read(&spec.write(), "utm.tif").unwrap();
    assert_eq!(dem.crs(), Crs::Utm { zone: 35, north: true });
    let (x, y) = utm_forward(60.171, 24.945, 35, true);
    let expected = 20.0 + 0.01 * (x - geo[2]) + 0.02 * (geo[3] - y);
    assert!((dem.elevation_m(60.171, 24.945).unwrap() - expected).abs() < 1e-3);
}

#[test]
fn utm_forward_puts_the_central_meridian_on_the_false_easting() {
    let (e, n) = utm_forward(0.0, 3.0, 31, true);
    assert!((e - 500_000.0).abs() < 1e-6 && n.abs() < 1e-6, "{e} {n}");
    // On the central meridian the northing is 0.9996 x the meridian arc: 45 deg N is
    // 4 984 944.378 m of arc on WGS84.
    let (e, n) = utm_forward(45.0, 27.0, 35, true);
    assert!((e - 500_000.0).abs() < 1e-6 && (n - 0.9996 * 4_984_944.378).abs() < 0.01, "{e} {n}");
    let (_, south) = utm_forward(-45.0, 27.0, 35, false);
    assert!((south - (10_000_000.0 - 0.9996 * 4_984_944.378)).abs() < 0.01);
}

#[test]
fn an_srtm_tile_is_read_by_its_name_with_voids() {
    let side = 1201usize;
    let mut bytes = Vec::with_capacity(side * side * 2);
    for j in 0..side {
        for i in 0..side {
            let v: i16 = if (i, j) == (600, 600) { -32768 } else { (i + j) as i16 };
            bytes.extend_from_slice(&v.to_be_bytes());
        }
    }
    let dem = Dem::read(&bytes, "data/N60E024.hgt").unwrap();
    // Row 0 is the north edge (61 N); column 0 the west edge (24 E).
    assert_eq!(dem.elevation_m(61.0, 24.0), Some(0.0));
    assert_eq!(dem.elevation_m(60.0, 25.0), Some(2400.0));
    assert_eq!(dem.elevation_m(60.5, 24.5), None, "the void");
    assert!((dem.elevation_m(60.75, 24.25).unwrap() - 600.0).abs() < 1e-6);
    let e = Dem::read(&bytes, "tile.hgt").unwrap_err().to_string();
    assert!(e.contains("named by its south-west corner"), "{e}");
    let e = Dem::read(&bytes[..1000], "N60E024.hgt").unwrap_err().to_string();
    assert!(e.contains("1000 bytes"), "{e}");
}

#[test]
fn a_dem_smaller_than_the_world_is_refused_naming_a_point() {
    let dem = Dem::read(&plane_tiff().write(), "a.tif").unwrap();
    let inside = LocalFrame::new(GeoPoint::new(60.025, 24.05, 0.0));
    dem.check_covers(&inside, 1000.0).expect("1 km around the centre is inside 5.5 x 5.5 km");
    let e = dem.check_covers(&inside, 5000.0).unwrap_err().to_string();
    assert!(e.contains("does not cover world.extentM 5000 m") && e.contains("outside the grid"), "{e}");
}

#[test]
fn broken_or_unsupported_dems_are_refused_with_what_to_do() {
    let good = plane_tiff().write();
    let mut no_geo = plane_tiff();
    no_geo.geo = None;
    let mut mercator = plane_tiff();
    mercator.epsg = 3857;
    let mut nad27 = plane_tiff();
    nad27.epsg = 4267;
    let mut lzw = plane_tiff();
    lzw.compression = Some(5);
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("not a DEM", b"GIF89a...".to_vec(), "neither a GeoTIFF"),
        ("BigTIFF", b"II+\0\x08\0\0\0".to_vec(), "BigTIFF"),
        ("truncated", good[..good.len() / 2].to_vec(), "truncated"),
        ("no georeference", no_geo.write(), "no georeferencing"),
        ("web mercator", mercator.write(), "EPSG:3857"),
        ("NAD27", nad27.write(), "geographic EPSG:4267"),
        ("LZW", lzw.write(), "LZW compression"),
    ];
    for (what, bytes, expected) in cases {
        let e = Dem::read(&bytes, "x.tif").expect_err(what).to_string();
        assert!(e.contains(expected), "{what}: {e}");
    }
}

#[test]
fn sizes_given_as_huge_floats_are_refused_not_overflowed() {
    // Found by fuzz/fuzz_targets/dem.rs: ImageWidth as a FLOAT of 1e30 saturated to
    // usize::MAX, and width x height overflowed. Tags are sorted: entry 0 is ImageWidth.
    let mut bytes = plane_tiff().write();
    let at = u32::from_le_bytes(bytes[4..8].try_into().unwrap()) as usize + 2;
    assert_eq!(u16::from_le_bytes(bytes[at..at + 2].try_into().unwrap()), 256);
    bytes[at + 2..at + 4].copy_from_slice(&11u16.to_le_bytes());
    bytes[at + 8..at + 12].copy_from_slice(&1e30f32.to_bits().to_le_bytes());
    let e = Dem::read(&bytes, "x.tif").unwrap_err().to_string();
    assert!(e.contains("18446744073709551615 x 50 pixels (expected 1 to 25000000 pixels)"), "{e}");
}

#[test]
fn the_fuzz_seeds_are_valid_dems() {
    // The seed corpus of fuzz/fuzz_targets/dem.rs: small grids (a fuzzer mutates every byte
    // of a small file more often) in each layout the reader reads. The target takes the
    // file name from the first byte: 0 is `dem.tif`.
    let small = || {
        Spec::plane(8, 6, [0.01, 0.01, LON0, LAT0 + 0.06], |lon, lat| {
            10.0 + 1000.0 * (lon - LON0) + 500.0 * (lat - LAT0)
        })
    };
    let mut int16_be = small();
    (int16_be.int16, int16_be.big_endian) = (true, true);
    let mut deflate = small();
    (deflate.int16, deflate.deflate) = (true, true);
    let mut nodata = small();
    nodata.values[10] = -9999.0;
    nodata.nodata = Some("-9999");
    let (e0, n0) = utm_forward(60.03, 24.05, 35, true);
    let mut utm = Spec::plane(6, 6, [400.0, 400.0, (e0 - 1200.0).round(), (n0 + 1200.0).round()], |x, _| x * 1e-4);
    utm.epsg = 32635;
    let seeds: Vec<(&str, Vec<u8>)> = [
        ("float.tif", small()),
        ("int16-be.tif", int16_be),
        ("deflate.tif", deflate),
        ("nodata.tif", nodata),
        ("utm.tif", utm),
    ]
    .into_iter()
    .map(|(name, spec)| (name, [vec![0u8], spec.write()].concat()))
    .collect();
    for (name, bytes) in &seeds {
        let dem = Dem::read(&bytes[1..], "dem.tif").unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(dem.elevation_m(60.03, 24.05).is_some() || *name == "nodata.tif", "{name}");
    }
    crate::fuzz::write_seeds("dem", &seeds);
}

#[test]
fn arbitrary_bytes_never_panic() {
    let good = plane_tiff().write();
    for n in (0..good.len()).step_by(7) {
        let _ = Dem::read(&good[..n], "x.tif");
    }
    // Flip bytes of the header and IFD (the end of the file) more than pixel data.
    let n = good.len();
    let pick = |r: u64| if r & 1 == 0 { (r >> 8) as usize % 8 } else { n - 1 - (r >> 8) as usize % 300 };
    for bytes in crate::fuzz::mutations(&good, 2000, 0x9e37_79b9_7f4a_7c15, pick) {
        if let Ok(dem) = Dem::read(&bytes, "x.tif") {
            let _ = dem.elevation_m(60.02, 24.05);
        }
    }
}
