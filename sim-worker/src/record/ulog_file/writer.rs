//! The ULog byte format (PX4 `docs/en/dev_log/ulog_file_format.md`), written over any
//! [`Write`]: no files, no clocks, so tests run it on a `Vec<u8>`.
//!
//! A file is a 16-byte header, then messages `[u16 msg_size][u8 msg_type][payload]`
//! (little-endian, `msg_size` excludes the 3-byte message header):
//! - definitions: `B` flag bits (must follow the header), `F` formats, `I` info, `P`
//!   parameters;
//! - data: `A` subscriptions (a format name bound to a `msg_id`), `D` data (`msg_id` then the
//!   fields exactly as the format declares them, packed), `L` logged strings.

use std::io::{self, Write};

/// The file magic: "ULog" then 0x01 0x12 0x35.
pub const MAGIC: [u8; 7] = *b"ULog\x01\x12\x35";
/// The format version we write (the only one PX4 defines).
pub const VERSION: u8 = 1;

/// Message types (the `msg_type` byte).
pub mod msg_type {
    pub const FLAG_BITS: u8 = b'B';
    pub const FORMAT: u8 = b'F';
    pub const INFO: u8 = b'I';
    pub const PARAMETER: u8 = b'P';
    pub const ADD_LOGGED: u8 = b'A';
    pub const DATA: u8 = b'D';
    pub const LOGGING: u8 = b'L';
}

/// Severity of an `L` message, as PX4 writes it: the ASCII digit of the syslog level
/// (`'0'` emergency .. `'7'` debug), which pyulog and Flight Review decode.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum LogLevel {
    Emergency = b'0',
    Alert = b'1',
    Critical = b'2',
    Error = b'3',
    Warning = b'4',
    Notice = b'5',
    Info = b'6',
    Debug = b'7',
}

/// A parameter value (`P` message): PX4 parameters are `int32_t` or `float`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ParamValue {
    Int32(i32),
    Float(f32),
}

/// Writes ULog messages in order. The caller keeps the sections in order (definitions,
/// then data); sizes, names and the header are checked here.
#[derive(Debug)]
pub struct UlogWriter<W: Write> {
    out: W,
    /// Scratch buffer for one message, reused.
    message: Vec<u8>,
    /// Bytes of the header and whole messages `out` took.
    written: u64,
}

impl<W: Write> UlogWriter<W> {
    /// Writes the header (logging start at `start_us`, microseconds) and the flag bits
    /// message (no compat/incompat flags, no appended data), which must follow it.
    ///
    /// # Errors
    /// I/O errors of `out`.
    pub fn new(mut out: W, start_us: u64) -> io::Result<Self> {
        let mut header = [0u8; 16];
        header[..7].copy_from_slice(&MAGIC);
        header[7] = VERSION;
        header[8..].copy_from_slice(&start_us.to_le_bytes());
        out.write_all(&header)?;
        let mut writer = Self { out, message: Vec::with_capacity(512), written: header.len() as u64 };
        // compat_flags[8], incompat_flags[8], appended_offsets[3] (u64): all zero.
        writer.message(msg_type::FLAG_BITS, |m| m.extend_from_slice(&[0u8; 40]))?;
        Ok(writer)
    }

    /// An `F` message: `name:type0 field0;type1 field1;...` (types such as `uint64_t`,
    /// `float[4]`). The first field must be `uint64_t timestamp`.
    ///
    /// # Errors
    /// `InvalidInput` for a name that is not `[A-Za-z0-9_]+` or a first field other than
    /// the timestamp; I/O errors.
    pub fn format(&mut self, name: &str, fields: &[(String, &str)]) -> io::Result<()> {
        check_name("format name", name)?;
        match fields.first() {
            Some((t, n)) if t == "uint64_t" && *n == "timestamp" => {}
            _ => return Err(invalid(format!("format {name}: the first field must be `uint64_t timestamp`"))),
        }
        let mut text = format!("{name}:");
        for (ty, field) in fields {
            check_name("field name", field)?;
            text.push_str(ty);
            text.push(' ');
            text.push_str(field);
            text.push(';');
        }
        self.message(msg_type::FORMAT, |m| m.extend_from_slice(text.as_bytes()))
    }

    /// An `I` message with a string value: key `char[len] key`.
    ///
    /// # Errors
    /// `InvalidInput` for a bad key or a value over the message size; I/O errors.
    pub fn info_str(&mut self, key: &str, value: &str) -> io::Result<()> {
        check_name("info key", key)?;
        let typed = format!("char[{}] {key}", value.len());
        self.key_value(msg_type::INFO, &typed, value.as_bytes())
    }

    /// An `I` message with an `int32_t` value.
    ///
    /// # Errors
    /// `InvalidInput` for a bad key; I/O errors.
    pub fn info_i32(&mut self, key: &str, value: i32) -> io::Result<()> {
        check_name("info key", key)?;
        self.key_value(msg_type::INFO, &format!("int32_t {key}"), &value.to_le_bytes())
    }

