//! WGS84 geodesy: geodetic (lat/lon/alt) <-> ECEF <-> local ENU/NED.
//!
//! Every component shares one local frame per run: **ENU** (x east, y north, z up, metres)
//! with its origin at `spec.origin` on the WGS84 ellipsoid height given there. MAVLink
//! speaks **NED** (x north, y east, z down); [`Enu::to_ned`] converts.
//!
//! The conversions are exact (no flat-earth approximation): geodetic -> ECEF is closed
//! form, ECEF -> geodetic uses Heikkinen's closed-form solution (sub-millimetre for any
//! point near the Earth's surface), ECEF -> ENU is the rotation at the origin.
//!
//! Altitudes here are heights above the WGS84 ellipsoid. We treat them as MSL: the geoid
//! offset (tens of metres) is constant over a city-sized world and cancels in every
//! relative quantity the simulator uses.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// WGS84 semi-major axis, metres.
pub const WGS84_A_M: f64 = 6_378_137.0;
/// WGS84 flattening (dimensionless).
pub const WGS84_F: f64 = 1.0 / 298.257_223_563;
/// WGS84 semi-minor axis, metres: b = a (1 - f).
pub const WGS84_B_M: f64 = WGS84_A_M * (1.0 - WGS84_F);
/// First eccentricity squared: e^2 = f (2 - f).
pub const WGS84_E2: f64 = WGS84_F * (2.0 - WGS84_F);

/// A geodetic position: latitude and longitude in degrees (WGS84), altitude in metres MSL.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "camelCase")]
pub struct GeoPoint {
    pub latitude_deg: f64,
    pub longitude_deg: f64,
    pub altitude_msl_m: f64,
}

/// A local position in the run's ENU frame, metres.
#[derive(Clone, Copy, Debug, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "camelCase")]
pub struct Enu {
    /// East of the origin, metres.
    pub east_m: f64,
    /// North of the origin, metres.
    pub north_m: f64,
    /// Up from the origin's altitude, metres.
    pub up_m: f64,
}

/// A local position in NED (north, east, down), metres: MAVLink's `LOCAL_POSITION_NED` frame.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Ned {
    pub north_m: f64,
    pub east_m: f64,
    pub down_m: f64,
}

impl Enu {
    pub const fn new(east_m: f64, north_m: f64, up_m: f64) -> Self {
        Self { east_m, north_m, up_m }
    }

    /// Same point in NED axes.
    pub fn to_ned(self) -> Ned {
        Ned { north_m: self.north_m, east_m: self.east_m, down_m: -self.up_m }
    }

    /// Horizontal distance from the origin, metres.
    pub fn horizontal_norm_m(self) -> f64 {
        self.east_m.hypot(self.north_m)
    }
}

impl Ned {
    pub fn to_enu(self) -> Enu {
        Enu { east_m: self.east_m, north_m: self.north_m, up_m: -self.down_m }
    }
}

/// Earth-centred, Earth-fixed Cartesian coordinates, metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ecef {
    pub x_m: f64,
    pub y_m: f64,
    pub z_m: f64,
}

impl GeoPoint {
    pub const fn new(latitude_deg: f64, longitude_deg: f64, altitude_msl_m: f64) -> Self {
        Self { latitude_deg, longitude_deg, altitude_msl_m }
    }

    /// Geodetic -> ECEF (closed form). N is the prime-vertical radius of curvature.
    pub fn to_ecef(self) -> Ecef {
        let (lat, lon) = (self.latitude_deg.to_radians(), self.longitude_deg.to_radians());
        let h = self.altitude_msl_m;
        let n = WGS84_A_M / (1.0 - WGS84_E2 * lat.sin().powi(2)).sqrt();
        Ecef {
            x_m: (n + h) * lat.cos() * lon.cos(),
            y_m: (n + h) * lat.cos() * lon.sin(),
            z_m: (n * (1.0 - WGS84_E2) + h) * lat.sin(),
        }
    }
}

