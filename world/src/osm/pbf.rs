//! The OpenStreetMap PBF format (<https://wiki.openstreetmap.org/wiki/PBF_Format>), decoded
//! from bytes: the nodes' coordinates, the ways' node lists and the relations' members, with
//! the tags [`super::assemble`] reads.
//!
//! A file is a sequence of blobs: a 4-byte big-endian length, a `BlobHeader` message of that
//! length (`type`, `datasize`), then a `Blob` of `datasize` bytes holding the payload raw or
//! zlib-compressed. The first blob is an `OSMHeader` (`HeaderBlock`: bounding box, required
//! features), the others `OSMData` (`PrimitiveBlock`: a string table and groups of nodes,
//! dense nodes, ways or relations). Protocol Buffers are decoded by hand (varints, zigzag,
//! length-delimited fields): the format needs a dozen fields, and decoding them here keeps
//! every malformed byte a [`PbfError`] with its offset instead of a panic in a generated
//! parser.
//!
//! Coordinates are WGS84 degrees: `1e-9 * (offset + granularity * value)` (nanodegrees).

use std::collections::HashMap;
use std::io::Read;

use crate::protobuf::{Bad, Cursor, Fields, Value, bad};

/// Largest `BlobHeader`, bytes (the format's limit).
const MAX_HEADER_BYTES: usize = 64 * 1024;
/// Largest blob, compressed or not, bytes (the format's limit).
const MAX_BLOB_BYTES: usize = 32 * 1024 * 1024;
/// Features of `HeaderBlock.required_features` this reader understands.
const SUPPORTED_FEATURES: [&str; 2] = ["OsmSchema-V0.6", "DenseNodes"];

/// What a file holds, as read: every node's position, every way and relation with the tags
/// in `keep_tag`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RawOsm {
    /// `HeaderBlock.bbox` as `[min_lon, min_lat, max_lon, max_lat]` degrees, when the file
    /// declares one.
    pub bbox: Option<[f64; 4]>,
    /// Node id -> `[latitude_deg, longitude_deg]`.
    pub nodes: HashMap<i64, [f64; 2]>,
    pub ways: Vec<RawWay>,
    pub relations: Vec<RawRelation>,
}

/// `(key, value)` pairs, in file order.
pub type Tags = Vec<(String, String)>;

/// One way: its node ids in order (closed when the first equals the last).
#[derive(Clone, Debug, PartialEq)]
pub struct RawWay {
    pub id: i64,
    pub tags: Tags,
    pub refs: Vec<i64>,
}

/// One relation and its members.
#[derive(Clone, Debug, PartialEq)]
pub struct RawRelation {
    pub id: i64,
    pub tags: Tags,
    pub members: Vec<Member>,
}

/// A relation member.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Member {
    pub kind: MemberKind,
    pub id: i64,
    /// `outer`, `inner`, `part`, ... (may be empty).
    pub role: String,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MemberKind {
    Node,
    Way,
    Relation,
}

/// Why the bytes are not a readable OSM PBF file.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum PbfError {
    /// The bytes break the format at `offset` (a byte of the file; inside a compressed
    /// blob, the blob's first byte, with `inner` the offset in the decompressed payload).
    #[error("byte {offset}{}: {message}", inner.map(|i| format!(" (blob payload byte {i})")).unwrap_or_default())]
    Malformed { offset: u64, inner: Option<u64>, message: String },
    /// The file needs something this reader does not do (a compression, a required feature).
    #[error("byte {offset}: not supported: {message}")]
    Unsupported { offset: u64, message: String },
}

