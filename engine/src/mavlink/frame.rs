//! MAVLink 2 framing: bytes in, checked frames out; messages in, bytes out.
//!
//! Written against the wire format (<https://mavlink.io/en/guide/serialization.html>) rather
//! than the `mavlink` crate's blocking readers, because every endpoint must survive
//! arbitrary bytes: a UDP datagram or a TCP stream may hold several frames, half a frame,
//! garbage, a wrong checksum or a payload shortened by MAVLink 2's trailing-zero
//! truncation. The parser never panics and never waits: it consumes what it can and keeps
//! an incomplete tail for the next call. Message (de)serialisation itself is the `mavlink`
//! crate's generated code for the common dialect.
//!
//! MAVLink 1 frames (STX 0xFE) are skipped (and counted): PX4 answers MAVLink 2 to MAVLink 2
//! peers and every client we target (QGroundControl, MAVSDK, pymavlink with `MAVLINK20=1`)
//! speaks 2.

use ::mavlink::dialects::common::MavMessage;
use ::mavlink::error::ParserError;
use ::mavlink::{MavHeader, MavlinkVersion, Message};

use super::signing::{IFLAG_SIGNED, SIGNATURE_BLOCK_LEN};

/// MAVLink 2 start-of-frame marker.
pub const STX_V2: u8 = 0xFD;
/// MAVLink 1 start-of-frame marker.
const STX_V1: u8 = 0xFE;
/// Header after the STX: len, incompat flags, compat flags, seq, sysid, compid, msgid (3).
const HEADER_LEN: usize = 9;
/// MAVLink 1 header after the STX: len, seq, sysid, compid, msgid (1).
const HEADER_LEN_V1: usize = 5;
const CHECKSUM_LEN: usize = 2;
/// Largest MAVLink 2 frame: STX + header + 255 payload + checksum + signature block.
pub const MAX_FRAME_LEN: usize = 1 + HEADER_LEN + 255 + CHECKSUM_LEN + SIGNATURE_BLOCK_LEN;
/// Message ids of COMMAND_INT and COMMAND_LONG (both carry the command id at byte 28).
const COMMAND_INT_ID: u32 = 75;
const COMMAND_LONG_ID: u32 = 76;

/// One frame with a good checksum.
#[derive(Clone, Debug)]
pub struct Frame {
    /// Sender system, component and sequence.
    pub header: MavHeader,
    pub message_id: u32,
    /// The frame exactly as received (for routers, which forward without re-encoding).
    pub bytes: Vec<u8>,
    /// The decoded message, or why it could not be decoded.
    pub message: Decoded,
}

/// What a checksummed frame decodes to. (Frames live for one poll; boxing the message to
/// shrink the rarer variants would cost an allocation per frame for nothing.)
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum Decoded {
    Message(MavMessage),
    /// A COMMAND_LONG or COMMAND_INT whose command id the common dialect does not define.
    /// It still deserves an answer: COMMAND_ACK with MAV_RESULT_UNSUPPORTED.
    UnknownCommand {
        command: u16,
        target_system: u8,
        target_component: u8,
    },
    /// A message id outside the common dialect, or a field with an undefined enum value.
    Undecodable(String),
}

/// Counters of what the parser threw away (for logs and tests).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ParseStats {
    pub frames: u64,
    /// Frames whose checksum did not match (dropped).
    pub bad_checksum: u64,
    /// Bytes skipped while looking for a start marker (MAVLink 1 frames not included).
    pub skipped_bytes: u64,
    /// Complete MAVLink 1 frames with a good checksum (skipped whole).
    pub mavlink1_frames: u64,
}

/// Incremental MAVLink 2 parser for one byte stream (a TCP connection) or a sequence of
/// datagrams (call [`FrameParser::reset`] between unrelated datagram sources if desired).
#[derive(Debug, Default)]
pub struct FrameParser {
    buf: Vec<u8>,
    pub stats: ParseStats,
}

