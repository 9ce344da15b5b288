//! Flight modes as a pure state machine: commands and mission items in, a control
//! [`Setpoint`] and events out. Behaves like PX4's navigator and commander to its user:
//! TAKEOFF climbs to an altitude and holds, MISSION flies items in order, HOLD keeps
//! position, OFFBOARD follows external setpoints (and falls back to HOLD when they stop),
//! RTL climbs, returns and lands, LAND descends and disarms on touchdown. Arming checks and
//! failsafes (GNSS loss -> LAND, low battery -> RTL, critical battery -> LAND) live here.
//!
//! Positions are ENU metres from the run origin; altitudes in commands are relative to the
//! home position (PX4's relative-altitude frame).

use nalgebra::{Vector2, Vector3};

use crate::autopilot::control::Setpoint;
use crate::autopilot::estimator::Estimate;
use crate::autopilot::mission::{MissionItem, MissionPlan};
use crate::events::{EventKind, FlightMode};

/// Tunables, PX4 parameter names in brackets.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NavigatorConfig {
    /// Horizontal acceptance radius of a waypoint, m [NAV_ACC_RAD].
    pub acceptance_radius_m: f64,
    /// Vertical acceptance, m [NAV_MC_ALT_RAD].
    pub altitude_acceptance_m: f64,
    /// Climb speed during takeoff, m/s [MPC_TKO_SPEED].
    pub takeoff_speed_mps: f64,
    /// Descent speed for the last metres of a landing, m/s [MPC_LAND_SPEED].
    pub land_speed_mps: f64,
    /// Descent speed above `land_slow_below_m`, m/s [MPC_Z_V_AUTO_DN].
    pub descent_speed_mps: f64,
    /// Height above home below which a landing slows to `land_speed_mps`, m [MPC_LAND_ALT2].
    pub land_slow_below_m: f64,
    /// Return altitude above home, m [RTL_RETURN_ALT] (capped by the group's ceiling).
    pub rtl_altitude_m: f64,
    /// Offboard setpoints older than this trigger the offboard-loss failsafe, s [COM_OF_LOSS_T].
    pub offboard_timeout_s: f64,
    /// Remaining battery fraction that triggers RTL [BAT_LOW_THR].
    pub battery_low: f64,
    /// Remaining battery fraction that triggers LAND [BAT_CRIT_THR].
    pub battery_critical: f64,
}

/// PX4's default battery thresholds as fractions of the capacity left: BAT_LOW_THR (return
/// to launch), BAT_CRIT_THR (land), BAT_EMERGEN_THR (the ULogs' emergency warning).
pub const BAT_LOW_THR: f64 = 0.15;
pub const BAT_CRIT_THR: f64 = 0.07;
pub const BAT_EMERGEN_THR: f64 = 0.05;

impl Default for NavigatorConfig {
    fn default() -> Self {
        Self {
            acceptance_radius_m: 1.0,
            altitude_acceptance_m: 0.8,
            takeoff_speed_mps: 1.5,
            land_speed_mps: 0.7,
            descent_speed_mps: 1.5,
            land_slow_below_m: 5.0,
            rtl_altitude_m: 30.0,
            offboard_timeout_s: 1.0,
            battery_low: BAT_LOW_THR,
            battery_critical: BAT_CRIT_THR,
        }
    }
}

/// What the vehicle reports about itself each step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VehicleStatus {
    /// Resting on the ground (land detector).
    pub on_ground: bool,
    /// Remaining battery fraction, 0..1.
    pub battery_remaining: f64,
    /// GNSS fixes are arriving.
    pub gnss_healthy: bool,
    /// The height reference has settled: the estimator knows the barometer's offset from
    /// GNSS height to [`crate::autopilot::estimator::HEIGHT_SETTLED_SIGMA_M`] (PX4 refuses
    /// to arm until its GNSS checks have passed for a while, `EKF2_REQ_GPS_H`).
    pub height_settled: bool,
}

