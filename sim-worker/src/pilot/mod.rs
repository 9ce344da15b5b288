//! Pilots that fly drones without an external program: scripted missions from the
//! scenario. External MAVLink pilots connect through the `mavlink` module instead.

pub mod scripted;