/// The CRC-16/MCRF4XX (X.25) MAVLink uses, over `data` then the message's CRC_EXTRA byte.
///
/// Every frame a fleet sends and every frame a router forwards passes through here (about
/// 265 a second per drone at PX4's default rates), so it is table-driven and takes eight
/// bytes per step ("slicing by 8": eight lookups into eight tables instead of a dependent
/// lookup per byte), which halves its instructions on a typical 30-60 byte frame.
pub fn checksum(data: &[u8], extra: u8) -> u16 {
    crc_accumulate(crc_accumulate(CRC_INIT, data), &[extra])
}

/// Initial value of MAVLink's CRC.
const CRC_INIT: u16 = 0xFFFF;

/// `CRC_TABLES[0][b]`: CRC-16/MCRF4XX of one byte value from a zero register (the
/// polynomial 0x1021 bit-reversed, 0x8408, since the CRC is computed least significant bit
/// first). `CRC_TABLES[k][b]`: the same byte followed by `k` zero bytes. Built at compile
/// time.
const CRC_TABLES: [[u16; 256]; 8] = {
    let mut tables = [[0u16; 256]; 8];
    let mut i = 0;
    while i < 256 {
        let mut crc = i as u16;
        let mut bit = 0;
        while bit < 8 {
            crc = if crc & 1 == 1 { (crc >> 1) ^ 0x8408 } else { crc >> 1 };
            bit += 1;
        }
        tables[0][i] = crc;
        i += 1;
    }
    let mut k = 1;
    while k < 8 {
        let mut i = 0;
        while i < 256 {
            let previous = tables[k - 1][i];
            tables[k][i] = (previous >> 8) ^ tables[0][(previous & 0xFF) as usize];
            i += 1;
        }
        k += 1;
    }
    tables
};

/// Continues the CRC `crc` over `data`: eight bytes at a time (the register's two bytes
/// folded into the first two), then byte by byte.
fn crc_accumulate(mut crc: u16, data: &[u8]) -> u16 {
    let t = &CRC_TABLES;
    let mut chunks = data.chunks_exact(8);
    for c in &mut chunks {
        let [lo, hi] = crc.to_le_bytes();
        crc = t[7][usize::from(c[0] ^ lo)]
            ^ t[6][usize::from(c[1] ^ hi)]
            ^ t[5][usize::from(c[2])]
            ^ t[4][usize::from(c[3])]
            ^ t[3][usize::from(c[4])]
            ^ t[2][usize::from(c[5])]
            ^ t[1][usize::from(c[6])]
            ^ t[0][usize::from(c[7])];
    }
    chunks.remainder().iter().fold(crc, |crc, &byte| (crc >> 8) ^ t[0][usize::from((crc as u8) ^ byte)])
}

impl FrameParser {
    pub fn new() -> Self {
        Self::default()
    }

    /// Drops any partial frame (a datagram boundary on UDP means the tail is garbage).
    pub fn reset(&mut self) {
        self.buf.clear();
    }

    /// Appends `bytes` and returns every complete, checksummed frame found. Bytes that
    /// cannot start a frame are skipped; an incomplete frame stays buffered.
    pub fn push(&mut self, bytes: &[u8]) -> Vec<Frame> {
        self.buf.extend_from_slice(bytes);
        let mut frames = Vec::new();
        let mut at = 0;
        while at < self.buf.len() {
            let rest = &self.buf[at..];
            match find(rest, &mut self.stats) {
                Found::Frame(f) => {
                    let message = decode(f.message_id, &f.bytes[1 + HEADER_LEN..1 + HEADER_LEN + f.payload_len()]);
                    self.stats.frames += 1;
                    at += f.bytes.len();
                    frames.push(Frame { header: f.header, message_id: f.message_id, bytes: f.bytes.to_vec(), message });
                }
                Found::Skipped(n) => at += n,
                Found::Incomplete => break,
            }
        }
        self.buf.drain(..at);
        // A buffer can only hold one incomplete frame; anything longer is garbage that
        // began with STX and a large length. Bound memory per connection.
        if self.buf.len() > MAX_FRAME_LEN {
            let excess = self.buf.len() - MAX_FRAME_LEN;
            self.buf.drain(..excess);
            self.stats.skipped_bytes += excess as u64;
        }
        frames
    }
}

