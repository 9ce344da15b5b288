//! Airframe presets: one record per preset (PX4's airframe files), holding everything a
//! drone of that preset is: its physics ([`Airframe`]), its PX4 identity (`SYS_AUTOSTART`),
//! the flight-controller gains and limits it flies with ([`Gains`]) and the PX4 parameter
//! values its airframe file sets.
//!
//! Every consumer takes the preset from here: the shard builds the drone (physics and
//! controller), the MAVLink parameter table and the ULog parameters are derived from the
//! same record (`mavlink::params`), so the three cannot disagree. `sadesim_crds::airframe`
//! holds only the names and descriptions the validator accepts; a test checks that both
//! lists name the same presets.

use crate::autopilot::control::Gains;
use crate::vehicle::airframe::{self, Airframe};

/// One airframe preset.
#[derive(Clone, Debug, PartialEq)]
pub struct Preset {
    /// Physics: mass, inertia, rotors, motors, drag, battery, flight limits.
    pub airframe: Airframe,
    /// PX4's airframe id (`SYS_AUTOSTART`) of the airframe this preset stands for.
    pub sys_autostart: i32,
    /// What the drone's flight controller flies with (the MAVLink `MC_*` / `MPC_*` values
    /// are derived from these).
    pub gains: Gains,
    /// Parameter values set by the preset's PX4 airframe file, by PX4 name, in the
    /// parameter's unit (an INT32 parameter takes the integer part). Applied on top of the
    /// firmware defaults; values derived from [`Preset::airframe`] and [`Preset::gains`]
    /// are not listed here.
    pub param_overrides: Vec<(&'static str, f64)>,
}

/// The presets, in the order of `sadesim_crds::airframe::AIRFRAME_PRESETS` (tested).
const PRESETS: [fn() -> Preset; 2] = [x500, mini250];

impl Preset {
    /// The preset of that name, `None` for an unknown name.
    pub fn named(name: &str) -> Option<Self> {
        Self::all().into_iter().find(|p| p.airframe.name == name)
    }

    /// Every preset.
    pub fn all() -> Vec<Self> {
        PRESETS.iter().map(|build| build()).collect()
    }

    /// The name (`sadesim_crds::airframe::AIRFRAME_PRESETS`).
    pub fn name(&self) -> &str {
        &self.airframe.name
    }

    /// A preset around `airframe` flying [`Gains::for_airframe`].
    fn with_default_gains(airframe: Airframe, sys_autostart: i32, param_overrides: Vec<(&'static str, f64)>) -> Self {
        let gains = Gains::for_airframe(&airframe);
        Self { airframe, sys_autostart, gains, param_overrides }
    }
}

/// The Holybro X500 V2 as PX4 SITL flies it (`make px4_sitl gz_x500`): airframe
/// `4001_gz_x500`, which sets MPC_THR_HOVER 0.6 and NAV_DLL_ACT 2 (return on data link loss).
fn x500() -> Preset {
    Preset::with_default_gains(airframe::x500(), 4001, vec![("MPC_THR_HOVER", 0.6), ("NAV_DLL_ACT", 2.0)])
}

/// The sub-250 g quad. PX4 has no SITL model of one; its closest documented airframe is
/// `4050_generic_250` ("Generic 250 Racer", Quadrotor X, a 250 mm-class quad; the mini250's
/// motor diagonal is 213 mm), so that is the id it reports. Overrides: NAV_DLL_ACT 2, the
/// same link-loss policy as the x500, and MPC_THR_HOVER, the normalised collective thrust
/// that carries the weight (weight / full thrust, 0.36).
fn mini250() -> Preset {
    let airframe = airframe::mini250();
    let hover_thrust = airframe.weight_n() / airframe.max_thrust_n();
    Preset::with_default_gains(airframe, 4050, vec![("MPC_THR_HOVER", hover_thrust), ("NAV_DLL_ACT", 2.0)])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crds_names_and_presets_are_the_same_list() {
        let crds: Vec<&str> = sadesim_crds::airframe::AIRFRAME_PRESETS.iter().map(|p| p.name).collect();
        let presets = Preset::all();
        let ours: Vec<&str> = presets.iter().map(Preset::name).collect();
        assert_eq!(ours, crds, "every crds name has exactly one preset, in the same order");
        for name in crds {
            assert_eq!(Preset::named(name).map(|p| p.airframe.name), Some(name.to_owned()));
        }
        assert!(Preset::named("no-such-frame").is_none());
    }

    #[test]
    fn presets_have_distinct_px4_airframe_ids() {
        let presets = Preset::all();
        for (i, a) in presets.iter().enumerate() {
            assert!(a.sys_autostart > 0, "{}", a.name());
            assert!(presets[i + 1..].iter().all(|b| b.sys_autostart != a.sys_autostart), "{}", a.name());
        }
        assert_eq!(Preset::named("x500").map(|p| p.sys_autostart), Some(4001), "PX4 SITL gz_x500");
    }

    #[test]
    fn gains_respect_the_airframe_tilt_limit() {
        for p in Preset::all() {
            let a = &p.airframe;
            let limit = p.gains.velocity_xy.output_limit;
            assert!((limit.atan2(crate::vehicle::GRAVITY_MPS2) - a.max_tilt_rad).abs() < 1e-12, "{}", p.name());
        }
    }
}