/// A request from a pilot (scripted or, later, over MAVLink).
#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    Arm,
    Disarm,
    /// Take off to an altitude above home, then hold.
    Takeoff {
        altitude_rel_home_m: f64,
    },
    /// Replace the mission (does not start it).
    LoadMission(MissionPlan),
    /// Switch to MISSION and fly from the current item.
    StartMission,
    /// Switch to HOLD here.
    Hold,
    /// Fly to a position (ENU, altitude above home) and hold there (PX4 DO_REPOSITION).
    GoTo {
        target_en_m: Vector2<f64>,
        altitude_rel_home_m: f64,
    },
    /// An offboard setpoint (PX4 SET_POSITION_TARGET_*): followed while in OFFBOARD, kept
    /// otherwise so that a switch to OFFBOARD has something to fly.
    OffboardSetpoint(Setpoint),
    /// Switch to OFFBOARD; refused unless a setpoint arrived within the offboard timeout
    /// (PX4 denies the switch without a setpoint stream).
    StartOffboard,
    /// Make mission item `seq` the current one (MISSION_SET_CURRENT); flown from there when
    /// in (or switched to) MISSION.
    SetCurrentItem(usize),
    ReturnToLaunch,
    Land,
}

/// Why a command was refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum Rejection {
    #[error("arming refused: {0}")]
    ArmingCheck(String),
    #[error("not armed")]
    NotArmed,
    #[error("no mission loaded")]
    NoMission,
    #[error("disarming refused: vehicle is airborne")]
    Airborne,
    #[error("offboard refused: no setpoint received in the last {0} s")]
    NoOffboardSetpoint(f64),
    #[error("mission item {0} does not exist")]
    NoSuchItem(usize),
}

/// Progress through the current mode.
#[derive(Clone, Debug, PartialEq)]
enum Phase {
    /// Moving the setpoint along a straight leg at `speed`; then hold `hold_s` at the end.
    Leg {
        from: Vector3<f64>,
        to: Vector3<f64>,
        started_s: f64,
        speed_mps: f64,
        hold_s: f64,
        reached_s: Option<f64>,
    },
    /// Hold a point until `until_s` (None = forever).
    Hold {
        at: Vector3<f64>,
        until_s: Option<f64>,
    },
    /// Descend above `from`'s horizontal position; the setpoint height `carrot_z` sinks at
    /// the descent speed, then at the land speed near the ground.
    Descend {
        from: Vector3<f64>,
        carrot_z: f64,
        last_s: f64,
    },
    Ground,
}

/// The navigator of one drone.
#[derive(Clone, Debug)]
pub struct Navigator {
    config: NavigatorConfig,
    mode: FlightMode,
    armed: bool,
    /// Home: where the drone armed, ENU (its ground point).
    home_enu_m: Vector3<f64>,
    mission: Option<MissionPlan>,
    current_item: usize,
    phase: Phase,
    /// RTL stage: 0 climb, 1 return, 2 land.
    rtl_stage: u8,
    yaw_rad: f64,
    offboard: Option<(Setpoint, f64)>,
    was_on_ground: bool,
    low_battery_reported: bool,
    events: Vec<EventKind>,
}

impl Navigator {
    pub fn new(config: NavigatorConfig, home_enu_m: Vector3<f64>) -> Self {
        Self {
            config,
            mode: FlightMode::Idle,
            armed: false,
            home_enu_m,
            mission: None,
            current_item: 0,
            phase: Phase::Ground,
            rtl_stage: 0,
            yaw_rad: 0.0,
            offboard: None,
            was_on_ground: true,
            low_battery_reported: false,
            events: Vec::new(),
        }
    }

    pub fn mode(&self) -> FlightMode {
        self.mode
    }
    pub fn is_armed(&self) -> bool {
        self.armed
    }
    pub fn home_enu_m(&self) -> Vector3<f64> {
        self.home_enu_m
    }
    /// Index of the mission item being flown.
    pub fn current_item(&self) -> usize {
        self.current_item
    }
    /// The loaded mission.
    pub fn mission(&self) -> Option<&MissionPlan> {
        self.mission.as_ref()
    }
    /// Tunables in force (the MAVLink parameters change some of them).
    pub fn config(&self) -> &NavigatorConfig {
        &self.config
    }
    pub fn set_config(&mut self, config: NavigatorConfig) {
        self.config = config;
    }
    /// The estimator's position jumped by `delta` (ENU, m): the setpoints derived from the
    /// old estimate (a hold point, a descent's column, a leg's start) move with it, so the
    /// vehicle stays where it is instead of flying the jump. Mission waypoints and home are
    /// places on the map and stay.
    pub fn shift_for_estimate_reset(&mut self, delta: Vector3<f64>) {
        match &mut self.phase {
            Phase::Leg { from, .. } => *from += delta,
            Phase::Hold { at, .. } => *at += delta,
            Phase::Descend { from, carrot_z, .. } => {
                *from += delta;
                *carrot_z += delta.z;
            }
            Phase::Ground => {}
        }
    }