/// Reads a whole `.osm.pbf` file from `bytes`, keeping the way and relation tags whose key
/// `keep_tag` accepts (all positions and members are kept).
///
/// # Errors
/// [`PbfError`] naming the byte: not a PBF file (no `OSMHeader` first), a truncated blob,
/// a malformed message, an unsupported compression or required feature.
pub fn read(bytes: &[u8], keep_tag: &dyn Fn(&str) -> bool) -> Result<RawOsm, PbfError> {
    let mut out = RawOsm::default();
    let mut pos = 0usize;
    let mut blob_index = 0usize;
    while pos < bytes.len() {
        let at = pos as u64;
        let malformed = |message: String| PbfError::Malformed { offset: at, inner: None, message };
        let len_bytes: [u8; 4] = bytes
            .get(pos..pos + 4)
            .and_then(|b| b.try_into().ok())
            .ok_or_else(|| malformed("truncated: a blob's 4-byte header length is cut off".into()))?;
        let header_len = u32::from_be_bytes(len_bytes) as usize;
        if header_len == 0 || header_len > MAX_HEADER_BYTES {
            return Err(malformed(if blob_index == 0 {
                format!(
                    "not an OSM PBF file: the first 4 bytes give a blob header of {header_len} bytes (expected 1 to {MAX_HEADER_BYTES})"
                )
            } else {
                format!("blob header length {header_len} is outside 1..{MAX_HEADER_BYTES}")
            }));
        }
        pos += 4;
        let header = bytes.get(pos..pos + header_len).ok_or_else(|| {
            malformed(format!("truncated: the blob header needs {header_len} bytes, {} remain", bytes.len() - pos))
        })?;
        let (kind, data_size) = blob_header(header).map_err(|e| placed(e, pos as u64, None))?;
        pos += header_len;
        if data_size > MAX_BLOB_BYTES {
            return Err(malformed(format!("blob of {data_size} bytes is over the format's {MAX_BLOB_BYTES}")));
        }
        let blob_at = pos as u64;
        let blob = bytes.get(pos..pos + data_size).ok_or_else(|| {
            malformed(format!("truncated: the blob needs {data_size} bytes, {} remain", bytes.len() - pos))
        })?;
        pos += data_size;
        match (blob_index, kind.as_str()) {
            (0, "OSMHeader") => {
                let payload = blob_payload(blob, blob_at)?;
                header_block(&payload, &mut out).map_err(|e| placed(e, blob_at, Some(())))?;
            }
            (0, other) => {
                return Err(malformed(format!(
                    "not an OSM PBF file: the first blob is {other:?}, expected \"OSMHeader\""
                )));
            }
            (_, "OSMData") => {
                let payload = blob_payload(blob, blob_at)?;
                primitive_block(&payload, keep_tag, &mut out).map_err(|e| placed(e, blob_at, Some(())))?;
            }
            // Unknown blob types are skipped, as the format asks.
            _ => {}
        }
        blob_index += 1;
    }
    if blob_index == 0 {
        return Err(PbfError::Malformed { offset: 0, inner: None, message: "empty file".into() });
    }
    Ok(out)
}

/// Places a decoding error inside one message in the file: `base` is where the message
/// starts in the file, or the blob's first byte with `payload` set (then the offset is
/// inside the decompressed payload).
fn placed(e: Bad, base: u64, payload: Option<()>) -> PbfError {
    match payload {
        None => PbfError::Malformed { offset: base + e.offset as u64, inner: None, message: e.message },
        Some(()) => PbfError::Malformed { offset: base, inner: Some(e.offset as u64), message: e.message },
    }
}

/// The payload of a `Blob`: `raw`, or `zlib_data` inflated to `raw_size` bytes.
fn blob_payload(blob: &[u8], at: u64) -> Result<Vec<u8>, PbfError> {
    let mut raw: Option<&[u8]> = None;
    let mut zlib: Option<&[u8]> = None;
    let mut raw_size: Option<usize> = None;
    let mut fields = Fields::new(blob);
    while let Some((field, value)) = fields.next().map_err(|e| placed(e, at, None))? {
        match (field, value) {
            (1, Value::Bytes(b)) => raw = Some(b),
            (2, Value::Varint(n)) => raw_size = Some(n as usize),
            (3, Value::Bytes(b)) => zlib = Some(b),
            (4..=7, _) => {
                let name = ["lzma", "bzip2", "lz4", "zstd"][field as usize - 4];
                return Err(PbfError::Unsupported {
                    offset: at,
                    message: format!("{name}-compressed blob (this reader reads raw and zlib blobs)"),
                });
            }
            _ => {}
        }
    }
    match (raw, zlib, raw_size) {
        (Some(raw), _, _) => Ok(raw.to_vec()),
        (None, Some(zlib), Some(size)) if size <= MAX_BLOB_BYTES => {
            let mut out = Vec::with_capacity(size);
            flate2::read::ZlibDecoder::new(zlib).take(size as u64 + 1).read_to_end(&mut out).map_err(|e| {
                PbfError::Malformed { offset: at, inner: None, message: format!("the zlib data does not inflate: {e}") }
            })?;
            if out.len() != size {
                return Err(PbfError::Malformed {
                    offset: at,
                    inner: None,
                    message: format!("the zlib data inflates to {} bytes, the blob says {size}", out.len()),
                });
            }
            Ok(out)
        }
        (None, Some(_), size) => Err(PbfError::Malformed {
            offset: at,
            inner: None,
            message: format!("zlib blob with raw_size {size:?} (expected 1 to {MAX_BLOB_BYTES})"),
        }),
        (None, None, _) => Err(PbfError::Malformed { offset: at, inner: None, message: "blob without data".into() }),
    }
}

