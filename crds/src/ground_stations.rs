//! `spec.groundStations`: who outside the run may reach its MAVLink routers, drone endpoints
//! and airspace API, and how MAVLink traffic from ground stations is authenticated
//! (issue 19, "isolation per run").

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::fleet::Credential;

/// Shortest passphrase accepted for `signing.key`, characters: anything shorter is guessed
/// offline from one signed frame in moments.
pub const MIN_PASSPHRASE_CHARS: usize = 8;

/// The environment variable that hands the passphrase to `sim-worker router` (never a flag,
/// which `ps` would show).
pub const SIGNING_KEY_ENV: &str = "SADESIM_MAVLINK_SIGNING_KEY";

/// Ground stations (QGroundControl, MAVSDK or pymavlink scripts, MAVProxy) outside the run.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Default, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct GroundStations {
    /// Source address ranges (CIDR, IPv4 or IPv6, e.g. `10.20.0.0/16`) that may reach the
    /// run's MAVLink routers, drone endpoints and airspace API besides the run's own pods.
    /// On Kubernetes the run's NetworkPolicy admits exactly these; empty (the default): only
    /// the run's own pods. Locally every service binds 127.0.0.1 and this has no effect.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    #[schemars(length(max = 64), inner(length(min = 3, max = 49)))]
    pub allow_from: Vec<String>,
    /// MAVLink 2 message signing on the routers' ground-station side.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub signing: Option<Signing>,
}

/// MAVLink 2 signing (the MAVLink signing protocol): the routers accept only ground-station
/// frames signed with the key (and with timestamps that never go back), and sign what they
/// send to ground stations. The drones' own endpoints stay unsigned.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, JsonSchema)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
pub struct Signing {
    /// The passphrase the 32-byte secret key is derived from, as QGroundControl and MAVProxy
    /// derive it: SHA-256 of its UTF-8 bytes (a trailing line break counts). A Secret's key on
    /// Kubernetes (`secretKeyRef`), or an inline `value` of at least 8 characters for local
    /// runs and tests.
    pub key: Credential,
}
