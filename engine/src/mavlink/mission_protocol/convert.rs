//! Item conversion: stored `MISSION_ITEM_INT`s -> the autopilot's [`MissionPlan`], and
//! legacy `MISSION_ITEM` <-> `MISSION_ITEM_INT` encodings.

use ::mavlink::dialects::common::{MISSION_ITEM_DATA, MISSION_ITEM_INT_DATA, MavCmd, MavFrame, MavMissionResult};
use nalgebra::Vector2;

use crate::autopilot::mission::{MissionItem, MissionPlan};

use super::endpoint::MissionContext;

/// `hold_s` of a `MAV_CMD_NAV_LOITER_UNLIM`: never elapses in the navigator's
/// `t - reached >= hold_s` test. `f64::MAX` rather than infinity because plans are
/// serialised as JSON, where infinity does not survive.
pub const HOLD_FOREVER_S: f64 = f64::MAX;
/// How far a `MAV_CMD_NAV_LAND` position may lie from where the previous item leaves the
/// drone and still be flown as "land here", m. The navigator lands where the drone is (one
/// [`MissionItem`] per MAVLink seq and no "fly there, then land" item), so a landing point
/// further away is refused rather than silently landed somewhere else.
pub const LAND_POSITION_TOLERANCE_M: f64 = 5.0;

/// Converts a mission as stored (one `MISSION_ITEM_INT` per seq) into the autopilot's plan,
/// one [`MissionItem`] per seq so `MISSION_CURRENT` and `MISSION_ITEM_REACHED` numbers are
/// the client's own.
///
/// | MAVLink item | [`MissionItem`] |
/// |---|---|
/// | `NAV_WAYPOINT` (param1 hold s; NaN = 0) | `Waypoint` |
/// | `NAV_LOITER_TIME` (param1 s) at a position | `Waypoint` holding param1 |
/// | `NAV_LOITER_TIME` without position (lat/lon 0/0 or `INT32_MAX`) | `Loiter` |
/// | `NAV_LOITER_UNLIM` | as `LOITER_TIME` with [`HOLD_FOREVER_S`] |
/// | `NAV_TAKEOFF` (z = altitude; lat/lon ignored: climb in place) | `Takeoff` |
/// | `NAV_LAND` without position, or within [`LAND_POSITION_TOLERANCE_M`] of the previous item's target | `Land` |
/// | `NAV_RETURN_TO_LAUNCH` | `ReturnToLaunch` |
/// | `DO_CHANGE_SPEED` (param1 type 0/1, param2 m/s) | `ChangeSpeed` |
///
/// Positions: `x`/`y` are lat/lon in 1e-7 degrees in `MAV_FRAME_GLOBAL_RELATIVE_ALT(_INT)`
/// (`z` above home) and `MAV_FRAME_GLOBAL(_INT)` (`z` AMSL, minus
/// [`MissionContext::home_alt_amsl_m`]). The non-INT frame names are accepted in
/// `MISSION_ITEM_INT` with the same 1e-7 encoding, as QGroundControl sends them and PX4 reads
/// them. `RETURN_TO_LAUNCH` and `DO_CHANGE_SPEED` carry no position and also accept
/// `MAV_FRAME_MISSION`.
///
/// `DO_CHANGE_SPEED` speed -1 ("no change") and 0 become a `ChangeSpeed` to the speed in
/// force at that point of the list (the default, or the last change before it), -2 to
/// [`MissionContext::cruise_speed_mps`]; climb/descent speed types (2, 3) keep the speed, as
/// the navigator flies fixed vertical speeds.
///
/// Ignored parameters: acceptance radius, yaw, pass radius, loiter radius, land abort
/// altitude and precision mode, and `LAND`'s altitude (the land detector finds the ground).
///
/// # Errors
/// The first refused item as `(seq, result)`: `MAV_MISSION_UNSUPPORTED` for any other
/// command, `MAV_MISSION_UNSUPPORTED_FRAME` for local, terrain-relative or other frames,
/// `MAV_MISSION_INVALID_PARAM5_X` / `PARAM6_Y` for latitude outside ±90° / longitude outside
/// ±180° (and for a `LAND` point away from the previous target), `PARAM7` for a non-finite
/// altitude or a takeoff altitude not above home, `PARAM1` / `PARAM2` for a negative or
/// non-finite hold time and an invalid speed type / speed.
pub fn to_plan(items: &[MISSION_ITEM_INT_DATA], ctx: &MissionContext) -> Result<MissionPlan, (u16, MavMissionResult)> {
    let mut plan = PlanBuilder::new(ctx.cruise_speed_mps);
    for (i, item) in items.iter().enumerate() {
        plan.push(item, ctx).map_err(|r| (u16::try_from(i).unwrap_or(u16::MAX), r))?;
    }
    Ok(plan.finish())
}

