//! The shard protocol on TCP (protocol version 4): length-prefixed binary frames.
//!
//! Versions up to 3 sent each message as a JSON line. Every window a shard sent every
//! drone's snapshot as about 1 kB of JSON, and parsing it back was most of the
//! coordinator's serial work over TCP, about 6 µs per drone per window
//! (docs/performance.md, "The lockstep across shards"). The window messages are now fixed
//! layouts of little-endian integers and IEEE-754 doubles (exact, as the JSON numbers were);
//! the rare messages stay JSON inside a frame.
//!
//! # Frames
//! `u32` payload length (little-endian, at most [`MAX_FRAME_BYTES`]), then the payload,
//! whose first byte says what it holds:
//!
//! | kind | message | layout after the kind byte |
//! |---|---|---|
//! | `A` | `ToShard::Advance` | `until_step` u64, `release_pilots` u8, leases flag u8 (+ count u32, `[drone u32, zone u32]` each) |
//! | `W` | `FromShard::Advanced` | `shard` u32, `step` u64, `ready` u8, drone count u32, the drones ([`put_drone`]), events: JSON byte count u32 + a JSON array (0: none) |
//! | `J` | any other message (`Hello`, `Held`, `Stopped`, `Failed`, `Hold`, `Stop`) | the message as JSON |
//!
//! A flag byte is 0 (absent, false) or 1 (present, true); anything else is refused. Every
//! decoding error names the byte offset in the payload and the field it was reading.

use sadesim_engine::events::{Event, FlightMode};
use sadesim_engine::protocol::{DroneDetail, DroneSnapshot, EstimateDetail, FromShard, GnssDetail, SkyDetail, ToShard};

/// Largest accepted payload (a 2000-drone shard's window is about 1 MB).
pub const MAX_FRAME_BYTES: usize = 64 * 1024 * 1024;

const ADVANCE: u8 = b'A';
const WINDOW: u8 = b'W';
const JSON: u8 = b'J';

/// A message that travels in frames.
pub trait Wire: Sized {
    /// Appends the payload (kind byte first) to `out`.
    fn encode(&self, out: &mut Vec<u8>);
    /// Decodes one payload.
    ///
    /// # Errors
    /// What is wrong, naming the byte offset and the field.
    fn decode(payload: &[u8]) -> Result<Self, String>;
}

impl Wire for ToShard {
    fn encode(&self, out: &mut Vec<u8>) {
        match self {
            ToShard::Advance { until_step, release_pilots, leases } => {
                out.push(ADVANCE);
                out.extend_from_slice(&until_step.to_le_bytes());
                out.push(u8::from(*release_pilots));
                put_optional(out, leases.as_ref(), |out, pairs| {
                    put_u32(out, len_u32(pairs.len()));
                    for [drone, zone] in pairs {
                        put_u32(out, *drone);
                        put_u32(out, *zone);
                    }
                });
            }
            ToShard::Hold { .. } | ToShard::Stop => put_json(out, self),
        }
    }

    fn decode(payload: &[u8]) -> Result<Self, String> {
        let mut r = Reader::new(payload);
        match r.u8("kind")? {
            ADVANCE => {
                let until_step = r.u64("untilStep")?;
                let release_pilots = r.flag("releasePilots")?;
                let leases = r.optional("leases", |r| {
                    let n = r.count("leases", 8)?;
                    (0..n).map(|_| Ok([r.u32("leases[].drone")?, r.u32("leases[].zone")?])).collect()
                })?;
                r.end()?;
                Ok(ToShard::Advance { until_step, release_pilots, leases })
            }
            JSON => r.json("message"),
            other => Err(unknown_kind(other)),
        }
    }
}

