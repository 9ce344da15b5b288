//! PX4's parameters and its parameter protocol, per simulated drone (pure: messages in,
//! messages out).
//!
//! Ground stations download every parameter when they connect (QGroundControl shows a vehicle
//! as ready only after the full list arrived) and clients read and write a few
//! (`MAVSDK::Param::set_param_float("MPC_XY_CRUISE", ..)`). [`ParamTable::handle`] answers the
//! parameter protocol (<https://mavlink.io/en/services/parameter.html>) the way PX4's
//! `MavlinkParametersManager` does, over a subset of real PX4 parameters whose
//! navigator-related values are live: [`ParamTable::navigator_config`] maps them back onto
//! the autopilot, so `PARAM_SET RTL_RETURN_ALT` changes where the drone returns.
//!
//! # Values
//! What PX4 SITL reports for the drone's airframe preset ([`Preset`]), in layers:
//! 1. firmware defaults (PX4 main, the modules' `*_params.c` / `*.yaml`), overridden by
//!    `rc.mc_defaults` (MAV_TYPE, NAV_ACC_RAD, RTL_RETURN_ALT, RTL_DESCEND_ALT) and by the
//!    SITL `rcS` (the simulated sensors' CAL_*_ID, EKF2_REQ_GPS_H);
//! 2. the preset, through [`preset`]: the values the drone actually flies with, from its
//!    physics and its controller gains (MC_*_P, MC_*RATE_*, MPC_*_P, MPC_*_VEL_*,
//!    MPC_TILTMAX_AIR, BAT1_*), its PX4 airframe id (SYS_AUTOSTART) and the values its PX4
//!    airframe file sets (for the x500 `4001_gz_x500`: MPC_THR_HOVER, NAV_DLL_ACT);
//! 3. this drone's MAVLink system id and the navigator's tunables: NAV_ACC_RAD is 1 m in
//!    this simulation (PX4: 10 m firmware default, 2 m for multicopters).
//!
//! The same table is written into the drone's ULog ([`plan::drone_table`]), so a log and a
//! ground station see the same values.
//!
//! # Encoding
//! PX4 advertises `MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE`: an INT32 value travels in
//! the float field as the float whose bit pattern is the integer (`f32::from_bits(i as u32)`,
//! so MAV_SYS_ID 1 reads as 1.4e-45 to a client that ignores `param_type`), and a PARAM_SET
//! of an INT32 parameter is decoded the same way. The bit pattern of some integers is a NaN
//! (-1 is `0xFFFF_FFFF`); it is carried through untouched.
//!
//! # Where this differs from PX4
//! - No `_HASH_CHECK`: PX4 first sends a hash of all values so QGroundControl can reuse its
//!   cache; without it QGroundControl downloads the list (90 values) on every connect.
//! - Ranges are enforced. PX4's firmware stores any value of the right type and leaves
//!   ranges to the ground station; here a value outside PX4's documented `@min`/`@max` is
//!   refused, so the simulated autopilot never runs on a value PX4 calls invalid.
//! - A refused write (wrong type, out of range, read-only) is answered with PARAM_VALUE
//!   holding the unchanged value, as the parameter protocol asks of a failed write. PX4
//!   answers out-of-range values like that too (it does not check them, see above) but stays
//!   silent on a type mismatch (it only logs "param types mismatch"): a silent refusal makes
//!   the client wait for its timeout instead of seeing at once that nothing changed.
//! - MAV_SYS_ID, MAV_COMP_ID and SYS_AUTOSTART are read-only: the run plan assigns them and
//!   the simulation never reboots to apply a change (PX4 needs a reboot for them too).
//! - The controller's parameters (MC_*, MPC_* outside the navigator's) report what the
//!   controller flies with; a PARAM_SET of one is stored and reported back but does not
//!   retune the running controller.
//! - `target_system` 0 (broadcast) is accepted; PX4 answers only its own system id.
//! - PARAM_REQUEST_LIST is answered with the whole list at once; PX4 spreads it over its
//!   stream cycles. Pacing is the caller's to do if a link needs it.

use ::mavlink::dialects::common::{
    MavMessage, MavParamType, PARAM_REQUEST_LIST_DATA, PARAM_REQUEST_READ_DATA, PARAM_SET_DATA, PARAM_VALUE_DATA,
};
use ::mavlink::types::CharArray;

