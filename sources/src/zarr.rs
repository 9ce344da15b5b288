//! Zarr v2 groups of dense arrays: what Python's `zarr` and `xarray` open directly
//! (`xarray.open_zarr(path)`), locally or on an object store, with no HDF5 or NetCDF
//! library on our side. Used for the sky grid (`sadesim gnss grid`) and the urban wind
//! field of the asset cache.
//!
//! A group is a folder: `.zgroup`, `.zattrs` (the group's attributes, JSON), `.zmetadata`
//! (all of the metadata consolidated, what `xarray.open_zarr` reads first), and one folder
//! per array with `.zarray` (shape, chunks, dtype, compressor), `.zattrs`
//! (`_ARRAY_DIMENSIONS`: xarray's dimension names) and its chunks. Arrays here are
//! little-endian, C order, and chunked along their first axis only: either one chunk for the
//! whole array, or one chunk per index of the first axis (a time slice, a wind sector), so
//! a reader takes one slice without the rest. Chunks are raw or zlib-compressed
//! (numcodecs' `zlib`, which `zarr` decodes by default).
//!
//! Everything here is bytes in and out: [`group_files`] gives `(relative path, bytes)` to
//! write anywhere, and the readers take a function that fetches a relative path.

use serde_json::{Value, json};

/// Element type of an array.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dtype {
    U8,
    F32,
    F64,
}

impl Dtype {
    /// The numpy type string Zarr v2 uses.
    pub fn zarr_name(self) -> &'static str {
        match self {
            Self::U8 => "|u1",
            Self::F32 => "<f4",
            Self::F64 => "<f8",
        }
    }

    pub fn size(self) -> usize {
        match self {
            Self::U8 => 1,
            Self::F32 => 4,
            Self::F64 => 8,
        }
    }
}

/// How chunks are stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Compression {
    Raw,
    /// zlib at this level (1 fastest .. 9 smallest).
    Zlib(u32),
}

/// One array to write.
#[derive(Clone, Debug)]
pub struct ArrayOut {
    pub name: String,
    pub dtype: Dtype,
    pub shape: Vec<usize>,
    /// Dimension names, as many as `shape` (xarray's `_ARRAY_DIMENSIONS`).
    pub dims: Vec<String>,
    /// One chunk per index of the first axis (else one chunk for the whole array).
    pub chunk_first_axis: bool,
    /// The elements, little-endian, C order.
    pub data: Vec<u8>,
    /// `fill_value` of the metadata (what a reader shows for a missing chunk).
    pub fill: Value,
    /// Attributes besides the dimension names (units, meaning).
    pub attrs: Value,
}

impl ArrayOut {
    /// An array of `f32` elements.
    pub fn f32(name: &str, dims: &[&str], shape: Vec<usize>, values: &[f32]) -> Self {
        Self::new(name, Dtype::F32, dims, shape, values.iter().flat_map(|v| v.to_le_bytes()).collect())
    }

    /// An array of `f64` elements.
    pub fn f64(name: &str, dims: &[&str], shape: Vec<usize>, values: &[f64]) -> Self {
        Self::new(name, Dtype::F64, dims, shape, values.iter().flat_map(|v| v.to_le_bytes()).collect())
    }

    /// An array of bytes (`uint8`), e.g. flags.
    pub fn u8(name: &str, dims: &[&str], shape: Vec<usize>, values: Vec<u8>) -> Self {
        Self::new(name, Dtype::U8, dims, shape, values)
    }

    fn new(name: &str, dtype: Dtype, dims: &[&str], shape: Vec<usize>, data: Vec<u8>) -> Self {
        assert_eq!(dims.len(), shape.len(), "{name}: one dimension name per axis");
        assert_eq!(data.len(), shape.iter().product::<usize>() * dtype.size(), "{name}: data fills the shape");
        // No fill value for integers: xarray masks the fill value as missing (NaN), and a 0
        // in a flag or count array is data.
        let fill = if dtype == Dtype::U8 { Value::Null } else { json!("NaN") };
        Self {
            name: name.to_string(),
            dtype,
            shape,
            dims: dims.iter().map(|d| d.to_string()).collect(),
            chunk_first_axis: false,
            data,
            fill,
            attrs: json!({}),
        }
    }

