//! Protobuf encoding of the ground-truth streams (`/drones/<name>/pose`, `/drones/<name>/velocity`,
//! `/tf`), the recording's three 100 Hz streams: binary doubles are about a third of the
//! bytes of their JSON text and cost nothing to format, which is most of what recording
//! costs (docs/performance.md, "Recording cost").
//!
//! MCAP's protobuf profile: schema encoding `protobuf`, schema name the message's full name
//! (`foxglove.PoseInFrame`), schema data a binary `google.protobuf.FileDescriptorSet` with
//! the message's `.proto` file and every file it imports, imports first; message encoding
//! `protobuf`. The descriptors are built here from [`FILES`], which copies Foxglove's
//! published `.proto` files (github.com/foxglove/schemas, `schemas/proto/foxglove/`) field
//! for field; `tests/interop/test_recording_mcap.py` compares them with the
//! `foxglove-schemas-protobuf` package's.
//!
//! Values are rounded to a binary grid before encoding ([`quantize`]): the result is still
//! an exact double, within half a grid step of the truth, and its low mantissa bytes are
//! zero, which zstd compresses; full-precision doubles hardly compress at all.

/// Protobuf wire types.
const VARINT: u8 = 0;
const FIXED64: u8 = 1;
const LENGTH_DELIMITED: u8 = 2;
const FIXED32: u8 = 5;

/// Appends `v` as a base-128 varint.
pub fn varint(out: &mut Vec<u8>, mut v: u64) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

fn key(out: &mut Vec<u8>, field: u32, wire_type: u8) {
    varint(out, (u64::from(field) << 3) | u64::from(wire_type));
}

/// A `double` field.
pub fn double(out: &mut Vec<u8>, field: u32, v: f64) {
    key(out, field, FIXED64);
    out.extend_from_slice(&v.to_le_bytes());
}

/// An unsigned or non-negative `int32`/`int64`/`uint32`/`uint64`/`enum` field.
pub fn uint(out: &mut Vec<u8>, field: u32, v: u64) {
    key(out, field, VARINT);
    varint(out, v);
}

/// A `fixed32` field.
pub fn fixed32(out: &mut Vec<u8>, field: u32, v: u32) {
    key(out, field, FIXED32);
    out.extend_from_slice(&v.to_le_bytes());
}

/// A `repeated double` field, packed (proto3's encoding of repeated scalars: one
/// length-delimited field holding the values back to back). Nothing for an empty list.
pub fn packed_doubles(out: &mut Vec<u8>, field: u32, values: &[f64]) {
    if values.is_empty() {
        return;
    }
    key(out, field, LENGTH_DELIMITED);
    varint(out, (values.len() * 8) as u64);
    for v in values {
        out.extend_from_slice(&v.to_le_bytes());
    }
}

/// A `string` or `bytes` field.
pub fn bytes(out: &mut Vec<u8>, field: u32, v: &[u8]) {
    key(out, field, LENGTH_DELIMITED);
    varint(out, v.len() as u64);
    out.extend_from_slice(v);
}

/// An embedded message field whose content `body` appends. Its length is known only
/// afterwards: one byte is reserved (every message of ours under 128 bytes fits it) and the
/// content moved when the length needs more.
pub fn message(out: &mut Vec<u8>, field: u32, body: impl FnOnce(&mut Vec<u8>)) {
    key(out, field, LENGTH_DELIMITED);
    let at = out.len();
    out.push(0);
    body(out);
    let len = out.len() - at - 1;
    if len < 0x80 {
        out[at] = len as u8;
    } else {
        let mut prefix = Vec::with_capacity(4);
        varint(&mut prefix, len as u64);
        out.splice(at..=at, prefix);
    }
}