use crate::autopilot::mission::DEFAULT_CRUISE_MPS;
use crate::autopilot::navigator::NavigatorConfig;
use crate::preset::Preset;

pub mod plan;
pub mod preset;

/// MAV_COMP_ID_AUTOPILOT1: the component id PX4's autopilot answers as (MAV_COMP_ID).
pub const AUTOPILOT_COMPONENT_ID: u8 = 1;
/// Longest parameter name MAVLink carries: `param_id` is `char[16]`, null-terminated only
/// when shorter.
pub const NAME_MAX_LEN: usize = 16;

/// A parameter value with its PX4 type (PX4 has only these two).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ParamValue {
    /// MAV_PARAM_TYPE_REAL32.
    Real32(f32),
    /// MAV_PARAM_TYPE_INT32 (also PX4's booleans and enumerations).
    Int32(i32),
}

impl ParamValue {
    /// The MAVLink type tag sent with the value.
    pub fn mav_type(self) -> MavParamType {
        match self {
            Self::Real32(_) => MavParamType::MAV_PARAM_TYPE_REAL32,
            Self::Int32(_) => MavParamType::MAV_PARAM_TYPE_INT32,
        }
    }

    /// The float that carries the value in PARAM_VALUE / PARAM_SET (bytewise for INT32).
    pub fn to_wire(self) -> f32 {
        match self {
            Self::Real32(v) => v,
            Self::Int32(i) => f32::from_bits(i.cast_unsigned()),
        }
    }

    /// Decodes the float field of PARAM_SET given its `param_type`; `None` for types PX4
    /// does not have.
    pub fn from_wire(raw: f32, mav_type: MavParamType) -> Option<Self> {
        match mav_type {
            MavParamType::MAV_PARAM_TYPE_REAL32 => Some(Self::Real32(raw)),
            MavParamType::MAV_PARAM_TYPE_INT32 => Some(Self::Int32(raw.to_bits().cast_signed())),
            _ => None,
        }
    }

    /// The value as f64. A REAL32 converts through its shortest decimal form, so 0.7 set by
    /// a user gives 0.7, not 0.699999988 (f32 0.7 widened); an INT32 converts exactly.
    pub fn as_f64(self) -> f64 {
        match self {
            Self::Real32(v) => v.to_string().parse().unwrap_or(f64::from(v)),
            Self::Int32(i) => f64::from(i),
        }
    }
}

/// One parameter: name, current value, PX4's documented range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Param {
    /// PX4's name, at most [`NAME_MAX_LEN`] ASCII characters.
    pub name: &'static str,
    pub value: ParamValue,
    /// PX4's `@min` / `@max` (for enumerations without them, the span of the `@value`s), in
    /// the parameter's unit.
    pub min: Option<f64>,
    pub max: Option<f64>,
    /// Refuses PARAM_SET (identity fixed by the run plan).
    pub read_only: bool,
}

impl Param {
    const fn real(name: &'static str, value: f32) -> Self {
        Self { name, value: ParamValue::Real32(value), min: None, max: None, read_only: false }
    }

    const fn int(name: &'static str, value: i32) -> Self {
        Self { name, value: ParamValue::Int32(value), min: None, max: None, read_only: false }
    }

    const fn range(self, min: f64, max: f64) -> Self {
        Self { min: Some(min), max: Some(max), ..self }
    }

    const fn at_least(self, min: f64) -> Self {
        Self { min: Some(min), ..self }
    }

    const fn fixed(self) -> Self {
        Self { read_only: true, ..self }
    }

    /// Whether `value` is inside the range, compared in the parameter's own type (a REAL32
    /// limit of 0.6 admits f32 0.6, which is slightly above 0.6 as f64).
    fn admits(&self, value: ParamValue) -> bool {
        match value {
            ParamValue::Real32(v) => {
                self.min.is_none_or(|min| v >= min as f32) && self.max.is_none_or(|max| v <= max as f32)
            }
            ParamValue::Int32(i) => {
                let v = f64::from(i);
                self.min.is_none_or(|min| v >= min) && self.max.is_none_or(|max| v <= max)
            }
        }
    }
}

