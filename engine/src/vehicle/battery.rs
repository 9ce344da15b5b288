//! Flight battery: state of charge by coulomb counting, LiPo open-circuit voltage, sag.
//!
//! Electrical load `P = Σ P_mech,i / η + P_avionics`, with `P_mech,i = Q_i ω_i` the rotor
//! shaft power and `η` the ESC+motor efficiency. The terminal voltage sags with the current,
//! `V = V_oc(SoC) − I R`, and `P = V I`, so the current solves `R I² − V_oc I + P = 0`:
//! `I = (V_oc − sqrt(V_oc² − 4 R P)) / (2 R)` (the smaller root, the physical one).
//!
//! # Caveats
//! No temperature, no capacity fade, no recovery after load; the voltage does not yet limit
//! the motors' top speed.

use super::airframe::BatterySpec;

/// LiPo open-circuit voltage per cell at SoC = 0, 0.05, ..., 1.0 (a commonly used rested
/// discharge curve: 4.20 V full, plateau 3.75-3.85 V, knee below 10 %, 3.30 V empty).
const CELL_OCV_V: [f64; 21] = [
    3.30, 3.55, 3.68, 3.71, 3.73, 3.75, 3.77, 3.79, 3.80, 3.82, 3.84, 3.85, 3.87, 3.91, 3.95, 3.98, 4.02, 4.08, 4.11,
    4.15, 4.20,
];

/// Open-circuit voltage of one LiPo cell at state of charge `soc` ∈ [0, 1], V.
pub fn lipo_cell_ocv_v(soc: f64) -> f64 {
    let x = soc.clamp(0.0, 1.0) * (CELL_OCV_V.len() - 1) as f64;
    let i = (x.floor() as usize).min(CELL_OCV_V.len() - 2);
    let f = x - i as f64;
    CELL_OCV_V[i] + f * (CELL_OCV_V[i + 1] - CELL_OCV_V[i])
}

/// A battery's state.
#[derive(Clone, Debug, PartialEq)]
pub struct Battery {
    pub spec: BatterySpec,
    consumed_mah: f64,
    current_a: f64,
    voltage_v: f64,
}

impl Battery {
    /// A full battery at rest.
    pub fn new(spec: BatterySpec) -> Self {
        Self::with_remaining_fraction(spec, 1.0)
    }

    /// A battery at rest with `remaining` ∈ [0, 1] of its capacity left.
    pub fn with_remaining_fraction(spec: BatterySpec, remaining: f64) -> Self {
        let consumed_mah = (1.0 - remaining.clamp(0.0, 1.0)) * spec.capacity_mah;
        let mut b = Self { spec, consumed_mah, current_a: 0.0, voltage_v: 0.0 };
        b.voltage_v = b.open_circuit_voltage_v();
        b
    }

    /// Draws the electrical power for `rotor_mechanical_power_w` (sum over rotors, W) plus the
    /// avionics for `dt_s`, updating current, voltage and charge.
    pub fn update(&mut self, rotor_mechanical_power_w: f64, dt_s: f64) {
        let s = &self.spec;
        let power_w = rotor_mechanical_power_w.max(0.0) / s.propulsion_efficiency + s.avionics_power_w;
        let v_oc = self.open_circuit_voltage_v();
        let r = s.internal_resistance_ohm;
        self.current_a = if r > 0.0 {
            // Beyond the maximum-power point (V_oc² / 4R) the pack cannot deliver: cap there.
            let disc = (v_oc * v_oc - 4.0 * r * power_w).max(0.0);
            (v_oc - disc.sqrt()) / (2.0 * r)
        } else {
            power_w / v_oc
        };
        self.voltage_v = v_oc - self.current_a * r;
        self.consumed_mah = (self.consumed_mah + self.current_a * dt_s / 3.6).min(s.capacity_mah);
    }

    /// Fraction of the capacity left, [0, 1].
    pub fn remaining_fraction(&self) -> f64 {
        1.0 - self.consumed_mah / self.spec.capacity_mah
    }

    /// Charge drawn so far, mAh.
    pub fn consumed_mah(&self) -> f64 {
        self.consumed_mah
    }

    /// Terminal voltage under the last load, V.
    pub fn voltage_v(&self) -> f64 {
        self.voltage_v
    }

    /// Current of the last update, A.
    pub fn current_a(&self) -> f64 {
        self.current_a
    }

    /// Rested pack voltage at the present state of charge, V.
    pub fn open_circuit_voltage_v(&self) -> f64 {
        self.spec.cells as f64 * lipo_cell_ocv_v(self.remaining_fraction())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vehicle::airframe::preset;

    #[test]
    fn cell_curve_spans_full_to_empty_and_is_monotonic() {
        assert!((lipo_cell_ocv_v(1.0) - 4.2).abs() < 1e-12);
        assert!((lipo_cell_ocv_v(0.0) - 3.3).abs() < 1e-12);
        assert!((3.7..=3.9).contains(&lipo_cell_ocv_v(0.5)));
        let mut prev = 0.0;
        for i in 0..=1000 {
            let v = lipo_cell_ocv_v(i as f64 / 1000.0);
            assert!(v >= prev);
            prev = v;
        }
    }

    #[test]
    fn voltage_sags_under_load_and_charge_is_the_integral_of_current() {
        let spec = preset("x500").unwrap().battery;
        let mut b = Battery::new(spec);
        assert!((b.voltage_v() - 16.8).abs() < 1e-9);
        let (mut integral_as, mut v_oc) = (0.0, 0.0);
        for _ in 0..60_000 {
            v_oc = b.open_circuit_voltage_v(); // the rested voltage this update starts from
            b.update(240.0, 1e-3); // ~x500 hover
            integral_as += b.current_a() * 1e-3;
        }
        let sag = v_oc - b.voltage_v();
        assert!((sag - b.current_a() * spec.internal_resistance_ohm).abs() < 1e-9);
        assert!(sag > 0.3, "sag {sag} V at {} A", b.current_a());
        assert!((b.voltage_v() * b.current_a() - (240.0 / 0.7 + 5.0)).abs() < 1e-6, "P = V I");
        assert!((b.consumed_mah() - integral_as / 3.6).abs() < 1e-9);
        let expected = 1.0 - integral_as / 3.6 / spec.capacity_mah;
        assert!((b.remaining_fraction() - expected).abs() < 1e-12);
        assert!(b.remaining_fraction() < 0.93, "one minute of x500 hover uses ~7 %");
    }

    #[test]
    fn heavier_load_sags_more() {
        let spec = preset("mini250").unwrap().battery;
        let (mut light, mut heavy) = (Battery::new(spec), Battery::new(spec));
        light.update(20.0, 1e-3);
        heavy.update(80.0, 1e-3);
        assert!(heavy.current_a() > light.current_a());
        assert!(heavy.voltage_v() < light.voltage_v());
    }

    #[test]
    fn empty_battery_stays_at_zero() {
        let spec = preset("mini250").unwrap().battery;
        let mut b = Battery::with_remaining_fraction(spec, 0.001);
        for _ in 0..10_000 {
            b.update(100.0, 0.01);
        }
        assert_eq!(b.remaining_fraction(), 0.0);
        assert!(b.voltage_v() > 0.0);
    }
}
