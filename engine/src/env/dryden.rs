//! Dryden turbulence, MIL-F-8785C low-altitude model, as exactly discretised filters.
//!
//! Units: the military spec states lengths in feet and speeds in knots or ft/s; every
//! public quantity here is SI (metres, m/s) and the conversion happens in one place,
//! [`DrydenScales::low_altitude`].
//!
//! Spectra (Taylor's frozen turbulence: temporal frequency ω = V · spatial frequency):
//!
//! H_u(s) = σ_u · sqrt(2 T_u) / (1 + T_u s)                       T_u = L_u / V   [s]
//! H_v(s) = σ_v · sqrt(T_v) · (1 + √3 T_v s) / (1 + T_v s)^2      T_v = L_v / V   [s]
//! H_w(s) = σ_w · sqrt(T_w) · (1 + √3 T_w s) / (1 + T_w s)^2      T_w = L_w / V   [s]
//!
//! driven by unit-intensity white noise (E[η(t) η(t')] = δ(t - t')), so each output has
//! variance σ². (MIL-F-8785C writes the gains as σ·sqrt(2L/(πV)) and σ·sqrt(L/(πV)) for
//! noise of spectral density π; same process.) In time nondimensionalised by T the filters
//! no longer depend on V or L, so the state is kept nondimensional with unit-variance
//! output and each step advances it by h = dt / T = dt · V / L. The discretisation is exact
//! (transition matrix and noise covariance integrated in closed form), so statistics hold
//! for any dt and a change of airspeed or height causes no transient.

use nalgebra::Vector3;
use sadesim_crds::environment::Turbulence;
use sadesim_crds::random::Rng;

/// Metres per international foot.
pub const M_PER_FT: f64 = 0.3048;
/// m/s per knot (1 kt = 1852 m/h).
pub const MPS_PER_KT: f64 = 1852.0 / 3600.0;

/// The low-altitude model is stated for 10 ft < h < 1000 ft; heights are clamped to it.
const MIN_HEIGHT_FT: f64 = 10.0;
const MAX_HEIGHT_FT: f64 = 1000.0;

/// Airspeed floor of the filters, m/s: a hovering drone still sees turbulence advected past
/// it, and T = L / V must stay finite.
pub const MIN_AIRSPEED_MPS: f64 = 3.0;

/// W20, the wind speed at 20 ft that sets turbulence intensity, m/s (MIL-F-8785C:
/// light 15 kt, moderate 30 kt, severe 45 kt). `None` for no turbulence.
pub fn wind_speed_at_20ft_mps(level: Turbulence) -> Option<f64> {
    let knots = match level {
        Turbulence::None => return None,
        Turbulence::Light => 15.0,
        Turbulence::Moderate => 30.0,
        Turbulence::Severe => 45.0,
    };
    Some(knots * MPS_PER_KT)
}

/// Intensities and scale lengths of the three components at one height.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DrydenScales {
    /// Longitudinal (along the mean wind), lateral and vertical standard deviations, m/s.
    pub sigma_u_mps: f64,
    pub sigma_v_mps: f64,
    pub sigma_w_mps: f64,
    /// Scale lengths, metres.
    pub length_u_m: f64,
    pub length_v_m: f64,
    pub length_w_m: f64,
}

impl DrydenScales {
    /// MIL-F-8785C low-altitude model (h < 1000 ft), h clamped to [10, 1000] ft:
    ///
    /// L_w = h                                       [ft]
    /// L_u = L_v = h / (0.177 + 0.000823 h)^1.2      [ft, h in ft]
    /// σ_w = 0.1 · W20                               [same unit as W20]
    /// σ_u = σ_v = σ_w / (0.177 + 0.000823 h)^0.4    [h in ft]
    pub fn low_altitude(height_agl_m: f64, w20_mps: f64) -> Self {
        let h_ft = (height_agl_m / M_PER_FT).clamp(MIN_HEIGHT_FT, MAX_HEIGHT_FT);
        let k = 0.177 + 0.000_823 * h_ft; // dimensionless
        let length_uv_m = h_ft / k.powf(1.2) * M_PER_FT;
        let length_w_m = h_ft * M_PER_FT;
        let sigma_w_mps = 0.1 * w20_mps;
        let sigma_uv_mps = sigma_w_mps / k.powf(0.4);
        Self {
            sigma_u_mps: sigma_uv_mps,
            sigma_v_mps: sigma_uv_mps,
            sigma_w_mps,
            length_u_m: length_uv_m,
            length_v_m: length_uv_m,
            length_w_m,
        }
    }
}

/// The three shaping filters of one drone with their own random stream.
#[derive(Clone, Debug)]
pub struct DrydenFilter {
    rng: Rng,
    /// Nondimensional states: u is first order, v and w second order.
    u: f64,
    v: [f64; 2],
    w: [f64; 2],
}