impl Wire for FromShard {
    fn encode(&self, out: &mut Vec<u8>) {
        match self {
            FromShard::Advanced { shard, step, ready, drones, events } => {
                out.push(WINDOW);
                put_u32(out, *shard);
                out.extend_from_slice(&step.to_le_bytes());
                out.push(u8::from(*ready));
                put_u32(out, len_u32(drones.len()));
                for d in drones {
                    put_drone(out, d);
                }
                if events.is_empty() {
                    put_u32(out, 0);
                } else {
                    let json = serde_json::to_vec(events).expect("events serialize to JSON");
                    put_u32(out, len_u32(json.len()));
                    out.extend_from_slice(&json);
                }
            }
            _ => put_json(out, self),
        }
    }

    fn decode(payload: &[u8]) -> Result<Self, String> {
        let mut r = Reader::new(payload);
        match r.u8("kind")? {
            WINDOW => {
                let shard = r.u32("shard")?;
                let step = r.u64("step")?;
                let ready = r.flag("ready")?;
                // A drone is at least MIN_DRONE_BYTES: a count the payload cannot hold is
                // refused before anything is allocated for it.
                let n = r.count("drones", MIN_DRONE_BYTES)?;
                let mut drones = Vec::with_capacity(n);
                for i in 0..n {
                    drones.push(take_drone(&mut r).map_err(|e| format!("drones[{i}]: {e}"))?);
                }
                let events_bytes = r.count("events", 1)?;
                let events: Vec<Event> = if events_bytes == 0 {
                    Vec::new()
                } else {
                    let at = r.at;
                    let json = r.take(events_bytes, "events")?;
                    serde_json::from_slice(json).map_err(|e| format!("byte {at}: events: {}", one_line(&e)))?
                };
                r.end()?;
                Ok(FromShard::Advanced { shard, step, ready, drones, events })
            }
            JSON => r.json("message"),
            other => Err(unknown_kind(other)),
        }
    }
}

fn unknown_kind(kind: u8) -> String {
    let hint = if kind == b'{' {
        " (a JSON line: the peer speaks the shard protocol of sadesim before version 4; run the same sadesim version in every role)"
    } else {
        ""
    };
    format!("byte 0: kind: expected 'A', 'W' or 'J', found {kind:#04x}{hint}")
}

/// A JSON error on one line: serde_json quotes the peer's text (an unknown variant) as it
/// came, line breaks included; they are escaped so that the error stays one log line.
fn one_line(e: &serde_json::Error) -> String {
    e.to_string().chars().map(|c| if c.is_control() { c.escape_default().to_string() } else { c.to_string() }).collect()
}

fn put_json(out: &mut Vec<u8>, msg: &impl serde::Serialize) {
    out.push(JSON);
    serde_json::to_writer(&mut *out, msg).expect("protocol messages serialize to JSON");
}

fn put_u32(out: &mut Vec<u8>, v: u32) {
    out.extend_from_slice(&v.to_le_bytes());
}

fn put_f64s(out: &mut Vec<u8>, values: &[f64]) {
    for v in values {
        out.extend_from_slice(&v.to_le_bytes());
    }
}

/// A flag byte (0: `None`), then `put` of the value when there is one.
fn put_optional<T>(out: &mut Vec<u8>, v: Option<T>, put: impl FnOnce(&mut Vec<u8>, T)) {
    match v {
        None => out.push(0),
        Some(v) => {
            out.push(1);
            put(out, v);
        }
    }
}

/// A count for the wire; a shard holds at most 2 000 drones and a window a few events, so
/// a count beyond `u32` is a bug.
fn len_u32(n: usize) -> u32 {
    u32::try_from(n).expect("a protocol count fits in 32 bits")
}

/// Bytes of a drone without estimate and GNSS: the smallest record [`take_drone`] accepts.
const MIN_DRONE_BYTES: usize = 4 + 11 * 8 + 2 + 8 + 3 * 8 + 2 + 8 * 8 + 1 + 9 * 8;

/// The drone flags byte.
const ARMED: u8 = 1;
const ON_GROUND: u8 = 2;
const CRASHED: u8 = 4;
const POSITION_VALID: u8 = 8;

