//! What the fuzz targets share: turning mutated MAVLink bytes back into frames the parser
//! accepts, the signing key and clock of the signed-frame inputs, and the drone the session
//! targets talk to.
//!
//! A fuzzer that flips a byte of a MAVLink frame breaks its CRC (and its signature), and the
//! parser then drops the frame: without help every mutation would exercise the resync path
//! only. [`repair`] rewrites the CRC (and, given the key, the signature) of every frame-like
//! run of bytes, so the MAVLink targets fuzz both: the bytes as they came (garbage,
//! resynchronisation) and the same bytes repaired (the decoders, the session, the signing
//! checks). The seed files are plain MAVLink streams written by the engine's own encoder
//! (`engine/src/mavlink/fuzz_seeds.rs`).

use ::mavlink::Message;
use ::mavlink::dialects::common::MavMessage;
use sadesim_engine::mavlink::frame::{STX_V2, checksum};
use sadesim_engine::mavlink::signing::{IFLAG_SIGNED, SIGNATURE_BLOCK_LEN, SecretKey, signature};

/// MAVLink 1 start-of-frame marker.
const STX_V1: u8 = 0xFE;
/// STX and the MAVLink 2 header (len, incompat, compat, seq, sysid, compid, msgid x3).
const V2_HEADER: usize = 10;
/// STX and the MAVLink 1 header (len, seq, sysid, compid, msgid).
const V1_HEADER: usize = 6;

/// The passphrase of the signed seeds (`engine/src/mavlink/fuzz_seeds.rs` signs with it).
pub const PASSPHRASE: &str = "sadesim fuzz";

/// The signing key of the signed seeds.
pub fn key() -> SecretKey {
    SecretKey::from_passphrase(PASSPHRASE)
}

/// The receiver's signing clock of the signed-frame targets: the seeds' timestamps are
/// around it (2026-12-06 00:00 UTC in 10 µs units since 2015-01-01).
pub const NOW: u64 = (1_796_515_200 - 1_420_070_400) * 100_000;

/// Rewrites, in place, the CRC of every MAVLink 1 and 2 frame-like run of bytes in `data`
/// (a start marker and a header whose declared length fits), and with `key` the signature
/// of every signed MAVLink 2 frame (keeping its link id and timestamp), walking from frame
/// to frame as the parser would. Bytes that cannot start a frame are left alone.
pub fn repair(data: &mut [u8], key: Option<&SecretKey>) {
    let mut at = 0;
    while at < data.len() {
        let rest = &mut data[at..];
        if rest.len() < 2 {
            break;
        }
        at += match rest[0] {
            STX_V2 if rest.len() >= V2_HEADER + 2 + usize::from(rest[1]) => {
                let crc_at = V2_HEADER + usize::from(rest[1]);
                let id = u32::from_le_bytes([rest[7], rest[8], rest[9], 0]);
                let crc = checksum(&rest[1..crc_at], MavMessage::extra_crc(id));
                rest[crc_at..crc_at + 2].copy_from_slice(&crc.to_le_bytes());
                let unsigned = crc_at + 2;
                if rest[2] & IFLAG_SIGNED == 0 {
                    unsigned
                } else {
                    if let Some(key) = key
                        && rest.len() >= unsigned + SIGNATURE_BLOCK_LEN
                    {
                        let link = rest[unsigned];
                        let mut stamp = [0u8; 8];
                        stamp[..6].copy_from_slice(&rest[unsigned + 1..unsigned + 7]);
                        let sig = signature(key, &rest[..unsigned], link, u64::from_le_bytes(stamp));
                        rest[unsigned + 7..unsigned + SIGNATURE_BLOCK_LEN].copy_from_slice(&sig);
                    }
                    unsigned + SIGNATURE_BLOCK_LEN
                }
            }
            STX_V1 if rest.len() >= V1_HEADER + 2 + usize::from(rest[1]) => {
                let crc_at = V1_HEADER + usize::from(rest[1]);
                let crc = checksum(&rest[1..crc_at], MavMessage::extra_crc(u32::from(rest[5])));
                rest[crc_at..crc_at + 2].copy_from_slice(&crc.to_le_bytes());
                crc_at + 2
            }
            _ => 1,
        };
    }
}

/// `data` repaired ([`repair`]) into a new buffer.
pub fn repaired(data: &[u8], key: Option<&SecretKey>) -> Vec<u8> {
    let mut bytes = data.to_vec();
    repair(&mut bytes, key);
    bytes
}
