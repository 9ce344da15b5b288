//! `events.jsonl`: one event per line, flushed every window.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

use sadesim_engine::events::Event;

/// Appends events as JSON lines.
#[derive(Debug)]
pub struct EventLog {
    out: BufWriter<File>,
}

impl EventLog {
    /// # Errors
    /// When the file cannot be created.
    pub fn create(path: &Path) -> std::io::Result<Self> {
        Ok(Self { out: BufWriter::new(File::create(path)?) })
    }

    /// Writes and flushes a batch (one window's events).
    ///
    /// # Errors
    /// I/O errors.
    pub fn write(&mut self, events: &[Event]) -> std::io::Result<()> {
        for e in events {
            serde_json::to_writer(&mut self.out, e).map_err(std::io::Error::other)?;
            self.out.write_all(b"\n")?;
        }
        self.out.flush()
    }
}