/// PX4 SITL's parameters before [`ParamTable::px4`] applies the preset's and the drone's own
/// values, grouped by PX4 module. Firmware defaults unless a comment names the script that
/// overrides them; values marked "preset" are always overwritten from the [`Preset`].
const PX4_SITL: &[Param] = &[
    // Battery (src/lib/battery). BAT1_CAPACITY, BAT1_N_CELLS: preset.
    Param::real("BAT1_CAPACITY", -1.0).range(-1.0, 100_000.0),
    Param::int("BAT1_N_CELLS", 0).range(0.0, 16.0),
    Param::int("BAT1_SOURCE", 0).range(-1.0, 2.0),
    Param::real("BAT1_V_CHARGED", 4.05),
    Param::real("BAT1_V_EMPTY", 3.6),
    Param::real("BAT_CRIT_THR", 0.07).range(0.05, 0.5),
    Param::real("BAT_EMERGEN_THR", 0.05).range(0.03, 0.5),
    Param::real("BAT_LOW_THR", 0.15).range(0.12, 0.5),
    // Sensors. Device ids of SITL's simulated IMU and magnetometer (rcS): non-zero ids tell a
    // ground station the sensors are calibrated.
    Param::int("CAL_ACC0_ID", 1_310_988),
    Param::int("CAL_GYRO0_ID", 1_310_988),
    Param::int("CAL_MAG0_ID", 197_388),
    Param::int("SENS_BOARD_ROT", 0).range(-1.0, 40.0),
    // Commander. NAV_DLL_ACT: preset (4001_gz_x500 sets 2, return on data link loss).
    Param::int("COM_ARM_WO_GPS", 1).range(0.0, 2.0),
    Param::real("COM_DISARM_LAND", 2.0),
    Param::real("COM_DISARM_PRFLT", 10.0),
    Param::int("COM_DL_LOSS_T", 10).range(5.0, 300.0),
    Param::real("COM_FAIL_ACT_T", 5.0).range(0.0, 25.0),
    Param::int("COM_HOME_EN", 1).range(0.0, 1.0),
    Param::int("COM_LOW_BAT_ACT", 0).range(0.0, 3.0),
    Param::int("COM_OBL_RC_ACT", 0).range(0.0, 7.0),
    Param::real("COM_OF_LOSS_T", 1.0).range(0.0, 60.0),
    Param::real("COM_POS_FS_EPH", 5.0).range(-1.0, 400.0),
    Param::int("COM_RCL_EXCEPT", 0).range(0.0, 7.0),
    Param::int("COM_RC_IN_MODE", 3).range(0.0, 4.0),
    Param::real("COM_RC_LOSS_T", 0.5).range(0.0, 35.0),
    Param::int("NAV_DLL_ACT", 0).range(0.0, 6.0),
    Param::int("NAV_RCL_ACT", 2).range(1.0, 6.0),
    // Estimator (src/modules/ekf2). EKF2_REQ_GPS_H 0.5 s: SITL rcS (firmware: 10 s).
    Param::int("EKF2_BARO_CTRL", 1).range(0.0, 1.0),
    Param::int("EKF2_GPS_CTRL", 7).range(0.0, 15.0),
    Param::real("EKF2_GPS_DELAY", 110.0).range(0.0, 300.0),
    Param::int("EKF2_HGT_REF", 1).range(0.0, 3.0),
    Param::real("EKF2_REQ_EPH", 3.0).range(2.0, 100.0),
    Param::real("EKF2_REQ_EPV", 5.0).range(2.0, 100.0),
    Param::real("EKF2_REQ_GPS_H", 0.5).at_least(0.1),
    Param::int("EKF2_REQ_NSATS", 6).range(4.0, 12.0),
    // Geofence (navigator).
    Param::int("GF_ACTION", 2).range(0.0, 5.0),
    Param::real("GF_MAX_HOR_DIST", 0.0).range(0.0, 10_000.0),
    Param::real("GF_MAX_VER_DIST", 0.0).range(0.0, 10_000.0),
    // Land detector.
    Param::real("LNDMC_ALT_GND", 2.0).at_least(-1.0),
    Param::real("LNDMC_ROT_MAX", 20.0),
    Param::real("LNDMC_TRIG_TIME", 1.0).range(0.1, 10.0),
    Param::real("LNDMC_XY_VEL_MAX", 1.5),
    Param::real("LNDMC_Z_VEL_MAX", 0.25).at_least(0.0),
    // MAVLink. MAV_TYPE 2 (quadrotor): rc.mc_defaults (firmware: 0, generic).
    Param::int("MAV_COMP_ID", AUTOPILOT_COMPONENT_ID as i32).range(1.0, 250.0).fixed(),
    Param::int("MAV_SYS_ID", 1).range(1.0, 250.0).fixed(),
    Param::int("MAV_TYPE", 2).range(0.0, 22.0),
    // Attitude and rate control (mc_att_control, mc_rate_control): preset.
    Param::real("MC_PITCHRATE_MAX", 220.0).range(0.0, 1800.0),
    Param::real("MC_PITCHRATE_P", 0.15).range(0.01, 0.6),
    Param::real("MC_PITCH_P", 4.0).range(0.0, 12.0),
    Param::real("MC_ROLLRATE_MAX", 220.0).range(0.0, 1800.0),
    Param::real("MC_ROLLRATE_P", 0.15).range(0.01, 0.5),
    Param::real("MC_ROLL_P", 4.0).range(0.0, 12.0),
    Param::real("MC_YAWRATE_MAX", 200.0).range(0.0, 1800.0),
    Param::real("MC_YAWRATE_P", 0.2).range(0.0, 0.6),
    Param::real("MC_YAW_P", 2.8).range(0.0, 5.0),
    // Mission (navigator). NAV_ACC_RAD 2: rc.mc_defaults (firmware: 10).
    Param::real("MIS_DIST_1WP", 10_000.0).range(-1.0, 100_000.0),
    Param::real("MIS_TAKEOFF_ALT", 2.5).at_least(0.0),
    Param::int("MIS_TKO_LAND_REQ", 0).range(0.0, 5.0),
    Param::real("NAV_ACC_RAD", 2.0).range(0.05, 200.0),
    Param::real("NAV_MC_ALT_RAD", 0.8).range(0.05, 200.0),
    // Position control (mc_pos_control). Gains, speed and tilt limits: preset. MPC_THR_HOVER:
    // preset (4001_gz_x500 sets 0.6).
    Param::real("MPC_ACC_HOR", 3.0).range(2.0, 15.0),
    Param::real("MPC_JERK_AUTO", 4.0).range(1.0, 80.0),
    Param::real("MPC_LAND_ALT1", 10.0).range(0.0, 122.0),
    Param::real("MPC_LAND_ALT2", 5.0).range(0.0, 122.0),
    Param::real("MPC_LAND_SPEED", 0.7).at_least(0.6),
    Param::real("MPC_THR_HOVER", 0.5).range(0.1, 0.8),
    Param::real("MPC_TILTMAX_AIR", 45.0).range(20.0, 89.0),
    Param::real("MPC_TKO_SPEED", 1.5).range(1.0, 5.0),
    Param::real("MPC_XY_CRUISE", DEFAULT_CRUISE_MPS as f32).range(3.0, 20.0),
    Param::real("MPC_XY_P", 0.95).range(0.0, 2.0),
    Param::real("MPC_XY_VEL_MAX", 12.0).range(0.0, 20.0),
    Param::real("MPC_XY_VEL_P_ACC", 1.8).range(1.2, 5.0),
    Param::real("MPC_YAWRAUTO_MAX", 60.0).range(5.0, 360.0),
    Param::int("MPC_YAW_MODE", 0).range(0.0, 5.0),
    Param::real("MPC_Z_P", 1.0).range(0.1, 1.5),
    Param::real("MPC_Z_VEL_MAX_DN", 1.5).range(0.5, 4.0),
    Param::real("MPC_Z_VEL_MAX_UP", 3.0).range(0.5, 8.0),
    Param::real("MPC_Z_VEL_P_ACC", 4.0).range(2.0, 15.0),
    Param::real("MPC_Z_V_AUTO_DN", 1.5).range(0.5, 4.0),
    Param::real("MPC_Z_V_AUTO_UP", 3.0).range(0.5, 8.0),
    // Return mode (navigator). RTL_RETURN_ALT 30 and RTL_DESCEND_ALT 10: rc.mc_defaults
    // (firmware: 60 and 30).
    Param::int("RTL_CONE_ANG", 45).range(0.0, 90.0),
    Param::real("RTL_DESCEND_ALT", 10.0).at_least(0.0),
    Param::real("RTL_LAND_DELAY", 0.0).at_least(-1.0),
    Param::real("RTL_RETURN_ALT", 30.0).at_least(0.0),
    Param::int("RTL_TYPE", 0).range(0.0, 4.0),
    // System. SYS_AUTOSTART: preset.
    Param::int("SYS_AUTOSTART", 0).range(0.0, 9_999_999.0).fixed(),
    Param::int("SYS_HAS_BARO", 1).range(0.0, 1.0),
    Param::int("SYS_HAS_GPS", 1).range(0.0, 1.0),
    Param::int("SYS_HAS_MAG", 1).at_least(0.0),
    Param::int("SYS_HITL", 0).range(-1.0, 2.0),
];

