//! The undisturbed wind: the neutral log law over the city's roughness, as a factor of the
//! wind at the reference height (the same law as the flight's mean wind,
//! `sadesim_engine::env::MeanWind`).

/// `u(h) / u(h_ref) = ln(h / z0) / ln(h_ref / z0)`, with `h` clamped to at least `z0`
/// (zero in the roughness sublayer), heights above the local ground in metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LogProfile {
    /// Roughness length, metres.
    pub roughness_length_m: f64,
    /// Height where the factor is 1, metres.
    pub reference_height_m: f64,
}

/// The fields are factors of the wind at 10 m above ground (WMO's reference height) in a
/// city (z0 = 1 m, Wieringa 1992): the defaults of the flight's mean wind.
pub const FIELD_PROFILE: LogProfile = LogProfile { roughness_length_m: 1.0, reference_height_m: 10.0 };

impl LogProfile {
    pub fn factor(&self, height_agl_m: f64) -> f64 {
        let z0 = self.roughness_length_m;
        let h_ref = self.reference_height_m.max(z0 + 1.0);
        (height_agl_m.max(z0) / z0).ln() / (h_ref / z0).ln()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_factor_is_one_at_the_reference_height_and_zero_in_the_roughness_layer() {
        assert!((FIELD_PROFILE.factor(10.0) - 1.0).abs() < 1e-12);
        assert_eq!(FIELD_PROFILE.factor(0.5), 0.0);
        assert!((FIELD_PROFILE.factor(100.0) - 2.0).abs() < 1e-12, "ln 100 / ln 10");
    }
}