/// Altitude reference of a global frame.
#[derive(Clone, Copy, Debug)]
pub(super) enum AltRef {
    /// Metres above home ground.
    Home,
    /// Metres AMSL.
    Amsl,
}

/// Builds a plan item by item, tracking what later items depend on.
#[derive(Debug)]
pub(super) struct PlanBuilder {
    items: Vec<MissionItem>,
    /// The plan's default cruise speed, m/s.
    default_speed_mps: f64,
    /// Speed in force after the items so far, m/s (for DO_CHANGE_SPEED "no change").
    speed_mps: f64,
    /// Horizontal ENU position the items so far leave the drone at, if known, m.
    at_en_m: Option<Vector2<f64>>,
}

impl PlanBuilder {
    pub(super) fn new(default_speed_mps: f64) -> Self {
        Self { items: Vec::new(), default_speed_mps, speed_mps: default_speed_mps, at_en_m: None }
    }

    pub(super) fn finish(self) -> MissionPlan {
        MissionPlan { items: self.items, speed_mps: self.default_speed_mps }
    }

    pub(super) fn push(&mut self, item: &MISSION_ITEM_INT_DATA, ctx: &MissionContext) -> Result<(), MavMissionResult> {
        use MavMissionResult as R;
        let converted = match item.command {
            MavCmd::MAV_CMD_NAV_WAYPOINT => {
                let hold_s = if item.param1.is_nan() { 0.0 } else { hold_time(item.param1)? };
                self.go_to(item, global(item)?, hold_s, ctx)?
            }
            // A loiter at a position flies there first; without one it holds where the drone
            // is (MAVLink: "NaN or INT32_MAX ... to use the component's current latitude").
            MavCmd::MAV_CMD_NAV_LOITER_TIME | MavCmd::MAV_CMD_NAV_LOITER_UNLIM => {
                let alt_ref = global(item)?;
                let hold_s = match item.command {
                    MavCmd::MAV_CMD_NAV_LOITER_TIME => hold_time(item.param1)?,
                    _ => HOLD_FOREVER_S,
                };
                if position_unset(item) {
                    MissionItem::Loiter { hold_s }
                } else {
                    self.go_to(item, alt_ref, hold_s, ctx)?
                }
            }
            MavCmd::MAV_CMD_NAV_TAKEOFF => {
                let alt_rel_home_m = altitude(item, global(item)?, ctx)?;
                if alt_rel_home_m <= 0.0 {
                    return Err(R::MAV_MISSION_INVALID_PARAM7);
                }
                // Climbs over wherever the drone is when the item starts: position unknown here.
                self.at_en_m = None;
                MissionItem::Takeoff { alt_rel_home_m }
            }
            MavCmd::MAV_CMD_NAV_LAND => {
                global(item)?;
                if !position_unset(item) {
                    let target = horizontal(item, ctx)?;
                    let near = self.at_en_m.is_some_and(|at| (at - target).norm() <= LAND_POSITION_TOLERANCE_M);
                    if !near {
                        return Err(R::MAV_MISSION_INVALID_PARAM5_X);
                    }
                }
                self.at_en_m = None;
                MissionItem::Land
            }
            MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH => {
                positionless(item)?;
                self.at_en_m = None;
                MissionItem::ReturnToLaunch
            }
            MavCmd::MAV_CMD_DO_CHANGE_SPEED => {
                positionless(item)?;
                self.change_speed(item)?
            }
            // Wait where the drone is (MAVSDK sends this for a mission item's
            // `loiter_time_s`). Only the relative delay (param1 >= 0) is supported; the
            // time-of-day form (param1 = -1 with hours/minutes/seconds) is refused.
            MavCmd::MAV_CMD_NAV_DELAY => MissionItem::Loiter { hold_s: hold_time(item.param1)? },
            _ => return Err(R::MAV_MISSION_UNSUPPORTED),
        };
        self.items.push(converted);
        Ok(())
    }