/// A REAL32 parameter that mirrors a [`NavigatorConfig`] field.
struct NavigatorParam {
    name: &'static str,
    get: fn(&NavigatorConfig) -> f64,
    set: fn(&mut NavigatorConfig, f64),
}

/// The PX4 names in [`NavigatorConfig`]'s field docs, one mapping used both ways.
const NAVIGATOR_PARAMS: [NavigatorParam; 10] = [
    NavigatorParam { name: "NAV_ACC_RAD", get: |c| c.acceptance_radius_m, set: |c, v| c.acceptance_radius_m = v },
    NavigatorParam {
        name: "NAV_MC_ALT_RAD",
        get: |c| c.altitude_acceptance_m,
        set: |c, v| c.altitude_acceptance_m = v,
    },
    NavigatorParam { name: "MPC_TKO_SPEED", get: |c| c.takeoff_speed_mps, set: |c, v| c.takeoff_speed_mps = v },
    NavigatorParam { name: "MPC_LAND_SPEED", get: |c| c.land_speed_mps, set: |c, v| c.land_speed_mps = v },
    NavigatorParam { name: "MPC_Z_V_AUTO_DN", get: |c| c.descent_speed_mps, set: |c, v| c.descent_speed_mps = v },
    NavigatorParam { name: "MPC_LAND_ALT2", get: |c| c.land_slow_below_m, set: |c, v| c.land_slow_below_m = v },
    NavigatorParam { name: "RTL_RETURN_ALT", get: |c| c.rtl_altitude_m, set: |c, v| c.rtl_altitude_m = v },
    NavigatorParam { name: "COM_OF_LOSS_T", get: |c| c.offboard_timeout_s, set: |c, v| c.offboard_timeout_s = v },
    NavigatorParam { name: "BAT_LOW_THR", get: |c| c.battery_low, set: |c, v| c.battery_low = v },
    NavigatorParam { name: "BAT_CRIT_THR", get: |c| c.battery_critical, set: |c, v| c.battery_critical = v },
];

