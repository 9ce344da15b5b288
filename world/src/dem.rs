//! Terrain from a digital elevation model: a GeoTIFF (geographic WGS84 or WGS84 UTM) or an
//! SRTM `.hgt` tile, decoded from bytes and sampled bilinearly at WGS84 positions.
//!
//! Pure: the caller reads the file. Elevations are metres as the file gives them (SRTM and
//! most national DEMs: above the geoid, i.e. mean sea level), the frame of
//! `spec.origin.altitudeMslM`.
//!
//! Sampling: a pixel's value sits at its centre (GeoTIFF `PixelIsArea`, the default) or at
//! its corner (`PixelIsPoint`, and SRTM); between values the surface is bilinear, and a
//! position outside the grid or next to a no-data value has no elevation.

mod tiff;

#[cfg(test)]
mod tests;

use sadesim_crds::geo::{Enu, LocalFrame};

/// The DEM's coordinate reference system.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Crs {
    /// EPSG:4326: x = longitude, y = latitude, degrees.
    Geographic,
    /// WGS84 / UTM zone `zone` (EPSG:326zz north, 327zz south): x = easting, y = northing,
    /// metres.
    Utm { zone: u8, north: bool },
}

impl std::fmt::Display for Crs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Crs::Geographic => write!(f, "EPSG:4326 (WGS84 latitude/longitude)"),
            Crs::Utm { zone, north: true } => write!(f, "EPSG:{} (WGS84 / UTM zone {zone}N)", 32600 + u32::from(*zone)),
            Crs::Utm { zone, north: false } => {
                write!(f, "EPSG:{} (WGS84 / UTM zone {zone}S)", 32700 + u32::from(*zone))
            }
        }
    }
}

/// Why a DEM cannot be the world's terrain. The caller adds the file's name (the messages
/// do not repeat it).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum DemError {
    #[error("not a readable DEM: {0}")]
    Malformed(String),
    #[error("not supported: {0}")]
    Unsupported(String),
    #[error("no georeferencing: {0}")]
    NotGeoreferenced(String),
    #[error("unsupported coordinate reference system {0}")]
    UnsupportedCrs(String),
    /// A point of the world square has no elevation (outside the grid or no-data).
    #[error(
        "the DEM does not cover world.extentM {extent_m} m around the origin: no elevation at latitude {latitude_deg:.6}, longitude {longitude_deg:.6} ({what}); use a larger DEM or a smaller extent"
    )]
    NotCovering { extent_m: f64, latitude_deg: f64, longitude_deg: f64, what: &'static str },
}

/// One band of elevations on a north-up grid.
#[derive(Clone, Debug, PartialEq)]
pub struct Dem {
    width: usize,
    height: usize,
    /// Row-major, row 0 at the top (north); NaN where the file has no data.
    values: Vec<f32>,
    /// `[x0, y0, dx, dy]`: CRS coordinates of the value of pixel (0, 0); column `i`, row
    /// `j` is at `(x0 + i dx, y0 - j dy)`.
    geo: [f64; 4],
    crs: Crs,
    /// SHA-256 of the file's bytes, hex (part of the asset cache key).
    source_sha256: String,
}

impl Dem {
    fn new(
        width: usize,
        height: usize,
        mut values: Vec<f32>,
        geo: [f64; 4],
        crs: Crs,
        nodata: Option<f64>,
    ) -> Result<Self, DemError> {
        if !geo.iter().all(|v| v.is_finite()) || geo[2] <= 0.0 || geo[3] <= 0.0 {
            return Err(DemError::NotGeoreferenced(format!("unusable grid origin or pixel size {geo:?}")));
        }
        if width < 2 || height < 2 {
            return Err(DemError::Malformed(format!(
                "{width} x {height} pixels: at least 2 x 2 are needed to interpolate"
            )));
        }
        if let Some(nodata) = nodata {
            for v in &mut values {
                if f64::from(*v) == nodata || (*v - nodata as f32).abs() < f32::EPSILON * nodata.abs() as f32 {
                    *v = f32::NAN;
                }
            }
        }
        Ok(Self { width, height, values, geo, crs, source_sha256: String::new() })
    }