    /// Events since the last call.
    pub fn take_events(&mut self) -> Vec<EventKind> {
        std::mem::take(&mut self.events)
    }

    /// Whether [`Navigator::take_events`] has anything (asked every physics step; taking
    /// an empty list costs more than asking).
    pub fn has_events(&self) -> bool {
        !self.events.is_empty()
    }

    fn set_mode(&mut self, to: FlightMode) {
        if self.mode != to {
            self.events.push(EventKind::ModeChanged { from: self.mode, to });
            self.mode = to;
        }
    }

    fn hold_here(&mut self, est: &Estimate) {
        self.phase = Phase::Hold { at: est.position_enu_m, until_s: None };
    }

    /// Handles a command at sim time `t_s`.
    ///
    /// # Errors
    /// A [`Rejection`] saying why (arming checks, not armed, no mission, airborne).
    pub fn command(
        &mut self,
        cmd: Command,
        t_s: f64,
        est: Option<&Estimate>,
        status: &VehicleStatus,
    ) -> Result<(), Rejection> {
        match cmd {
            Command::Arm => {
                if self.armed {
                    return Ok(());
                }
                self.arming_check(est, status)?;
                let Some(est) = est else { return Err(Rejection::NotArmed) };
                self.armed = true;
                self.home_enu_m = est.position_enu_m;
                self.yaw_rad = crate::vehicle::yaw_of(&est.attitude);
                self.events.push(EventKind::Armed);
                self.set_mode(FlightMode::Hold);
                self.phase = Phase::Ground;
                Ok(())
            }
            Command::Disarm => {
                if !status.on_ground {
                    return Err(Rejection::Airborne);
                }
                self.disarm();
                Ok(())
            }
            // Missions upload while disarmed, as with PX4.
            Command::LoadMission(plan) => {
                self.mission = Some(plan);
                self.current_item = 0;
                Ok(())
            }
            // Setpoints may stream before arming, as PX4 recommends before switching modes.
            Command::OffboardSetpoint(sp) => {
                self.offboard = Some((sp, t_s));
                Ok(())
            }
            Command::SetCurrentItem(seq) => {
                let count = self.mission.as_ref().map_or(0, |m| m.items.len());
                if seq >= count {
                    return Err(Rejection::NoSuchItem(seq));
                }
                self.current_item = seq;
                if self.mode == FlightMode::Mission
                    && let Some(est) = est
                {
                    self.begin_item(t_s, est);
                }
                Ok(())
            }
            _ if !self.armed => Err(Rejection::NotArmed),
            Command::Takeoff { altitude_rel_home_m } => {
                let est = est.ok_or(Rejection::NotArmed)?;
                self.start_takeoff(t_s, est, altitude_rel_home_m);
                self.set_mode(FlightMode::Takeoff);
                Ok(())
            }
            Command::StartMission => {
                let est = est.ok_or(Rejection::NotArmed)?;
                let count = self.mission.as_ref().map_or(0, |m| m.items.len());
                if count == 0 {
                    return Err(Rejection::NoMission);
                }
                if self.current_item >= count {
                    self.current_item = 0; // a finished mission starts over, as in PX4
                }
                self.set_mode(FlightMode::Mission);
                self.begin_item(t_s, est);
                Ok(())
            }
            Command::Hold => {
                let est = est.ok_or(Rejection::NotArmed)?;
                self.set_mode(FlightMode::Hold);
                self.hold_here(est);
                Ok(())
            }
            Command::GoTo { target_en_m, altitude_rel_home_m } => {
                let est = est.ok_or(Rejection::NotArmed)?;
                let to = Vector3::new(target_en_m.x, target_en_m.y, self.home_enu_m.z + altitude_rel_home_m);
                self.set_mode(FlightMode::Hold);
                self.phase = self.leg(t_s, est.position_enu_m, to, self.cruise_speed(), 0.0);
                Ok(())
            }
            Command::StartOffboard => {
                let fresh = self.offboard.is_some_and(|(_, at)| t_s - at <= self.config.offboard_timeout_s);
                if !fresh {
                    return Err(Rejection::NoOffboardSetpoint(self.config.offboard_timeout_s));
                }
                self.set_mode(FlightMode::Offboard);
                Ok(())
            }
            Command::ReturnToLaunch => {
                let est = est.ok_or(Rejection::NotArmed)?;
                self.start_rtl(t_s, est);
                Ok(())
            }
            Command::Land => {
                let est = est.ok_or(Rejection::NotArmed)?;
                self.start_land(t_s, est);
                Ok(())
            }
        }
    }