    /// Chunked per index of the first axis.
    pub fn per_slice(mut self) -> Self {
        self.chunk_first_axis = true;
        self
    }

    pub fn with_attrs(mut self, attrs: Value) -> Self {
        self.attrs = attrs;
        self
    }

    pub fn with_fill(mut self, fill: Value) -> Self {
        self.fill = fill;
        self
    }
}

/// The files of a group with attributes `attrs` and `arrays`: `(path relative to the
/// group's folder, bytes)`, deterministic (same arrays, same bytes).
pub fn group_files(attrs: &Value, arrays: &[ArrayOut], compression: Compression) -> Vec<(String, Vec<u8>)> {
    let mut files = vec![
        (".zgroup".to_string(), json!({"zarr_format": 2}).to_string().into_bytes()),
        (".zattrs".to_string(), attrs.to_string().into_bytes()),
    ];
    for a in arrays {
        let mut chunks = a.shape.clone();
        if a.chunk_first_axis && !chunks.is_empty() {
            chunks[0] = 1;
        }
        let compressor = match compression {
            Compression::Raw => Value::Null,
            Compression::Zlib(level) => json!({"id": "zlib", "level": level}),
        };
        let meta = json!({"zarr_format": 2, "shape": a.shape, "chunks": chunks, "dtype": a.dtype.zarr_name(),
                          "compressor": compressor, "fill_value": a.fill, "filters": null, "order": "C"});
        files.push((format!("{}/.zarray", a.name), meta.to_string().into_bytes()));
        let mut attrs = a.attrs.clone();
        attrs["_ARRAY_DIMENSIONS"] = json!(a.dims);
        files.push((format!("{}/.zattrs", a.name), attrs.to_string().into_bytes()));
        let rest = ".0".repeat(a.shape.len().saturating_sub(1));
        let per_chunk = if a.chunk_first_axis { a.data.len() / a.shape[0].max(1) } else { a.data.len() };
        for (s, chunk) in a.data.chunks(per_chunk.max(1)).enumerate() {
            files.push((format!("{}/{s}{rest}", a.name), compress(chunk, compression)));
        }
    }
    // Consolidated metadata (`.zmetadata`): xarray and zarr read every array's metadata in
    // one request instead of one per file (what an object store makes slow).
    let mut metadata = serde_json::Map::new();
    for (path, bytes) in &files {
        if path.ends_with(".zgroup") || path.ends_with(".zattrs") || path.ends_with(".zarray") {
            let value: Value = serde_json::from_slice(bytes).expect("written above as JSON");
            metadata.insert(path.clone(), value);
        }
    }
    let consolidated = json!({"zarr_consolidated_format": 1, "metadata": metadata});
    files.push((".zmetadata".to_string(), consolidated.to_string().into_bytes()));
    files
}

fn compress(bytes: &[u8], compression: Compression) -> Vec<u8> {
    match compression {
        Compression::Raw => bytes.to_vec(),
        Compression::Zlib(level) => {
            use std::io::Write as _;
            let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::new(level));
            z.write_all(bytes).expect("writing to memory");
            z.finish().expect("writing to memory")
        }
    }
}

/// Writes `files` ([`group_files`]) under `dir`; returns the bytes written.
///
/// # Errors
/// A folder or file cannot be written.
pub fn write_group(dir: &std::path::Path, files: &[(String, Vec<u8>)]) -> std::io::Result<u64> {
    let mut written = 0;
    for (rel, bytes) in files {
        let path = dir.join(rel);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent)?;
        }
        std::fs::write(&path, bytes)?;
        written += bytes.len() as u64;
    }
    Ok(written)
}

/// Why a group cannot be read: `file` is the path relative to the group (as `fetch` got
/// it).
#[derive(Debug, thiserror::Error)]
#[error("{file}: {problem}")]
pub struct ZarrError {
    pub file: String,
    pub problem: String,
}

fn problem(file: &str, problem: impl Into<String>) -> ZarrError {
    ZarrError { file: file.to_string(), problem: problem.into() }
}