    /// Reads a DEM: a GeoTIFF (by its magic bytes) or an SRTM tile (by a name like
    /// `N60E024.hgt`).
    ///
    /// # Errors
    /// [`DemError`]: not a TIFF or `.hgt`, an unsupported layout or CRS, no georeferencing.
    pub fn read(bytes: &[u8], file_name: &str) -> Result<Self, DemError> {
        let base = file_name.rsplit(['/', '\\']).next().unwrap_or(file_name);
        let mut dem = if bytes.starts_with(b"II") || bytes.starts_with(b"MM") {
            tiff::read(bytes)?
        } else if base.to_ascii_lowercase().ends_with(".hgt") {
            Self::read_hgt(bytes, base)?
        } else {
            return Err(DemError::Malformed(
                "neither a GeoTIFF (no TIFF header) nor an SRTM tile named like N60E024.hgt".into(),
            ));
        };
        dem.source_sha256 = sadesim_crds::parts::sha256_hex(bytes);
        Ok(dem)
    }

    /// SHA-256 of the file's bytes, hex.
    pub fn source_sha256(&self) -> &str {
        &self.source_sha256
    }

    /// Reads an SRTM tile: 1201 x 1201 (3 arc-seconds) or 3601 x 3601 (1 arc-second)
    /// big-endian 16-bit metres, -32768 for voids; `name` (`N60E024.hgt`) gives its
    /// south-west corner.
    ///
    /// Errors: a name that is not `[NS]dd[EW]ddd.hgt`, or a size that is neither grid.
    fn read_hgt(bytes: &[u8], name: &str) -> Result<Self, DemError> {
        let upper = name.to_ascii_uppercase();
        let parse = || -> Option<(f64, f64)> {
            let b = upper.as_bytes();
            let lat: f64 = upper.get(1..3)?.parse().ok()?;
            let lon: f64 = upper.get(4..7)?.parse().ok()?;
            let lat = match b.first()? {
                b'N' => lat,
                b'S' => -lat,
                _ => return None,
            };
            let lon = match b.get(3)? {
                b'E' => lon,
                b'W' => -lon,
                _ => return None,
            };
            Some((lat, lon))
        };
        let (lat, lon) = parse().ok_or_else(|| {
            DemError::NotGeoreferenced(
                "an SRTM tile is named by its south-west corner, e.g. N60E024.hgt, and this name gives none".into(),
            )
        })?;
        let side = match bytes.len() {
            n if n == 1201 * 1201 * 2 => 1201,
            n if n == 3601 * 3601 * 2 => 3601,
            n => {
                return Err(DemError::Malformed(format!(
                    "{n} bytes; an SRTM tile has {} (3 arc-seconds) or {} (1 arc-second)",
                    1201 * 1201 * 2,
                    3601 * 3601 * 2
                )));
            }
        };
        let values = bytes.chunks_exact(2).map(|b| f32::from(i16::from_be_bytes([b[0], b[1]]))).collect();
        let step = 1.0 / (side - 1) as f64;
        Self::new(side, side, values, [lon, lat + 1.0, step, step], Crs::Geographic, Some(-32768.0))
    }

    pub fn crs(&self) -> Crs {
        self.crs
    }

    /// `(width, height)` in pixels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Elevation at a WGS84 position, metres; `None` outside the grid or next to no-data.
    pub fn elevation_m(&self, latitude_deg: f64, longitude_deg: f64) -> Option<f64> {
        let (fi, fj) = self.pixel(latitude_deg, longitude_deg);
        // Within a millionth of a pixel of the last row or column counts as on it.
        const SNAP: f64 = 1e-6;
        let (w, h) = ((self.width - 1) as f64, (self.height - 1) as f64);
        if !(fi > -SNAP && fj > -SNAP && fi < w + SNAP && fj < h + SNAP) {
            return None;
        }
        let (fi, fj) = (fi.clamp(0.0, w), fj.clamp(0.0, h));
        let (i, j) = ((fi.floor() as usize).min(self.width - 2), (fj.floor() as usize).min(self.height - 2));
        let (u, v) = (fi - i as f64, fj - j as f64);
        let at = |i: usize, j: usize| f64::from(self.values[j * self.width + i]);
        let z = (1.0 - u) * (1.0 - v) * at(i, j)
            + u * (1.0 - v) * at(i + 1, j)
            + (1.0 - u) * v * at(i, j + 1)
            + u * v * at(i + 1, j + 1);
        z.is_finite().then_some(z)
    }