    /// PX4's preflight checks that this simulation models: a position estimate from a GNSS
    /// fix of good accuracy, a battery above the low threshold, resting on the ground.
    ///
    /// # Errors
    /// [`Rejection::ArmingCheck`] naming the first failing check.
    pub fn arming_check(&self, est: Option<&Estimate>, status: &VehicleStatus) -> Result<(), Rejection> {
        let Some(est) = est else {
            return Err(Rejection::ArmingCheck("no position estimate (waiting for a GNSS fix)".into()));
        };
        if !status.gnss_healthy {
            return Err(Rejection::ArmingCheck("no GNSS fix".into()));
        }
        if est.eph_m > 5.0 {
            return Err(Rejection::ArmingCheck(format!("horizontal position accuracy {:.1} m > 5 m", est.eph_m)));
        }
        if !status.height_settled {
            return Err(Rejection::ArmingCheck(
                "height estimate not settled (calibrating the barometer on GNSS)".into(),
            ));
        }
        if status.battery_remaining <= self.config.battery_low {
            return Err(Rejection::ArmingCheck(format!(
                "battery {:.0}% at or below the low threshold",
                status.battery_remaining * 100.0
            )));
        }
        if !status.on_ground {
            return Err(Rejection::ArmingCheck("not on the ground".into()));
        }
        Ok(())
    }

    fn disarm(&mut self) {
        if self.armed {
            self.armed = false;
            self.events.push(EventKind::Disarmed);
        }
        self.set_mode(FlightMode::Idle);
        self.phase = Phase::Ground;
        self.offboard = None;
    }

    fn cruise_speed(&self) -> f64 {
        self.mission.as_ref().map_or(crate::autopilot::mission::DEFAULT_CRUISE_MPS, |m| m.speed_mps)
    }

    fn leg(&self, t_s: f64, from: Vector3<f64>, to: Vector3<f64>, speed_mps: f64, hold_s: f64) -> Phase {
        Phase::Leg { from, to, started_s: t_s, speed_mps, hold_s, reached_s: None }
    }

    fn start_takeoff(&mut self, t_s: f64, est: &Estimate, altitude_rel_home_m: f64) {
        let from = est.position_enu_m;
        let to = Vector3::new(from.x, from.y, self.home_enu_m.z + altitude_rel_home_m);
        self.phase = self.leg(t_s, from, to, self.config.takeoff_speed_mps, 0.0);
    }

    fn start_rtl(&mut self, t_s: f64, est: &Estimate) {
        self.set_mode(FlightMode::ReturnToLaunch);
        self.rtl_stage = 0;
        let p = est.position_enu_m;
        let climb_to = p.z.max(self.home_enu_m.z + self.config.rtl_altitude_m);
        self.phase = self.leg(t_s, p, Vector3::new(p.x, p.y, climb_to), self.config.takeoff_speed_mps, 0.0);
    }

    fn start_land(&mut self, t_s: f64, est: &Estimate) {
        self.set_mode(FlightMode::Land);
        self.phase = Phase::Descend { from: est.position_enu_m, carrot_z: est.position_enu_m.z, last_s: t_s };
    }

