//! MAVLink 2 signing on the router's ground-station side: what the router keeps to check
//! ground stations' frames and sign its own. Its refusals are logged by `refusal_log`.
//!
//! The drone side stays unsigned: the drones' endpoints are inside the run.

use std::sync::Mutex;

use sadesim_engine::mavlink::signing::{SecretKey, Signer, Verifier};

/// The link id in the signatures of frames the router sends to ground stations. Receivers
/// keep one replay stream per (link id, system id, component id); the system and component
/// ids are the drones', so one link id serves every ground station.
pub const ROUTER_LINK_ID: u8 = 0;
/// SETUP_SIGNING, which the router never passes on when it signs (it holds the key).
pub(super) const SETUP_SIGNING_ID: u32 = 256;

/// Signing state shared by the router's threads.
#[derive(Debug)]
pub(super) struct GcsSigning {
    /// Signs drone frames on their way to the ground stations.
    pub(super) signer: Signer,
    /// Checks ground stations' frames (one replay table for UDP and TCP: a frame captured
    /// on one and replayed on the other is still a replay).
    pub(super) verifier: Mutex<Verifier>,
}

impl GcsSigning {
    pub(super) fn new(key: SecretKey) -> Self {
        Self { signer: Signer::new(key.clone(), ROUTER_LINK_ID), verifier: Mutex::new(Verifier::new(key)) }
    }
}