/// A checksummed MAVLink 2 frame inside a buffer, not copied and not decoded.
#[derive(Clone, Copy, Debug)]
pub struct FrameRef<'a> {
    pub header: MavHeader,
    pub message_id: u32,
    /// The whole frame, signature block included.
    pub bytes: &'a [u8],
}

impl FrameRef<'_> {
    fn payload_len(&self) -> usize {
        usize::from(self.bytes[1])
    }
}

/// The checksummed frames of one datagram, in order, without copying them: what a router
/// needs to pass a datagram on (UDP keeps datagram boundaries, so no state carries from one
/// datagram to the next). Bytes that are not part of a good frame are counted in `stats`,
/// an incomplete frame at the end as skipped bytes.
#[derive(Debug)]
pub struct DatagramFrames<'a> {
    bytes: &'a [u8],
    at: usize,
    pub stats: ParseStats,
}

impl<'a> DatagramFrames<'a> {
    pub fn new(datagram: &'a [u8]) -> Self {
        Self { bytes: datagram, at: 0, stats: ParseStats::default() }
    }
}

impl<'a> Iterator for DatagramFrames<'a> {
    type Item = FrameRef<'a>;

    fn next(&mut self) -> Option<FrameRef<'a>> {
        while self.at < self.bytes.len() {
            let rest = &self.bytes[self.at..];
            match find(rest, &mut self.stats) {
                Found::Frame(f) => {
                    self.stats.frames += 1;
                    self.at += f.bytes.len();
                    return Some(f);
                }
                Found::Skipped(n) => self.at += n,
                Found::Incomplete => {
                    self.stats.skipped_bytes += rest.len() as u64;
                    self.at = self.bytes.len();
                }
            }
        }
        None
    }
}

/// The length of the whole frame at the start of `frames`, which holds whole frames (as a
/// [`DatagramFrames`] item or a router's gathered bytes): from the header alone, unchecked.
pub fn whole_frame_len(frames: &[u8]) -> Option<usize> {
    let len = declared_len(frames.get(..1 + HEADER_LEN)?);
    (frames[0] == STX_V2 && len <= frames.len()).then_some(len)
}

/// The length of a MAVLink 2 frame as its STX and header declare it: payload length,
/// checksum, and the signature block when the signed flag is set.
fn declared_len(stx_and_header: &[u8]) -> usize {
    let signature = if stx_and_header[2] & IFLAG_SIGNED != 0 { SIGNATURE_BLOCK_LEN } else { 0 };
    1 + HEADER_LEN + usize::from(stx_and_header[1]) + CHECKSUM_LEN + signature
}

/// What the start of a buffer holds.
enum Found<'a> {
    /// A MAVLink 2 frame with a good checksum.
    Frame(FrameRef<'a>),
    /// This many bytes to skip: not a frame start, a bad checksum (counted in the stats), or
    /// a whole MAVLink 1 frame.
    Skipped(usize),
    /// A MAVLink 2 frame may start here but is not complete yet.
    Incomplete,
}

