//! Deterministic port plan.
//!
//! PX4 SITL conventions where they exist, so SDK defaults work unchanged:
//!
//! | what | port | why |
//! |---|---|---|
//! | drone i API/offboard link (drone sends, pilot listens) | 14540+i for i < 10, 14600+i for i >= 10 | PX4 SITL uses 14540+i; 14550.. is kept for the GCS |
//! | drone i endpoint (pilot connects: `udpout`/`tcpout`) | 24600+i, UDP and TCP | one free range above every API port |
//! | router segment s, GCS UDP | 14550+s | QGroundControl listens on 14550 |
//! | router segment s, GCS TCP | 5760+s | the SITL TCP convention |
//!
//! With the maximum of 10 000 drones: API ports 14540..14549 and 14610..24599, GCS UDP
//! 14550..14589, endpoints 24600..34599: no overlap. (PX4 itself collides at instance 10,
//! whose API port 14550 is QGroundControl's; we shift instead.)

use sadesim_crds::fleet::MAX_DRONES;
use sadesim_crds::plan::ServicePorts;

/// MAVLink system ids per router segment (1..=250; 251..=255 are left for ground stations
/// and companions, e.g. MAVSDK's 245 and QGroundControl's 255).
pub const SYSTEM_IDS_PER_SEGMENT: u32 = 250;
/// Segments needed for the largest fleet.
pub const MAX_SEGMENTS: u32 = MAX_DRONES.div_ceil(SYSTEM_IDS_PER_SEGMENT);

const API_BASE: u32 = 14540;
const API_SHIFTED_BASE: u32 = 14600;
const ENDPOINT_BASE: u32 = 24600;
const GCS_UDP_BASE: u32 = 14550;
const GCS_TCP_BASE: u32 = 5760;

/// Port drone `index` sends its API link to on the pilot's host.
pub fn api_udp_port(index: u32) -> u16 {
    let port = if index < 10 { API_BASE + index } else { API_SHIFTED_BASE + index };
    u16::try_from(port).expect("index < MAX_DRONES keeps ports below 65536")
}

/// Port drone `index` listens on (UDP and TCP) for clients that connect to it.
pub fn endpoint_port(index: u32) -> u16 {
    u16::try_from(ENDPOINT_BASE + index).expect("index < MAX_DRONES keeps ports below 65536")
}

/// GCS UDP port of router segment `segment`.
pub fn gcs_udp_port(segment: u32) -> u16 {
    u16::try_from(GCS_UDP_BASE + segment).expect("segment < MAX_SEGMENTS")
}

/// GCS TCP port of router segment `segment`.
pub fn gcs_tcp_port(segment: u32) -> u16 {
    u16::try_from(GCS_TCP_BASE + segment).expect("segment < MAX_SEGMENTS")
}

/// Ports of the run-wide services (the same locally and in every pod).
pub fn service_ports() -> ServicePorts {
    ServicePorts { coordinator: 7400, airspace_http: 8480, renderer_http: 8490, metrics: 9090 }
}
