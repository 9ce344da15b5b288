//! GeoTIFF (TIFF 6.0 + GeoTIFF 1.0 keys) decoded from bytes: one band of elevations, its
//! georeferencing and no-data value.
//!
//! Read: little- and big-endian classic TIFF; strips or tiles; no compression or Deflate
//! (with predictor 1 or 2); samples of 8/16/32-bit signed or unsigned integers and 32/64-bit
//! floats; `ModelPixelScale` + `ModelTiepoint` georeferencing; geographic WGS84
//! (EPSG:4326) or UTM on WGS84 (EPSG:326zz north, 327zz south); `GDAL_NODATA`. Anything else
//! is a [`DemError`] that says what the file has and what is read.

use std::io::Read;

use super::{Crs, Dem, DemError};

/// Largest grid read, pixels (5000 x 5000 float pixels are 100 MB in memory): a world of
/// 50 km half-width at 20 m resolution. Crop larger DEMs with `gdal_translate -projwin`.
const MAX_PIXELS: u64 = 25_000_000;

struct Tiff<'a> {
    bytes: &'a [u8],
    little: bool,
}

/// One IFD entry.
#[derive(Clone, Copy)]
struct Entry {
    tag: u16,
    kind: u16,
    count: u32,
    /// Offset of the value bytes (inline in the entry when they fit in 4).
    at: usize,
}

fn bad(message: impl Into<String>) -> DemError {
    DemError::Malformed(message.into())
}

impl<'a> Tiff<'a> {
    fn get(&self, at: usize, n: usize) -> Result<&'a [u8], DemError> {
        at.checked_add(n).and_then(|end| self.bytes.get(at..end)).ok_or_else(|| {
            bad(format!("truncated: {n} bytes at byte {at} run past the file's {} bytes", self.bytes.len()))
        })
    }

    fn u16(&self, at: usize) -> Result<u16, DemError> {
        let b: [u8; 2] = self.get(at, 2)?.try_into().expect("2 bytes");
        Ok(if self.little { u16::from_le_bytes(b) } else { u16::from_be_bytes(b) })
    }

    fn u32(&self, at: usize) -> Result<u32, DemError> {
        let b: [u8; 4] = self.get(at, 4)?.try_into().expect("4 bytes");
        Ok(if self.little { u32::from_le_bytes(b) } else { u32::from_be_bytes(b) })
    }

    fn f64(&self, at: usize) -> Result<f64, DemError> {
        let b: [u8; 8] = self.get(at, 8)?.try_into().expect("8 bytes");
        Ok(if self.little { f64::from_le_bytes(b) } else { f64::from_be_bytes(b) })
    }

    /// The entry's values as numbers (integers, rationals and floats).
    fn numbers(&self, e: Entry) -> Result<Vec<f64>, DemError> {
        let n = e.count as usize;
        // The values must be in the file before anything is allocated for them.
        self.get(e.at, n.saturating_mul(type_size(e.kind)))?;
        let mut out = Vec::with_capacity(n);
        for i in 0..n {
            out.push(match e.kind {
                1 | 7 => f64::from(self.get(e.at + i, 1)?[0]),
                6 => f64::from(self.get(e.at + i, 1)?[0] as i8),
                3 => f64::from(self.u16(e.at + 2 * i)?),
                8 => f64::from(self.u16(e.at + 2 * i)? as i16),
                4 => f64::from(self.u32(e.at + 4 * i)?),
                9 => f64::from(self.u32(e.at + 4 * i)? as i32),
                5 => f64::from(self.u32(e.at + 8 * i)?) / f64::from(self.u32(e.at + 8 * i + 4)?.max(1)),
                11 => f64::from(f32::from_bits(self.u32(e.at + 4 * i)?)),
                12 => self.f64(e.at + 8 * i)?,
                k => return Err(bad(format!("tag {}: unknown field type {k}", e.tag))),
            });
        }
        Ok(out)
    }

    fn text(&self, e: Entry) -> Result<String, DemError> {
        let b = self.get(e.at, e.count as usize)?;
        Ok(String::from_utf8_lossy(b).trim_end_matches('\0').trim().to_string())
    }
}