/// One drone's snapshot: index u32; position, velocity (3 f64 each), attitude (4),
/// height AGL; mode u8 ([`mode_code`]); flags u8 (armed 1, on ground 2, crashed 4,
/// position valid 8); battery remaining; then the detail: body rates (3), the estimate
/// (flag + position, velocity, attitude, eph, epv), the GNSS output (flag + time,
/// position, velocity, fix type u8, satellites u8, eph, epv, hdop, vdop as flag + f64
/// each, sky as flag + 3 u8), motor commands (8), motor count u8, battery voltage, current,
/// consumed, wind (3), local origin (3).
///
/// The structs are destructured whole, so a field added to them does not compile until it
/// is carried here too.
pub fn put_drone(out: &mut Vec<u8>, d: &DroneSnapshot) {
    let DroneSnapshot {
        index,
        position_enu_m,
        velocity_enu_mps,
        attitude_wxyz,
        height_agl_m,
        mode,
        armed,
        on_ground,
        crashed,
        battery_remaining,
        position_valid,
        detail,
    } = d;
    put_u32(out, *index);
    put_f64s(out, position_enu_m);
    put_f64s(out, velocity_enu_mps);
    put_f64s(out, attitude_wxyz);
    put_f64s(out, &[*height_agl_m]);
    out.push(mode_code(*mode));
    let flag = |on: bool, bit: u8| if on { bit } else { 0 };
    out.push(
        flag(*armed, ARMED)
            | flag(*on_ground, ON_GROUND)
            | flag(*crashed, CRASHED)
            | flag(*position_valid, POSITION_VALID),
    );
    put_f64s(out, &[*battery_remaining]);
    let DroneDetail {
        rate_body_rps,
        estimate,
        gnss,
        motor_commands,
        motor_count,
        battery_voltage_v,
        battery_current_a,
        battery_consumed_mah,
        wind_enu_mps,
        local_origin_enu_m,
    } = detail;
    put_f64s(out, rate_body_rps);
    put_optional(out, estimate.as_ref(), |out, e| {
        let EstimateDetail { position_enu_m, velocity_enu_mps, attitude_wxyz, eph_m, epv_m } = e;
        put_f64s(out, position_enu_m);
        put_f64s(out, velocity_enu_mps);
        put_f64s(out, attitude_wxyz);
        put_f64s(out, &[*eph_m, *epv_m]);
    });
    put_optional(out, gnss.as_ref(), |out, g| {
        let GnssDetail {
            time_s,
            position_enu_m,
            velocity_enu_mps,
            fix_type,
            satellites,
            eph_m,
            epv_m,
            hdop,
            vdop,
            sky,
        } = g;
        put_f64s(out, &[*time_s]);
        put_f64s(out, position_enu_m);
        put_f64s(out, velocity_enu_mps);
        out.extend_from_slice(&[*fix_type, *satellites]);
        for v in [eph_m, epv_m, hdop, vdop] {
            put_optional(out, *v, |out, v| put_f64s(out, &[v]));
        }
        put_optional(out, sky.as_ref(), |out, SkyDetail { above_mask, line_of_sight, reflected }| {
            out.extend_from_slice(&[*above_mask, *line_of_sight, *reflected]);
        });
    });
    put_f64s(out, motor_commands);
    out.push(*motor_count);
    put_f64s(out, &[*battery_voltage_v, *battery_current_a, *battery_consumed_mah]);
    put_f64s(out, wind_enu_mps);
    put_f64s(out, local_origin_enu_m);
}