/// Looks at the start of `rest`, counting what it skips in `stats`.
fn find<'a>(rest: &'a [u8], stats: &mut ParseStats) -> Found<'a> {
    if let Some(len) = mavlink1_frame_len(rest) {
        stats.mavlink1_frames += 1;
        return Found::Skipped(len);
    }
    if rest[0] == STX_V1
        && rest.get(1).is_none_or(|&len| rest.len() < 1 + HEADER_LEN_V1 + usize::from(len) + CHECKSUM_LEN)
    {
        // A MAVLink 1 frame may start here but is not complete yet: skipping its marker
        // would count a frame split across two TCP reads as garbage and look for frames
        // inside it.
        return Found::Incomplete;
    }
    if rest[0] != STX_V2 {
        stats.skipped_bytes += 1;
        return Found::Skipped(1);
    }
    if rest.len() < 1 + HEADER_LEN {
        return Found::Incomplete; // header incomplete
    }
    let total = declared_len(rest);
    if rest.len() < total {
        return Found::Incomplete;
    }
    let message_id = u32::from(rest[7]) | u32::from(rest[8]) << 8 | u32::from(rest[9]) << 16;
    let crc_end = 1 + HEADER_LEN + usize::from(rest[1]);
    let received = u16::from_le_bytes([rest[crc_end], rest[crc_end + 1]]);
    if checksum(&rest[1..crc_end], MavMessage::extra_crc(message_id)) != received {
        // Not a frame (or a corrupted one): resynchronise one byte later, since a real
        // frame may start inside what looked like this one.
        stats.bad_checksum += 1;
        return Found::Skipped(1);
    }
    let header = MavHeader { sequence: rest[4], system_id: u32::from(rest[5]), component_id: rest[6] };
    Found::Frame(FrameRef { header, message_id, bytes: &rest[..total] })
}

/// The length of the MAVLink 1 frame at the start of `bytes`, if a complete one with a good
/// checksum is there. Only counted, never decoded: a router that requires signed frames
/// says "MAVLink 1" rather than "garbage" when refusing one.
fn mavlink1_frame_len(bytes: &[u8]) -> Option<usize> {
    if bytes.first() != Some(&STX_V1) || bytes.len() < 1 + HEADER_LEN_V1 {
        return None;
    }
    let crc_at = 1 + HEADER_LEN_V1 + usize::from(bytes[1]);
    let crc = bytes.get(crc_at..crc_at + CHECKSUM_LEN)?;
    let extra = MavMessage::extra_crc(u32::from(bytes[5]));
    (checksum(&bytes[1..crc_at], extra) == u16::from_le_bytes([crc[0], crc[1]])).then_some(crc_at + CHECKSUM_LEN)
}

/// Decodes a checksummed payload (possibly truncated: MAVLink 2 drops trailing zeros).
fn decode(message_id: u32, payload: &[u8]) -> Decoded {
    match MavMessage::parse(MavlinkVersion::V2, message_id, payload) {
        Ok(m) => Decoded::Message(m),
        Err(ParserError::InvalidEnum { enum_type, value })
            if (message_id == COMMAND_LONG_ID || message_id == COMMAND_INT_ID) && enum_type.contains("MavCmd") =>
        {
            // Both messages put command (u16) at 28, target system at 30, component at 31.
            let mut full = [0u8; 32];
            let n = payload.len().min(32);
            full[..n].copy_from_slice(&payload[..n]);
            let _ = value;
            Decoded::UnknownCommand {
                command: u16::from_le_bytes([full[28], full[29]]),
                target_system: full[30],
                target_component: full[31],
            }
        }
        Err(e) => Decoded::Undecodable(format!("message {message_id}: {e}")),
    }
}

/// Encodes `message` as one MAVLink 2 frame from `header` (unsigned).
pub fn encode(header: MavHeader, message: &MavMessage) -> Vec<u8> {
    let mut out = Vec::new();
    encode_into(&mut out, header, message);
    out
}

