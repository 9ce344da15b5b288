//! The MAVLink edge of a drone (the MAVLink issue builds the endpoint, session state
//! machine and router here). So far: PX4's flight-mode encoding, which the HEARTBEAT and
//! DO_SET_MODE need and which must match PX4 bit for bit for ground stations and SDKs.

pub mod px4_mode;