/// A relative path's bytes, or why not (the fetch's own error, in words).
pub type Fetch<'a> = dyn FnMut(&str) -> Result<Vec<u8>, String> + 'a;

/// The group's attributes (`.zattrs`).
///
/// # Errors
/// Missing or not JSON; not a Zarr v2 group (`.zgroup`).
pub fn read_group_attrs(fetch: &mut Fetch) -> Result<Value, ZarrError> {
    let group: Value = json_of(fetch, ".zgroup")?;
    if group["zarr_format"] != json!(2) {
        return Err(problem(".zgroup", format!("zarr_format {}: expected 2", group["zarr_format"])));
    }
    json_of(fetch, ".zattrs")
}

fn json_of(fetch: &mut Fetch, file: &str) -> Result<Value, ZarrError> {
    let bytes = fetch(file).map_err(|e| problem(file, e))?;
    serde_json::from_slice(&bytes).map_err(|e| problem(file, format!("not JSON: {e}")))
}

/// An array read back: its shape and its elements, little-endian, C order.
#[derive(Clone, Debug, PartialEq)]
pub struct ArrayIn {
    pub shape: Vec<usize>,
    pub dtype: Dtype,
    pub data: Vec<u8>,
}

impl ArrayIn {
    pub fn to_f32(&self) -> Vec<f32> {
        assert_eq!(self.dtype, Dtype::F32);
        self.data.chunks_exact(4).map(|b| f32::from_le_bytes(b.try_into().expect("4 bytes"))).collect()
    }

    pub fn to_f64(&self) -> Vec<f64> {
        assert_eq!(self.dtype, Dtype::F64);
        self.data.chunks_exact(8).map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes"))).collect()
    }
}

