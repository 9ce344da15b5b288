//! Carriers of the shard protocol: in-process channels (one thread per shard) and
//! length-prefixed binary frames over TCP (one process per shard, see [`wire`]). Both carry
//! exactly `protocol`'s messages.

pub mod wire;

use std::io::{BufReader, BufWriter, Read, Write};
use std::net::TcpStream;
use std::sync::mpsc::{Receiver, Sender, channel};
use std::thread::JoinHandle;

use sadesim_crds::plan::RunPlan;

use crate::record::Lap;
use crate::shard_io::{self, MavlinkOptions, StartError};
use sadesim_engine::coordinator::{LinkError, ShardLink};
use sadesim_engine::protocol::{FromShard, ToShard};
use sadesim_engine::shard::{MavlinkIo, Shard};
use wire::{MAX_FRAME_BYTES, Wire};

/// The machine's wall clock, which paces a run (`sadesim_engine::pacing::WallClock`).
#[derive(Clone, Copy, Debug, Default)]
pub struct SystemClock;

impl sadesim_engine::pacing::WallClock for SystemClock {
    fn now(&self) -> std::time::Instant {
        std::time::Instant::now()
    }

    fn sleep(&self, duration: std::time::Duration) {
        std::thread::sleep(duration);
    }
}

/// The coordinator's end of an in-process shard thread.
#[derive(Debug)]
pub struct ThreadLink {
    to_shard: Sender<ToShard>,
    from_shard: Receiver<FromShard>,
}

impl ShardLink for ThreadLink {
    fn send(&mut self, msg: &ToShard) -> Result<(), LinkError> {
        self.to_shard.send(msg.clone()).map_err(|_| LinkError::Closed)
    }
    fn recv(&mut self) -> Result<FromShard, LinkError> {
        self.from_shard.recv().map_err(|_| LinkError::Closed)
    }
}

/// Serves one shard over any message source and sink until `Stop`, `io` carrying its
/// MAVLink queues. The first error of `recv` or `send` (the coordinator gone, a broken
/// connection) ends it and is returned.
///
/// Returns the CPU time, s, the shard spent: this thread handling the coordinator's
/// messages (stepping the drones and moving their MAVLink queues, the waits for the next
/// message excluded: `CLOCK_THREAD_CPUTIME_ID`, two readings per window), plus what `io`
/// spent on a thread of its own (building, encoding and sending the telemetry,
/// [`MavlinkIo::finish`]). It is the shard's own per-drone cost, apart from the
/// coordinator's and the recorder's (`summary.json` `shardCpuS`, `sadesim bench`).
///
/// # Errors
/// The first error of `recv` or `send`.
pub fn serve<E>(
    mut shard: Shard,
    mut io: impl MavlinkIo,
    mut recv: impl FnMut() -> Result<ToShard, E>,
    mut send: impl FnMut(FromShard) -> Result<(), E>,
) -> Result<f64, E> {
    let mut busy_s = 0.0;
    send(shard.hello())?;
    loop {
        let msg = recv()?;
        let mut lap = Lap::start();
        let reply = shard.handle_with(msg, &mut io);
        lap.add_to(&mut busy_s);
        // `None` is the answer to Stop: the shard is done (its last frames leave first).
        let Some(reply) = reply else { return Ok(busy_s + io.finish()) };
        send(reply)?;
    }
}

/// Starts shard `index` of `plan` on its own thread, in `surroundings` (see [`Shard::new`]).
/// The thread returns the CPU seconds it spent stepping the shard (see [`serve`]), `None`
/// when the coordinator's end went away before `Stop`.
///
/// # Errors
/// When the shard cannot be built (reported before any thread starts).
pub fn spawn_thread(
    plan: &RunPlan,
    index: u32,
    surroundings: &sadesim_engine::shard::Surroundings,
    mavlink: Option<&MavlinkOptions>,
) -> Result<(ThreadLink, JoinHandle<Option<f64>>), StartError> {
    let (shard, sockets) = shard_io::start(plan, index, surroundings, mavlink)?;
    let (to_shard, shard_rx) = channel::<ToShard>();
    let (shard_tx, from_shard) = channel::<FromShard>();
    let handle = std::thread::Builder::new()
        .name(format!("shard-{index}"))
        .spawn(move || serve(shard, sockets, || shard_rx.recv().map_err(drop), |m| shard_tx.send(m).map_err(drop)).ok())
        .expect("the OS can start a thread");
    Ok((ThreadLink { to_shard, from_shard }, handle))
}

