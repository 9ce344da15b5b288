//! The MAVLink router's datagram path (`sim-worker/src/mavlink/router`) on arbitrary
//! datagrams, through the pure functions it calls: the router itself opens sockets and
//! threads, and sim-worker's dependency tree (axum, tokio, the recorder, the renderer) would
//! triple this crate's build, so this target makes the same calls in the same order.
//!
//! - Drone side (`Shared::drone_frames`): the frames of a shard's datagram are checked where
//!   they lie (`DatagramFrames`); the router's own frames are dropped; without signing the
//!   clean datagram goes on as it came, otherwise the frames are copied out; with signing
//!   every frame is signed (`Signer::sign_into`). Then the GCS side's gathering splits what
//!   goes out at frame boundaries (`whole_frame_len`, `Gathered::add`).
//! - GCS side (`Shared::parse_gcs`, `route_gcs_frames`): the stream parser, the signature
//!   check, SETUP_SIGNING never passed on, and each frame's destination system.
//!
//! What is asserted: never a panic; what the router forwards is whole frames only, exactly
//! the good frames of the datagram that are not its own, in order; a signed frame it sends
//! decodes to the same message and passes a ground station's signature check (which refuses
//! it when replayed); the destination of every GCS frame indexes the 256-entry table.
#![no_main]

use std::borrow::Cow;

use libfuzzer_sys::fuzz_target;
use sadesim_engine::mavlink::frame::{DatagramFrames, Decoded, FrameParser, FrameRef, target_system, whole_frame_len};
use sadesim_engine::mavlink::signing::{Refusal, Signer, Verifier};
use sadesim_fuzz::{NOW, key, repaired};

/// The router's own ids (`sim-worker/src/mavlink/router/config.rs`).
const ROUTER_SYSTEM_ID: u8 = 253;
const ROUTER_COMPONENT_ID: u8 = 240;
/// SETUP_SIGNING.
const SETUP_SIGNING_ID: u32 = 256;
/// The largest datagram the router sends a ground station (`router/sockets.rs`).
const GCS_DATAGRAM: usize = 1400;

fuzz_target!(|data: &[u8]| {
    drone_side(data);
    let fixed = repaired(data, Some(&key()));
    drone_side(&fixed);
    gcs_side(&fixed);
});

fn own(f: &FrameRef<'_>) -> bool {
    f.header.system_id == u32::from(ROUTER_SYSTEM_ID) && f.header.component_id == ROUTER_COMPONENT_ID
}

/// `Shared::drone_frames` without and with signing, then the gathering.
fn drone_side(datagram: &[u8]) {
    let expected: Vec<&[u8]> = DatagramFrames::new(datagram).filter(|f| !own(f)).map(|f| f.bytes).collect();

    // Without signing.
    let mut frames = DatagramFrames::new(datagram);
    let (mut covered, mut any_own) = (0, false);
    for f in frames.by_ref() {
        covered += f.bytes.len();
        any_own |= own(&f);
    }
    let out: Cow<'_, [u8]> = if covered == datagram.len() && !any_own {
        Cow::Borrowed(datagram)
    } else {
        let mut kept = Vec::with_capacity(covered);
        for f in DatagramFrames::new(datagram).filter(|f| !own(f)) {
            kept.extend_from_slice(f.bytes);
        }
        Cow::Owned(kept)
    };
    assert_eq!(out.as_ref(), expected.concat(), "forwarded bytes are not the datagram's good frames");
    let mut again = DatagramFrames::new(&out);
    let forwarded: Vec<&[u8]> = again.by_ref().map(|f| f.bytes).collect();
    assert_eq!(forwarded, expected, "what the router forwards does not parse as the same frames");
    assert_eq!(again.stats.skipped_bytes + again.stats.bad_checksum, 0, "the router forwarded garbage");
    gather(&out, &expected);

    // With signing: every frame signed, and a ground station with the key accepts each once.
    let signer = Signer::new(key(), 0);
    let mut signed = Vec::with_capacity(datagram.len() * 2);
    for f in DatagramFrames::new(datagram).filter(|f| !own(f)) {
        signer.sign_into(&mut signed, f.bytes, NOW);
    }
    let received = FrameParser::new().push(&signed);
    assert_eq!(received.len(), expected.len(), "a signed frame did not parse");
    let mut gcs = Verifier::new(key());
    for (f, original) in received.iter().zip(&expected) {
        let n = usize::from(original[1]);
        assert_eq!(f.bytes[10..10 + n], original[10..10 + n], "signing changed the payload");
        assert_eq!(gcs.check(&f.bytes, NOW), Ok(()), "a frame the router signed is refused");
        assert_eq!(gcs.check(&f.bytes, NOW), Err(Refusal::OldTimestamp), "a replay was accepted");
    }
    let signed_frames: Vec<&[u8]> = received.iter().map(|f| f.bytes.as_slice()).collect();
    gather(&signed, &signed_frames);
}

/// `Gathered::add`: splits whole frames into datagrams of at most GCS_DATAGRAM bytes (or
/// one frame) at frame boundaries.
fn gather(frames: &[u8], expected: &[&[u8]]) {
    let mut datagrams: Vec<Vec<u8>> = vec![Vec::new()];
    let mut lens = Vec::new();
    let mut rest = frames;
    while !rest.is_empty() {
        let len = whole_frame_len(rest).unwrap_or(rest.len());
        assert!(len > 0, "a zero-length frame would loop forever");
        let last = datagrams.last_mut().expect("one datagram");
        if !last.is_empty() && last.len() + len > GCS_DATAGRAM {
            datagrams.push(Vec::new());
        }
        datagrams.last_mut().expect("one datagram").extend_from_slice(&rest[..len]);
        lens.push(len);
        rest = &rest[len..];
    }
    assert_eq!(lens, expected.iter().map(|f| f.len()).collect::<Vec<_>>(), "gathering split a frame");
    assert!(datagrams.iter().all(|d| d.len() <= GCS_DATAGRAM || whole_frame_len(d) == Some(d.len())));
}

/// `Shared::parse_gcs` with signing, then the routing decision of each frame.
fn gcs_side(bytes: &[u8]) {
    let mut parser = FrameParser::new();
    let mut frames = parser.push(bytes);
    let mut verifier = Verifier::new(key());
    frames.retain(|f| verifier.check(&f.bytes, NOW).is_ok());
    frames.retain(|f| f.message_id != SETUP_SIGNING_ID);
    let index_of = [None::<usize>; 256];
    for f in &frames {
        let to = match &f.message {
            Decoded::Message(m) => target_system(m),
            Decoded::UnknownCommand { target_system, .. } => Some(*target_system),
            Decoded::Undecodable(_) => None,
        };
        if let Some(id) = to {
            let _ = index_of[usize::from(id)];
        }
    }
}