/// `v` rounded to the nearest multiple of 2^-`bits` (ties to even): exact in binary, so the
/// double's mantissa below that bit is zero (compressible) and the error is at most
/// 2^-(`bits`+1). Values too large for the grid (and NaN, infinities) are returned as they are.
pub fn quantize(v: f64, bits: i32) -> f64 {
    // 2^bits, built from its exponent: `powi` and `round` are libm calls on baseline x86-64,
    // and this runs 20 times per drone per 10 ms.
    let scale = f64::from_bits(((1023 + bits) as u64) << 52);
    let x = v * scale;
    // Adding 1.5 * 2^52 leaves no fraction bits, so the sum is rounded to an integer (to
    // even on ties); subtracting it again is exact. Valid while |x| < 2^51.
    const ROUNDER: f64 = 6_755_399_441_055_744.0;
    if x.abs() < 2_251_799_813_685_248.0 { ((x + ROUNDER) - ROUNDER) / scale } else { v }
}

/// Positions and velocities: 2^-10 m (about 1 mm; at most 0.49 mm off).
pub const METRES_BITS: i32 = 10;
/// Quaternion components: 2^-17 (about 7.6e-6, an angle of about 1.5e-5 rad).
pub const UNIT_BITS: i32 = 17;

/// `google.protobuf.Timestamp` from nanoseconds since the run start.
pub fn timestamp(out: &mut Vec<u8>, field: u32, ns: u64) {
    message(out, field, |b| {
        uint(b, 1, ns / 1_000_000_000);
        uint(b, 2, ns % 1_000_000_000);
    });
}

/// `foxglove.Vector3`, each component rounded to 2^-`bits`.
pub fn vector3(out: &mut Vec<u8>, field: u32, v: [f64; 3], bits: i32) {
    message(out, field, |b| {
        double(b, 1, quantize(v[0], bits));
        double(b, 2, quantize(v[1], bits));
        double(b, 3, quantize(v[2], bits));
    });
}

/// `foxglove.Quaternion` from our `[w, x, y, z]`.
pub fn quaternion(out: &mut Vec<u8>, field: u32, wxyz: [f64; 4]) {
    message(out, field, |b| {
        double(b, 1, quantize(wxyz[1], UNIT_BITS));
        double(b, 2, quantize(wxyz[2], UNIT_BITS));
        double(b, 3, quantize(wxyz[3], UNIT_BITS));
        double(b, 4, quantize(wxyz[0], UNIT_BITS));
    });
}

/// The type of a field in a `.proto` file (`FieldDescriptorProto.Type`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Double,
    Int64,
    Int32,
    Fixed32,
    String,
    Bytes,
    /// A message, by full name with the leading dot (`.foxglove.Vector3`).
    Message(&'static str),
}

impl Kind {
    /// `FieldDescriptorProto.Type` number.
    fn number(self) -> u64 {
        match self {
            Kind::Double => 1,
            Kind::Int64 => 3,
            Kind::Int32 => 5,
            Kind::Fixed32 => 7,
            Kind::String => 9,
            Kind::Bytes => 12,
            Kind::Message(_) => 11,
        }
    }
}

/// One field of a message.
#[derive(Debug, Clone, Copy)]
pub struct Field {
    pub name: &'static str,
    pub number: u32,
    pub repeated: bool,
    pub kind: Kind,
}

const fn field(name: &'static str, number: u32, kind: Kind) -> Field {
    Field { name, number, repeated: false, kind }
}

const fn repeated(name: &'static str, number: u32, kind: Kind) -> Field {
    Field { name, number, repeated: true, kind }
}

/// A `.proto` file with one message (as each of Foxglove's files has).
#[derive(Debug)]
pub struct ProtoFile {
    /// Path, as imported: `foxglove/Pose.proto`.
    pub name: &'static str,
    pub package: &'static str,
    pub dependencies: &'static [&'static str],
    pub message: &'static str,
    pub fields: &'static [Field],
}

impl ProtoFile {
    /// The message's full name: `foxglove.Pose`.
    pub fn full_name(&self) -> String {
        format!("{}.{}", self.package, self.message)
    }
}

