//! The MCAP byte format (https://mcap.dev/spec), written by us rather than the `mcap`
//! crate's `Writer`: records are appended to one uncompressed chunk buffer and the whole
//! chunk is compressed in a single call when it is closed. The crate's writer streams
//! every record field through the compressor (about seven small compressor calls per
//! message) and keeps per-message index bookkeeping; at 100 drones that was a quarter of
//! the recording's CPU time.
//!
//! Layout written: magic, Header, the data section (Chunks only: the first holds the
//! Schemas and Channels, so a streaming reader of a cut file knows every channel), DataEnd,
//! the summary section (Schemas, Channels, Statistics, Chunk Indexes, each group located by
//! a Summary Offset), Footer, magic. No Message Index records: readers locate messages
//! through the chunk indexes (time range and offset of each chunk).
//!
//! CRCs: each chunk carries the CRC-32 of its uncompressed records (cheap beside the
//! compression); the data and summary section CRCs are 0 ("not computed", as the spec
//! allows).

use std::collections::BTreeMap;
use std::io::{self, Write};

/// Leading and trailing magic bytes (major version `0`).
pub const MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";

/// Record opcodes.
mod op {
    pub const HEADER: u8 = 0x01;
    pub const FOOTER: u8 = 0x02;
    pub const SCHEMA: u8 = 0x03;
    pub const CHANNEL: u8 = 0x04;
    pub const MESSAGE: u8 = 0x05;
    pub const CHUNK: u8 = 0x06;
    pub const CHUNK_INDEX: u8 = 0x08;
    pub const STATISTICS: u8 = 0x0B;
    pub const SUMMARY_OFFSET: u8 = 0x0E;
    pub const DATA_END: u8 = 0x0F;
}

/// Bytes of a Message record before its data: opcode, length, channel id, sequence,
/// log time, publish time.
pub const MESSAGE_HEADER_BYTES: usize = 1 + 8 + 2 + 4 + 8 + 8;

/// How chunks are compressed.
pub enum ChunkCompression {
    /// zstd at a level (one reused context: no allocation per chunk).
    Zstd(Box<zstd::bulk::Compressor<'static>>),
    /// LZ4 frame format, as MCAP readers expect for `lz4`.
    Lz4,
    None,
}

impl std::fmt::Debug for ChunkCompression {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl ChunkCompression {
    /// zstd at `level` (1 is the fastest standard level).
    ///
    /// # Errors
    /// If zstd rejects the level.
    pub fn zstd(level: i32) -> io::Result<Self> {
        Ok(Self::Zstd(Box::new(zstd::bulk::Compressor::new(level)?)))
    }

    /// The `compression` string of the Chunk record.
    fn name(&self) -> &'static str {
        match self {
            Self::Zstd(_) => "zstd",
            Self::Lz4 => "lz4",
            Self::None => "",
        }
    }