/// `BlobHeader`: `(type, datasize)`.
fn blob_header(bytes: &[u8]) -> Result<(String, usize), Bad> {
    let mut kind = None;
    let mut size = None;
    let mut fields = Fields::new(bytes);
    while let Some((field, value)) = fields.next()? {
        match (field, value) {
            (1, Value::Bytes(b)) => kind = Some(String::from_utf8_lossy(b).into_owned()),
            (3, Value::Varint(n)) => size = Some(n as usize),
            _ => {}
        }
    }
    match (kind, size) {
        (Some(kind), Some(size)) => Ok((kind, size)),
        _ => Err(bad(0, "blob header without type or datasize")),
    }
}

/// `HeaderBlock`: the bounding box and the required features.
fn header_block(bytes: &[u8], out: &mut RawOsm) -> Result<(), Bad> {
    let mut fields = Fields::new(bytes);
    while let Some((field, value)) = fields.next()? {
        match (field, value) {
            (1, Value::Bytes(b)) => {
                // HeaderBBox: left, right, top, bottom as sint64 nanodegrees.
                let mut bbox = [0i64; 4];
                let mut inner = Fields::new(b);
                while let Some((f, v)) = inner.next()? {
                    if let (1..=4, Value::Varint(n)) = (f, v) {
                        bbox[f as usize - 1] = zigzag(n);
                    }
                }
                let deg = |n: i64| n as f64 * 1e-9;
                out.bbox = Some([deg(bbox[0]), deg(bbox[3]), deg(bbox[1]), deg(bbox[2])]);
            }
            (4, Value::Bytes(b)) => {
                let feature = String::from_utf8_lossy(b);
                if !SUPPORTED_FEATURES.contains(&feature.as_ref()) {
                    return Err(bad(
                        fields.last,
                        format!("the file requires feature {feature:?} (this reader supports {SUPPORTED_FEATURES:?})"),
                    ));
                }
            }
            _ => {}
        }
    }
    Ok(())
}

/// The coordinate scaling of one block.
#[derive(Clone, Copy)]
struct Scale {
    granularity: i64,
    lat_offset: i64,
    lon_offset: i64,
}

impl Scale {
    fn degrees(self, lat: i64, lon: i64) -> [f64; 2] {
        // Wrapping: a hostile file must not panic on overflow (the result is then garbage
        // that the coverage check or the footprint validation refuses).
        [
            1e-9 * self.lat_offset.wrapping_add(self.granularity.wrapping_mul(lat)) as f64,
            1e-9 * self.lon_offset.wrapping_add(self.granularity.wrapping_mul(lon)) as f64,
        ]
    }
}

/// `PrimitiveBlock`: the string table and the groups.
fn primitive_block(bytes: &[u8], keep_tag: &dyn Fn(&str) -> bool, out: &mut RawOsm) -> Result<(), Bad> {
    let mut strings: Vec<&[u8]> = Vec::new();
    let mut groups: Vec<(usize, &[u8])> = Vec::new();
    let mut scale = Scale { granularity: 100, lat_offset: 0, lon_offset: 0 };
    let mut fields = Fields::new(bytes);
    while let Some((field, value)) = fields.next()? {
        match (field, value) {
            (1, Value::Bytes(b)) => {
                let mut table = Fields::new(b);
                while let Some((f, v)) = table.next()? {
                    if let (1, Value::Bytes(s)) = (f, v) {
                        strings.push(s);
                    }
                }
            }
            (2, Value::Bytes(b)) => groups.push((fields.last, b)),
            (17, Value::Varint(n)) => scale.granularity = n as i64,
            (19, Value::Varint(n)) => scale.lat_offset = n as i64,
            (20, Value::Varint(n)) => scale.lon_offset = n as i64,
            _ => {}
        }
    }
    let table = StringTable(strings);
    for (at, group) in groups {
        primitive_group(group, scale, &table, keep_tag, out).map_err(|e| bad(at + e.offset, e.message))?;
    }
    Ok(())
}