const TIMESTAMP: Kind = Kind::Message(".google.protobuf.Timestamp");
const VECTOR3: Kind = Kind::Message(".foxglove.Vector3");
const QUATERNION: Kind = Kind::Message(".foxglove.Quaternion");

/// Every `.proto` file the recording's protobuf schemas need, imports before importers.
pub const FILES: &[ProtoFile] = &[
    ProtoFile {
        name: "google/protobuf/timestamp.proto",
        package: "google.protobuf",
        dependencies: &[],
        message: "Timestamp",
        fields: &[field("seconds", 1, Kind::Int64), field("nanos", 2, Kind::Int32)],
    },
    ProtoFile {
        name: "foxglove/Vector3.proto",
        package: "foxglove",
        dependencies: &[],
        message: "Vector3",
        fields: &[field("x", 1, Kind::Double), field("y", 2, Kind::Double), field("z", 3, Kind::Double)],
    },
    ProtoFile {
        name: "foxglove/Quaternion.proto",
        package: "foxglove",
        dependencies: &[],
        message: "Quaternion",
        fields: &[
            field("x", 1, Kind::Double),
            field("y", 2, Kind::Double),
            field("z", 3, Kind::Double),
            field("w", 4, Kind::Double),
        ],
    },
    ProtoFile {
        name: "foxglove/Pose.proto",
        package: "foxglove",
        dependencies: &["foxglove/Quaternion.proto", "foxglove/Vector3.proto"],
        message: "Pose",
        fields: &[field("position", 1, VECTOR3), field("orientation", 2, QUATERNION)],
    },
    ProtoFile {
        name: "foxglove/PoseInFrame.proto",
        package: "foxglove",
        dependencies: &["foxglove/Pose.proto", "google/protobuf/timestamp.proto"],
        message: "PoseInFrame",
        fields: &[
            field("timestamp", 1, TIMESTAMP),
            field("frame_id", 2, Kind::String),
            field("pose", 3, Kind::Message(".foxglove.Pose")),
        ],
    },
    ProtoFile {
        name: "foxglove/FrameTransform.proto",
        package: "foxglove",
        dependencies: &["foxglove/Quaternion.proto", "foxglove/Vector3.proto", "google/protobuf/timestamp.proto"],
        message: "FrameTransform",
        fields: &[
            field("timestamp", 1, TIMESTAMP),
            field("parent_frame_id", 2, Kind::String),
            field("child_frame_id", 3, Kind::String),
            field("translation", 4, VECTOR3),
            field("rotation", 5, QUATERNION),
        ],
    },
    ProtoFile {
        name: "foxglove/FrameTransforms.proto",
        package: "foxglove",
        dependencies: &["foxglove/FrameTransform.proto"],
        message: "FrameTransforms",
        fields: &[Field {
            name: "transforms",
            number: 1,
            repeated: true,
            kind: Kind::Message(".foxglove.FrameTransform"),
        }],
    },
    // Onboard cameras (issue 18). Fields in the order of Foxglove's files, which is not
    // the order of their numbers.
    ProtoFile {
        name: "foxglove/CompressedImage.proto",
        package: "foxglove",
        dependencies: &["google/protobuf/timestamp.proto"],
        message: "CompressedImage",
        fields: &[
            field("timestamp", 1, TIMESTAMP),
            field("frame_id", 4, Kind::String),
            field("data", 2, Kind::Bytes),
            field("format", 3, Kind::String),
        ],
    },
    ProtoFile {
        name: "foxglove/CameraCalibration.proto",
        package: "foxglove",
        dependencies: &["google/protobuf/timestamp.proto"],
        message: "CameraCalibration",
        fields: &[
            field("timestamp", 1, TIMESTAMP),
            field("frame_id", 9, Kind::String),
            field("width", 2, Kind::Fixed32),
            field("height", 3, Kind::Fixed32),
            field("distortion_model", 4, Kind::String),
            repeated("D", 5, Kind::Double),
            repeated("K", 6, Kind::Double),
            repeated("R", 7, Kind::Double),
            repeated("P", 8, Kind::Double),
        ],
    },
    ProtoFile {
        name: "foxglove/RawImage.proto",
        package: "foxglove",
        dependencies: &["google/protobuf/timestamp.proto"],
        message: "RawImage",
        fields: &[
            field("timestamp", 1, TIMESTAMP),
            field("frame_id", 7, Kind::String),
            field("width", 2, Kind::Fixed32),
            field("height", 3, Kind::Fixed32),
            field("encoding", 4, Kind::String),
            field("step", 5, Kind::Fixed32),
            field("data", 6, Kind::Bytes),
        ],
    },
    // Ours: the ground-truth velocity, linear in `world` (ENU, m/s) and angular in the body
    // frame (FLU, rad/s).
    ProtoFile {
        name: "sadesim/Velocity.proto",
        package: "sadesim",
        dependencies: &["foxglove/Vector3.proto", "google/protobuf/timestamp.proto"],
        message: "Velocity",
        fields: &[
            field("timestamp", 1, TIMESTAMP),
            field("frame_id", 2, Kind::String),
            field("velocity_enu_mps", 3, VECTOR3),
            field("rate_body_rps", 4, VECTOR3),
        ],
    },
];

