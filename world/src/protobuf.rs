//! A minimal Protocol Buffers reader: the fields of one message, in order, every value
//! checked against the buffer's end, every error a byte offset and a message (never a
//! panic). The OSM PBF reader ([`crate::osm`]) and the replay of `recording.mcap`'s
//! protobuf poses (`sim_worker::view::replay`) read their few fields with it instead of a
//! generated parser.

/// A malformed message: where (bytes from the start of the message given to
/// [`Fields::new`]) and what.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Bad {
    pub offset: usize,
    pub message: String,
}

impl std::fmt::Display for Bad {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} at byte {}", self.message, self.offset)
    }
}

/// A [`Bad`] at `offset`.
pub fn bad(offset: usize, message: impl Into<String>) -> Bad {
    Bad { offset, message: message.into() }
}

/// One field's value, by wire type.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Value<'a> {
    /// Wire type 0.
    Varint(u64),
    /// Wire type 1, little-endian (a `double` is `f64::from_bits`).
    Fixed64(u64),
    /// Wire type 2: bytes, a string, an embedded message or a packed repeated field.
    Bytes(&'a [u8]),
    /// Wire type 5, little-endian.
    Fixed32(u32),
}

/// Reads varints from `bytes` at `pos`.
#[derive(Debug)]
pub struct Cursor<'a> {
    pub bytes: &'a [u8],
    pub pos: usize,
}

impl Cursor<'_> {
    /// The varint at `pos`, moving past it.
    ///
    /// # Errors
    /// A truncated varint, or one longer than 10 bytes, at its first byte.
    pub fn varint(&mut self) -> Result<u64, Bad> {
        let start = self.pos;
        let mut value = 0u64;
        for shift in (0..64).step_by(7) {
            let byte = *self.bytes.get(self.pos).ok_or_else(|| bad(start, "truncated varint"))?;
            self.pos += 1;
            value |= u64::from(byte & 0x7f) << shift;
            if byte & 0x80 == 0 {
                return Ok(value);
            }
        }
        Err(bad(start, "varint longer than 10 bytes"))
    }
}

/// The fields of one message, in order.
#[derive(Debug)]
pub struct Fields<'a> {
    cursor: Cursor<'a>,
    /// Offset of the last field's value (of its content for length-delimited fields): where
    /// an embedded message starts, for the offsets of errors inside it.
    pub last: usize,
}

impl<'a> Fields<'a> {
    pub fn new(bytes: &'a [u8]) -> Self {
        Self { cursor: Cursor { bytes, pos: 0 }, last: 0 }
    }

    /// The next field (number and value), `None` at the message's end.
    ///
    /// # Errors
    /// A truncated key or value, a length past the end, a group or invalid wire type.
    #[allow(clippy::should_implement_trait)] // fallible: not an Iterator
    pub fn next(&mut self) -> Result<Option<(u32, Value<'a>)>, Bad> {
        let c = &mut self.cursor;
        if c.pos >= c.bytes.len() {
            return Ok(None);
        }
        let at = c.pos;
        let key = c.varint()?;
        let field = (key >> 3) as u32;
        let value = match key & 7 {
            0 => Value::Varint(c.varint()?),
            wire @ (1 | 5) => {
                let width = if wire == 1 { 8 } else { 4 };
                let Some(raw) = c.bytes.get(c.pos..c.pos + width) else {
                    return Err(bad(at, format!("field {field}: truncated {width}-byte value")));
                };
                c.pos += width;
                match raw.try_into() {
                    Ok(eight) => Value::Fixed64(u64::from_le_bytes(eight)),
                    Err(_) => Value::Fixed32(u32::from_le_bytes(raw.try_into().expect("4 bytes"))),
                }
            }
            2 => {
                let len = c.varint()? as usize;
                let start = c.pos;
                let end = start.checked_add(len).filter(|&e| e <= c.bytes.len()).ok_or_else(|| {
                    bad(at, format!("field {field}: length {len} runs past the message's {} bytes", c.bytes.len()))
                })?;
                c.pos = end;
                self.last = start;
                return Ok(Some((field, Value::Bytes(&c.bytes[start..end]))));
            }
            wire => return Err(bad(at, format!("field {field}: wire type {wire} (groups or invalid)"))),
        };
        self.last = at;
        Ok(Some((field, value)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_wire_type_reads_and_a_truncated_value_names_its_byte() {
        // field 1 varint 150, field 2 fixed64 1.5, field 3 bytes "ab", field 4 fixed32 7.
        let mut m = vec![0x08, 0x96, 0x01, 0x11];
        m.extend_from_slice(&1.5f64.to_le_bytes());
        m.extend_from_slice(&[0x1A, 2, b'a', b'b', 0x25, 7, 0, 0, 0]);
        let mut f = Fields::new(&m);
        assert_eq!(f.next().unwrap(), Some((1, Value::Varint(150))));
        assert_eq!(f.next().unwrap(), Some((2, Value::Fixed64(1.5f64.to_bits()))));
        assert_eq!(f.next().unwrap(), Some((3, Value::Bytes(b"ab"))));
        assert_eq!(f.last, 14, "where the bytes start");
        assert_eq!(f.next().unwrap(), Some((4, Value::Fixed32(7))));
        assert_eq!(f.next().unwrap(), None);
        let e = Fields::new(&m[..8]).next().and_then(|_| Fields::new(&m[3..8]).next()).unwrap_err();
        assert_eq!(e, bad(0, "field 2: truncated 8-byte value"));
        let long = Fields::new(&[0x1A, 9, 1]).next().unwrap_err();
        assert_eq!(long.to_string(), "field 3: length 9 runs past the message's 3 bytes at byte 0");
    }
}