impl Ecef {
    /// ECEF -> geodetic with Heikkinen's closed form (1982), as given by Zhu (1994).
    pub fn to_geodetic(self) -> GeoPoint {
        let (a, b, e2) = (WGS84_A_M, WGS84_B_M, WGS84_E2);
        let ep2 = (a * a - b * b) / (b * b);
        let (x, y, z) = (self.x_m, self.y_m, self.z_m);
        let p = x.hypot(y);
        let f = 54.0 * b * b * z * z;
        let g = p * p + (1.0 - e2) * z * z - e2 * (a * a - b * b);
        let c = e2 * e2 * f * p * p / (g * g * g);
        let s = (1.0 + c + (c * c + 2.0 * c).sqrt()).cbrt();
        let k = s + 1.0 + 1.0 / s;
        let pp = f / (3.0 * k * k * g * g);
        let q = (1.0 + 2.0 * e2 * e2 * pp).sqrt();
        let r0 = -(pp * e2 * p) / (1.0 + q)
            + (0.5 * a * a * (1.0 + 1.0 / q) - pp * (1.0 - e2) * z * z / (q * (1.0 + q)) - 0.5 * pp * p * p)
                .max(0.0)
                .sqrt();
        let u = ((p - e2 * r0).powi(2) + z * z).sqrt();
        let v = ((p - e2 * r0).powi(2) + (1.0 - e2) * z * z).sqrt();
        let z0 = b * b * z / (a * v);
        GeoPoint {
            latitude_deg: (z + ep2 * z0).atan2(p).to_degrees(),
            longitude_deg: y.atan2(x).to_degrees(),
            altitude_msl_m: u * (1.0 - b * b / (a * v)),
        }
    }
}

/// The run's local tangent frame at `origin`: converts geodetic positions to ENU and back.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LocalFrame {
    origin: GeoPoint,
    origin_ecef: Ecef,
    sin_lat: f64,
    cos_lat: f64,
    sin_lon: f64,
    cos_lon: f64,
}

impl LocalFrame {
    pub fn new(origin: GeoPoint) -> Self {
        let (lat, lon) = (origin.latitude_deg.to_radians(), origin.longitude_deg.to_radians());
        Self {
            origin,
            origin_ecef: origin.to_ecef(),
            sin_lat: lat.sin(),
            cos_lat: lat.cos(),
            sin_lon: lon.sin(),
            cos_lon: lon.cos(),
        }
    }

    pub fn origin(&self) -> GeoPoint {
        self.origin
    }

    /// Geodetic -> ENU: rotate the ECEF offset from the origin into east/north/up axes.
    pub fn to_enu(&self, p: GeoPoint) -> Enu {
        self.ecef_to_enu(p.to_ecef())
    }

    /// Earth-fixed -> ENU: the offset from the origin, rotated into the tangent plane's
    /// east/north/up axes (satellites, thousands of kilometres away, included).
    pub fn ecef_to_enu(&self, e: Ecef) -> Enu {
        let (dx, dy, dz) = (e.x_m - self.origin_ecef.x_m, e.y_m - self.origin_ecef.y_m, e.z_m - self.origin_ecef.z_m);
        self.rotate_to_enu(dx, dy, dz)
    }

    /// An Earth-fixed vector (a velocity, an offset) in the tangent plane's axes.
    pub fn rotate_to_enu(&self, dx: f64, dy: f64, dz: f64) -> Enu {
        Enu {
            east_m: -self.sin_lon * dx + self.cos_lon * dy,
            north_m: -self.sin_lat * self.cos_lon * dx - self.sin_lat * self.sin_lon * dy + self.cos_lat * dz,
            up_m: self.cos_lat * self.cos_lon * dx + self.cos_lat * self.sin_lon * dy + self.sin_lat * dz,
        }
    }

    /// ENU -> geodetic: the transposed rotation back to ECEF, then ECEF -> geodetic.
    pub fn to_geodetic(&self, p: Enu) -> GeoPoint {
        let (e, n, u) = (p.east_m, p.north_m, p.up_m);
        let dx = -self.sin_lon * e - self.sin_lat * self.cos_lon * n + self.cos_lat * self.cos_lon * u;
        let dy = self.cos_lon * e - self.sin_lat * self.sin_lon * n + self.cos_lat * self.sin_lon * u;
        let dz = self.cos_lat * n + self.sin_lat * u;
        Ecef { x_m: self.origin_ecef.x_m + dx, y_m: self.origin_ecef.y_m + dy, z_m: self.origin_ecef.z_m + dz }
            .to_geodetic()
    }

