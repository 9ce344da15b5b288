//! Requests to end a running coordinator's run early, from outside its process: the stdin
//! line (`sadesim run --processes`) and the Pod annotation (Kubernetes), each carrying an
//! [`EndReason`]. The polling and parsing live with the coordinator role.

use serde::{Deserialize, Serialize};

use super::ending::EndReason;

/// Pod annotation whose value is the reason to end the run (e.g. `pilotExited`).
pub const STOP_ANNOTATION: &str = "sadesim.io/stop";

/// One line of the coordinator's stdin.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(tag = "type", rename_all = "camelCase", rename_all_fields = "camelCase")]
pub enum Control {
    /// End the run after the current window with this reason (e.g. `pilotExited`).
    Stop { reason: EndReason },
}
