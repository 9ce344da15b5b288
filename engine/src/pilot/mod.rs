//! Pilots that fly drones without an external program: scripted missions from the
//! scenario (`scripted` expands them, `scripted_pilot` flies them). External MAVLink pilots
//! connect through the `mavlink` module instead.

pub mod scripted;
pub mod scripted_pilot;

pub use scripted_pilot::ScriptedPilot;