/// The coordinator's end of a TCP connection to a `sim-worker shard` process: one
/// [`wire`] frame per message.
#[derive(Debug)]
pub struct TcpLink {
    reader: BufReader<TcpStream>,
    writer: BufWriter<TcpStream>,
    /// The last frame read, and the next one written (kept to reuse their allocations).
    incoming: Vec<u8>,
    outgoing: Vec<u8>,
}

impl TcpLink {
    /// # Errors
    /// When the stream cannot be cloned.
    pub fn new(stream: TcpStream) -> std::io::Result<Self> {
        stream.set_nodelay(true)?;
        Ok(Self {
            reader: BufReader::new(stream.try_clone()?),
            writer: BufWriter::new(stream),
            incoming: Vec::new(),
            outgoing: Vec::new(),
        })
    }
}

/// Writes one message as a frame (its payload encoded into `buf`) and flushes.
///
/// # Errors
/// I/O errors of the stream.
pub fn write_message(w: &mut impl Write, msg: &impl Wire, buf: &mut Vec<u8>) -> std::io::Result<()> {
    buf.clear();
    msg.encode(buf);
    let len = u32::try_from(buf.len()).ok().filter(|&n| n as usize <= MAX_FRAME_BYTES).ok_or_else(|| {
        std::io::Error::other(format!("a message of {} bytes is over the {MAX_FRAME_BYTES}-byte limit", buf.len()))
    })?;
    w.write_all(&len.to_le_bytes())?;
    w.write_all(buf)?;
    w.flush()
}

/// Reads one frame into `buf` and decodes it; `Ok(None)` at the end of the stream before a
/// frame starts.
///
/// # Errors
/// I/O errors, an end of stream inside a frame, over-long frames and undecodable payloads.
pub fn read_message<T: Wire>(r: &mut impl Read, buf: &mut Vec<u8>) -> Result<Option<T>, LinkError> {
    let mut len = [0u8; 4];
    let mut got = 0;
    while got < len.len() {
        match r.read(&mut len[got..]) {
            Ok(0) if got == 0 => return Ok(None),
            Ok(0) => {
                return Err(LinkError::Decode(format!("the stream ended inside a frame's length ({got} of 4 bytes)")));
            }
            Ok(n) => got += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(LinkError::Io(e)),
        }
    }
    let n = u32::from_le_bytes(len) as usize;
    if n > MAX_FRAME_BYTES {
        // `{"ty` read as a length is about 2 GB: the JSON line of a peer before version 4
        // (serde writes the `type` tag first). A real frame may well start with 0x7b.
        let reason = if len[0] == b'{' {
            "a JSON line: the peer speaks the shard protocol of sadesim before version 4; run the same sadesim version in every role".into()
        } else {
            format!("a frame of {n} bytes is over the {MAX_FRAME_BYTES}-byte limit")
        };
        return Err(LinkError::Decode(reason));
    }
    buf.clear();
    buf.resize(n, 0);
    let mut got = 0;
    while got < n {
        match r.read(&mut buf[got..]) {
            // A truncated frame: say how much of it came, so a peer that cuts its frames
            // short (a bug, a proxy, a full disk on its side) is told from one that left.
            Ok(0) => {
                return Err(LinkError::Decode(format!(
                    "the stream ended inside a frame of {n} bytes ({got} of them received{})",
                    describe_kind(&buf[..got])
                )));
            }
            Ok(k) => got += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(LinkError::Io(e)),
        }
    }
    T::decode(buf).map(Some).map_err(LinkError::Decode)
}

/// ", a window (`W`) frame" for the start of a frame's payload: what the frame was meant to
/// carry, by its kind byte ([`wire`]'s table).
fn describe_kind(received: &[u8]) -> String {
    match received.first() {
        Some(b'A') => ", an advance (`A`) frame".into(),
        Some(b'W') => ", a window (`W`) frame".into(),
        Some(b'J') => ", a JSON (`J`) frame".into(),
        Some(other) => format!(", whose kind byte 0x{other:02x} is none of `A`, `W`, `J`"),
        None => String::new(),
    }
}

impl ShardLink for TcpLink {
    fn send(&mut self, msg: &ToShard) -> Result<(), LinkError> {
        write_message(&mut self.writer, msg, &mut self.outgoing).map_err(LinkError::Io)
    }
    fn recv(&mut self) -> Result<FromShard, LinkError> {
        read_message(&mut self.reader, &mut self.incoming)?.ok_or(LinkError::Closed)
    }
}

#[cfg(test)]
mod tests;
