//! Which telemetry messages are due when: PX4's default stream rates for the messages this
//! endpoint produces, changed by MAV_CMD_SET_MESSAGE_INTERVAL (pure: sim time in, due message
//! ids out).
//!
//! # Default rates
//! A PX4 SITL drone's API link is started with `mavlink start ... -m onboard`, so the rates
//! are PX4's `MAVLINK_MODE_ONBOARD` ones (`Mavlink::configure_streams_to_default` in
//! `src/modules/mavlink/mavlink_main.cpp`):
//!
//! | message | Hz | note |
//! |---|---:|---|
//! | HEARTBEAT | 1 | always on, not configurable (PX4 refuses SET_MESSAGE_INTERVAL for it) |
//! | SYS_STATUS | 5 | |
//! | SYSTEM_TIME | 1 | |
//! | GPS_RAW_INT | 5 | onboard: "unlimited", i.e. every GNSS fix; our receiver's default rate |
//! | ATTITUDE | 100 | |
//! | ATTITUDE_QUATERNION | 50 | |
//! | LOCAL_POSITION_NED | 30 | |
//! | GLOBAL_POSITION_INT | 50 | |
//! | MISSION_CURRENT | 1 | not a stream in PX4: the mission manager sends it at 1 Hz |
//! | VFR_HUD | 10 | |
//! | ALTITUDE | 10 | |
//! | BATTERY_STATUS | 0.5 | |
//! | HOME_POSITION | 0.5 | |
//! | EXTENDED_SYS_STATE | 5 | |
//!
//! # Timing
//! A stream is due on a fixed grid: each emission's due time is the previous one plus the
//! interval, never the time it was actually sent, so rates do not drift with the caller's
//! step (a 50 Hz stream polled every 10 ms comes out 50 times a second, a 30 Hz one 30
//! times). One call emits a stream at most once: a caller far behind (a paused simulation)
//! skips the missed grid points instead of sending a burst of stale copies.
//!
//! The fastest rate is [`MIN_INTERVAL_US`] (100 Hz): the endpoint is polled once per 10 ms
//! simulation window, so a shorter interval could not be honoured; it is clamped, and
//! [`StreamScheduler::interval_us`] then reports the interval actually used, which is what
//! MESSAGE_INTERVAL must carry.

use ::mavlink::MessageData;
use ::mavlink::dialects::common::{
    ALTITUDE_DATA, ATTITUDE_DATA, ATTITUDE_QUATERNION_DATA, BATTERY_STATUS_DATA, EXTENDED_SYS_STATE_DATA,
    GLOBAL_POSITION_INT_DATA, GPS_RAW_INT_DATA, HEARTBEAT_DATA, HOME_POSITION_DATA, LOCAL_POSITION_NED_DATA,
    MISSION_CURRENT_DATA, SYS_STATUS_DATA, SYSTEM_TIME_DATA, VFR_HUD_DATA,
};

/// Shortest interval a stream can have, µs (100 Hz: one emission per 10 ms window).
pub const MIN_INTERVAL_US: u32 = 10_000;
/// Longest interval, µs: what MESSAGE_INTERVAL's `int32_t interval_us` can carry (~36 min).
pub const MAX_INTERVAL_US: u32 = i32::MAX.unsigned_abs();
/// How early a call may be and still count as on time, s (float sums of 0.01 s steps).
const DUE_TOLERANCE_S: f64 = 1e-6;

/// PX4 onboard-mode defaults, (message id, Hz); see the module docs.
const PX4_ONBOARD_RATES_HZ: [(u32, f64); 14] = [
    (HEARTBEAT_DATA::ID, 1.0),
    (SYS_STATUS_DATA::ID, 5.0),
    (SYSTEM_TIME_DATA::ID, 1.0),
    (GPS_RAW_INT_DATA::ID, 5.0),
    (ATTITUDE_DATA::ID, 100.0),
    (ATTITUDE_QUATERNION_DATA::ID, 50.0),
    (LOCAL_POSITION_NED_DATA::ID, 30.0),
    (GLOBAL_POSITION_INT_DATA::ID, 50.0),
    (MISSION_CURRENT_DATA::ID, 1.0),
    (VFR_HUD_DATA::ID, 10.0),
    (ALTITUDE_DATA::ID, 10.0),
    (BATTERY_STATUS_DATA::ID, 0.5),
    (HOME_POSITION_DATA::ID, 0.5),
    (EXTENDED_SYS_STATE_DATA::ID, 5.0),
];