/// Parameters outside [`NavigatorConfig`] that the autopilot reads too.
const TAKEOFF_ALT: &str = "MIS_TAKEOFF_ALT";
const CRUISE: &str = "MPC_XY_CRUISE";

fn is_navigator_param(name: &str) -> bool {
    name == TAKEOFF_ALT || name == CRUISE || NAVIGATOR_PARAMS.iter().any(|p| p.name == name)
}

/// Why a write was refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SetRejection {
    /// No parameter of that name (PX4 does not answer these).
    #[error("failed to set {0}: no such parameter")]
    Unknown(String),
    /// The run plan owns the value.
    #[error("failed to set {0}: read-only in the simulation")]
    ReadOnly(&'static str),
    /// PARAM_SET's `param_type` is not the parameter's type (PX4: "param types mismatch").
    #[error("failed to set {name}: it is {expected:?}, the request was {got:?}")]
    TypeMismatch { name: &'static str, expected: MavParamType, got: MavParamType },
    /// A REAL32 NaN or infinity.
    #[error("failed to set {0}: value is not finite")]
    NotFinite(&'static str),
    /// Outside PX4's documented range (an absent bound is shown as infinite).
    #[error("failed to set {name}: {value} is outside [{min}, {max}]")]
    OutOfRange { name: &'static str, value: f64, min: f64, max: f64 },
}

/// What [`ParamTable::handle`] asks the caller to do.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ParamReply {
    /// PARAM_VALUE messages to send, in order (empty: the message was not for us, or PX4
    /// would not answer it).
    pub messages: Vec<MavMessage>,
    /// A write changed a value the autopilot reads ([`ParamTable::navigator_config`],
    /// [`ParamTable::takeoff_altitude_m`], [`ParamTable::cruise_speed_mps`]).
    pub navigator_changed: bool,
    /// Why a PARAM_SET was refused (the reply then holds the unchanged value), for a log
    /// line or a STATUSTEXT.
    pub rejection: Option<SetRejection>,
}

/// One drone's parameters, sorted by name (the order of `param_index`).
#[derive(Clone, Debug, PartialEq)]
pub struct ParamTable {
    params: Vec<Param>,
    system_id: u8,
}

impl ParamTable {
    /// The parameters PX4 SITL reports for a drone of `preset` with MAVLink system id
    /// `system_id` and the navigator tunables of `nav` (see the module docs' layers).
    ///
    /// `nav`'s and the preset's values are taken as they are, even outside PX4's ranges
    /// (they are validated where the scenario is, or are what the controller flies with);
    /// only later writes are range-checked.
    pub fn px4(system_id: u8, preset: &Preset, nav: &NavigatorConfig) -> Self {
        let mut params = PX4_SITL.to_vec();
        params.sort_by(|a, b| a.name.cmp(b.name));
        let mut table = Self { params, system_id };
        for (name, value) in self::preset::values(preset) {
            table.put_number(name, value);
        }
        table.put("MAV_SYS_ID", ParamValue::Int32(i32::from(system_id)));
        for p in &NAVIGATOR_PARAMS {
            table.put(p.name, ParamValue::Real32((p.get)(nav) as f32));
        }
        table
    }

    /// Overwrites a value in the parameter's own type without checks (construction only):
    /// an INT32 takes the integer part of `value`, a REAL32 its nearest f32.
    fn put_number(&mut self, name: &str, value: f64) {
        match self.get(name) {
            Some(ParamValue::Int32(_)) => self.put(name, ParamValue::Int32(value as i32)),
            Some(ParamValue::Real32(_)) => self.put(name, ParamValue::Real32(value as f32)),
            None => {}
        }
    }

    /// Overwrites a value without checks (construction only).
    fn put(&mut self, name: &str, value: ParamValue) {
        if let Some(i) = self.index_of(name) {
            self.params[i].value = value;
        }
    }

    /// Number of parameters (PARAM_VALUE.param_count).
    pub fn len(&self) -> usize {
        self.params.len()
    }

    pub fn is_empty(&self) -> bool {
        self.params.is_empty()
    }

    /// All parameters in `param_index` order.
    pub fn params(&self) -> &[Param] {
        &self.params
    }

    /// The `param_index` of a name.
    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.params.binary_search_by(|p| p.name.cmp(name)).ok()
    }

    /// A parameter's current value.
    pub fn get(&self, name: &str) -> Option<ParamValue> {
        self.index_of(name).map(|i| self.params[i].value)
    }

    /// Writes a value after PX4's checks plus the range.
    ///
    /// # Errors
    /// [`SetRejection`] saying why; the table is then unchanged.
    ///
    /// # Guarantees
    /// `Ok(true)` when the stored value changed, `Ok(false)` when it was already that value.
    pub fn set(&mut self, name: &str, value: ParamValue) -> Result<bool, SetRejection> {
        let index = self.index_of(name).ok_or_else(|| SetRejection::Unknown(name.to_owned()))?;
        let param = &mut self.params[index];
        if param.read_only {
            return Err(SetRejection::ReadOnly(param.name));
        }
        if param.value.mav_type() != value.mav_type() {
            return Err(SetRejection::TypeMismatch {
                name: param.name,
                expected: param.value.mav_type(),
                got: value.mav_type(),
            });
        }
        if let ParamValue::Real32(v) = value
            && !v.is_finite()
        {
            return Err(SetRejection::NotFinite(param.name));
        }
        if !param.admits(value) {
            return Err(SetRejection::OutOfRange {
                name: param.name,
                value: value.as_f64(),
                min: param.min.unwrap_or(f64::NEG_INFINITY),
                max: param.max.unwrap_or(f64::INFINITY),
            });
        }
        let changed = param.value != value;
        param.value = value;
        Ok(changed)
    }

    /// `base` with the navigator parameters' values. A field keeps `base`'s exact value
    /// while its parameter still equals it in f32, so an untouched table returns `base`
    /// bit for bit; a written value arrives as its decimal (see [`ParamValue::as_f64`]).
    pub fn navigator_config(&self, base: NavigatorConfig) -> NavigatorConfig {
        let mut config = base;
        for p in &NAVIGATOR_PARAMS {
            if let Some(ParamValue::Real32(v)) = self.get(p.name)
                && v != (p.get)(&base) as f32
            {
                (p.set)(&mut config, ParamValue::Real32(v).as_f64());
            }
        }
        config
    }

    /// Altitude above home of a TAKEOFF without one, m [MIS_TAKEOFF_ALT].
    pub fn takeoff_altitude_m(&self) -> f64 {
        self.real_or(TAKEOFF_ALT, 2.5)
    }

    /// Horizontal speed of missions and go-tos without one, m/s [MPC_XY_CRUISE].
    pub fn cruise_speed_mps(&self) -> f64 {
        self.real_or(CRUISE, DEFAULT_CRUISE_MPS)
    }

    fn real_or(&self, name: &str, fallback: f64) -> f64 {
        match self.get(name) {
            Some(v @ ParamValue::Real32(_)) => v.as_f64(),
            _ => fallback,
        }
    }

    /// PARAM_VALUE for the parameter at `index`.
    pub fn value_message(&self, index: usize) -> Option<MavMessage> {
        let p = self.params.get(index)?;
        Some(MavMessage::PARAM_VALUE(PARAM_VALUE_DATA {
            param_value: p.value.to_wire(),
            param_count: u16::try_from(self.params.len()).unwrap_or(u16::MAX),
            param_index: u16::try_from(index).unwrap_or(u16::MAX),
            param_id: CharArray::from(p.name),
            param_type: p.value.mav_type(),
        }))
    }

    /// Answers PARAM_REQUEST_LIST, PARAM_REQUEST_READ and PARAM_SET addressed to this drone's
    /// autopilot (or broadcast); every other message gets an empty reply.
    pub fn handle(&mut self, msg: &MavMessage) -> ParamReply {
        match msg {
            MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA { target_system, target_component })
                if self.addressed(*target_system, *target_component) =>
            {
                ParamReply {
                    messages: (0..self.params.len()).filter_map(|i| self.value_message(i)).collect(),
                    ..ParamReply::default()
                }
            }
            MavMessage::PARAM_REQUEST_READ(req) if self.addressed(req.target_system, req.target_component) => {
                ParamReply { messages: self.read(req).into_iter().collect(), ..ParamReply::default() }
            }
            MavMessage::PARAM_SET(set) if self.addressed(set.target_system, set.target_component) => self.write(set),
            _ => ParamReply::default(),
        }
    }

    fn addressed(&self, target_system: u8, target_component: u8) -> bool {
        (target_system == 0 || target_system == self.system_id)
            && (target_component == 0 || target_component == AUTOPILOT_COMPONENT_ID)
    }

    /// By index when `param_index >= 0`, else by name (PX4); unknown: no answer.
    fn read(&self, req: &PARAM_REQUEST_READ_DATA) -> Option<MavMessage> {
        let index = match usize::try_from(req.param_index) {
            Ok(index) => index,
            Err(_) => self.index_of(req.param_id.to_str().ok()?)?,
        };
        self.value_message(index)
    }

    fn write(&mut self, set: &PARAM_SET_DATA) -> ParamReply {
        let Some(index) = set.param_id.to_str().ok().and_then(|name| self.index_of(name)) else {
            return ParamReply::default();
        };
        let name = self.params[index].name;
        let result = match ParamValue::from_wire(set.param_value, set.param_type) {
            Some(value) => self.set(name, value),
            None => Err(SetRejection::TypeMismatch {
                name,
                expected: self.params[index].value.mav_type(),
                got: set.param_type,
            }),
        };
        let (navigator_changed, rejection) = match result {
            Ok(changed) => (changed && is_navigator_param(name), None),
            Err(why) => (false, Some(why)),
        };
        ParamReply { messages: self.value_message(index).into_iter().collect(), navigator_changed, rejection }
    }
}

#[cfg(test)]
mod tests;