struct StringTable<'a>(Vec<&'a [u8]>);

impl StringTable<'_> {
    fn get(&self, index: u64, at: usize) -> Result<String, Bad> {
        self.0
            .get(index as usize)
            .map(|s| String::from_utf8_lossy(s).into_owned())
            .ok_or_else(|| bad(at, format!("string index {index} is outside the block's table of {}", self.0.len())))
    }

    fn tags(&self, keys: &[u64], vals: &[u64], at: usize, keep: &dyn Fn(&str) -> bool) -> Result<Tags, Bad> {
        if keys.len() != vals.len() {
            return Err(bad(at, format!("{} tag keys but {} values", keys.len(), vals.len())));
        }
        let mut tags = Vec::new();
        for (&k, &v) in keys.iter().zip(vals) {
            let key = self.get(k, at)?;
            if keep(&key) {
                tags.push((key, self.get(v, at)?));
            }
        }
        Ok(tags)
    }
}

fn primitive_group(
    bytes: &[u8],
    scale: Scale,
    table: &StringTable,
    keep: &dyn Fn(&str) -> bool,
    out: &mut RawOsm,
) -> Result<(), Bad> {
    let mut fields = Fields::new(bytes);
    while let Some((field, value)) = fields.next()? {
        let at = fields.last;
        let Value::Bytes(b) = value else { continue };
        let inside = |e: Bad| bad(at + e.offset, e.message);
        match field {
            1 => node(b, scale, out).map_err(inside)?,
            2 => dense_nodes(b, scale, out).map_err(inside)?,
            3 => out.ways.push(way(b, table, keep).map_err(inside)?),
            4 => out.relations.push(relation(b, table, keep).map_err(inside)?),
            _ => {}
        }
    }
    Ok(())
}

fn node(bytes: &[u8], scale: Scale, out: &mut RawOsm) -> Result<(), Bad> {
    let (mut id, mut lat, mut lon) = (None, None, None);
    let mut fields = Fields::new(bytes);
    while let Some((field, value)) = fields.next()? {
        match (field, value) {
            (1, Value::Varint(n)) => id = Some(zigzag(n)),
            (8, Value::Varint(n)) => lat = Some(zigzag(n)),
            (9, Value::Varint(n)) => lon = Some(zigzag(n)),
            _ => {}
        }
    }
    match (id, lat, lon) {
        (Some(id), Some(lat), Some(lon)) => {
            out.nodes.insert(id, scale.degrees(lat, lon));
            Ok(())
        }
        _ => Err(bad(0, "node without id, lat or lon")),
    }
}

fn dense_nodes(bytes: &[u8], scale: Scale, out: &mut RawOsm) -> Result<(), Bad> {
    let (mut ids, mut lats, mut lons) = (Vec::new(), Vec::new(), Vec::new());
    let mut fields = Fields::new(bytes);
    while let Some((field, value)) = fields.next()? {
        let at = fields.last;
        match field {
            1 => packed(value, &mut ids, at)?,
            8 => packed(value, &mut lats, at)?,
            9 => packed(value, &mut lons, at)?,
            _ => {}
        }
    }
    if ids.len() != lats.len() || ids.len() != lons.len() {
        return Err(bad(0, format!("dense nodes: {} ids, {} lats, {} lons", ids.len(), lats.len(), lons.len())));
    }
    let (mut id, mut lat, mut lon) = (0i64, 0i64, 0i64);
    for i in 0..ids.len() {
        // Delta-coded; wrapping: a hostile file must not panic on overflow.
        id = id.wrapping_add(zigzag(ids[i]));
        lat = lat.wrapping_add(zigzag(lats[i]));
        lon = lon.wrapping_add(zigzag(lons[i]));
        out.nodes.insert(id, scale.degrees(lat, lon));
    }
    Ok(())
}

