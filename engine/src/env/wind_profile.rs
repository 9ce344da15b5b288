//! Mean wind: logarithmic height profile and meteorological direction.

use nalgebra::Vector3;

/// Aerodynamic roughness length of a city centre, metres (Davenport classification, as
/// revised by Wieringa 1992: "chaotic" / city centres z0 >= 1 m).
pub const URBAN_ROUGHNESS_LENGTH_M: f64 = 1.0;

/// Meteorological reference height of wind measurements, metres (WMO).
pub const DEFAULT_REFERENCE_HEIGHT_M: f64 = 10.0;

/// The reference height is kept at least this far above `z0`, metres, so the profile's
/// denominator ln(h_ref / z0) stays well away from zero.
const MIN_REFERENCE_ABOVE_Z0_M: f64 = 1.0;

/// Mean (time-averaged) wind over flat rough terrain.
///
/// # Caveats
/// No zero-plane displacement and no building wakes: a building-aware factor refines this.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeanWind {
    /// Speed at `reference_height_m` above ground, m/s.
    pub speed_ref_mps: f64,
    /// Direction the wind blows *from*, degrees clockwise from true north.
    pub direction_from_deg: f64,
    /// Height of `speed_ref_mps` above ground, metres.
    pub reference_height_m: f64,
    /// Roughness length z0, metres: the height where the log profile reaches zero.
    pub roughness_length_m: f64,
}

impl MeanWind {
    /// Mean wind in a city (z0 = 1 m) from the spec's speed, direction and reference height.
    pub fn urban(speed_ref_mps: f64, direction_from_deg: f64, reference_height_m: Option<f64>) -> Self {
        Self {
            speed_ref_mps,
            direction_from_deg,
            reference_height_m: reference_height_m.unwrap_or(DEFAULT_REFERENCE_HEIGHT_M),
            roughness_length_m: URBAN_ROUGHNESS_LENGTH_M,
        }
    }

    /// Horizontal speed at `height_agl_m`, m/s, by the neutral log law
    ///
    /// u(h) = u_ref · ln(h / z0) / ln(h_ref / z0)        [m/s; h, h_ref, z0 in metres]
    ///
    /// with h clamped to >= z0, so the speed is 0 at and below z0 (inside the roughness
    /// sublayer) and never negative.
    pub fn speed_at_mps(&self, height_agl_m: f64) -> f64 {
        let z0 = self.roughness_length_m;
        let h_ref = self.reference_height_m.max(z0 + MIN_REFERENCE_ABOVE_Z0_M);
        let h = height_agl_m.max(z0);
        self.speed_ref_mps * (h / z0).ln() / (h_ref / z0).ln()
    }

    /// Unit vector, world ENU, of where the air moves *to* (opposite of "from").
    ///
    /// A wind from bearing θ (clockwise from north) comes from (sin θ, cos θ) in (east,
    /// north), so it blows along -(sin θ, cos θ): from 270° (west) it blows toward +east.
    pub fn downwind_enu(&self) -> Vector3<f64> {
        let theta = self.direction_from_deg.to_radians();
        Vector3::new(-theta.sin(), -theta.cos(), 0.0)
    }

    /// Mean wind velocity at `height_agl_m`, world ENU, m/s (horizontal).
    pub fn velocity_enu_mps(&self, height_agl_m: f64) -> Vector3<f64> {
        self.downwind_enu() * self.speed_at_mps(height_agl_m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn profile_follows_the_log_law_and_vanishes_at_and_below_z0() {
        let wind = MeanWind::urban(8.0, 270.0, None);
        // Hand-computed u(h) = 8 ln(h) / ln(10) for z0 = 1 m, h_ref = 10 m.
        for (h, expected) in [(10.0, 8.0), (100.0, 16.0), (2.0, 2.408_24), (50.0, 13.591_76), (1.5, 1.408_73)] {
            let got = wind.speed_at_mps(h);
            assert!(close(got, expected, 1e-4), "h {h}: {got} vs {expected}");
        }
        for h in [1.0, 0.5, 0.0, -3.0] {
            assert_eq!(wind.speed_at_mps(h), 0.0, "h {h}");
        }
        // Monotonic above z0.
        let speeds: Vec<f64> = (1..200).map(|k| wind.speed_at_mps(f64::from(k) * 0.5)).collect();
        assert!(speeds.windows(2).all(|p| p[1] >= p[0]));
    }

    #[test]
    fn reference_height_is_honoured() {
        let wind = MeanWind::urban(5.0, 0.0, Some(30.0));
        assert!(close(wind.speed_at_mps(30.0), 5.0, 1e-12));
        // A reference at z0 itself is degenerate; it is raised to z0 + 1 m, not a NaN.
        let degenerate = MeanWind::urban(5.0, 0.0, Some(1.0));
        assert!(degenerate.speed_at_mps(20.0).is_finite());
    }

    #[test]
    fn direction_is_where_the_wind_comes_from() {
        let from_west = MeanWind::urban(10.0, 270.0, None).velocity_enu_mps(10.0);
        assert!(close(from_west.x, 10.0, 1e-9) && close(from_west.y, 0.0, 1e-9), "{from_west}");
        let from_north = MeanWind::urban(10.0, 0.0, None).velocity_enu_mps(10.0);
        assert!(close(from_north.x, 0.0, 1e-9) && close(from_north.y, -10.0, 1e-9), "{from_north}");
        let from_south_east = MeanWind::urban(10.0, 135.0, None).velocity_enu_mps(10.0);
        assert!(from_south_east.x < 0.0 && from_south_east.y > 0.0, "{from_south_east}");
        assert_eq!(from_west.z, 0.0);
    }
}