    /// Lat/lon at the origin's altitude -> horizontal ENU (east, north), metres. The small
    /// `up` component caused by Earth curvature (~0.08 m at 1 km) is dropped: horizontal
    /// geometry (zones, homes, world extent) is 2-D in the local plane.
    pub fn to_plane(&self, latitude_deg: f64, longitude_deg: f64) -> (f64, f64) {
        let enu = self.to_enu(GeoPoint::new(latitude_deg, longitude_deg, self.origin.altitude_msl_m));
        (enu.east_m, enu.north_m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn ecef_of_reference_points_matches_wgs84_constants() {
        let e = GeoPoint::new(0.0, 0.0, 0.0).to_ecef();
        assert!(close(e.x_m, 6_378_137.0, 1e-6) && close(e.y_m, 0.0, 1e-6) && close(e.z_m, 0.0, 1e-6));
        let pole = GeoPoint::new(90.0, 0.0, 0.0).to_ecef();
        assert!(close(pole.z_m, 6_356_752.314_245, 1e-3), "{pole:?}");
        let e = GeoPoint::new(0.0, 90.0, 100.0).to_ecef();
        assert!(close(e.y_m, 6_378_237.0, 1e-6) && close(e.x_m, 0.0, 1e-6));
    }

    #[test]
    fn ecef_matches_published_example() {
        // MATLAB geodetic2ecef documentation example (Paris, 48.8562 N 2.3508 E, 67.4 m):
        // 4.2010e6, 1.7246e5, 4.7801e6 m (4-5 significant digits published).
        let e = GeoPoint::new(48.8562, 2.3508, 67.4).to_ecef();
        assert!(close(e.x_m, 4.2010e6, 100.0), "{e:?}");
        assert!(close(e.y_m, 1.7246e5, 10.0), "{e:?}");
        assert!(close(e.z_m, 4.7801e6, 100.0), "{e:?}");
    }

    #[test]
    fn ecef_geodetic_round_trip_is_sub_millimetre() {
        for &(lat, lon, h) in &[
            (41.8796, -87.6237, 181.0),
            (-33.8688, 151.2093, 58.0),
            (89.9, 10.0, 5000.0),
            (-89.5, -170.0, -50.0),
            (0.0, 179.999, 8848.0),
        ] {
            let back = GeoPoint::new(lat, lon, h).to_ecef().to_geodetic();
            assert!(close(back.latitude_deg, lat, 1e-9), "{lat} -> {back:?}");
            assert!(close(back.longitude_deg, lon, 1e-9), "{lon} -> {back:?}");
            assert!(close(back.altitude_msl_m, h, 1e-3), "{h} -> {back:?}");
        }
    }

    #[test]
    fn one_degree_of_latitude_matches_the_textbook_table() {
        // Length of 1 degree of latitude: 110 574 m at the equator, 111 132 m at 45 deg,
        // 111 694 m at the pole (centred on each latitude).
        for &(lat, metres) in &[(0.0, 110_574.0), (45.0, 111_132.0), (89.5, 111_694.0)] {
            let frame = LocalFrame::new(GeoPoint::new(lat, 0.0, 0.0));
            let a = frame.to_plane(lat - 0.5, 0.0).1;
            let b = frame.to_plane(lat + 0.5, 0.0).1;
            // The chord is shorter than the arc by ~arc^3/(24 R^2) ~ 1.2 m for one degree.
            assert!(close(b - a, metres, 3.0), "lat {lat}: {}", b - a);
        }
    }

    #[test]
    fn one_degree_of_longitude_at_the_equator_is_a_pi_over_180() {
        let frame = LocalFrame::new(GeoPoint::new(0.0, 0.0, 0.0));
        let (east, north) = frame.to_plane(0.0, 0.001);
        assert!(close(east, 111.319_490_8, 1e-4), "{east}");
        assert!(close(north, 0.0, 1e-6));
    }

    #[test]
    fn enu_round_trip_and_axes() {
        let frame = LocalFrame::new(GeoPoint::new(41.8796, -87.6237, 181.0));
        let p = Enu::new(1234.5, -987.25, 120.0);
        let g = frame.to_geodetic(p);
        assert!(g.longitude_deg > -87.6237 && g.latitude_deg < 41.8796, "east is +lon, south is -lat");
        let back = frame.to_enu(g);
        assert!(close(back.east_m, p.east_m, 1e-6) && close(back.north_m, p.north_m, 1e-6));
        assert!(close(back.up_m, p.up_m, 1e-6));
        let ned = p.to_ned();
        assert_eq!((ned.north_m, ned.east_m, ned.down_m), (-987.25, 1234.5, -120.0));
        assert_eq!(ned.to_enu(), p);
    }
}