    /// Checks that every point of the world square `[-extent, extent]²` around `frame`'s
    /// origin has an elevation (sampled on a 65 x 65 grid, edges included).
    ///
    /// # Errors
    /// [`DemError::NotCovering`] naming the first point without one.
    pub fn check_covers(&self, frame: &LocalFrame, extent_m: f64) -> Result<(), DemError> {
        const N: usize = 64;
        for a in 0..=N {
            for b in 0..=N {
                let e = -extent_m + 2.0 * extent_m * a as f64 / N as f64;
                let n = -extent_m + 2.0 * extent_m * b as f64 / N as f64;
                let p = frame.to_geodetic(Enu { east_m: e, north_m: n, up_m: 0.0 });
                if self.elevation_m(p.latitude_deg, p.longitude_deg).is_none() {
                    let what = if self.inside(p.latitude_deg, p.longitude_deg) {
                        "a no-data value"
                    } else {
                        "outside the grid"
                    };
                    return Err(DemError::NotCovering {
                        extent_m,
                        latitude_deg: p.latitude_deg,
                        longitude_deg: p.longitude_deg,
                        what,
                    });
                }
            }
        }
        Ok(())
    }

    /// Fractional `(column, row)` of a WGS84 position in the grid of values.
    fn pixel(&self, latitude_deg: f64, longitude_deg: f64) -> (f64, f64) {
        let (x, y) = match self.crs {
            Crs::Geographic => (longitude_deg, latitude_deg),
            Crs::Utm { zone, north } => utm_forward(latitude_deg, longitude_deg, zone, north),
        };
        let [x0, y0, dx, dy] = self.geo;
        ((x - x0) / dx, (y0 - y) / dy)
    }

    fn inside(&self, latitude_deg: f64, longitude_deg: f64) -> bool {
        let (fi, fj) = self.pixel(latitude_deg, longitude_deg);
        fi >= 0.0 && fj >= 0.0 && fi <= (self.width - 1) as f64 && fj <= (self.height - 1) as f64
    }
}

/// WGS84 latitude/longitude to UTM `(easting, northing)` metres in `zone`: the transverse
/// Mercator projection by Krüger's series to third order in n (Karney 2011, "Transverse
/// Mercator with an accuracy of a few nanometers"; third order is better than a millimetre
/// within a zone), scale 0.9996, false easting 500 km, false northing 10 000 km south.
pub fn utm_forward(latitude_deg: f64, longitude_deg: f64, zone: u8, north: bool) -> (f64, f64) {
    const A: f64 = 6_378_137.0;
    const F: f64 = 1.0 / 298.257_223_563;
    const K0: f64 = 0.9996;
    let n = F / (2.0 - F);
    let big_a = A / (1.0 + n) * (1.0 + n * n / 4.0 + n.powi(4) / 64.0);
    let alpha = [
        n / 2.0 - 2.0 * n * n / 3.0 + 5.0 * n.powi(3) / 16.0,
        13.0 * n * n / 48.0 - 3.0 * n.powi(3) / 5.0,
        61.0 * n.powi(3) / 240.0,
    ];
    let lon0 = (f64::from(zone) - 1.0) * 6.0 - 180.0 + 3.0;
    let phi = latitude_deg.to_radians();
    let dlon = (longitude_deg - lon0).to_radians();
    let e = 2.0 * n.sqrt() / (1.0 + n);
    let t = (phi.sin().atanh() - e * (e * phi.sin()).atanh()).sinh();
    let xi = t.atan2(dlon.cos());
    let eta = (dlon.sin() / (1.0 + t * t).sqrt()).atanh();
    let (mut x, mut y) = (eta, xi);
    for (j, a) in alpha.iter().enumerate() {
        let k = 2.0 * (j + 1) as f64;
        x += a * (k * xi).cos() * (k * eta).sinh();
        y += a * (k * xi).sin() * (k * eta).cosh();
    }
    (500_000.0 + K0 * big_a * x, if north { 0.0 } else { 10_000_000.0 } + K0 * big_a * y)
}