    pub(super) fn go_to(
        &mut self,
        item: &MISSION_ITEM_INT_DATA,
        alt_ref: AltRef,
        hold_s: f64,
        ctx: &MissionContext,
    ) -> Result<MissionItem, MavMissionResult> {
        let target_en_m = horizontal(item, ctx)?;
        let alt_rel_home_m = altitude(item, alt_ref, ctx)?;
        self.at_en_m = Some(target_en_m);
        Ok(MissionItem::Waypoint { target_en_m, alt_rel_home_m, hold_s })
    }

    pub(super) fn change_speed(&mut self, item: &MISSION_ITEM_INT_DATA) -> Result<MissionItem, MavMissionResult> {
        let kind = item.param1;
        let horizontal = kind.is_nan() || kind == 0.0 || kind == 1.0;
        let vertical = kind == 2.0 || kind == 3.0;
        let v = f64::from(item.param2);
        let speed_mps = if vertical {
            self.speed_mps
        } else if !horizontal {
            return Err(MavMissionResult::MAV_MISSION_INVALID_PARAM1);
        } else if v.is_finite() && v > 0.0 {
            v
        } else if v == -2.0 {
            self.default_speed_mps
        } else if v == -1.0 || v == 0.0 {
            self.speed_mps
        } else {
            return Err(MavMissionResult::MAV_MISSION_INVALID_PARAM2);
        };
        self.speed_mps = speed_mps;
        Ok(MissionItem::ChangeSpeed { speed_mps })
    }
}

/// The altitude reference of a positional item's frame; other frames are unsupported.
pub(super) fn global(item: &MISSION_ITEM_INT_DATA) -> Result<AltRef, MavMissionResult> {
    global_alt_ref(item.frame).ok_or(MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME)
}

/// Items without a position: `MAV_FRAME_MISSION` or any global frame (the frame is moot).
pub(super) fn positionless(item: &MISSION_ITEM_INT_DATA) -> Result<(), MavMissionResult> {
    if item.frame == MavFrame::MAV_FRAME_MISSION || global_alt_ref(item.frame).is_some() {
        Ok(())
    } else {
        Err(MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME)
    }
}

pub(super) fn global_alt_ref(frame: MavFrame) -> Option<AltRef> {
    match frame {
        MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT => Some(AltRef::Home),
        MavFrame::MAV_FRAME_GLOBAL | MavFrame::MAV_FRAME_GLOBAL_INT => Some(AltRef::Amsl),
        _ => None,
    }
}

/// Hold time in s: finite and non-negative.
pub(super) fn hold_time(param: f32) -> Result<f64, MavMissionResult> {
    let s = f64::from(param);
    if s.is_finite() && s >= 0.0 { Ok(s) } else { Err(MavMissionResult::MAV_MISSION_INVALID_PARAM1) }
}

/// MAVLink's "use the current position": lat/lon both 0, or `INT32_MAX`.
pub(super) fn position_unset(item: &MISSION_ITEM_INT_DATA) -> bool {
    (item.x == 0 && item.y == 0) || item.x == i32::MAX || item.y == i32::MAX
}