/// Reads what [`put_drone`] wrote.
fn take_drone(r: &mut Reader<'_>) -> Result<DroneSnapshot, String> {
    let index = r.u32("index")?;
    let position_enu_m = r.f64s("positionEnuM")?;
    let velocity_enu_mps = r.f64s("velocityEnuMps")?;
    let attitude_wxyz = r.f64s("attitudeWxyz")?;
    let height_agl_m = r.f64("heightAglM")?;
    let at = r.at;
    let code = r.u8("mode")?;
    let mode = mode_of(code).ok_or_else(|| format!("byte {at}: mode: no flight mode has code {code}"))?;
    let at = r.at;
    let flags = r.u8("flags")?;
    if flags & !(ARMED | ON_GROUND | CRASHED | POSITION_VALID) != 0 {
        return Err(format!("byte {at}: flags: unknown bits in {flags:#04x}"));
    }
    let battery_remaining = r.f64("batteryRemaining")?;
    let rate_body_rps = r.f64s("detail.rateBodyRps")?;
    let estimate = r.optional("detail.estimate", |r| {
        Ok(EstimateDetail {
            position_enu_m: r.f64s("detail.estimate.positionEnuM")?,
            velocity_enu_mps: r.f64s("detail.estimate.velocityEnuMps")?,
            attitude_wxyz: r.f64s("detail.estimate.attitudeWxyz")?,
            eph_m: r.f64("detail.estimate.ephM")?,
            epv_m: r.f64("detail.estimate.epvM")?,
        })
    })?;
    let gnss = r.optional("detail.gnss", |r| {
        Ok(GnssDetail {
            time_s: r.f64("detail.gnss.timeS")?,
            position_enu_m: r.f64s("detail.gnss.positionEnuM")?,
            velocity_enu_mps: r.f64s("detail.gnss.velocityEnuMps")?,
            fix_type: r.u8("detail.gnss.fixType")?,
            satellites: r.u8("detail.gnss.satellites")?,
            eph_m: r.opt_f64("detail.gnss.ephM")?,
            epv_m: r.opt_f64("detail.gnss.epvM")?,
            hdop: r.opt_f64("detail.gnss.hdop")?,
            vdop: r.opt_f64("detail.gnss.vdop")?,
            sky: r.optional("detail.gnss.sky", |r| {
                Ok(SkyDetail {
                    above_mask: r.u8("detail.gnss.sky.aboveMask")?,
                    line_of_sight: r.u8("detail.gnss.sky.lineOfSight")?,
                    reflected: r.u8("detail.gnss.sky.reflected")?,
                })
            })?,
        })
    })?;
    let detail = DroneDetail {
        rate_body_rps,
        estimate,
        gnss,
        motor_commands: r.f64s("detail.motorCommands")?,
        motor_count: r.u8("detail.motorCount")?,
        battery_voltage_v: r.f64("detail.batteryVoltageV")?,
        battery_current_a: r.f64("detail.batteryCurrentA")?,
        battery_consumed_mah: r.f64("detail.batteryConsumedMah")?,
        wind_enu_mps: r.f64s("detail.windEnuMps")?,
        local_origin_enu_m: r.f64s("detail.localOriginEnuM")?,
    };
    Ok(DroneSnapshot {
        index,
        position_enu_m,
        velocity_enu_mps,
        attitude_wxyz,
        height_agl_m,
        mode,
        armed: flags & ARMED != 0,
        on_ground: flags & ON_GROUND != 0,
        crashed: flags & CRASHED != 0,
        battery_remaining,
        position_valid: flags & POSITION_VALID != 0,
        detail,
    })
}

/// The flight modes by wire code ([`mode_code`] is the inverse).
const MODES: [FlightMode; 7] = [
    FlightMode::Idle,
    FlightMode::Takeoff,
    FlightMode::Hold,
    FlightMode::Mission,
    FlightMode::Offboard,
    FlightMode::ReturnToLaunch,
    FlightMode::Land,
];