/// Appends the frame of `message` to `out` (no allocation when `out` has room for the
/// largest frame). The payload is truncated as MAVLink 2 requires (trailing zero bytes
/// dropped); the bytes are those of the `mavlink` crate's
/// `MAVLinkV2MessageRaw` for system ids up to 255, which is all MAVLink has.
pub fn encode_into(out: &mut Vec<u8>, header: MavHeader, message: &MavMessage) {
    const MAX_PAYLOAD_LEN: usize = 255;
    debug_assert!(header.system_id <= u32::from(u8::MAX), "system id {} is not MAVLink", header.system_id);
    // Serialised on the stack, then only the truncated payload is copied: growing `out` by
    // 255 zero bytes per frame was a `memset` call for every message a fleet sends.
    let mut payload = [0u8; MAX_PAYLOAD_LEN];
    let payload_len = message.ser(MavlinkVersion::V2, &mut payload);
    let id = message.message_id().to_le_bytes();
    let start = out.len();
    out.extend_from_slice(&[
        STX_V2,
        payload_len as u8,
        0, // incompatibility flags: unsigned
        0, // compatibility flags
        header.sequence,
        header.system_id as u8,
        header.component_id,
        id[0],
        id[1],
        id[2],
    ]);
    out.extend_from_slice(&payload[..payload_len]);
    let crc = checksum(&out[start + 1..], MavMessage::extra_crc(message.message_id()));
    out.extend_from_slice(&crc.to_le_bytes());
}

/// COMMAND_ACK for any command number, including ones the dialect's `MavCmd` cannot
/// represent (an unknown command still deserves MAV_RESULT_UNSUPPORTED). Encoded by hand:
/// command u16, result u8, progress u8, result_param2 i32, target system, target component.
pub fn encode_command_ack(
    header: MavHeader,
    command: u16,
    result: ::mavlink::dialects::common::MavResult,
    target: (u8, u8),
) -> Vec<u8> {
    const COMMAND_ACK_ID: u32 = 77;
    let mut payload = vec![0u8; 10];
    payload[0..2].copy_from_slice(&command.to_le_bytes());
    payload[2] = result as u8;
    payload[8] = target.0;
    payload[9] = target.1;
    while payload.len() > 1 && payload.last() == Some(&0) {
        payload.pop(); // MAVLink 2 trailing-zero truncation
    }
    let mut frame = vec![
        STX_V2,
        payload.len() as u8,
        0,
        0,
        header.sequence,
        header.system_id as u8,
        header.component_id,
        COMMAND_ACK_ID as u8,
        0,
        0,
    ];
    frame.extend(&payload);
    let crc = checksum(&frame[1..], MavMessage::extra_crc(COMMAND_ACK_ID));
    frame.extend(crc.to_le_bytes());
    frame
}

/// The system a message is addressed to: `Some(0)` or `None` mean everyone.
pub fn target_system(message: &MavMessage) -> Option<u8> {
    message.target_system_id()
}

#[cfg(test)]
mod tests {
    use ::mavlink::dialects::common::{
        COMMAND_ACK_DATA, HEARTBEAT_DATA, MavAutopilot, MavCmd, MavModeFlag, MavResult, MavState, MavType,
        PARAM_REQUEST_LIST_DATA,
    };

    use super::*;