    /// A `P` message (a parameter's value at the start of the log).
    ///
    /// # Errors
    /// `InvalidInput` for a name that is not a PX4 parameter name (`[A-Za-z0-9_]`, at most
    /// 16 characters); I/O errors.
    pub fn parameter(&mut self, name: &str, value: ParamValue) -> io::Result<()> {
        check_name("parameter name", name)?;
        if name.len() > 16 {
            return Err(invalid(format!("parameter name {name}: PX4 names have at most 16 characters")));
        }
        match value {
            ParamValue::Int32(v) => self.key_value(msg_type::PARAMETER, &format!("int32_t {name}"), &v.to_le_bytes()),
            ParamValue::Float(v) => self.key_value(msg_type::PARAMETER, &format!("float {name}"), &v.to_le_bytes()),
        }
    }

    /// An `A` message: from here on, `D` messages with `msg_id` carry instance `multi_id`
    /// of the format `name`.
    ///
    /// # Errors
    /// `InvalidInput` for a bad name; I/O errors.
    pub fn add_logged(&mut self, multi_id: u8, msg_id: u16, name: &str) -> io::Result<()> {
        check_name("subscription name", name)?;
        self.message(msg_type::ADD_LOGGED, |m| {
            m.push(multi_id);
            m.extend_from_slice(&msg_id.to_le_bytes());
            m.extend_from_slice(name.as_bytes());
        })
    }

    /// A `D` message: `fields` packed as the subscribed format declares them.
    ///
    /// # Errors
    /// `InvalidInput` when the message would exceed 65535 bytes; I/O errors.
    pub fn data(&mut self, msg_id: u16, fields: &[u8]) -> io::Result<()> {
        self.message(msg_type::DATA, |m| {
            m.extend_from_slice(&msg_id.to_le_bytes());
            m.extend_from_slice(fields);
        })
    }

    /// An `L` message: `text` at `level`, at `timestamp_us`.
    ///
    /// # Errors
    /// `InvalidInput` when the text exceeds the message size; I/O errors.
    pub fn log(&mut self, level: LogLevel, timestamp_us: u64, text: &str) -> io::Result<()> {
        self.message(msg_type::LOGGING, |m| {
            m.push(level as u8);
            m.extend_from_slice(&timestamp_us.to_le_bytes());
            m.extend_from_slice(text.as_bytes());
        })
    }

    /// Flushes the underlying writer.
    ///
    /// # Errors
    /// I/O errors.
    pub fn flush(&mut self) -> io::Result<()> {
        self.out.flush()
    }

    /// The underlying writer (not flushed).
    pub fn into_inner(self) -> W {
        self.out
    }

    /// Bytes of the header and the whole messages written.
    pub fn written(&self) -> u64 {
        self.written
    }

    /// After a write error: hands the writer and [`Self::written`] to `cut`, which puts
    /// the file back at the end of the last whole message (dropping part of one that
    /// failed) and returns it.
    ///
    /// # Errors
    /// `cut`'s: the writer is gone then, and the file ends where `cut` left it.
    pub fn cut_back(self, cut: impl FnOnce(W, u64) -> io::Result<W>) -> io::Result<Self> {
        let Self { out, message, written } = self;
        Ok(Self { out: cut(out, written)?, message, written })
    }

    /// `[u8 key_len][key][value]`, as `I` and `P` messages are laid out.
    fn key_value(&mut self, kind: u8, typed_key: &str, value: &[u8]) -> io::Result<()> {
        let key_len = u8::try_from(typed_key.len())
            .map_err(|_| invalid(format!("key `{typed_key}`: at most 255 bytes, got {}", typed_key.len())))?;
        self.message(kind, |m| {
            m.push(key_len);
            m.extend_from_slice(typed_key.as_bytes());
            m.extend_from_slice(value);
        })
    }

    /// Builds the payload with `fill`, then writes header and payload in one call.
    fn message(&mut self, kind: u8, fill: impl FnOnce(&mut Vec<u8>)) -> io::Result<()> {
        self.message.clear();
        self.message.extend_from_slice(&[0, 0, kind]);
        fill(&mut self.message);
        let size = self.message.len() - 3;
        let size = u16::try_from(size).map_err(|_| {
            invalid(format!("ULog message '{}' of {size} bytes: at most 65535 fit in msg_size", kind as char))
        })?;
        self.message[..2].copy_from_slice(&size.to_le_bytes());
        self.out.write_all(&self.message)?;
        self.written += self.message.len() as u64;
        Ok(())
    }
}

fn check_name(what: &str, name: &str) -> io::Result<()> {
    if name.is_empty() || !name.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_') {
        return Err(invalid(format!("{what} `{name}`: expected letters, digits and `_` only")));
    }
    Ok(())
}

fn invalid(message: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidInput, message)
}