/// `(id, tag key indices, tag value indices)` of a way or relation.
type Element = (Option<i64>, Vec<u64>, Vec<u64>);

/// The fields ways and relations share (`id` 1, `keys` 2, `vals` 3), and the packed
/// integer lists `lists` asks for by field number.
fn element(bytes: &[u8], lists: &mut [(u32, &mut Vec<u64>)]) -> Result<Element, Bad> {
    let (mut id, mut keys, mut vals) = (None, Vec::new(), Vec::new());
    let mut fields = Fields::new(bytes);
    while let Some((field, value)) = fields.next()? {
        let at = fields.last;
        match (field, value) {
            (1, Value::Varint(n)) => id = Some(n as i64),
            (2, v) => packed(v, &mut keys, at)?,
            (3, v) => packed(v, &mut vals, at)?,
            (f, v) => {
                if let Some((_, list)) = lists.iter_mut().find(|(n, _)| *n == f) {
                    packed(v, list, at)?;
                }
            }
        }
    }
    Ok((id, keys, vals))
}

/// Delta-coded zigzag values (node refs, member ids) as absolute ids; wrapping, so a
/// hostile file cannot overflow.
fn undelta(deltas: &[u64]) -> Vec<i64> {
    let mut last = 0i64;
    deltas
        .iter()
        .map(|&d| {
            last = last.wrapping_add(zigzag(d));
            last
        })
        .collect()
}

fn way(bytes: &[u8], table: &StringTable, keep: &dyn Fn(&str) -> bool) -> Result<RawWay, Bad> {
    let mut refs = Vec::new();
    let (id, keys, vals) = element(bytes, &mut [(8, &mut refs)])?;
    let id = id.ok_or_else(|| bad(0, "way without id"))?;
    let tags = table.tags(&keys, &vals, 0, keep).map_err(|e| bad(e.offset, format!("way {id}: {}", e.message)))?;
    Ok(RawWay { id, tags, refs: undelta(&refs) })
}

fn relation(bytes: &[u8], table: &StringTable, keep: &dyn Fn(&str) -> bool) -> Result<RawRelation, Bad> {
    let (mut roles, mut ids, mut types) = (Vec::new(), Vec::new(), Vec::new());
    let (id, keys, vals) = element(bytes, &mut [(8, &mut roles), (9, &mut ids), (10, &mut types)])?;
    let id = id.ok_or_else(|| bad(0, "relation without id"))?;
    let named = |e: Bad| bad(e.offset, format!("relation {id}: {}", e.message));
    let tags = table.tags(&keys, &vals, 0, keep).map_err(named)?;
    if roles.len() != ids.len() || types.len() != ids.len() {
        return Err(named(bad(0, format!("{} member ids, {} roles, {} types", ids.len(), roles.len(), types.len()))));
    }
    let mut members = Vec::with_capacity(ids.len());
    for (i, member) in undelta(&ids).into_iter().enumerate() {
        let kind = match types[i] {
            0 => MemberKind::Node,
            1 => MemberKind::Way,
            2 => MemberKind::Relation,
            t => return Err(named(bad(0, format!("member type {t} (expected 0 node, 1 way, 2 relation)")))),
        };
        // Roles are string-table indices stored as int32 varints.
        members.push(Member { kind, id: member, role: table.get(roles[i] & 0xffff_ffff, 0).map_err(named)? });
    }
    Ok(RawRelation { id, tags, members })
}

/// A repeated varint field, packed (wire type 2) or not (wire type 0).
fn packed(value: Value, out: &mut Vec<u64>, at: usize) -> Result<(), Bad> {
    match value {
        Value::Varint(n) => out.push(n),
        Value::Bytes(b) => {
            let mut r = Cursor { bytes: b, pos: 0 };
            while r.pos < b.len() {
                out.push(r.varint().map_err(|e| bad(at + e.offset, e.message))?);
            }
        }
        _ => return Err(bad(at, "a repeated integer field with a fixed-width wire type")),
    }
    Ok(())
}

fn zigzag(n: u64) -> i64 {
    ((n >> 1) as i64) ^ -((n & 1) as i64)
}