fn type_size(kind: u16) -> usize {
    match kind {
        1 | 2 | 6 | 7 => 1,
        3 | 8 => 2,
        4 | 9 | 11 => 4,
        5 | 10 | 12 => 8,
        _ => 1,
    }
}

/// Reads a GeoTIFF's first image as a [`Dem`].
pub fn read(bytes: &[u8]) -> Result<Dem, DemError> {
    let little = match bytes.get(..4) {
        Some(b"II*\0") => true,
        Some(b"MM\0*") => false,
        Some(b"II+\0" | b"MM\0+") => {
            return Err(DemError::Unsupported(
                "BigTIFF (write a classic TIFF, e.g. gdal_translate -co BIGTIFF=NO)".into(),
            ));
        }
        _ => return Err(bad("not a TIFF file: the first bytes are not II*\\0 or MM\\0*")),
    };
    let t = Tiff { bytes, little };
    let ifd = t.u32(4)? as usize;
    let count = t.u16(ifd)? as usize;
    let mut entries = Vec::with_capacity(count);
    for k in 0..count {
        let at = ifd + 2 + 12 * k;
        let (tag, kind, n) = (t.u16(at)?, t.u16(at + 2)?, t.u32(at + 4)?);
        let size = type_size(kind).saturating_mul(n as usize);
        let value_at = if size <= 4 { at + 8 } else { t.u32(at + 8)? as usize };
        entries.push(Entry { tag, kind, count: n, at: value_at });
    }
    let find = |tag: u16| entries.iter().copied().find(|e| e.tag == tag);
    let number = |tag: u16, name: &str| -> Result<f64, DemError> {
        let e = find(tag).ok_or_else(|| bad(format!("no {name} tag ({tag})")))?;
        t.numbers(e)?.first().copied().ok_or_else(|| bad(format!("empty {name} tag")))
    };
    let optional = |tag: u16, default: f64| -> Result<f64, DemError> {
        match find(tag) {
            Some(e) => Ok(t.numbers(e)?.first().copied().unwrap_or(default)),
            None => Ok(default),
        }
    };
    // Sizes may come as floats (any numeric type is accepted): a huge one saturates the
    // cast, so products are checked.
    let at_most = |w: usize, h: usize| (w as u64).checked_mul(h as u64).is_some_and(|p| p <= MAX_PIXELS);
    let width = number(256, "ImageWidth")? as usize;
    let height = number(257, "ImageLength")? as usize;
    if width == 0 || height == 0 || !at_most(width, height) {
        return Err(bad(format!("{width} x {height} pixels (expected 1 to {MAX_PIXELS} pixels)")));
    }
    let bits = optional(258, 1.0)? as u32;
    let format = optional(339, 1.0)? as u32;
    let samples = optional(277, 1.0)? as u32;
    let compression = optional(259, 1.0)? as u32;
    let predictor = optional(317, 1.0)? as u32;
    if samples != 1 {
        return Err(DemError::Unsupported(format!("{samples} samples per pixel (a DEM has one band)")));
    }
    let sample = Sample::of(format, bits)?;
    if !matches!(compression, 1 | 8 | 32946) {
        let name = match compression {
            5 => "LZW",
            7 => "JPEG",
            34887 => "LERC",
            50000 => "ZSTD",
            _ => "this",
        };
        return Err(DemError::Unsupported(format!(
            "{name} compression (code {compression}); this reader reads uncompressed and Deflate GeoTIFFs: gdal_translate -co COMPRESS=DEFLATE"
        )));
    }
    if !matches!(predictor, 1 | 2) || (predictor == 2 && sample.is_float()) {
        return Err(DemError::Unsupported(format!("predictor {predictor} (read: 1, and 2 on integer samples)")));
    }

    // Strips are tiles as wide as the image.
    let (tile_w, tile_h, offsets, counts) = match (find(324), find(325)) {
        (Some(o), Some(c)) => (number(322, "TileWidth")? as usize, number(323, "TileLength")? as usize, o, c),
        _ => {
            let o = find(273).ok_or_else(|| bad("no StripOffsets or TileOffsets"))?;
            let c = find(279).ok_or_else(|| bad("no StripByteCounts"))?;
            (width, (optional(278, height as f64)? as usize).clamp(1, height), o, c)
        }
    };
    if tile_w == 0 || tile_h == 0 || !at_most(tile_w, tile_h) {
        return Err(bad(format!("tiles of {tile_w} x {tile_h} pixels (expected 1 to {MAX_PIXELS} pixels)")));
    }
    let offsets = t.numbers(offsets)?;
    let counts = t.numbers(counts)?;
    let across = width.div_ceil(tile_w);
    let down = height.div_ceil(tile_h);
    if offsets.len() < across * down || counts.len() < offsets.len() {
        return Err(bad(format!("{} blocks listed, the image needs {}", offsets.len(), across * down)));
    }
    let mut values = vec![f32::NAN; width * height];
    let block_bytes = tile_w * tile_h * sample.bytes();
    for (k, (&offset, &count)) in offsets.iter().zip(&counts).take(across * down).enumerate() {
        let raw = t.get(offset as usize, count as usize)?;
        let data = match compression {
            1 => raw.to_vec(),
            _ => {
                let mut out = Vec::with_capacity(block_bytes.min(raw.len().saturating_mul(8)));
                flate2::read::ZlibDecoder::new(raw)
                    .take(block_bytes as u64)
                    .read_to_end(&mut out)
                    .map_err(|e| bad(format!("block {k}: the Deflate data does not inflate: {e}")))?;
                out
            }
        };
        let (bx, by) = ((k % across) * tile_w, (k / across) * tile_h);
        // The last strip may be short; tiles are always whole.
        let rows = (data.len() / (tile_w * sample.bytes())).min(tile_h);
        for r in 0..rows {
            let mut row: Vec<f64> =
                (0..tile_w).map(|c| sample.read(&data[(r * tile_w + c) * sample.bytes()..], little)).collect();
            if predictor == 2 {
                for c in 1..tile_w {
                    row[c] = sample.wrap(row[c] + row[c - 1]);
                }
            }
            let y = by + r;
            if y >= height {
                break;
            }
            for (c, v) in row.iter().enumerate().take(width.saturating_sub(bx)) {
                values[y * width + bx + c] = *v as f32;
            }
        }
    }

    // Georeferencing.
    let scale = find(33550).map(|e| t.numbers(e)).transpose()?;
    let tie = find(33922).map(|e| t.numbers(e)).transpose()?;
    let (Some(scale), Some(tie)) = (scale, tie) else {
        return Err(DemError::NotGeoreferenced(
            if find(34264).is_some() {
                "it uses ModelTransformation (a rotated grid); write it north-up with gdalwarp"
            } else {
                "no ModelPixelScale and ModelTiepoint tags: georeference it (gdal_translate -a_srs ... -a_ullr ...)"
            }
            .into(),
        ));
    };
    if scale.len() < 2 || tie.len() < 6 || scale[0] <= 0.0 || scale[1] <= 0.0 {
        return Err(DemError::NotGeoreferenced(format!("pixel scale {scale:?} or tiepoint {tie:?} unusable")));
    }
    let keys = find(34735).map(|e| t.numbers(e)).transpose()?.unwrap_or_default();
    // GeoKeyDirectory: a 4-short header, then (key, location, count, value); location 0
    // means the value is the short itself.
    let key = |id: u32| {
        keys.chunks(4).skip(1).find(|k| k.len() == 4 && k[0] as u32 == id && k[1] == 0.0).map(|k| k[3] as u32)
    };
    let crs = match (key(1024), key(2048), key(3072)) {
        (_, _, Some(code @ 32601..=32660)) => Crs::Utm { zone: (code - 32600) as u8, north: true },
        (_, _, Some(code @ 32701..=32760)) => Crs::Utm { zone: (code - 32700) as u8, north: false },
        (_, _, Some(code)) => {
            return Err(DemError::UnsupportedCrs(format!(
                "EPSG:{code} (read: EPSG:4326 and WGS84 UTM EPSG:326zz/327zz; reproject with gdalwarp -t_srs EPSG:4326)"
            )));
        }
        (_, Some(4326), None) => Crs::Geographic,
        (_, Some(code), None) => {
            return Err(DemError::UnsupportedCrs(format!(
                "geographic EPSG:{code} (read: EPSG:4326; reproject with gdalwarp -t_srs EPSG:4326)"
            )));
        }
        (None, None, None) => return Err(DemError::NotGeoreferenced("no GeoKeyDirectory: the CRS is unknown".into())),
        (model, None, None) => {
            return Err(DemError::UnsupportedCrs(format!(
                "model type {model:?} without an EPSG code (user-defined CRS); reproject with gdalwarp -t_srs EPSG:4326"
            )));
        }
    };
    let pixel_is_point = key(1025) == Some(2);
    let nodata = match find(42113) {
        Some(e) => t.text(e)?.parse::<f64>().ok(),
        None => None,
    };
    // The value of pixel (0, 0) sits at the pixel's centre, unless PixelIsPoint.
    let centre = if pixel_is_point { 0.0 } else { 0.5 };
    let x0 = tie[3] + (centre - tie[0]) * scale[0];
    let y0 = tie[4] - (centre - tie[1]) * scale[1];
    Dem::new(width, height, values, [x0, y0, scale[0], scale[1]], crs, nodata)
}

