//! The MAVLink sockets: a drone's endpoint (UDP to ground stations and the API link, TCP
//! for pilots that dial in), the uplink to the fleet router, and the router itself. The
//! frames, signing and the per-drone session they carry are `sadesim_engine::mavlink`.

pub mod endpoint;
pub mod router;
pub mod uplink;
