//! Control allocation (the mixer), PX4's `control_allocator`: collective thrust and body
//! torques → per-rotor commands.

use nalgebra::{Matrix4, Vector3, Vector4};

use crate::vehicle::Airframe;

/// Why a controller cannot be built for an airframe.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ControlError {
    /// The rotors cannot produce independent thrust, roll, pitch and yaw (for example all
    /// spin the same way, or they sit on one line).
    #[error("failed to build the mixer for airframe {0}: rotor layout cannot control thrust, roll, pitch and yaw")]
    Unallocatable(String),
    /// More rotors than the mixer (and the snapshot's `motor_commands`) carry.
    #[error("failed to build the mixer for airframe {name}: {rotors} rotors, at most {MAX_ROTORS} are supported")]
    TooManyRotors { name: String, rotors: usize },
}

/// Rotors a mixer handles: an octocopter (the snapshot's `motor_commands` has 8 slots).
pub const MAX_ROTORS: usize = 8;

/// Per-rotor thrusts of one allocation and how much of the request survived saturation.
///
/// On the stack (no allocation per control step): the thrusts of up to [`MAX_ROTORS`].
#[derive(Clone, Debug, PartialEq)]
pub struct Allocation {
    rotor_thrust_n: [f64; MAX_ROTORS],
    rotors: usize,
    /// Factor applied to the roll/pitch torque (1 = as requested).
    pub roll_pitch_scale: f64,
    /// Factor applied to the yaw torque (1 = as requested).
    pub yaw_scale: f64,
}

impl Allocation {
    /// Each rotor's thrust, N, rotor order.
    pub fn rotor_thrust_n(&self) -> &[f64] {
        &self.rotor_thrust_n[..self.rotors]
    }
}

/// Collective thrust + body torques → per-rotor commands, for any rotor layout.
///
/// The effectiveness matrix `B` (4 × n) maps rotor thrusts to (thrust, τx, τy, τz): column
/// `i` is `(1, r_y, −r_x, s_i k_m)` (`r × T ẑ` plus the reaction torque, `s_i` from
/// [`crate::vehicle::Spin::reaction_sign`]). The mixer uses the pseudo-inverse
/// `B⁺ = Bᵀ (B Bᵀ)⁻¹` (the exact inverse for a quad).
///
/// Saturation, in priority order: roll/pitch first (scaled down only if they alone do not
/// fit in `[0, T_max]`), then collective thrust (shifted to make room), then yaw (clipped
/// to what headroom is left). Commands invert `T = k_f (u ω_max)²`.
#[derive(Clone, Debug, PartialEq)]
pub struct Mixer {
    /// Row `i` of `B⁺`: rotor `i`'s thrust per unit of (thrust, τx, τy, τz).
    pub(super) pinv: Vec<[f64; 4]>,
    /// Per rotor, `T_max / c0_i`: the collective thrust that alone saturates rotor `i`
    /// (N of collective). Fixed by the airframe, so divided once here instead of twice per
    /// rotor in every [`Mixer::allocate`]; the same division of the same numbers, so the
    /// same bits.
    collective_cap_n: [f64; MAX_ROTORS],
    pub thrust_coeff_n_per_rad_s2: f64,
    pub max_omega_rad_s: f64,
    pub max_rotor_thrust_n: f64,
}

impl Mixer {
    /// # Errors
    /// [`ControlError::Unallocatable`] when `B Bᵀ` is singular or some rotor would not
    /// contribute to collective thrust.
    pub fn new(airframe: &Airframe) -> Result<Self, ControlError> {
        if airframe.rotors.len() > MAX_ROTORS {
            return Err(ControlError::TooManyRotors { name: airframe.name.clone(), rotors: airframe.rotors.len() });
        }
        let km = airframe.torque_coeff_m;
        let columns: Vec<Vector4<f64>> = airframe
            .rotors
            .iter()
            .map(|r| {
                let p = r.position_body_m;
                Vector4::new(1.0, p.y, -p.x, r.spin.reaction_sign() * km)
            })
            .collect();
        let bbt: Matrix4<f64> = columns.iter().map(|c| c * c.transpose()).sum();
        let err = || ControlError::Unallocatable(airframe.name.clone());
        // Rank check on the correlation matrix (rows have different units: N vs N m).
        let d = bbt.diagonal().map(|x| if x > 0.0 { 1.0 / x.sqrt() } else { 0.0 });
        let correlation = Matrix4::from_diagonal(&d) * bbt * Matrix4::from_diagonal(&d);
        if correlation.symmetric_eigenvalues().min() < 1e-9 {
            return Err(err());
        }
        let inv = bbt.try_inverse().ok_or_else(err)?;
        let pinv: Vec<[f64; 4]> = columns.iter().map(|c| (inv * c).into()).collect();
        if pinv.iter().any(|row| row[0] <= 1e-9) || !pinv.iter().flatten().all(|x| x.is_finite()) {
            return Err(err());
        }
        let max_rotor_thrust_n = airframe.max_rotor_thrust_n();
        let mut collective_cap_n = [0.0; MAX_ROTORS];
        for (cap, row) in collective_cap_n.iter_mut().zip(&pinv) {
            *cap = max_rotor_thrust_n / row[0];
        }
        Ok(Self {
            pinv,
            collective_cap_n,
            thrust_coeff_n_per_rad_s2: airframe.thrust_coeff_n_per_rad_s2,
            max_omega_rad_s: airframe.max_omega_rad_s,
            max_rotor_thrust_n,
        })
    }