    /// Compresses `records` into `out` (cleared first).
    fn compress(&mut self, records: &[u8], out: &mut Vec<u8>) -> io::Result<()> {
        out.clear();
        match self {
            Self::Zstd(c) => {
                out.reserve(zstd::zstd_safe::compress_bound(records.len()));
                c.compress_to_buffer(records, out)?;
            }
            Self::Lz4 => {
                let mut encoder = lz4::EncoderBuilder::new().build(std::mem::take(out))?;
                encoder.write_all(records)?;
                let (buffer, result) = encoder.finish();
                *out = buffer;
                result?;
            }
            Self::None => out.extend_from_slice(records),
        }
        Ok(())
    }
}

fn put_str(out: &mut Vec<u8>, s: &str) {
    out.extend_from_slice(&(s.len() as u32).to_le_bytes());
    out.extend_from_slice(s.as_bytes());
}

/// Appends a record: opcode, content length, content.
fn put_record(out: &mut Vec<u8>, opcode: u8, content: &[u8]) {
    out.push(opcode);
    out.extend_from_slice(&(content.len() as u64).to_le_bytes());
    out.extend_from_slice(content);
}

/// One closed chunk, for its Chunk Index record.
#[derive(Debug, Clone, Copy)]
struct ChunkEntry {
    start_ns: u64,
    end_ns: u64,
    offset: u64,
    length: u64,
    compressed: u64,
    uncompressed: u64,
}

/// Writes an MCAP file chunk by chunk over `W`; each closed chunk is written with one
/// `write_all` and then `W` is flushed.
#[derive(Debug)]
pub struct McapWriter<W: Write> {
    out: W,
    /// Bytes written to `out` so far (offsets of the chunk indexes).
    position: u64,
    compression: ChunkCompression,
    /// Records of the open chunk, uncompressed.
    chunk: Vec<u8>,
    /// Log time range of the messages of the open chunk (`None`: no message yet).
    chunk_times: Option<(u64, u64)>,
    /// The compressed chunk (reused).
    compressed: Vec<u8>,
    /// Schema and Channel records, repeated in the summary.
    schemas: Vec<u8>,
    channels: Vec<u8>,
    schema_count: u16,
    channel_count: u16,
    chunks: Vec<ChunkEntry>,
    message_counts: Vec<u64>,
    times: Option<(u64, u64)>,
}

impl<W: Write> McapWriter<W> {
    /// Writes the magic and the Header record (`profile`, `library`).
    ///
    /// # Errors
    /// I/O errors.
    pub fn new(mut out: W, profile: &str, library: &str, compression: ChunkCompression) -> io::Result<Self> {
        let mut header = Vec::new();
        put_str(&mut header, profile);
        put_str(&mut header, library);
        let mut bytes = MAGIC.to_vec();
        put_record(&mut bytes, op::HEADER, &header);
        out.write_all(&bytes)?;
        Ok(Self {
            out,
            position: bytes.len() as u64,
            compression,
            chunk: Vec::with_capacity(super::CHUNK_BYTES + 64 * 1024),
            chunk_times: None,
            compressed: Vec::new(),
            schemas: Vec::new(),
            channels: Vec::new(),
            schema_count: 0,
            channel_count: 0,
            chunks: Vec::new(),
            message_counts: Vec::new(),
            times: None,
        })
    }