    fn heartbeat() -> MavMessage {
        MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            custom_mode: 0x0304_0000,
            mavtype: MavType::MAV_TYPE_QUADROTOR,
            autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
            base_mode: MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
            system_status: MavState::MAV_STATE_STANDBY,
            mavlink_version: 3,
        })
    }

    fn header(sys: u32) -> MavHeader {
        MavHeader { system_id: sys, component_id: 1, sequence: 7 }
    }

    /// The CRC one bit at a time, as the polynomial defines it.
    fn crc_bitwise(data: &[u8]) -> u16 {
        data.iter().fold(CRC_INIT, |mut crc, &byte| {
            crc ^= u16::from(byte);
            for _ in 0..8 {
                crc = if crc & 1 == 1 { (crc >> 1) ^ 0x8408 } else { crc >> 1 };
            }
            crc
        })
    }

    #[test]
    fn the_checksum_is_crc16_mcrf4xx_for_every_length() {
        // The catalogue's check value of CRC-16/MCRF4XX.
        assert_eq!(crc_accumulate(CRC_INIT, b"123456789"), 0x6F91);
        // Every length from empty to past several 8-byte steps, every start offset.
        let data: Vec<u8> = (0..300u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8).collect();
        for start in 0..8 {
            for end in start..data.len() {
                assert_eq!(
                    crc_accumulate(CRC_INIT, &data[start..end]),
                    crc_bitwise(&data[start..end]),
                    "{start}..{end}"
                );
            }
        }
        assert_eq!(checksum(b"12345678", b'9'), crc_bitwise(b"123456789"));
    }

    #[test]
    fn round_trips_several_frames_in_one_buffer() {
        let mut bytes = encode(header(3), &heartbeat());
        bytes.extend(encode(
            header(255),
            &MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA { target_system: 3, target_component: 1 }),
        ));
        let frames = FrameParser::new().push(&bytes);
        assert_eq!(frames.len(), 2);
        assert_eq!(frames[0].header.system_id, 3);
        assert_eq!(frames[0].header.sequence, 7);
        assert!(matches!(frames[0].message, Decoded::Message(MavMessage::HEARTBEAT(_))));
        match &frames[1].message {
            Decoded::Message(m) => assert_eq!(target_system(m), Some(3)),
            other => panic!("{other:?}"),
        }
        assert_eq!(frames[1].bytes, bytes[frames[0].bytes.len()..]);
    }

    #[test]
    fn a_datagrams_frames_are_found_where_they_lie_and_the_rest_is_counted() {
        let a = encode(header(3), &heartbeat());
        let b = encode(header(4), &heartbeat());
        let mut corrupt = encode(header(5), &heartbeat());
        let n = corrupt.len();
        corrupt[n - 1] ^= 0xFF;
        // Garbage, a frame, a corrupted frame, a frame, half a frame.
        let datagram = [&[0x00, 0x11][..], &a, &corrupt, &b, &a[..7]].concat();
        let mut frames = DatagramFrames::new(&datagram);
        let found: Vec<FrameRef<'_>> = frames.by_ref().collect();
        assert_eq!(found.iter().map(|f| f.header.system_id).collect::<Vec<_>>(), [3, 4]);
        assert_eq!(found[0].bytes, &a[..]);
        assert_eq!(found[1].bytes, &b[..]);
        assert_eq!(found[1].bytes.as_ptr(), datagram[2 + a.len() + corrupt.len()..].as_ptr(), "not copied");
        assert_eq!(frames.stats.frames, 2);
        assert_eq!(frames.stats.bad_checksum, 1);
        // 2 bytes before, the corrupted frame's bytes after its STX, the 7-byte tail.
        assert_eq!(frames.stats.skipped_bytes, 2 + (corrupt.len() as u64 - 1) + 7);
        // The same frames as the stream parser's.
        let parsed = FrameParser::new().push(&datagram);
        assert_eq!(parsed.iter().map(|f| f.bytes.clone()).collect::<Vec<_>>(), [a.clone(), b.clone()]);
        // whole_frame_len walks whole frames.
        let both = [a.clone(), b.clone()].concat();
        assert_eq!(whole_frame_len(&both), Some(a.len()));
        assert_eq!(whole_frame_len(&both[a.len()..]), Some(b.len()));
        assert_eq!(whole_frame_len(&both[..5]), None);
    }

    #[test]
    fn a_frame_split_across_pushes_is_reassembled() {
        let bytes = encode(header(1), &heartbeat());
        let mut p = FrameParser::new();
        assert!(p.push(&bytes[..5]).is_empty());
        assert!(p.push(&bytes[5..bytes.len() - 1]).is_empty());
        assert_eq!(p.push(&bytes[bytes.len() - 1..]).len(), 1);
    }

    #[test]
    fn wrong_checksum_is_dropped_and_the_next_frame_still_parses() {
        let mut bad = encode(header(1), &heartbeat());
        let n = bad.len();
        bad[n - 1] ^= 0xFF;
        let good = encode(header(2), &heartbeat());
        let mut p = FrameParser::new();
        let frames = p.push(&[bad, good].concat());
        assert_eq!(frames.len(), 1);
        assert_eq!(frames[0].header.system_id, 2);
        assert_eq!(p.stats.bad_checksum, 1);
    }

    #[test]
    fn truncated_payloads_decode_with_zeros() {
        // An ack with result 0 (ACCEPTED) and zero extension fields: MAVLink 2 sends only
        // the command id (the trailing zero bytes are cut).
        let ack = MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
            command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            result: MavResult::MAV_RESULT_ACCEPTED,
            ..Default::default()
        });
        let bytes = encode(header(1), &ack);
        assert!(bytes[1] < 10, "payload was truncated to {} bytes", bytes[1]);
        let frames = FrameParser::new().push(&bytes);
        match &frames[0].message {
            Decoded::Message(MavMessage::COMMAND_ACK(a)) => {
                assert_eq!(a.command, MavCmd::MAV_CMD_COMPONENT_ARM_DISARM);
                assert_eq!(a.result, MavResult::MAV_RESULT_ACCEPTED);
            }
            other => panic!("{other:?}"),
        }
    }

    /// Builds a COMMAND_LONG frame by hand with any command number.
    fn command_long(command: u16, target: u8) -> Vec<u8> {
        let mut payload = vec![0u8; 33];
        payload[28..30].copy_from_slice(&command.to_le_bytes());
        payload[30] = target;
        payload[31] = 1;
        let mut frame = vec![STX_V2, payload.len() as u8, 0, 0, 9, 255, 190, COMMAND_LONG_ID as u8, 0, 0];
        frame.extend(&payload);
        let crc = checksum(&frame[1..], MavMessage::extra_crc(COMMAND_LONG_ID));
        frame.extend(crc.to_le_bytes());
        frame
    }

    #[test]
    fn an_undefined_command_is_reported_with_its_number_and_target() {
        let frames = FrameParser::new().push(&command_long(31_999, 5));
        match frames[0].message {
            Decoded::UnknownCommand { command, target_system, target_component } => {
                assert_eq!((command, target_system, target_component), (31_999, 5, 1));
            }
            ref other => panic!("{other:?}"),
        }
        // A defined command decodes normally.
        let frames = FrameParser::new().push(&command_long(400, 5));
        assert!(matches!(frames[0].message, Decoded::Message(MavMessage::COMMAND_LONG(_))));
    }

    #[test]
    fn hand_encoded_acks_decode_like_typed_ones() {
        let bytes = encode_command_ack(header(4), 400, MavResult::MAV_RESULT_DENIED, (255, 190));
        match &FrameParser::new().push(&bytes)[0].message {
            Decoded::Message(MavMessage::COMMAND_ACK(a)) => {
                assert_eq!(a.command, MavCmd::MAV_CMD_COMPONENT_ARM_DISARM);
                assert_eq!(a.result, MavResult::MAV_RESULT_DENIED);
                assert_eq!((a.target_system, a.target_component), (255, 190));
            }
            other => panic!("{other:?}"),
        }
        // An undefined command number survives the trip (the typed decoder then refuses it).
        let bytes = encode_command_ack(header(4), 31_999, MavResult::MAV_RESULT_UNSUPPORTED, (255, 0));
        assert_eq!(u16::from_le_bytes([bytes[10], bytes[11]]), 31_999);
        assert_eq!(FrameParser::new().push(&bytes).len(), 1, "checksum is right");
    }

    #[test]
    fn mavlink1_frames_are_skipped_whole_and_counted() {
        // A MAVLink 1 HEARTBEAT from a GCS laid out by hand: STX, len, seq, sysid, compid,
        // msgid, payload, CRC with the heartbeat's CRC_EXTRA.
        let mut v1 = vec![STX_V1, 9, 0, 255, 190, 0, 0, 0, 0, 0, 6, 8, 0, 4, 3];
        let crc = checksum(&v1[1..], MavMessage::extra_crc(0));
        v1.extend(crc.to_le_bytes());
        let mut p = FrameParser::new();
        let frames = p.push(&[v1.clone(), encode(header(2), &heartbeat())].concat());
        assert_eq!(frames.len(), 1, "the MAVLink 2 frame after it");
        assert_eq!((p.stats.mavlink1_frames, p.stats.skipped_bytes), (1, 0));
        // With a wrong checksum it is garbage, as any other bytes.
        let last = v1.len() - 1;
        v1[last] ^= 0xFF;
        assert!(p.push(&v1).is_empty());
        assert_eq!(p.stats.mavlink1_frames, 1);
        assert!(p.stats.skipped_bytes > 0);
    }

    #[test]
    fn a_mavlink1_frame_split_across_reads_is_still_one_frame() {
        // Found by fuzz/fuzz_targets/mavlink_frame.rs: the first piece of a MAVLink 1 frame
        // was skipped as garbage, so a stream parsed in pieces lost frames a whole parse found.
        let mut v1 = vec![STX_V1, 9, 0, 255, 190, 0, 0, 0, 0, 0, 6, 8, 0, 4, 3];
        let crc = checksum(&v1[1..], MavMessage::extra_crc(0));
        v1.extend(crc.to_le_bytes());
        let stream = [v1, encode(header(2), &heartbeat())].concat();
        for piece in 1..stream.len() {
            let mut p = FrameParser::new();
            let frames: Vec<Frame> = stream.chunks(piece).flat_map(|c| p.push(c)).collect();
            assert_eq!(frames.len(), 1, "{piece}-byte pieces");
            assert_eq!((p.stats.mavlink1_frames, p.stats.skipped_bytes), (1, 0), "{piece}-byte pieces");
        }
    }

    #[test]
    fn the_table_crc_matches_the_reference() {
        // The catalogue check value of CRC-16/MCRF4XX over "123456789".
        assert_eq!(crc_accumulate(CRC_INIT, b"123456789"), 0x6F91);
        let mut x: u32 = 99;
        for len in 0..300 {
            let data: Vec<u8> = (0..len)
                .map(|_| {
                    x = x.wrapping_mul(1_103_515_245).wrapping_add(12_345);
                    (x >> 16) as u8
                })
                .collect();
            let extra = len as u8;
            assert_eq!(checksum(&data, extra), ::mavlink::calculate_crc(&data, extra), "{len} bytes");
        }
    }

    #[test]
    fn encoding_matches_the_mavlink_crate_byte_for_byte() {
        let id = crate::mavlink::telemetry::tests::identity();
        let view = crate::mavlink::telemetry::tests::view();
        let mut messages: Vec<MavMessage> = crate::mavlink::telemetry::PRODUCIBLE
            .iter()
            .filter_map(|&m| crate::mavlink::telemetry::build(m, &view, &id))
            .collect();
        messages.push(heartbeat());
        messages.push(MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA::default())); // all zeros
        let mut out = vec![0xAB]; // appends after what is there
        for (i, m) in messages.iter().enumerate() {
            let header = MavHeader { system_id: 250, component_id: 1, sequence: i as u8 };
            let before = out.len();
            encode_into(&mut out, header, m);
            let mut raw = ::mavlink::MAVLinkV2MessageRaw::new();
            raw.serialize_message(header, m);
            assert_eq!(&out[before..], raw.raw_bytes(), "message {}", m.message_id());
        }
        assert_eq!(out[0], 0xAB);
    }

    #[test]
    fn garbage_never_panics_and_memory_stays_bounded() {
        let mut p = FrameParser::new();
        let mut x: u32 = 12345;
        for _ in 0..20_000 {
            let chunk: Vec<u8> = (0..97)
                .map(|_| {
                    x ^= x << 13;
                    x ^= x >> 17;
                    x ^= x << 5;
                    if x.is_multiple_of(7) { STX_V2 } else { x as u8 }
                })
                .collect();
            p.push(&chunk);
            assert!(p.buf.len() <= MAX_FRAME_LEN);
        }
        // Still works afterwards.
        p.reset();
        assert_eq!(p.push(&encode(header(1), &heartbeat())).len(), 1);
    }
}
