//! A full disk in the middle of a recording: the room kept to close the files, the errors
//! that name the file, and cutting a file back to its last whole record.
//!
//! At its start a run sets aside [`reserve_bytes`] in its folder ([`RESERVE_FILE`]). When a
//! write fails (the disk filled, or any I/O error) the run stops; at the end the reserve is
//! deleted first, so its room is there to write what the writers still hold, close
//! `recording.mcap` (its summary and footer), and write `summary.json`, `incomplete.json`
//! and the manifest. Each recording is cut back to its last whole record before it is
//! closed, so every file that was written before opens in its readers.

use std::fs::File;
use std::io::{self, BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// The reserve's name in the run folder, deleted at the end of the run (left behind only by
/// a process that was killed).
pub const RESERVE_FILE: &str = ".sadesim-disk-reserve";

/// The room a run of `drones` drones sets aside: the open MCAP chunk written again (at most
/// [`super::mcap_file::CHUNK_BYTES`] and its record head), its summary section, each
/// ULog's buffer, and the end-of-run files (`summary.json`, `trajectory.geojson`, the
/// manifest): 3 MiB and 48 KiB per drone.
pub fn reserve_bytes(drones: usize) -> u64 {
    3 * 1024 * 1024 + 48 * 1024 * drones as u64
}

/// Room set aside in a run folder, given back by [`DiskReserve::release`] (or on drop).
#[derive(Debug)]
pub struct DiskReserve {
    path: PathBuf,
}

impl DiskReserve {
    /// Writes `bytes` bytes into `dir/`[`RESERVE_FILE`]. They are written, not only
    /// allocated (no `fallocate`, which some file systems lack), and are not zeros, which a
    /// compressing file system would store in nothing.
    ///
    /// # Errors
    /// The file cannot be written, naming it: the disk has less room than the run needs to
    /// close its files.
    pub fn create(dir: &Path, bytes: u64) -> io::Result<Self> {
        let path = dir.join(RESERVE_FILE);
        let reserve = Self { path };
        let fill = || -> io::Result<()> {
            let mut file = File::create(&reserve.path)?;
            let mut block = vec![0u8; 64 * 1024];
            let mut state = 0x9E37_79B9_7F4A_7C15u64;
            let mut left = bytes;
            while left > 0 {
                for b in block.chunks_exact_mut(8) {
                    // xorshift64: cheap bytes no compressor shrinks.
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    b.copy_from_slice(&state.to_le_bytes());
                }
                let n = left.min(block.len() as u64) as usize;
                file.write_all(&block[..n])?;
                left -= n as u64;
            }
            file.sync_all()
        };
        fill().map_err(|e| {
            io::Error::new(
                e.kind(),
                FileError {
                    file: RESERVE_FILE.into(),
                    source: io::Error::new(
                        e.kind(),
                        format!("setting aside {bytes} bytes to close the run's files if the disk fills: {e}"),
                    ),
                },
            )
        })?;
        Ok(reserve)
    }

    /// Deletes the reserve: its room is free for what follows.
    pub fn release(self) {}
}

impl Drop for DiskReserve {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

/// A write error and the file of the run folder it happened in (relative path).
#[derive(Debug, thiserror::Error)]
#[error("{file}: {source}")]
pub struct FileError {
    pub file: String,
    #[source]
    pub source: io::Error,
}

/// Wraps `e` so that it names `file` (relative to the run folder), keeping its kind
/// (`StorageFull` for a full disk); an error that names a file already is kept as it is.
pub fn named(file: &str, e: io::Error) -> io::Error {
    if failed_file(&e).is_some() {
        return e;
    }
    io::Error::new(e.kind(), FileError { file: file.to_string(), source: e })
}

/// The file a [`named`] error names.
pub fn failed_file(e: &io::Error) -> Option<&str> {
    e.get_ref().and_then(|inner| inner.downcast_ref::<FileError>()).map(|f| f.file.as_str())
}

/// Cuts the file under `w` back to its first `len` bytes (the whole records written) and
/// puts the write position there, for what follows: what `w` still buffers is written
/// first, then cut off with whatever part of a record followed it.
///
/// # Errors
/// What `w` buffers cannot be written (the disk is still full), or the file cannot be cut;
/// `w` is dropped without writing more, its file cut back to `len` if it was longer.
pub fn cut(mut w: BufWriter<File>, len: u64) -> io::Result<BufWriter<File>> {
    if let Err(e) = w.flush() {
        let (file, _unwritten) = w.into_parts();
        if file.metadata()?.len() > len {
            file.set_len(len)?;
        }
        return Err(e);
    }
    w.get_ref().set_len(len)?;
    w.get_mut().seek(SeekFrom::Start(len))?;
    Ok(w)
}

/// A file of the run written as it goes (`events.jsonl`, `trajectory.csv`, `gnss.csv`):
/// buffered, its errors naming it, and closed back to its last whole write.
#[derive(Debug)]
pub struct Appender {
    out: BufWriter<File>,
    /// Relative to the run folder.
    name: String,
    /// Bytes of the whole writes the buffer took.
    written: u64,
}

impl Appender {
    /// Creates `dir/name`.
    ///
    /// # Errors
    /// The file cannot be created, naming it.
    pub fn create(dir: &Path, name: &str) -> io::Result<Self> {
        let file = File::create(dir.join(name)).map_err(|e| named(name, e))?;
        Ok(Self { out: BufWriter::new(file), name: name.to_string(), written: 0 })
    }

    /// Appends `bytes` whole (a line, a sample's rows).
    ///
    /// # Errors
    /// I/O errors, naming the file; the bytes count only once taken whole.
    pub fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.out.write_all(bytes).map_err(|e| named(&self.name, e))?;
        self.written += bytes.len() as u64;
        Ok(())
    }

    /// # Errors
    /// I/O errors, naming the file.
    pub fn flush(&mut self) -> io::Result<()> {
        self.out.flush().map_err(|e| named(&self.name, e))
    }

    /// Writes what is buffered and closes the file at the end of its last whole write
    /// (after a write error, part of a write may have reached it).
    ///
    /// # Errors
    /// There is still no room for what is buffered (the file is cut back to its whole
    /// writes if it got further), naming the file.
    pub fn close(self) -> io::Result<()> {
        let Self { out, name, written } = self;
        cut(out, written).map(drop).map_err(|e| named(&name, e))
    }

    /// Its path in the run folder.
    pub fn name(&self) -> &str {
        &self.name
    }
}

/// Test support: a disk that fills. Takes bytes into memory until `room` is used up, the
/// last write partly, then fails with ENOSPC, as a file on a full disk does.
#[cfg(test)]
#[derive(Debug, Default)]
pub(crate) struct FillingDisk {
    pub bytes: Vec<u8>,
    /// Bytes it still takes.
    pub room: usize,
}

#[cfg(test)]
impl FillingDisk {
    pub fn with_room(room: usize) -> Self {
        Self { bytes: Vec::new(), room }
    }

    /// As [`cut`] does to a file once room was freed: `more` bytes of room, and the file
    /// cut back to `len`.
    pub fn freed(mut self, more: usize, len: u64) -> io::Result<Self> {
        self.room += more;
        self.bytes.truncate(len as usize);
        Ok(self)
    }
}

#[cfg(test)]
impl Write for FillingDisk {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        if self.room == 0 && !buf.is_empty() {
            return Err(io::Error::from_raw_os_error(28));
        }
        let n = buf.len().min(self.room);
        self.bytes.extend_from_slice(&buf[..n]);
        self.room -= n;
        Ok(n)
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_named_error_keeps_its_kind_and_names_the_file_once() {
        let e = named("recording.mcap", io::Error::from_raw_os_error(28));
        assert_eq!(e.kind(), io::ErrorKind::StorageFull);
        assert_eq!(failed_file(&e), Some("recording.mcap"));
        let again = named("summary.json", e);
        assert_eq!(again.to_string(), "recording.mcap: No space left on device (os error 28)");
    }

    /// After a failed write left part of a line in the file, closing cuts it back to the
    /// whole lines once there is room.
    #[test]
    fn an_appender_closes_at_its_last_whole_write() {
        let dir = super::super::test_dir::TempDir::new("disk-appender");
        let mut out = Appender::create(&dir.0, "events.jsonl").unwrap();
        out.write_all(b"{\"a\":1}\n").unwrap();
        out.flush().unwrap();
        // Half a line reaches the file, as a write interrupted by a full disk leaves it.
        let half = b"{\"b\":2";
        out.out.get_mut().write_all(half).unwrap();
        out.close().unwrap();
        assert_eq!(std::fs::read(dir.0.join("events.jsonl")).unwrap(), b"{\"a\":1}\n");
    }

    #[test]
    fn the_reserve_is_set_aside_and_given_back() {
        let dir = super::super::test_dir::TempDir::new("disk-reserve");
        let reserve = DiskReserve::create(&dir.0, 100_000).unwrap();
        assert_eq!(std::fs::metadata(dir.0.join(RESERVE_FILE)).unwrap().len(), 100_000);
        reserve.release();
        assert!(!dir.0.join(RESERVE_FILE).exists());
        // On a disk without the room (the reserve is `/dev/full`), the error names the
        // reserve and says why, and it is a full disk's.
        std::os::unix::fs::symlink("/dev/full", dir.0.join(RESERVE_FILE)).unwrap();
        let full = DiskReserve::create(&dir.0, 100_000).unwrap_err();
        assert_eq!(failed_file(&full), Some(RESERVE_FILE), "{full}");
        assert_eq!(full.kind(), io::ErrorKind::StorageFull);
        assert!(full.to_string().contains("setting aside 100000 bytes"), "{full}");
    }
}