    /// Starts mission item `current_item`.
    fn begin_item(&mut self, t_s: f64, est: &Estimate) {
        let Some(mission) = &self.mission else { return };
        let Some(item) = mission.items.get(self.current_item).cloned() else {
            self.events.push(EventKind::MissionCompleted);
            self.set_mode(FlightMode::Hold);
            self.hold_here(est);
            return;
        };
        let p = est.position_enu_m;
        let home_z = self.home_enu_m.z;
        match item {
            MissionItem::Takeoff { alt_rel_home_m } => self.start_takeoff(t_s, est, alt_rel_home_m),
            MissionItem::Waypoint { target_en_m, alt_rel_home_m, hold_s } => {
                let to = Vector3::new(target_en_m.x, target_en_m.y, home_z + alt_rel_home_m);
                self.phase = self.leg(t_s, p, to, mission.speed_mps, hold_s);
            }
            MissionItem::Loiter { hold_s } => {
                // At the current position setpoint, as PX4 does
                // (`setLoiterItemFromCurrentPositionSetpoint`): after a takeoff or a
                // waypoint, the target just reached, not wherever the acceptance radius
                // (0.8 m vertically) let the leg end.
                let at = match &self.phase {
                    Phase::Leg { to, .. } => *to,
                    Phase::Hold { at, .. } => *at,
                    _ => p,
                };
                self.phase = Phase::Hold { at, until_s: Some(t_s + hold_s) };
            }
            MissionItem::ReturnToLaunch => self.start_rtl(t_s, est),
            MissionItem::Land => self.start_land(t_s, est),
            MissionItem::ChangeSpeed { speed_mps } => {
                if let Some(m) = &mut self.mission {
                    m.speed_mps = speed_mps;
                }
                self.item_done(t_s, est);
            }
        }
    }

    /// Advances the state machine at sim time `t_s` and returns the setpoint to fly.
    pub fn update(&mut self, t_s: f64, est: Option<&Estimate>, status: &VehicleStatus) -> Setpoint {
        // Take-off and touch-down events from the land detector.
        if self.armed && self.was_on_ground && !status.on_ground {
            self.events.push(EventKind::Takeoff);
        }
        if self.armed && !self.was_on_ground && status.on_ground {
            self.events.push(EventKind::Landed);
        }
        self.was_on_ground = status.on_ground;

        let Some(est) = est else { return Setpoint::Idle };
        if !self.armed {
            return Setpoint::Idle;
        }
        self.failsafes(t_s, est, status);
        if !self.armed {
            return Setpoint::Idle;
        }

        if self.mode == FlightMode::Offboard {
            match self.offboard {
                Some((sp, at)) if t_s - at <= self.config.offboard_timeout_s => return sp,
                _ => {
                    self.events.push(EventKind::Failsafe { reason: "offboardLost".into(), action: FlightMode::Hold });
                    self.offboard = None;
                    self.set_mode(FlightMode::Hold);
                    self.hold_here(est);
                }
            }
        }

        let p = est.position_enu_m;
        match self.phase.clone() {
            // Armed on the ground and waiting for a takeoff: motors at idle (PX4 spins them
            // slowly; no thrust to speak of), no position control fighting the ground.
            Phase::Ground => Setpoint::Idle,
            Phase::Hold { at, until_s } => {
                if until_s.is_some_and(|u| t_s >= u) {
                    self.item_done(t_s, est);
                }
                self.position(at, Vector3::zeros())
            }
            Phase::Descend { from, carrot_z, last_s } => {
                if status.on_ground {
                    self.disarm();
                    return Setpoint::Idle;
                }
                // The setpoint keeps sinking below the vehicle so it reaches the ground and
                // the land detector fires; slower for the last metres, like PX4.
                let high = p.z - self.home_enu_m.z > self.config.land_slow_below_m;
                let speed = if high { self.config.descent_speed_mps } else { self.config.land_speed_mps };
                let carrot_z = carrot_z.min(p.z + 1.0) - speed * (t_s - last_s);
                self.phase = Phase::Descend { from, carrot_z, last_s: t_s };
                self.position(Vector3::new(from.x, from.y, carrot_z), Vector3::new(0.0, 0.0, -speed))
            }
            Phase::Leg { from, to, started_s, speed_mps, hold_s, reached_s } => {
                let delta = to - from;
                let length = delta.norm();
                let travelled = (speed_mps * (t_s - started_s)).min(length);
                let dir = if length > 1e-9 { delta / length } else { Vector3::zeros() };
                let carrot = from + dir * travelled;
                let ff = if travelled < length { dir * speed_mps } else { Vector3::zeros() };
                let horizontal = Vector2::new(to.x - p.x, to.y - p.y);
                if horizontal.norm() > 2.0 && travelled < length {
                    // Face the direction of travel (PX4 MPC_YAW_MODE 0).
                    self.yaw_rad = horizontal.y.atan2(horizontal.x);
                }
                let arrived = horizontal.norm() <= self.config.acceptance_radius_m
                    && (to.z - p.z).abs() <= self.config.altitude_acceptance_m;
                match reached_s {
                    None if arrived => {
                        self.phase = Phase::Leg { from, to, started_s, speed_mps, hold_s, reached_s: Some(t_s) };
                        if hold_s <= 0.0 {
                            self.leg_done(t_s, est);
                        }
                    }
                    Some(r) if t_s - r >= hold_s => self.leg_done(t_s, est),
                    _ => {}
                }
                self.position(carrot, ff)
            }
        }
    }

