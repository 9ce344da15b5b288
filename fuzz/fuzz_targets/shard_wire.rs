//! The shard protocol's payload decoder (`sim-worker/src/transport/wire.rs`: the binary
//! frames between the coordinator and the shard pods) on arbitrary payloads, as both
//! directions' messages.
//!
//! The module is compiled here from sim-worker's own source file (`#[path]`): it needs only
//! the engine's protocol types and serde_json, while depending on sim-worker would bring its
//! whole tree (axum, tokio, the recorder, the renderer) into this build.
//!
//! What is asserted: never a panic, hang or runaway allocation (a count the payload cannot
//! hold is refused before anything is allocated); an error is one line naming the byte
//! offset; a decoded message encodes to a payload that decodes to the same message (the
//! same bytes again); an `Advance` payload is decoded exactly (its encoding is the input).
#![no_main]

use libfuzzer_sys::fuzz_target;
use sadesim_engine::protocol::{FromShard, ToShard};

#[allow(dead_code, clippy::all)]
#[path = "../../sim-worker/src/transport/wire.rs"]
mod wire;

use wire::Wire;

fuzz_target!(|data: &[u8]| {
    check::<ToShard>(data);
    check::<FromShard>(data);
});

fn check<T: Wire + std::fmt::Debug>(payload: &[u8]) {
    match T::decode(payload) {
        Ok(message) => {
            let mut once = Vec::new();
            message.encode(&mut once);
            let again =
                T::decode(&once).unwrap_or_else(|e| panic!("{message:?} encodes to an undecodable payload: {e}"));
            let mut twice = Vec::new();
            again.encode(&mut twice);
            assert_eq!(once, twice, "{message:?} changed in a round trip");
            if payload.first() == Some(&b'A') {
                assert_eq!(once, payload, "an Advance decodes to another message");
            }
        }
        Err(e) => {
            assert!(!e.contains('\n'), "not one line: {e:?}");
            assert!(e.contains("byte "), "the error names no byte offset: {e:?}");
        }
    }
}
