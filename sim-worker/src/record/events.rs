//! `events.jsonl`: one event per line, flushed every window.

use std::path::Path;

use sadesim_engine::events::Event;

use super::disk::Appender;

/// Appends events as JSON lines.
#[derive(Debug)]
pub struct EventLog {
    out: Appender,
    /// One line, reused.
    line: Vec<u8>,
}

impl EventLog {
    /// Creates `dir/events.jsonl`.
    ///
    /// # Errors
    /// When the file cannot be created, naming it.
    pub fn create(dir: &Path) -> std::io::Result<Self> {
        let out = Appender::create(dir, sadesim_crds::outcome::run_folder::EVENTS)?;
        Ok(Self { out, line: Vec::with_capacity(256) })
    }

    /// Writes and flushes a batch (one window's events), line by line.
    ///
    /// # Errors
    /// I/O errors, naming the file.
    pub fn write(&mut self, events: &[Event]) -> std::io::Result<()> {
        for e in events {
            self.line.clear();
            serde_json::to_writer(&mut self.line, e).map_err(std::io::Error::other)?;
            self.line.push(b'\n');
            self.out.write_all(&self.line)?;
        }
        self.out.flush()
    }

    /// Closes the file at its last whole line ([`Appender::close`]).
    ///
    /// # Errors
    /// As [`Appender::close`].
    pub fn close(self) -> std::io::Result<()> {
        self.out.close()
    }
}