    /// Rotor thrusts for a collective thrust (N) and body torque (N m), saturation handled.
    ///
    /// Runs at every physics step (PX4's allocator follows its rate loop), so it is written
    /// for that: one pass per quantity over stack arrays, no allocation, and minima and
    /// maxima as plain comparisons (a NaN never replaces the running value, exactly as
    /// `f64::min`/`f64::max` keep the other operand).
    pub fn allocate(&self, thrust_n: f64, torque_body_nm: &Vector3<f64>) -> Allocation {
        let t_max = self.max_rotor_thrust_n;
        let tau = torque_body_nm;
        let n = self.pinv.len();
        let rows = &self.pinv[..];
        let caps = &self.collective_cap_n[..n];
        // Rotor i's roll/pitch thrust rp_i, and ratio_i = rp_i / c0_i (c0 = collective column).
        let mut rp = [0.0; MAX_ROTORS];
        let mut ratio = [0.0; MAX_ROTORS];
        let mut min_ratio = f64::INFINITY;
        for ((rp, ratio), row) in rp.iter_mut().zip(ratio.iter_mut()).zip(rows) {
            *rp = row[1] * tau.x + row[2] * tau.y;
            *ratio = *rp / row[0];
            if *ratio < min_ratio {
                min_ratio = *ratio;
            }
        }
        let (rp, ratio) = (&rp[..n], &ratio[..n]);
        // Some collective F keeps F c0_i + s rp_i in [0, T_max] for all i iff, for all i, j,
        // s (ratio_j − ratio_i) ≤ T_max / c0_j: take the largest such s ≤ 1. For each j the
        // binding i is the one with the smallest ratio (the largest spread; division by a
        // larger positive number never rounds to a larger quotient), so one pass over the
        // rotors gives the same s as every pair: n divisions instead of n².
        let mut s: f64 = 1.0;
        for (cap_j, ratio_j) in caps.iter().zip(ratio) {
            let spread = ratio_j - min_ratio;
            if spread > 0.0 {
                let fits = cap_j / spread;
                if fits < s {
                    s = fits;
                }
            }
        }
        // The collective thrusts that keep every rotor in [0, T_max] at that scale.
        let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
        for (cap, r) in caps.iter().zip(ratio) {
            let (low, high) = (-s * r, cap - s * r);
            if low > lo {
                lo = low;
            }
            if high < hi {
                hi = high;
            }
        }
        let f = if lo <= hi { thrust_n.clamp(lo, hi) } else { 0.5 * (lo + hi) };
        let mut thrusts = [0.0; MAX_ROTORS];
        // Yaw gets what headroom is left.
        let mut k: f64 = 1.0;
        for ((ti, row), rp) in thrusts.iter_mut().zip(rows).zip(rp) {
            *ti = f * row[0] + s * rp;
            let y = row[3] * tau.z;
            let fits = if y > 0.0 {
                (t_max - *ti) / y
            } else if y < 0.0 {
                -*ti / y
            } else {
                f64::INFINITY
            };
            if fits < k {
                k = fits;
            }
        }
        let k = k.max(0.0);
        for (ti, row) in thrusts[..n].iter_mut().zip(rows) {
            *ti = (*ti + k * row[3] * tau.z).clamp(0.0, t_max);
        }
        Allocation { rotor_thrust_n: thrusts, rotors: n, roll_pitch_scale: s, yaw_scale: k }
    }

    /// Normalised command in [0, 1] for one rotor's thrust: `sqrt(T / k_f) / ω_max`.
    pub fn command_for_thrust(&self, rotor_thrust_n: f64) -> f64 {
        ((rotor_thrust_n.max(0.0) / self.thrust_coeff_n_per_rad_s2).sqrt() / self.max_omega_rad_s).clamp(0.0, 1.0)
    }

    /// Per-rotor normalised commands for a collective thrust (N) and body torque (N m).
    pub fn mix(&self, thrust_n: f64, torque_body_nm: &Vector3<f64>) -> Vec<f64> {
        let allocation = self.allocate(thrust_n, torque_body_nm);
        let mut u = vec![0.0; allocation.rotors];
        self.commands_into(&allocation, &mut u);
        u
    }

    /// Normalised commands for an allocation's rotor thrusts, into `out` (rotor order; as
    /// many as both have).
    pub fn commands_into(&self, allocation: &Allocation, out: &mut [f64]) {
        for (u, t) in out.iter_mut().zip(allocation.rotor_thrust_n()) {
            *u = self.command_for_thrust(*t);
        }
    }
}
