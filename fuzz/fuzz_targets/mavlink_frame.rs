//! MAVLink framing and signing (`sadesim_engine::mavlink::frame` and `::signing`) on
//! arbitrary bytes: MAVLink 1, MAVLink 2 and signed MAVLink 2 streams, as a TCP stream in
//! pieces and as datagrams, then the same bytes with their CRCs and signatures repaired
//! (`sadesim_fuzz::repair`) so that the decoders and the signature checks see whole frames.
//!
//! What is asserted: never a panic; the stream parser finds the same frames whether the bytes
//! come at once or in pieces, and the datagram iterator finds the same frames as the stream
//! parser; every frame it returns is a whole MAVLink 2 frame with a good CRC whose decoded
//! message encodes and decodes back to the same bytes; the parser's buffer stays bounded; a
//! frame the verifier accepts is refused when replayed, and only signed frames are accepted.
#![no_main]

use ::mavlink::MavHeader;
use libfuzzer_sys::fuzz_target;
use sadesim_engine::mavlink::frame::{
    DatagramFrames, Decoded, Frame, FrameParser, MAX_FRAME_LEN, STX_V2, checksum, encode, whole_frame_len,
};
use sadesim_engine::mavlink::signing::{IFLAG_SIGNED, Refusal, SecretKey, Verifier};
use sadesim_fuzz::{NOW, key, repaired};

fuzz_target!(|data: &[u8]| {
    let Some((&pieces, bytes)) = data.split_first() else { return };
    check(bytes, pieces);
    let fixed = repaired(bytes, Some(&key()));
    let frames = check(&fixed, pieces);
    verify(&frames);
});

/// Parses `bytes` every way the endpoints and the router do; returns the frames.
fn check(bytes: &[u8], pieces: u8) -> Vec<Frame> {
    let whole = FrameParser::new().push(bytes);
    for f in &whole {
        frame_is_whole(f);
    }

    // A TCP stream delivers the same bytes in arbitrary pieces.
    let piece = usize::from(pieces % 64) + 1;
    let mut parser = FrameParser::new();
    let mut streamed = Vec::new();
    for chunk in bytes.chunks(piece) {
        streamed.extend(parser.push(chunk));
    }
    assert_eq!(ids(&streamed), ids(&whole), "the frames of a stream depend on how it was split ({piece}-byte pieces)");
    assert!(format!("{parser:?}").len() < 64 * MAX_FRAME_LEN, "the parser's buffer grew without bound");

    // A datagram: the router's zero-copy iterator agrees with the parser.
    let mut datagram = DatagramFrames::new(bytes);
    let refs: Vec<(u32, &[u8])> = datagram.by_ref().map(|f| (f.message_id, f.bytes)).collect();
    assert_eq!(refs.len(), whole.len());
    for ((id, b), f) in refs.iter().zip(&whole) {
        assert_eq!((*id, *b), (f.message_id, f.bytes.as_slice()));
        assert_eq!(whole_frame_len(b), Some(b.len()), "the router's gathering splits frames where they end");
    }
    let covered: usize = refs.iter().map(|(_, b)| b.len()).sum();
    assert!(covered + datagram.stats.skipped_bytes as usize <= bytes.len());
    whole
}

/// The bytes and ids of the frames, to compare two parses.
fn ids(frames: &[Frame]) -> Vec<(u32, &[u8])> {
    frames.iter().map(|f| (f.message_id, f.bytes.as_slice())).collect()
}

/// A frame as the parser promises it: MAVLink 2, its declared length, a good CRC, and a
/// decoded message that survives our encoder and the parser unchanged.
fn frame_is_whole(f: &Frame) {
    let b = &f.bytes;
    assert_eq!(b[0], STX_V2);
    let payload = usize::from(b[1]);
    let signed = b[2] & IFLAG_SIGNED != 0;
    assert_eq!(b.len(), 10 + payload + 2 + if signed { 13 } else { 0 });
    assert_eq!(f.message_id, u32::from_le_bytes([b[7], b[8], b[9], 0]));
    let crc = u16::from_le_bytes([b[10 + payload], b[11 + payload]]);
    use ::mavlink::Message;
    assert_eq!(checksum(&b[1..10 + payload], ::mavlink::dialects::common::MavMessage::extra_crc(f.message_id)), crc);
    if let Decoded::Message(m) = &f.message {
        let header = MavHeader { system_id: f.header.system_id, component_id: f.header.component_id, sequence: 3 };
        let once = encode(header, m);
        let again = FrameParser::new().push(&once);
        assert_eq!(again.len(), 1, "our encoding of {m:?} does not parse as one frame");
        match &again[0].message {
            Decoded::Message(m2) => assert_eq!(encode(header, m2), once, "{m:?} changed in a round trip"),
            other => panic!("our encoding of {m:?} decodes as {other:?}"),
        }
    }
}

/// The router's signing check on the GCS side: one verifier over every frame, in order.
fn verify(frames: &[Frame]) {
    let mut verifier = Verifier::new(key());
    let mut stranger = Verifier::new(SecretKey::from_bytes([7; 32]));
    for f in frames {
        let signed = f.bytes[2] & IFLAG_SIGNED != 0;
        match verifier.check(&f.bytes, NOW) {
            Ok(()) => {
                assert!(signed, "an unsigned frame was accepted");
                assert_eq!(verifier.check(&f.bytes, NOW), Err(Refusal::OldTimestamp), "a replay was accepted");
                assert_eq!(stranger.check(&f.bytes, NOW), Err(Refusal::BadSignature), "another key accepted it");
            }
            Err(Refusal::Unsigned) => assert!(!signed),
            Err(Refusal::Mavlink1) => panic!("a MAVLink 2 frame refused as MAVLink 1"),
            Err(Refusal::BadSignature | Refusal::OldTimestamp) => assert!(signed),
        }
    }
}
