//! Run events as ULog logged strings (`L`), with the severity PX4 would use: routine state
//! changes are INFO, refusals and failsafes CRITICAL (PX4's `mavlink_log_critical`), zone
//! denials and expiries WARNING, rule violations ERROR, crashes EMERGENCY.

use super::writer::LogLevel;
use sadesim_engine::events::{EventKind, FlightMode};

/// Mode names as PX4 shows them (Flight Review, QGroundControl).
pub fn mode_name(mode: FlightMode) -> &'static str {
    match mode {
        FlightMode::Idle => "Idle (Hold)",
        FlightMode::Takeoff => "Takeoff",
        FlightMode::Hold => "Hold",
        FlightMode::Mission => "Mission",
        FlightMode::Offboard => "Offboard",
        FlightMode::ReturnToLaunch => "Return",
        FlightMode::Land => "Land",
    }
}

/// The level and text of an event; `drone_name` names another drone by global index.
pub fn describe(kind: &EventKind, drone_name: impl Fn(u32) -> String) -> (LogLevel, String) {
    use LogLevel::*;
    match kind {
        EventKind::RunStarted { drones, shards } => {
            (Info, format!("[sadesim] run started: {drones} drones on {shards} shards"))
        }
        EventKind::PilotsReleased => (Info, "[sadesim] pilots released".into()),
        EventKind::RunEnded { reason } => (Info, format!("[sadesim] run ended: {reason}")),
        EventKind::Armed => (Info, "[commander] Armed".into()),
        EventKind::Disarmed => (Info, "[commander] Disarmed".into()),
        EventKind::Takeoff => (Info, "[commander] Takeoff detected".into()),
        EventKind::Landed => (Info, "[commander] Landing detected".into()),
        EventKind::Crashed { with, speed_mps } => {
            (Emergency, format!("[sadesim] crashed into {with} at {speed_mps:.1} m/s"))
        }
        EventKind::ModeChanged { from, to } => {
            (Info, format!("[commander] mode: {} -> {}", mode_name(*from), mode_name(*to)))
        }
        EventKind::WaypointReached { seq } => (Info, format!("[navigator] mission item {seq} reached")),
        EventKind::MissionCompleted => (Info, "[navigator] mission finished".into()),
        EventKind::Failsafe { reason, action } => {
            (Critical, format!("[commander] failsafe activated: {reason}, action: {}", mode_name(*action)))
        }
        EventKind::CommandRejected { command, reason } => {
            (Critical, format!("[commander] {command} rejected: {reason}"))
        }
        EventKind::ZoneRequested { zone, request, operator, min_agl_m, max_agl_m } => (
            Info,
            format!("[airspace] request {request} for zone {zone} by {operator}, {min_agl_m:.0}..{max_agl_m:.0} m AGL"),
        ),
        EventKind::ZoneGranted { zone, request, lease, expires_at_s, .. } => (
            Info,
            format!("[airspace] request {request} for zone {zone} granted: lease {lease} until {expires_at_s:.1} s"),
        ),
        EventKind::ZoneDenied { zone, request, reason, message } => {
            (Warning, format!("[airspace] request {request} for zone {zone} denied: {reason}: {message}"))
        }
        EventKind::LeaseRenewed { zone, lease, expires_at_s } => {
            (Info, format!("[airspace] lease {lease} for zone {zone} renewed until {expires_at_s:.1} s"))
        }
        EventKind::LeaseReleased { zone, lease } => {
            (Info, format!("[airspace] lease {lease} for zone {zone} released"))
        }
        EventKind::LeaseExpired { zone, lease } => {
            (Warning, format!("[airspace] lease {lease} for zone {zone} expired"))
        }
        EventKind::ZoneEntered { zone, authorized: true, at } => {
            (Info, format!("[airspace] entered zone {zone} (authorized) at {:.1} m AGL", at.height_agl_m))
        }
        EventKind::ZoneEntered { zone, authorized: false, at } => {
            (Error, format!("[airspace] entered zone {zone} WITHOUT authorization at {:.1} m AGL", at.height_agl_m))
        }
        EventKind::ZoneExited { zone, duration_s, .. } => {
            (Info, format!("[airspace] left zone {zone} after {duration_s:.1} s"))
        }
        EventKind::ViolationStarted { rule, zone, other, detail, .. } => {
            let mut text = format!("[airspace] violation started: {rule}");
            if let Some(zone) = zone {
                text.push_str(&format!(" (zone {zone})"));
            }
            if let Some(other) = other {
                text.push_str(&format!(" (with {})", drone_name(*other)));
            }
            text.push_str(&format!(": {detail}"));
            (Error, text)
        }
        EventKind::ViolationEnded { rule, duration_s, worst_m, .. } => {
            (Notice, format!("[airspace] violation ended: {rule} after {duration_s:.1} s, worst {worst_m:.1} m"))
        }
    }
}