/// The file that defines the message `full_name` (`foxglove.Pose`).
pub fn file_of(full_name: &str) -> Option<&'static ProtoFile> {
    FILES.iter().find(|f| f.full_name() == full_name)
}

/// The `FileDescriptorSet` of the message `full_name`: its file and everything it imports,
/// imports first. `None` for a message not in [`FILES`].
pub fn descriptor_set(full_name: &str) -> Option<Vec<u8>> {
    let file = file_of(full_name)?;
    let mut needed = Vec::new();
    collect(file, &mut needed);
    let mut out = Vec::new();
    for f in needed {
        // FileDescriptorSet.file = 1
        message(&mut out, 1, |b| file_descriptor(b, f));
    }
    Some(out)
}

/// `file` after everything it imports (depth first), each once.
fn collect(file: &'static ProtoFile, out: &mut Vec<&'static ProtoFile>) {
    for dependency in file.dependencies {
        if let Some(d) = FILES.iter().find(|f| f.name == *dependency) {
            collect(d, out);
        }
    }
    if !out.iter().any(|f| f.name == file.name) {
        out.push(file);
    }
}

/// `google.protobuf.FileDescriptorProto` of `file` (proto3 syntax).
fn file_descriptor(out: &mut Vec<u8>, file: &ProtoFile) {
    bytes(out, 1, file.name.as_bytes());
    bytes(out, 2, file.package.as_bytes());
    for d in file.dependencies {
        bytes(out, 3, d.as_bytes());
    }
    // message_type = 4: DescriptorProto { name = 1, field = 2 }
    message(out, 4, |m| {
        bytes(m, 1, file.message.as_bytes());
        for f in file.fields {
            // FieldDescriptorProto { name = 1, number = 3, label = 4, type = 5, type_name = 6 }
            message(m, 2, |b| {
                bytes(b, 1, f.name.as_bytes());
                uint(b, 3, u64::from(f.number));
                uint(b, 4, if f.repeated { 3 } else { 1 });
                uint(b, 5, f.kind.number());
                if let Kind::Message(type_name) = f.kind {
                    bytes(b, 6, type_name.as_bytes());
                }
            });
        }
    });
    bytes(out, 12, b"proto3");
}

#[cfg(test)]
pub mod decode {
    //! A protobuf decoder driven by [`FILES`], for the tests: a message becomes the JSON
    //! value the recording would have held with JSON encoding (field names as keys,
    //! `Timestamp` as `{"sec", "nsec"}`), so the tests read both encodings alike.

    use serde_json::{Map, Value, json};

    use super::{FILES, Kind};

    /// Reads the varint at `data[*at..]` and moves `at` past it.
    pub fn varint(data: &[u8], at: &mut usize) -> u64 {
        let mut v = 0u64;
        for shift in (0..64).step_by(7) {
            let byte = data[*at];
            *at += 1;
            v |= u64::from(byte & 0x7f) << shift;
            if byte < 0x80 {
                return v;
            }
        }
        panic!("varint longer than 10 bytes");
    }

