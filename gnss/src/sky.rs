//! How a receiver sees a satellite: azimuth, elevation and range.

use sadesim_crds::geo::{Ecef, GeoPoint, LocalFrame};

/// A satellite seen from a receiver.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LookAngles {
    /// Degrees clockwise from true north, [0, 360).
    pub azimuth_deg: f64,
    /// Degrees above the receiver's tangent plane (the WGS84 ellipsoid's normal is up).
    pub elevation_deg: f64,
    /// Metres from the receiver's antenna.
    pub range_m: f64,
    /// Unit line of sight from the receiver to the satellite, local ENU.
    pub unit_enu: [f64; 3],
}

impl LookAngles {
    /// The satellite at `satellite` seen from a receiver at `receiver` (WGS84, height
    /// above the ellipsoid in `altitude_msl_m`: the geoid's undulation, tens of metres,
    /// changes an elevation by microdegrees at GNSS distances).
    pub fn of(receiver: GeoPoint, satellite: Ecef) -> Self {
        let enu = LocalFrame::new(receiver).ecef_to_enu(satellite);
        let v = [enu.east_m, enu.north_m, enu.up_m];
        let range_m = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let unit_enu = v.map(|c| c / range_m);
        let elevation_deg = unit_enu[2].clamp(-1.0, 1.0).asin().to_degrees();
        let azimuth_deg = v[0].atan2(v[1]).to_degrees().rem_euclid(360.0);
        Self { azimuth_deg, elevation_deg, range_m, unit_enu }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_point_straight_up_is_at_the_zenith_and_one_east_is_at_azimuth_90() {
        let here = GeoPoint::new(60.17, 24.94, 0.0);
        let up = GeoPoint::new(60.17, 24.94, 20_000_000.0).to_ecef();
        let look = LookAngles::of(here, up);
        assert!((look.elevation_deg - 90.0).abs() < 1e-6 && (look.range_m - 20_000_000.0).abs() < 1e-3);
        let frame = LocalFrame::new(here);
        let east = frame.to_geodetic(sadesim_crds::geo::Enu::new(1000.0, 0.0, 0.0)).to_ecef();
        let look = LookAngles::of(here, east);
        assert!((look.azimuth_deg - 90.0).abs() < 1e-6 && look.elevation_deg.abs() < 1e-6, "{look:?}");
    }
}