/// Why a SET_MESSAGE_INTERVAL was refused (answer MAV_RESULT_FAILED, as PX4 does).
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum StreamError {
    /// Not a message this endpoint streams.
    #[error("failed to set the interval of message {0}: not a stream of this endpoint")]
    Unknown(u32),
    /// HEARTBEAT: its 1 Hz is what links use to detect loss.
    #[error("failed to set the interval of message {0}: its rate is fixed")]
    Fixed(u32),
    /// A NaN interval.
    #[error("failed to set the interval of message {0}: the interval is not a number")]
    NotANumber(u32),
}

/// A stream's configured rate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Rate {
    Default,
    /// Interval, µs, within [MIN_INTERVAL_US, MAX_INTERVAL_US].
    Custom(u32),
    Disabled,
}

#[derive(Clone, Debug, PartialEq)]
struct Stream {
    message_id: u32,
    default_interval_us: u32,
    fixed: bool,
    rate: Rate,
    /// Grid time of the next emission, s; `None`: at the next call.
    next_due_s: Option<f64>,
    /// Grid time of the last emission, s.
    last_due_s: Option<f64>,
}

impl Stream {
    fn interval_us(&self) -> Option<u32> {
        match self.rate {
            Rate::Default => Some(self.default_interval_us),
            Rate::Custom(us) => Some(us),
            Rate::Disabled => None,
        }
    }
}

/// The telemetry streams of one endpoint and when each is next due.
#[derive(Clone, Debug, PartialEq)]
pub struct StreamScheduler {
    /// Sorted by message id: the order [`StreamScheduler::due`] reports them in.
    streams: Vec<Stream>,
}

impl StreamScheduler {
    /// PX4's onboard-mode rates; every stream is due at the first call of [`Self::due`].
    pub fn px4_default() -> Self {
        let mut streams: Vec<Stream> = PX4_ONBOARD_RATES_HZ
            .iter()
            .map(|&(message_id, hz)| Stream {
                message_id,
                default_interval_us: clamp_interval_us(1e6 / hz),
                fixed: message_id == HEARTBEAT_DATA::ID,
                rate: Rate::Default,
                next_due_s: None,
                last_due_s: None,
            })
            .collect();
        streams.sort_by_key(|s| s.message_id);
        Self { streams }
    }