/// Lat/lon (1e-7 degrees) -> ENU east/north from the run origin, m.
pub(super) fn horizontal(item: &MISSION_ITEM_INT_DATA, ctx: &MissionContext) -> Result<Vector2<f64>, MavMissionResult> {
    let lat_deg = f64::from(item.x) * 1e-7;
    let lon_deg = f64::from(item.y) * 1e-7;
    if !(-90.0..=90.0).contains(&lat_deg) {
        return Err(MavMissionResult::MAV_MISSION_INVALID_PARAM5_X);
    }
    if !(-180.0..=180.0).contains(&lon_deg) {
        return Err(MavMissionResult::MAV_MISSION_INVALID_PARAM6_Y);
    }
    let (east_m, north_m) = ctx.frame.to_plane(lat_deg, lon_deg);
    Ok(Vector2::new(east_m, north_m))
}

/// `z` -> metres above home ground.
pub(super) fn altitude(
    item: &MISSION_ITEM_INT_DATA,
    alt_ref: AltRef,
    ctx: &MissionContext,
) -> Result<f64, MavMissionResult> {
    let z = f64::from(item.z);
    if !z.is_finite() {
        return Err(MavMissionResult::MAV_MISSION_INVALID_PARAM7);
    }
    Ok(match alt_ref {
        AltRef::Home => z,
        AltRef::Amsl => z - ctx.home_alt_amsl_m,
    })
}

/// A legacy `MISSION_ITEM` in the INT encoding: in global frames lat/lon degrees -> 1e-7
/// degrees (NaN, MAVLink's "current position" in float fields, -> `INT32_MAX`, its INT
/// spelling); elsewhere param5/6 rounded as they are. The frame is kept.
pub(super) fn legacy_to_int(m: &MISSION_ITEM_DATA) -> MISSION_ITEM_INT_DATA {
    let global = global_alt_ref(m.frame).is_some();
    // `as` saturates: out-of-range degrees become ±INT32_MAX and fail the range check later.
    let encode = |v: f32| match (global, v.is_finite()) {
        (true, true) => (f64::from(v) * 1e7).round() as i32,
        (true, false) => i32::MAX,
        (false, _) => f64::from(v).round() as i32,
    };
    MISSION_ITEM_INT_DATA {
        param1: m.param1,
        param2: m.param2,
        param3: m.param3,
        param4: m.param4,
        x: encode(m.x),
        y: encode(m.y),
        z: m.z,
        seq: m.seq,
        command: m.command,
        target_system: m.target_system,
        target_component: m.target_component,
        frame: m.frame,
        current: m.current,
        autocontinue: m.autocontinue,
        mission_type: m.mission_type,
    }
}

/// The stored item as a legacy `MISSION_ITEM`: float lat/lon degrees in the non-INT frame.
pub(super) fn int_to_legacy(m: &MISSION_ITEM_INT_DATA) -> MISSION_ITEM_DATA {
    let frame = match m.frame {
        MavFrame::MAV_FRAME_GLOBAL_INT => MavFrame::MAV_FRAME_GLOBAL,
        MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT => MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
        other => other,
    };
    let global = global_alt_ref(m.frame).is_some();
    let decode = |v: i32| match (global, v == i32::MAX) {
        (true, true) => f32::NAN,
        (true, false) => (f64::from(v) * 1e-7) as f32,
        (false, _) => v as f32,
    };
    MISSION_ITEM_DATA {
        param1: m.param1,
        param2: m.param2,
        param3: m.param3,
        param4: m.param4,
        x: decode(m.x),
        y: decode(m.y),
        z: m.z,
        seq: m.seq,
        command: m.command,
        target_system: m.target_system,
        target_component: m.target_component,
        frame,
        current: m.current,
        autocontinue: m.autocontinue,
        mission_type: m.mission_type,
    }
}