    /// Decodes `data` as the message `full_name` (`foxglove.PoseInFrame`).
    ///
    /// # Panics
    /// On bytes that are not a valid encoding of it (what the tests check).
    pub fn to_json(full_name: &str, data: &[u8]) -> Value {
        let file = FILES
            .iter()
            .find(|f| f.full_name() == full_name.trim_start_matches('.'))
            .unwrap_or_else(|| panic!("unknown message {full_name}"));
        let mut fields = Map::new();
        let mut at = 0;
        while at < data.len() {
            let key = varint(data, &mut at);
            let (number, wire_type) = ((key >> 3) as u32, (key & 7) as u8);
            let field = file
                .fields
                .iter()
                .find(|f| f.number == number)
                .unwrap_or_else(|| panic!("{full_name} has no field {number}"));
            let value = match (field.kind, wire_type) {
                (Kind::Double, 1) => {
                    let v = f64::from_le_bytes(data[at..at + 8].try_into().unwrap());
                    at += 8;
                    json!(v)
                }
                (Kind::Int64 | Kind::Int32, 0) => json!(varint(data, &mut at)),
                (Kind::Fixed32, 5) => {
                    let v = u32::from_le_bytes(data[at..at + 4].try_into().unwrap());
                    at += 4;
                    json!(v)
                }
                // A packed `repeated double`: every value at once.
                (Kind::Double, 2) if field.repeated => {
                    let len = varint(data, &mut at) as usize;
                    let values: Vec<f64> =
                        data[at..at + len].chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().unwrap())).collect();
                    at += len;
                    fields.insert(field.name.to_string(), json!(values));
                    continue;
                }
                (Kind::Bytes, 2) => {
                    let len = varint(data, &mut at) as usize;
                    let body = &data[at..at + len];
                    at += len;
                    json!({"bytes": body.len(), "head": body.iter().take(4).collect::<Vec<_>>()})
                }
                (Kind::String | Kind::Message(_), 2) => {
                    let len = varint(data, &mut at) as usize;
                    let body = &data[at..at + len];
                    at += len;
                    match field.kind {
                        Kind::String => json!(std::str::from_utf8(body).expect("UTF-8 string")),
                        Kind::Message(".google.protobuf.Timestamp") => {
                            let t = to_json("google.protobuf.Timestamp", body);
                            json!({"sec": t.get("seconds").cloned().unwrap_or(json!(0)), "nsec": t.get("nanos").cloned().unwrap_or(json!(0))})
                        }
                        Kind::Message(name) => to_json(name, body),
                        _ => unreachable!(),
                    }
                }
                (kind, wire) => panic!("{full_name}.{}: {kind:?} with wire type {wire}", field.name),
            };
            if field.repeated {
                fields.entry(field.name).or_insert_with(|| json!([])).as_array_mut().unwrap().push(value);
            } else {
                fields.insert(field.name.to_string(), value);
            }
        }
        Value::Object(fields)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn varints_match_the_protobuf_encoding_guide() {
        let enc = |v| {
            let mut b = Vec::new();
            varint(&mut b, v);
            b
        };
        assert_eq!(enc(1), [0x01]);
        assert_eq!(enc(150), [0x96, 0x01]);
        assert_eq!(enc(u64::MAX).len(), 10);
    }

    #[test]
    fn long_embedded_messages_get_a_longer_length_prefix() {
        let mut out = vec![0xAA];
        message(&mut out, 1, |b| b.extend(std::iter::repeat_n(7u8, 300)));
        // key (field 1, wire type 2), varint 300 = [0xAC, 0x02], then the content.
        assert_eq!(&out[..4], &[0xAA, 0x0A, 0xAC, 0x02]);
        assert_eq!(out.len(), 4 + 300);
        assert!(out[4..].iter().all(|&b| b == 7));
    }

    #[test]
    fn quantized_values_are_close_and_have_short_mantissas() {
        for v in [0.0, 1e-9, -3.25, 123.456_789, -54_321.987_654, 0.699_999_9, 2.5 / 1024.0] {
            let q = quantize(v, METRES_BITS);
            assert!((q - v).abs() <= 0.5 / 1024.0, "{v} -> {q}");
            assert_eq!(q, (v * 1024.0).round_ties_even() / 1024.0, "{v}");
            // A multiple of 2^-10 below 2^16 needs at most 26 significant bits: the low 26
            // of the 52 mantissa bits are zero.
            assert_eq!(q.to_bits() & ((1 << 26) - 1), 0, "{v} -> {q}");
        }
    }

    #[test]
    fn values_off_the_grid_pass_through() {
        assert_eq!(quantize(1e300, METRES_BITS), 1e300);
        assert_eq!(quantize(-f64::INFINITY, UNIT_BITS), -f64::INFINITY);
        assert!(quantize(f64::NAN, UNIT_BITS).is_nan());
        assert_eq!(quantize(0.123_456_789, UNIT_BITS), (0.123_456_789f64 * 131_072.0).round() / 131_072.0);
    }

    #[test]
    fn every_import_is_defined_before_its_importers() {
        for (i, file) in FILES.iter().enumerate() {
            for d in file.dependencies {
                let at = FILES.iter().position(|f| f.name == *d).unwrap_or_else(|| panic!("{d} is not defined"));
                assert!(at < i, "{} imports {d}, defined after it", file.name);
            }
            for f in file.fields {
                if let Kind::Message(name) = f.kind {
                    let defining = file_of(name.trim_start_matches('.')).expect("message type defined");
                    assert!(
                        defining.name == file.name || file.dependencies.contains(&defining.name),
                        "{}.{} uses {name} without importing {}",
                        file.message,
                        f.name,
                        defining.name
                    );
                }
            }
        }
    }

    #[test]
    fn a_descriptor_set_holds_the_file_and_its_imports_once_each() {
        let set = descriptor_set("foxglove.FrameTransforms").unwrap();
        // Walk the FileDescriptorSet's files and read each one's name (field 1, first).
        let mut names = Vec::new();
        let mut at = 0;
        while at < set.len() {
            assert_eq!(set[at], 0x0A, "FileDescriptorSet.file");
            at += 1;
            let len = decode::varint(&set, &mut at) as usize;
            let file = &set[at..at + len];
            assert_eq!(file[0], 0x0A, "FileDescriptorProto.name first");
            let name_len = file[1] as usize;
            names.push(std::str::from_utf8(&file[2..2 + name_len]).unwrap().to_string());
            at += len;
        }
        assert_eq!(
            names,
            [
                "foxglove/Quaternion.proto",
                "foxglove/Vector3.proto",
                "google/protobuf/timestamp.proto",
                "foxglove/FrameTransform.proto",
                "foxglove/FrameTransforms.proto"
            ]
        );
        assert!(descriptor_set("foxglove.NoSuchThing").is_none());
    }

    #[test]
    fn a_pose_decodes_to_what_was_encoded() {
        let mut out = Vec::new();
        timestamp(&mut out, 1, 12_340_000_000);
        bytes(&mut out, 2, b"world");
        message(&mut out, 3, |b| {
            vector3(b, 1, [1.5, -2.25, 30.0], METRES_BITS);
            quaternion(b, 2, [0.5, 0.5, -0.5, 0.5]);
        });
        let v = decode::to_json("foxglove.PoseInFrame", &out);
        assert_eq!(
            v,
            serde_json::json!({
                "timestamp": {"sec": 12, "nsec": 340_000_000},
                "frame_id": "world",
                "pose": {"position": {"x": 1.5, "y": -2.25, "z": 30.0}, "orientation": {"x": 0.5, "y": -0.5, "z": 0.5, "w": 0.5}}
            })
        );
    }
}