/// Reads array `name` of the layout [`group_files`] writes (any compression of it), checking
/// that it is `dtype` with `rank` axes.
///
/// # Errors
/// A missing or unreadable file, metadata of another layout (order, filters, chunking,
/// dtype, rank), or a chunk of the wrong size after decompression: each naming the file.
pub fn read_array(fetch: &mut Fetch, name: &str, dtype: Dtype, rank: usize) -> Result<ArrayIn, ZarrError> {
    let meta_file = format!("{name}/.zarray");
    let meta = json_of(fetch, &meta_file)?;
    let bad = |what: String| problem(&meta_file, what);
    let shape: Vec<usize> = serde_json::from_value(meta["shape"].clone())
        .map_err(|_| bad(format!("shape {}: expected a list of sizes", meta["shape"])))?;
    let chunks: Vec<usize> = serde_json::from_value(meta["chunks"].clone())
        .map_err(|_| bad(format!("chunks {}: expected a list of sizes", meta["chunks"])))?;
    if shape.len() != rank {
        return Err(bad(format!("{} axes: expected {rank}", shape.len())));
    }
    if meta["dtype"] != json!(dtype.zarr_name()) {
        return Err(bad(format!("dtype {}: expected {:?}", meta["dtype"], dtype.zarr_name())));
    }
    if meta["order"] != json!("C") || !meta["filters"].is_null() {
        return Err(bad("expected order \"C\" and no filters".into()));
    }
    let per_slice = chunks.len() == rank && chunks[0] == 1 && chunks[1..] == shape[1..];
    if chunks != shape && !per_slice {
        return Err(bad(format!(
            "chunks {chunks:?}: expected the whole array {shape:?} or one slice of the first axis"
        )));
    }
    let zlib = match &meta["compressor"] {
        Value::Null => false,
        c if c["id"] == json!("zlib") => true,
        c => return Err(bad(format!("compressor {c}: expected none or zlib"))),
    };
    let chunk_count = if chunks == shape { 1 } else { shape[0] };
    let chunk_bytes = chunks.iter().product::<usize>() * dtype.size();
    let rest = ".0".repeat(rank.saturating_sub(1));
    let mut data = Vec::with_capacity(chunk_bytes * chunk_count);
    for s in 0..chunk_count {
        let file = format!("{name}/{s}{rest}");
        let raw = fetch(&file).map_err(|e| problem(&file, e))?;
        let bytes = if zlib {
            use std::io::Read as _;
            let mut out = Vec::with_capacity(chunk_bytes);
            flate2::read::ZlibDecoder::new(raw.as_slice())
                .read_to_end(&mut out)
                .map_err(|e| problem(&file, format!("not zlib data: {e}")))?;
            out
        } else {
            raw
        };
        if bytes.len() != chunk_bytes {
            return Err(problem(&file, format!("{} bytes: expected {chunk_bytes} for chunk {chunks:?}", bytes.len())));
        }
        data.extend_from_slice(&bytes);
    }
    Ok(ArrayIn { shape, dtype, data })
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use super::*;

    fn files_map(files: Vec<(String, Vec<u8>)>) -> BTreeMap<String, Vec<u8>> {
        files.into_iter().collect()
    }

    fn fetcher(map: &BTreeMap<String, Vec<u8>>) -> impl FnMut(&str) -> Result<Vec<u8>, String> + '_ {
        |p: &str| map.get(p).cloned().ok_or_else(|| "no such file".to_string())
    }

    fn sample(compression: Compression) -> BTreeMap<String, Vec<u8>> {
        let values: Vec<f32> = (0..24).map(|i| i as f32 * 0.5).collect();
        let arrays = [
            ArrayOut::f32("v", &["sector", "up", "east"], vec![2, 3, 4], &values).per_slice(),
            ArrayOut::u8("flags", &["up", "east"], vec![3, 4], (0..12).collect()),
        ];
        files_map(group_files(&json!({"spacingM": 5.0}), &arrays, compression))
    }

    #[test]
    fn arrays_round_trip_raw_and_compressed_with_one_chunk_per_slice() {
        for compression in [Compression::Raw, Compression::Zlib(1)] {
            let files = sample(compression);
            assert!(files.contains_key("v/0.0.0") && files.contains_key("v/1.0.0") && files.contains_key("flags/0.0"));
            let consolidated: Value = serde_json::from_slice(&files[".zmetadata"]).unwrap();
            assert_eq!(consolidated["metadata"]["v/.zarray"]["chunks"], json!([1, 3, 4]));
            let mut fetch = fetcher(&files);
            assert_eq!(read_group_attrs(&mut fetch).unwrap()["spacingM"], json!(5.0));
            let v = read_array(&mut fetch, "v", Dtype::F32, 3).unwrap();
            assert_eq!(v.shape, [2, 3, 4]);
            assert_eq!(v.to_f32(), (0..24).map(|i| i as f32 * 0.5).collect::<Vec<_>>());
            assert_eq!(read_array(&mut fetch, "flags", Dtype::U8, 2).unwrap().data, (0..12).collect::<Vec<u8>>());
            let dims: Value = serde_json::from_slice(&files["v/.zattrs"]).unwrap();
            assert_eq!(dims["_ARRAY_DIMENSIONS"], json!(["sector", "up", "east"]));
        }
    }

    #[test]
    fn a_wrong_type_a_short_chunk_or_a_missing_chunk_names_the_file() {
        let mut files = sample(Compression::Raw);
        let e = read_array(&mut fetcher(&files), "v", Dtype::F64, 3).unwrap_err();
        assert_eq!(e.file, "v/.zarray");
        assert!(e.problem.contains("<f8"), "{e}");
        files.get_mut("v/1.0.0").unwrap().pop();
        let e = read_array(&mut fetcher(&files), "v", Dtype::F32, 3).unwrap_err();
        assert_eq!(e.to_string(), "v/1.0.0: 47 bytes: expected 48 for chunk [1, 3, 4]");
        files.remove("v/1.0.0");
        let e = read_array(&mut fetcher(&files), "v", Dtype::F32, 3).unwrap_err();
        assert_eq!(e.to_string(), "v/1.0.0: no such file");
        let mut zipped = sample(Compression::Zlib(1));
        zipped.insert("v/0.0.0".into(), b"not zlib".to_vec());
        let e = read_array(&mut fetcher(&zipped), "v", Dtype::F32, 3).unwrap_err();
        assert!(e.to_string().starts_with("v/0.0.0: not zlib data"), "{e}");
    }
}
