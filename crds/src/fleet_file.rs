//! The fleet file (`fleet.json`, path in `SADESIM_FLEET`): everything a pilot needs to find
//! and fly its drones. Pilots in any language read it; keep it plain JSON and stable.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::fleet::Role;
use crate::geo::GeoPoint;

/// Bumped on incompatible changes.
pub const FLEET_FILE_VERSION: u32 = 1;

#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct FleetFile {
    pub version: u32,
    /// Run name.
    pub run: String,
    /// Origin of the run's local frame.
    pub origin: GeoPoint,
    /// Airspace authority base URL (e.g. `http://127.0.0.1:8480`).
    pub airspace_url: String,
    /// MAVLink GCS endpoints of the router segments, in segment order.
    pub gcs_urls: Vec<String>,
    pub drones: Vec<FleetDrone>,
    /// Zones as a GeoJSON FeatureCollection (polygons with floor/ceiling/policy properties).
    pub zones: serde_json::Value,
}

/// One drone as the pilot sees it.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct FleetDrone {
    pub index: u32,
    pub name: String,
    pub group: String,
    pub operator: String,
    pub role: Role,
    pub airframe: String,
    pub system_id: u8,
    pub component_id: u8,
    /// Name of the environment variable that holds the drone's bearer credential for the
    /// airspace API (the value itself never appears in this file).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub credential_env: Option<String>,
    pub mavlink: MavlinkUrls,
    pub home: GeoPoint,
    pub max_altitude_agl_m: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min_altitude_agl_m: Option<f64>,
    /// Flown by a scripted mission (the pilot should leave it alone).
    pub scripted: bool,
    /// The drone's onboard cameras (`spec.fleet[].cameras`) by name: the base URL of each
    /// camera's frames, ending in `/` (append `latest.jpg`, `next.jpg?after=T`, ...). Absent
    /// when the run serves no camera frames.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub cameras: BTreeMap<String, String>,
}

/// Ways to reach a drone over MAVLink, in MAVSDK/pymavlink URL syntax.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct MavlinkUrls {
    /// Listen here to receive the drone's API link (PX4 SITL style), e.g. `udpin://0.0.0.0:14540`.
    pub api: String,
    /// Connect to the drone's endpoint over UDP, e.g. `udpout://127.0.0.1:24600`.
    pub udp: String,
    /// Connect to the drone's endpoint over TCP, e.g. `tcpout://127.0.0.1:24600`.
    pub tcp: String,
}