    /// The message ids this scheduler knows, ascending.
    pub fn message_ids(&self) -> impl Iterator<Item = u32> + '_ {
        self.streams.iter().map(|s| s.message_id)
    }

    /// MAV_CMD_SET_MESSAGE_INTERVAL: `interval_us` < 0 disables the stream (MAVLink says -1;
    /// PX4 takes any negative value), 0 restores the default, > 0 sets the interval, clamped
    /// to [[`MIN_INTERVAL_US`], [`MAX_INTERVAL_US`]].
    ///
    /// # Errors
    /// [`StreamError`]; the stream is then unchanged.
    ///
    /// # Guarantees
    /// A stream that keeps running stays on its grid: its next emission is the last one plus
    /// the new interval (at once if that has passed). A stream that was disabled or never
    /// sent is due at the next call.
    pub fn set_interval(&mut self, message_id: u32, interval_us: f32) -> Result<(), StreamError> {
        let stream = self.stream_mut(message_id).ok_or(StreamError::Unknown(message_id))?;
        if stream.fixed {
            return Err(StreamError::Fixed(message_id));
        }
        if interval_us.is_nan() {
            return Err(StreamError::NotANumber(message_id));
        }
        let was_running = stream.rate != Rate::Disabled;
        stream.rate = if interval_us < 0.0 {
            Rate::Disabled
        } else if interval_us == 0.0 {
            Rate::Default
        } else {
            Rate::Custom(clamp_interval_us(f64::from(interval_us)))
        };
        stream.next_due_s = match (was_running, stream.last_due_s, stream.interval_us()) {
            (true, Some(last), Some(us)) => Some(last + interval_s(us)),
            _ => None,
        };
        Ok(())
    }

    /// The interval for a MESSAGE_INTERVAL reply, µs: -1 when disabled, `None` for a message
    /// that is not one of our streams (MESSAGE_INTERVAL says 0: not available).
    pub fn interval_us(&self, message_id: u32) -> Option<i32> {
        let stream = self.streams.iter().find(|s| s.message_id == message_id)?;
        Some(stream.interval_us().map_or(-1, |us| i32::try_from(us).unwrap_or(i32::MAX)))
    }

    /// The message ids due at sim time `now_s`, ascending, each scheduled for its next grid
    /// time. (Called for every drone at every sync window, so it does not allocate.)
    ///
    /// # Assumptions
    /// `now_s` does not decrease between calls (a call earlier than a stream's due time
    /// simply finds nothing due). A non-finite `now_s` finds nothing due and changes nothing.
    pub fn due(&mut self, now_s: f64) -> Due {
        let mut due = Due { ids: [0; STREAM_COUNT], len: 0 };
        if !now_s.is_finite() {
            return due;
        }
        for stream in &mut self.streams {
            let Some(us) = stream.interval_us() else { continue };
            let grid_s = match stream.next_due_s {
                None => now_s,
                Some(next) if next <= now_s + DUE_TOLERANCE_S => next,
                Some(_) => continue,
            };
            let step_s = interval_s(us);
            let mut next = grid_s + step_s;
            if next <= now_s + DUE_TOLERANCE_S {
                // More than one interval behind: skip to the first grid point after now.
                let missed = ((now_s + DUE_TOLERANCE_S - grid_s) / step_s).floor();
                next = grid_s + (missed + 1.0) * step_s;
            }
            stream.last_due_s = Some(grid_s);
            stream.next_due_s = Some(next);
            due.ids[due.len] = stream.message_id;
            due.len += 1;
        }
        due
    }

    fn stream_mut(&mut self, message_id: u32) -> Option<&mut Stream> {
        self.streams.iter_mut().find(|s| s.message_id == message_id)
    }
}

/// Streams a scheduler has: one per PX4 default.
const STREAM_COUNT: usize = PX4_ONBOARD_RATES_HZ.len();

/// The message ids [`StreamScheduler::due`] found due, ascending: a slice (`contains`,
/// `is_empty`, `iter`) and an iterator by value, without a heap allocation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Due {
    ids: [u32; STREAM_COUNT],
    len: usize,
}

impl std::ops::Deref for Due {
    type Target = [u32];
    fn deref(&self) -> &[u32] {
        &self.ids[..self.len]
    }
}

impl IntoIterator for Due {
    type Item = u32;
    type IntoIter = std::iter::Take<std::array::IntoIter<u32, STREAM_COUNT>>;
    fn into_iter(self) -> Self::IntoIter {
        self.ids.into_iter().take(self.len)
    }
}

impl PartialEq<Vec<u32>> for Due {
    fn eq(&self, other: &Vec<u32>) -> bool {
        **self == **other
    }
}

fn interval_s(us: u32) -> f64 {
    f64::from(us) * 1e-6
}

/// An interval in µs, rounded to whole µs (PX4 keeps whole µs too) and clamped.
fn clamp_interval_us(us: f64) -> u32 {
    // In range after the clamp, so the cast is exact.
    us.round().clamp(f64::from(MIN_INTERVAL_US), f64::from(MAX_INTERVAL_US)) as u32
}

#[cfg(test)]
mod tests;