/// A flight mode's wire code (an exhaustive match: a new mode does not compile until it
/// has a code, and the tests check [`MODES`] holds it).
fn mode_code(mode: FlightMode) -> u8 {
    match mode {
        FlightMode::Idle => 0,
        FlightMode::Takeoff => 1,
        FlightMode::Hold => 2,
        FlightMode::Mission => 3,
        FlightMode::Offboard => 4,
        FlightMode::ReturnToLaunch => 5,
        FlightMode::Land => 6,
    }
}

fn mode_of(code: u8) -> Option<FlightMode> {
    MODES.get(usize::from(code)).copied()
}

/// A cursor over one payload whose errors name the byte offset and the field.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        Self { bytes, at: 0 }
    }

    fn take(&mut self, n: usize, field: &str) -> Result<&'a [u8], String> {
        let end = self.at.checked_add(n).filter(|&end| end <= self.bytes.len()).ok_or_else(|| {
            format!("byte {}: {field}: the message ends after {} bytes, {n} more expected", self.at, self.bytes.len())
        })?;
        let bytes = &self.bytes[self.at..end];
        self.at = end;
        Ok(bytes)
    }

    fn array<const N: usize>(&mut self, field: &str) -> Result<[u8; N], String> {
        Ok(self.take(N, field)?.try_into().expect("take returns N bytes"))
    }

    fn u8(&mut self, field: &str) -> Result<u8, String> {
        Ok(self.array::<1>(field)?[0])
    }

    fn u32(&mut self, field: &str) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.array(field)?))
    }

    fn u64(&mut self, field: &str) -> Result<u64, String> {
        Ok(u64::from_le_bytes(self.array(field)?))
    }

    fn f64(&mut self, field: &str) -> Result<f64, String> {
        Ok(f64::from_le_bytes(self.array(field)?))
    }

    fn f64s<const N: usize>(&mut self, field: &str) -> Result<[f64; N], String> {
        let bytes = self.take(N * 8, field)?;
        Ok(std::array::from_fn(|i| f64::from_le_bytes(bytes[i * 8..i * 8 + 8].try_into().expect("8 bytes"))))
    }

    /// A flag byte: 0 or 1.
    fn flag(&mut self, field: &str) -> Result<bool, String> {
        let at = self.at;
        match self.u8(field)? {
            0 => Ok(false),
            1 => Ok(true),
            other => Err(format!("byte {at}: {field}: expected a flag (0 or 1), found {other}")),
        }
    }

    /// A flag byte, then `read` of the value when it is 1.
    fn optional<T>(
        &mut self,
        field: &str,
        read: impl FnOnce(&mut Self) -> Result<T, String>,
    ) -> Result<Option<T>, String> {
        if self.flag(field)? { read(self).map(Some) } else { Ok(None) }
    }

    fn opt_f64(&mut self, field: &str) -> Result<Option<f64>, String> {
        self.optional(field, |r| r.f64(field))
    }

    /// A `u32` count of items of at least `min_item_bytes` each, refused when the rest of
    /// the payload cannot hold that many.
    fn count(&mut self, field: &str, min_item_bytes: usize) -> Result<usize, String> {
        let at = self.at;
        let n = self.u32(field)? as usize;
        let left = self.bytes.len() - self.at;
        if n.saturating_mul(min_item_bytes) > left {
            return Err(format!("byte {at}: {field}: a count of {n} does not fit in the {left} bytes left"));
        }
        Ok(n)
    }

    /// The rest of the payload as one JSON message.
    fn json<T: serde::de::DeserializeOwned>(&mut self, field: &str) -> Result<T, String> {
        let at = self.at;
        let rest = &self.bytes[self.at..];
        self.at = self.bytes.len();
        serde_json::from_slice(rest).map_err(|e| format!("byte {at}: {field}: {}", one_line(&e)))
    }

    /// Nothing may follow the message.
    fn end(&self) -> Result<(), String> {
        match self.bytes.len() - self.at {
            0 => Ok(()),
            n => Err(format!("byte {}: {n} bytes after the end of the message", self.at)),
        }
    }
}

#[cfg(test)]
mod tests;
