//! Carriers of the shard protocol: in-process channels (one thread per shard) and JSON
//! lines over TCP (one process per shard). Both carry exactly `protocol`'s messages.

use std::io::{BufRead, BufReader, BufWriter, Read, Write};
use std::net::TcpStream;
use std::sync::mpsc::{Receiver, Sender, channel};
use std::thread::JoinHandle;

use sadesim_crds::plan::RunPlan;

use crate::coordinator::{LinkError, ShardLink};
use crate::protocol::{FromShard, ToShard};
use crate::roles::shard::ShardSockets;
use crate::shard::{MavlinkIo, Shard};

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

/// Serves one shard over any message source and sink until `Stop` or disconnection, `io`
/// carrying its MAVLink queues.
pub fn serve(
    mut shard: Shard,
    mut io: impl MavlinkIo,
    mut recv: impl FnMut() -> Option<ToShard>,
    mut send: impl FnMut(FromShard) -> bool,
) {
    if !send(shard.hello()) {
        return;
    }
    while let Some(msg) = recv() {
        // `None` is the answer to Stop: the shard is done.
        let Some(reply) = shard.handle_with(msg, &mut io) else { return };
        if !send(reply) {
            return;
        }
    }
}

/// Starts shard `index` of `plan` on its own thread, in `surroundings` (see [`Shard::new`]).
///
/// # Errors
/// When the shard cannot be built (reported before any thread starts).
pub fn spawn_thread(
    plan: &RunPlan,
    index: u32,
    surroundings: &crate::shard::Surroundings,
    mavlink: Option<&crate::shard::MavlinkOptions>,
) -> Result<(ThreadLink, JoinHandle<()>), crate::shard::ShardError> {
    let mut shard = Shard::new(plan, index, surroundings)?;
    let sockets = mavlink.map(|options| ShardSockets::open(&mut shard, plan, options)).transpose()?;
    let (to_shard, shard_rx) = channel::<ToShard>();
    let (shard_tx, from_shard) = channel::<FromShard>();
    let handle = std::thread::Builder::new()
        .name(format!("shard-{index}"))
        .spawn(move || serve(shard, sockets, || shard_rx.recv().ok(), |m| shard_tx.send(m).is_ok()))
        .expect("the OS can start a thread");
    Ok((ThreadLink { to_shard, from_shard }, handle))
}

/// The coordinator's end of a TCP connection to a `sim-worker shard` process. One JSON
/// message per line; a line longer than [`MAX_LINE_BYTES`] is refused.
#[derive(Debug)]
pub struct TcpLink {
    reader: BufReader<TcpStream>,
    writer: BufWriter<TcpStream>,
    line: String,
}

/// Longest accepted protocol line (a 2000-drone shard's window is ~600 kB).
pub const MAX_LINE_BYTES: usize = 64 * 1024 * 1024;

impl TcpLink {
    /// # Errors
    /// When the stream cannot be cloned.
    pub fn new(stream: TcpStream) -> std::io::Result<Self> {
        stream.set_nodelay(true)?;
        Ok(Self { reader: BufReader::new(stream.try_clone()?), writer: BufWriter::new(stream), line: String::new() })
    }
}

/// Writes one message as a JSON line and flushes.
///
/// # Errors
/// I/O errors of the stream.
pub fn write_line<T: serde::Serialize>(w: &mut impl Write, msg: &T) -> std::io::Result<()> {
    serde_json::to_writer(&mut *w, msg).map_err(std::io::Error::other)?;
    w.write_all(b"\n")?;
    w.flush()
}

/// Reads one JSON line; `Ok(None)` at end of stream.
///
/// # Errors
/// I/O errors, over-long lines and undecodable JSON.
pub fn read_line<T: serde::de::DeserializeOwned>(
    r: &mut impl BufRead,
    buf: &mut String,
) -> Result<Option<T>, LinkError> {
    buf.clear();
    let n = r.by_ref().take(MAX_LINE_BYTES as u64 + 1).read_line(buf)?;
    if n == 0 {
        return Ok(None);
    }
    if n > MAX_LINE_BYTES {
        return Err(LinkError::Decode(format!("message longer than {MAX_LINE_BYTES} bytes")));
    }
    serde_json::from_str(buf.trim_end()).map(Some).map_err(|e| LinkError::Decode(e.to_string()))
}

impl ShardLink for TcpLink {
    fn send(&mut self, msg: &ToShard) -> Result<(), LinkError> {
        write_line(&mut self.writer, msg).map_err(LinkError::Io)
    }
    fn recv(&mut self) -> Result<FromShard, LinkError> {
        read_line(&mut self.reader, &mut self.line)?.ok_or(LinkError::Closed)
    }
}

/// Serves a shard over a TCP stream (the `sim-worker shard` process side).
///
/// # Errors
/// When the stream cannot be cloned.
pub fn serve_tcp(shard: Shard, stream: TcpStream) -> std::io::Result<()> {
    stream.set_nodelay(true)?;
    let mut reader = BufReader::new(stream.try_clone()?);
    let mut writer = BufWriter::new(stream);
    let mut buf = String::new();
    serve(
        shard,
        crate::shard::NoMavlinkIo,
        || read_line::<ToShard>(&mut reader, &mut buf).ok().flatten(),
        |m| write_line(&mut writer, &m).is_ok(),
    );
    Ok(())
}