    /// Adds a schema (in the open chunk and in the summary); returns its id (from 1).
    ///
    /// # Errors
    /// `InvalidInput` past 65 535 schemas.
    pub fn add_schema(&mut self, name: &str, encoding: &str, data: &[u8]) -> io::Result<u16> {
        let id = self
            .schema_count
            .checked_add(1)
            .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "recording.mcap: more than 65535 schemas"))?;
        let mut content = Vec::with_capacity(data.len() + name.len() + 16);
        content.extend_from_slice(&id.to_le_bytes());
        put_str(&mut content, name);
        put_str(&mut content, encoding);
        content.extend_from_slice(&(data.len() as u32).to_le_bytes());
        content.extend_from_slice(data);
        put_record(&mut self.chunk, op::SCHEMA, &content);
        put_record(&mut self.schemas, op::SCHEMA, &content);
        self.schema_count = id;
        Ok(id)
    }

    /// Adds a channel without metadata (in the open chunk and in the summary); returns its
    /// id (from 0).
    ///
    /// # Errors
    /// `InvalidInput` past 65 536 channels.
    pub fn add_channel(&mut self, schema_id: u16, topic: &str, message_encoding: &str) -> io::Result<u16> {
        let id = u16::try_from(self.message_counts.len())
            .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "recording.mcap: more than 65536 channels"))?;
        let mut content = Vec::with_capacity(topic.len() + 24);
        content.extend_from_slice(&id.to_le_bytes());
        content.extend_from_slice(&schema_id.to_le_bytes());
        put_str(&mut content, topic);
        put_str(&mut content, message_encoding);
        // Metadata: an empty map (its byte length, 0).
        content.extend_from_slice(&0u32.to_le_bytes());
        put_record(&mut self.chunk, op::CHANNEL, &content);
        put_record(&mut self.channels, op::CHANNEL, &content);
        self.message_counts.push(0);
        self.channel_count = self.channel_count.wrapping_add(1);
        Ok(id)
    }

    /// Appends a Message record whose data `data` appends to the chunk buffer (no copy);
    /// returns the uncompressed size of the open chunk.
    ///
    /// # Panics
    /// If `channel` was not added.
    pub fn message(
        &mut self,
        channel: u16,
        sequence: u32,
        log_ns: u64,
        publish_ns: u64,
        data: impl FnOnce(&mut Vec<u8>),
    ) -> usize {
        let start = self.chunk.len();
        self.chunk.push(op::MESSAGE);
        self.chunk.extend_from_slice(&[0; 8]);
        self.chunk.extend_from_slice(&channel.to_le_bytes());
        self.chunk.extend_from_slice(&sequence.to_le_bytes());
        self.chunk.extend_from_slice(&log_ns.to_le_bytes());
        self.chunk.extend_from_slice(&publish_ns.to_le_bytes());
        data(&mut self.chunk);
        let length = (self.chunk.len() - start - 9) as u64;
        self.chunk[start + 1..start + 9].copy_from_slice(&length.to_le_bytes());
        self.message_counts[usize::from(channel)] += 1;
        let widen = |r: Option<(u64, u64)>| Some(r.map_or((log_ns, log_ns), |(a, b)| (a.min(log_ns), b.max(log_ns))));
        self.chunk_times = widen(self.chunk_times);
        self.times = widen(self.times);
        self.chunk.len()
    }

    /// Compresses and writes the open chunk (if it holds any record), then flushes `W`.
    ///
    /// # Errors
    /// I/O and compression errors.
    pub fn flush(&mut self) -> io::Result<()> {
        if !self.chunk.is_empty() {
            self.compression.compress(&self.chunk, &mut self.compressed)?;
            let (start_ns, end_ns) = self.chunk_times.unwrap_or((0, 0));
            let name = self.compression.name();
            let mut head = Vec::with_capacity(64);
            let content_len = 8 + 8 + 8 + 4 + 4 + name.len() + 8 + self.compressed.len();
            head.push(op::CHUNK);
            head.extend_from_slice(&(content_len as u64).to_le_bytes());
            head.extend_from_slice(&start_ns.to_le_bytes());
            head.extend_from_slice(&end_ns.to_le_bytes());
            head.extend_from_slice(&(self.chunk.len() as u64).to_le_bytes());
            head.extend_from_slice(&crc32fast::hash(&self.chunk).to_le_bytes());
            put_str(&mut head, name);
            head.extend_from_slice(&(self.compressed.len() as u64).to_le_bytes());
            // One write of the whole record (the compressed bytes appended to the head),
            // so a buffered file gets the chunk whole.
            head.extend_from_slice(&self.compressed);
            self.out.write_all(&head)?;
            self.chunks.push(ChunkEntry {
                start_ns,
                end_ns,
                offset: self.position,
                length: head.len() as u64,
                compressed: self.compressed.len() as u64,
                uncompressed: self.chunk.len() as u64,
            });
            self.position += head.len() as u64;
            self.chunk.clear();
            self.chunk_times = None;
        }
        self.out.flush()
    }

    /// Bytes of whole records written to `W` (magic, header, the chunks closed so far).
    pub fn position(&self) -> u64 {
        self.position
    }

    /// After a write error: hands `W` and [`Self::position`] to `cut`, which puts the
    /// sink back at the end of the last whole record (dropping a chunk `W` took part of)
    /// and returns it; the open chunk (also one whose write failed) is still to be written.
    ///
    /// # Errors
    /// `cut`'s: the writer is gone then, and the file ends where `cut` left it.
    pub fn cut_back(self, cut: impl FnOnce(W, u64) -> io::Result<W>) -> io::Result<Self> {
        // `W` is moved out and back: the writer is whole again only if `cut` succeeds.
        let Self { out, position, .. } = self;
        let out = cut(out, position)?;
        Ok(Self { out, ..self })
    }

    /// Drops the messages of the open chunk (they are not counted in the summary), for a
    /// file that has no room for them; returns how many.
    pub fn discard_open_chunk(&mut self) -> u64 {
        let mut dropped = 0;
        let mut at = 0;
        while at + 9 <= self.chunk.len() {
            let opcode = self.chunk[at];
            let len = u64::from_le_bytes(self.chunk[at + 1..at + 9].try_into().expect("8 bytes")) as usize;
            if opcode == op::MESSAGE && at + 11 <= self.chunk.len() {
                let channel = u16::from_le_bytes([self.chunk[at + 9], self.chunk[at + 10]]);
                self.message_counts[usize::from(channel)] -= 1;
                dropped += 1;
            }
            at += 9 + len;
        }
        self.chunk.clear();
        self.chunk_times = None;
        // The file's time range is the closed chunks'.
        self.times = self.chunks.iter().fold(None, |r, c| {
            Some(r.map_or((c.start_ns, c.end_ns), |(a, b): (u64, u64)| (a.min(c.start_ns), b.max(c.end_ns))))
        });
        dropped
    }

    /// Writes the last chunk, DataEnd, the summary and the footer; returns `W`.
    ///
    /// # Errors
    /// I/O and compression errors.
    pub fn finish(mut self) -> io::Result<W> {
        self.flush()?;
        let mut tail = Vec::new();
        put_record(&mut tail, op::DATA_END, &0u32.to_le_bytes());
        let summary_start = self.position + tail.len() as u64;
        let mut summary = Vec::new();
        let mut offsets = Vec::new();
        let mut group = |summary: &mut Vec<u8>, opcode: u8, records: &[u8]| {
            if records.is_empty() {
                return;
            }
            let start = summary_start + summary.len() as u64;
            summary.extend_from_slice(records);
            let mut content = vec![opcode];
            content.extend_from_slice(&start.to_le_bytes());
            content.extend_from_slice(&(records.len() as u64).to_le_bytes());
            put_record(&mut offsets, op::SUMMARY_OFFSET, &content);
        };
        group(&mut summary, op::SCHEMA, &self.schemas);
        group(&mut summary, op::CHANNEL, &self.channels);
        let mut statistics = Vec::new();
        let (start_ns, end_ns) = self.times.unwrap_or((0, 0));
        statistics.extend_from_slice(&self.message_counts.iter().sum::<u64>().to_le_bytes());
        statistics.extend_from_slice(&self.schema_count.to_le_bytes());
        statistics.extend_from_slice(&u32::from(self.channel_count).to_le_bytes());
        statistics.extend_from_slice(&0u32.to_le_bytes()); // attachments
        statistics.extend_from_slice(&0u32.to_le_bytes()); // metadata
        statistics.extend_from_slice(&(self.chunks.len() as u32).to_le_bytes());
        statistics.extend_from_slice(&start_ns.to_le_bytes());
        statistics.extend_from_slice(&end_ns.to_le_bytes());
        let counts: BTreeMap<u16, u64> =
            self.message_counts.iter().enumerate().filter(|(_, n)| **n > 0).map(|(i, n)| (i as u16, *n)).collect();
        statistics.extend_from_slice(&((counts.len() * 10) as u32).to_le_bytes());
        for (channel, n) in counts {
            statistics.extend_from_slice(&channel.to_le_bytes());
            statistics.extend_from_slice(&n.to_le_bytes());
        }
        let mut record = Vec::new();
        put_record(&mut record, op::STATISTICS, &statistics);
        group(&mut summary, op::STATISTICS, &record);
        let name = self.compression.name();
        let mut indexes = Vec::new();
        for c in &self.chunks {
            let mut content = Vec::with_capacity(64);
            for v in [c.start_ns, c.end_ns, c.offset, c.length] {
                content.extend_from_slice(&v.to_le_bytes());
            }
            content.extend_from_slice(&0u32.to_le_bytes()); // no message index offsets
            content.extend_from_slice(&0u64.to_le_bytes()); // message index length
            put_str(&mut content, name);
            content.extend_from_slice(&c.compressed.to_le_bytes());
            content.extend_from_slice(&c.uncompressed.to_le_bytes());
            put_record(&mut indexes, op::CHUNK_INDEX, &content);
        }
        group(&mut summary, op::CHUNK_INDEX, &indexes);
        let summary_offset_start = summary_start + summary.len() as u64;
        tail.extend_from_slice(&summary);
        tail.extend_from_slice(&offsets);
        let mut footer = Vec::with_capacity(20);
        footer.extend_from_slice(&summary_start.to_le_bytes());
        footer.extend_from_slice(&summary_offset_start.to_le_bytes());
        footer.extend_from_slice(&0u32.to_le_bytes()); // summary CRC not computed
        put_record(&mut tail, op::FOOTER, &footer);
        tail.extend_from_slice(MAGIC);
        self.out.write_all(&tail)?;
        self.out.flush()?;
        Ok(self.out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::disk::FillingDisk;

    /// Messages of about 1 KiB into chunks of 8 KiB on a disk of `room` bytes, until a chunk
    /// does not fit; returns the writer and the messages it was given.
    fn fill(room: usize) -> (McapWriter<FillingDisk>, u64) {
        let mut w = McapWriter::new(FillingDisk::with_room(room), "", "test", ChunkCompression::None).unwrap();
        let schema = w.add_schema("s", "jsonschema", b"{}").unwrap();
        let channel = w.add_channel(schema, "/t", "json").unwrap();
        for n in 0..10_000u64 {
            let size = w.message(channel, n as u32, n * 1000, n * 1000, |b| b.extend_from_slice(&[b'x'; 1000]));
            if size >= 8 * 1024 && w.flush().is_err() {
                return (w, n + 1);
            }
        }
        panic!("the disk never filled");
    }

    fn read_back(bytes: &[u8]) -> u64 {
        let summary = mcap::Summary::read(bytes).unwrap().expect("a summary section");
        let stats = summary.stats.expect("statistics");
        let streamed = mcap::MessageStream::new(bytes).unwrap().collect::<Result<Vec<_>, _>>().unwrap().len() as u64;
        assert_eq!(streamed, stats.message_count, "every message the summary counts is in the file");
        stats.message_count
    }

    /// A chunk half written when the disk filled: once there is room, the file is cut back
    /// to its last whole chunk, and the failed chunk and the summary are written: the
    /// `mcap` reader reads every message given.
    #[test]
    fn a_chunk_cut_by_a_full_disk_is_written_again_once_there_is_room() {
        let (w, given) = fill(50_000);
        assert!(w.out.bytes.len() as u64 > w.position(), "part of the failed chunk reached the disk");
        let w = w.cut_back(|disk, len| disk.freed(1 << 20, len)).unwrap();
        let bytes = w.finish().unwrap().bytes;
        assert_eq!(read_back(&bytes), given);
    }

    /// With room for the summary but not the chunk, the chunk's messages are dropped (and
    /// not counted) and the file still closes.
    #[test]
    fn without_room_for_the_chunk_the_file_closes_without_it() {
        let (w, given) = fill(50_000);
        let mut w = w.cut_back(|disk, len| disk.freed(0, len)).unwrap();
        // Room for the summary only.
        w.out.room = 4096;
        let dropped = w.discard_open_chunk();
        assert!(dropped > 0);
        let bytes = w.finish().unwrap().bytes;
        assert_eq!(read_back(&bytes), given - dropped);
    }
}