    fn position(&self, at: Vector3<f64>, velocity_ff: Vector3<f64>) -> Setpoint {
        Setpoint::Position { position_enu_m: at, yaw_rad: self.yaw_rad, velocity_ff }
    }

    /// A leg's end was reached (and its hold elapsed).
    fn leg_done(&mut self, t_s: f64, est: &Estimate) {
        match self.mode {
            FlightMode::Takeoff | FlightMode::Hold => {
                if let Phase::Leg { to, .. } = self.phase {
                    self.phase = Phase::Hold { at: to, until_s: None };
                }
                if self.mode == FlightMode::Takeoff {
                    self.set_mode(FlightMode::Hold);
                }
            }
            FlightMode::ReturnToLaunch => {
                self.rtl_stage += 1;
                let p = est.position_enu_m;
                if self.rtl_stage == 1 {
                    let to = Vector3::new(self.home_enu_m.x, self.home_enu_m.y, p.z);
                    self.phase = self.leg(t_s, p, to, self.cruise_speed(), 0.0);
                } else {
                    self.phase = Phase::Descend { from: p, carrot_z: p.z, last_s: t_s };
                }
            }
            _ => self.item_done(t_s, est),
        }
    }

    /// The current mission item is finished: report it and start the next.
    fn item_done(&mut self, t_s: f64, est: &Estimate) {
        if self.mode != FlightMode::Mission {
            return;
        }
        self.events.push(EventKind::WaypointReached { seq: self.current_item as u32 });
        self.current_item += 1;
        self.begin_item(t_s, est);
    }

    fn failsafes(&mut self, t_s: f64, est: &Estimate, status: &VehicleStatus) {
        if status.on_ground {
            return;
        }
        let landing = matches!(self.phase, Phase::Descend { .. });
        if !status.gnss_healthy && !landing {
            // Without GNSS the position estimate drifts: descend in place (PX4 COM_POSCTL_NAVL).
            self.events.push(EventKind::Failsafe { reason: "gnssLost".into(), action: FlightMode::Land });
            self.start_land(t_s, est);
        } else if status.battery_remaining <= self.config.battery_critical && !landing {
            self.events.push(EventKind::Failsafe { reason: "batteryCritical".into(), action: FlightMode::Land });
            self.start_land(t_s, est);
        } else if status.battery_remaining <= self.config.battery_low
            && !self.low_battery_reported
            && self.mode != FlightMode::ReturnToLaunch
            && !landing
        {
            self.low_battery_reported = true;
            self.events.push(EventKind::Failsafe { reason: "batteryLow".into(), action: FlightMode::ReturnToLaunch });
            self.start_rtl(t_s, est);
        }
    }
}

#[cfg(test)]
mod tests;