impl DrydenFilter {
    /// Filters started in their stationary distribution (no warm-up transient).
    pub fn new(mut rng: Rng) -> Self {
        let u = rng.normal();
        let v = stationary_second_order(&mut rng);
        let w = stationary_second_order(&mut rng);
        Self { rng, u, v, w }
    }

    /// Advances by `dt_s` at `airspeed_mps` (floored at [`MIN_AIRSPEED_MPS`]) and returns the
    /// gust (u, v, w) in the mean-wind frame, m/s: u along the mean wind, v to its left,
    /// w up. Draws exactly five normals per call, whatever the inputs.
    pub fn step(&mut self, scales: &DrydenScales, airspeed_mps: f64, dt_s: f64) -> Vector3<f64> {
        let v_mps = airspeed_mps.max(MIN_AIRSPEED_MPS);
        let dt_s = dt_s.max(0.0);
        let n: [f64; 5] = std::array::from_fn(|_| self.rng.normal());
        self.u = first_order_step(self.u, dt_s * v_mps / scales.length_u_m, n[0]);
        self.v = second_order_step(self.v, dt_s * v_mps / scales.length_v_m, n[1], n[2]);
        self.w = second_order_step(self.w, dt_s * v_mps / scales.length_w_m, n[3], n[4]);
        Vector3::new(
            scales.sigma_u_mps * self.u,
            scales.sigma_v_mps * second_order_output(self.v),
            scales.sigma_w_mps * second_order_output(self.w),
        )
    }
}

/// x' = -x + √2 η (unit variance), exactly over nondimensional step h:
/// x ← e^{-h} x + sqrt(1 - e^{-2h}) n.
fn first_order_step(x: f64, h: f64, n: f64) -> f64 {
    (-h).exp() * x + (-(-2.0 * h).exp_m1()).sqrt() * n
}

/// State (x1, x2) of (1 + √3 s) / (1 + s)^2 as x1' = -x1 + η, x2' = -x2 + x1,
/// y = √3 x1 + (1 - √3) x2.
fn second_order_output(x: [f64; 2]) -> f64 {
    let sqrt3 = 3.0_f64.sqrt();
    sqrt3 * x[0] + (1.0 - sqrt3) * x[1]
}

/// Exact step: Φ(h) = e^{-h} [[1, 0], [h, 1]]; noise covariance
/// Q = ∫0^h e^{-2τ} [1, τ]ᵀ[1, τ] dτ = [[I0, I1], [I1, I2]], sampled by its Cholesky factor.
fn second_order_step(x: [f64; 2], h: f64, n1: f64, n2: f64) -> [f64; 2] {
    let decay = (-h).exp();
    let [i0, i1, i2] = moments(h);
    let c11 = i0.sqrt();
    let c21 = if c11 > 0.0 { i1 / c11 } else { 0.0 };
    let c22 = (i2 - c21 * c21).max(0.0).sqrt();
    [decay * x[0] + c11 * n1, decay * (h * x[0] + x[1]) + c21 * n1 + c22 * n2]
}

/// Stationary covariance (h → ∞): I0 = 1/2, I1 = 1/4, I2 = 1/4.
fn stationary_second_order(rng: &mut Rng) -> [f64; 2] {
    let (n1, n2) = (rng.normal(), rng.normal());
    let c11 = 0.5_f64.sqrt();
    let c21 = 0.25 / c11;
    let c22 = (0.25 - c21 * c21).sqrt();
    [c11 * n1, c21 * n1 + c22 * n2]
}

/// I_k = ∫0^h τ^k e^{-2τ} dτ for k = 0, 1, 2. Closed forms lose digits for small h, where
/// the series I_k = Σ_n (-2)^n h^(n+k+1) / (n! (n+k+1)) converges fast instead.
fn moments(h: f64) -> [f64; 3] {
    if h >= 0.5 {
        let e = (-2.0 * h).exp();
        return [
            -(-2.0 * h).exp_m1() / 2.0,
            (1.0 - e * (1.0 + 2.0 * h)) / 4.0,
            (2.0 - e * (2.0 + 4.0 * h + 4.0 * h * h)) / 8.0,
        ];
    }
    let mut out = [0.0; 3];
    for (k, slot) in out.iter_mut().enumerate() {
        // term_n = (-2h)^n / n! · h^(k+1); |2h| < 1 so 30 terms reach machine precision.
        let mut power = h.powi(k as i32 + 1);
        for n in 0..30 {
            *slot += power / (n + k + 1) as f64;
            power *= -2.0 * h / (n + 1) as f64;
        }
    }
    out
}

#[cfg(test)]
mod tests;