/// The sample type.
#[derive(Clone, Copy)]
enum Sample {
    U8,
    I8,
    U16,
    I16,
    U32,
    I32,
    F32,
    F64,
}

impl Sample {
    fn of(format: u32, bits: u32) -> Result<Self, DemError> {
        Ok(match (format, bits) {
            (1, 8) => Sample::U8,
            (2, 8) => Sample::I8,
            (1, 16) => Sample::U16,
            (2, 16) => Sample::I16,
            (1, 32) => Sample::U32,
            (2, 32) => Sample::I32,
            (3, 32) => Sample::F32,
            (3, 64) => Sample::F64,
            _ => {
                return Err(DemError::Unsupported(format!(
                    "{bits}-bit samples of format {format} (read: 8/16/32-bit integers, 32/64-bit floats)"
                )));
            }
        })
    }

    fn bytes(self) -> usize {
        match self {
            Sample::U8 | Sample::I8 => 1,
            Sample::U16 | Sample::I16 => 2,
            Sample::U32 | Sample::I32 | Sample::F32 => 4,
            Sample::F64 => 8,
        }
    }

    fn is_float(self) -> bool {
        matches!(self, Sample::F32 | Sample::F64)
    }

    /// The sample at the start of `b` (zero when the block is short).
    fn read(self, b: &[u8], little: bool) -> f64 {
        let mut raw = [0u8; 8];
        let n = self.bytes().min(b.len());
        raw[..n].copy_from_slice(&b[..n]);
        if !little {
            raw[..self.bytes()].reverse();
        }
        let u = u64::from_le_bytes(raw);
        match self {
            Sample::U8 => u as u8 as f64,
            Sample::I8 => u as u8 as i8 as f64,
            Sample::U16 => u as u16 as f64,
            Sample::I16 => u as u16 as i16 as f64,
            Sample::U32 => u as u32 as f64,
            Sample::I32 => u as u32 as i32 as f64,
            Sample::F32 => f64::from(f32::from_bits(u as u32)),
            Sample::F64 => f64::from_bits(u),
        }
    }

    /// Horizontal-differencing sums wrap in the sample's integer type.
    fn wrap(self, v: f64) -> f64 {
        let i = v as i64;
        match self {
            Sample::U8 => i as u8 as f64,
            Sample::I8 => i as i8 as f64,
            Sample::U16 => i as u16 as f64,
            Sample::I16 => i as i16 as f64,
            Sample::U32 => i as u32 as f64,
            Sample::I32 => i as i32 as f64,
            Sample::F32 | Sample::F64 => v,
        }
    }
}
