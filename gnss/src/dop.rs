//! Dilution of precision: how the geometry of the satellites a receiver uses magnifies its
//! range errors into position and clock errors.
//!
//! With the unit lines of sight `u_i` (local ENU, receiver to satellite), the geometry
//! matrix has rows `[-u_i, 1]` (the partial derivatives of the pseudoranges by position and
//! by the receiver clock in metres); `Q = (GᵀG)⁻¹`. Then GDOP = √tr Q,
//! PDOP = √(Q_ee + Q_nn + Q_uu), HDOP = √(Q_ee + Q_nn), VDOP = √Q_uu, TDOP = √Q_tt.
//!
//! One clock for all systems, as most DOP figures are given (a receiver mixing systems
//! also estimates their time offsets; that adds a column per system).

use nalgebra::{Matrix4, Vector4};

/// The dilutions of precision of one satellite set.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
#[serde(rename_all = "camelCase")]
pub struct Dop {
    pub gdop: f64,
    pub pdop: f64,
    pub hdop: f64,
    pub vdop: f64,
    pub tdop: f64,
}

impl Dop {
    /// The DOP of the satellites whose unit lines of sight (local ENU) are `units`; `None`
    /// with fewer than four or when the geometry is singular (all in one plane).
    pub fn of(units: &[[f64; 3]]) -> Option<Self> {
        if units.len() < 4 {
            return None;
        }
        let mut normal = Matrix4::zeros();
        for u in units {
            let row = Vector4::new(-u[0], -u[1], -u[2], 1.0);
            normal += row * row.transpose();
        }
        let q = normal.try_inverse()?;
        let d = |k: usize| q[(k, k)];
        let ok = (0..4).all(|k| d(k).is_finite() && d(k) > 0.0);
        ok.then(|| Self {
            gdop: (d(0) + d(1) + d(2) + d(3)).sqrt(),
            pdop: (d(0) + d(1) + d(2)).sqrt(),
            hdop: (d(0) + d(1)).sqrt(),
            vdop: d(2).sqrt(),
            tdop: d(3).sqrt(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit(az_deg: f64, el_deg: f64) -> [f64; 3] {
        let (az, el) = (az_deg.to_radians(), el_deg.to_radians());
        [el.cos() * az.sin(), el.cos() * az.cos(), el.sin()]
    }

    /// The textbook case: one satellite at the zenith and three 120 degrees apart on the
    /// horizon, whose DOPs have a closed form.
    #[test]
    fn a_zenith_and_three_horizon_satellites_give_the_closed_form_dops() {
        let units = [unit(0.0, 90.0), unit(0.0, 0.0), unit(120.0, 0.0), unit(240.0, 0.0)];
        let dop = Dop::of(&units).expect("a full geometry");
        // GᵀG: ee = nn = 3/2; uu = 1, ut = -1, tt = 4 (the zenith row couples up and clock).
        // Its up/clock block [[1, -1], [-1, 4]] inverts to [[4, 1], [1, 1]] / 3.
        assert!((dop.hdop - (4.0_f64 / 3.0).sqrt()).abs() < 1e-12, "{dop:?}");
        assert!((dop.vdop - (4.0_f64 / 3.0).sqrt()).abs() < 1e-12, "{dop:?}");
        assert!((dop.tdop - (1.0_f64 / 3.0).sqrt()).abs() < 1e-12, "{dop:?}");
        assert!((dop.gdop.powi(2) - (dop.pdop.powi(2) + dop.tdop.powi(2))).abs() < 1e-12);
    }

    #[test]
    fn fewer_than_four_or_a_flat_geometry_has_no_dop() {
        assert_eq!(Dop::of(&[unit(0.0, 90.0), unit(0.0, 10.0), unit(120.0, 10.0)]), None);
        // Four satellites on the horizon: up and clock cannot be told apart.
        let flat = [unit(0.0, 0.0), unit(90.0, 0.0), unit(180.0, 0.0), unit(270.0, 0.0)];
        assert_eq!(Dop::of(&flat), None);
    }

    #[test]
    fn satellites_low_in_one_quarter_of_the_sky_dilute_more_than_spread_ones() {
        let spread = [unit(0.0, 80.0), unit(0.0, 20.0), unit(120.0, 20.0), unit(240.0, 20.0), unit(60.0, 45.0)];
        let canyon = [unit(0.0, 80.0), unit(10.0, 60.0), unit(350.0, 55.0), unit(180.0, 70.0), unit(5.0, 40.0)];
        let (a, b) = (Dop::of(&spread).unwrap(), Dop::of(&canyon).unwrap());
        assert!(b.hdop > 2.0 * a.hdop, "{a:?} vs {b:?}");
    }
}
