//! A recorded run as the view's frames: `sadesim view RUN` reads the run folder's
//! `recording.mcap` (each drone's ground-truth pose, `foxglove.PoseInFrame` in protobuf, and
//! its status, `sadesim.Status` in JSON) and `events.jsonl`, and resamples every drone at one
//! rate so the page plays, pauses and scrubs through frames in the live stream's format
//! ([`super::feed::encode_frame`]).
//!
//! A damaged recording is an error naming the topic and byte offset, never a silent gap.

use std::collections::HashMap;

use serde::Serialize;

use super::feed::{Pose, encode_frame, state_letter};
use sadesim_world::protobuf::{Bad, Fields, Value};

/// Why a recording cannot be replayed.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    #[error("recording.mcap: {0}")]
    Mcap(String),
    #[error("recording.mcap: {topic}: message at {log_time_ns} ns: {reason}")]
    Message { topic: String, log_time_ns: u64, reason: String },
    #[error("recording.mcap has no pose of drone {drone} (topic /drones/{drone}/pose)")]
    NoPose { drone: String },
    #[error("events.jsonl line {line}: {reason}")]
    Event { line: usize, reason: String },
    #[error("replay rate must be in (0, 1000] frames per simulated second, got {0}")]
    Rate(f64),
}

/// `/replay.json`.
#[derive(Serialize, Debug)]
#[serde(rename_all = "camelCase")]
pub struct Replay {
    /// Frames per simulated second.
    pub rate_hz: f64,
    /// Simulated seconds of the last frame.
    pub end_s: f64,
    /// Frames at `k / rate_hz` seconds (the last at `end_s`), each as [`encode_frame`] writes it.
    pub frames: Vec<serde_json::Value>,
    /// Every event of the run, in time order (the lines of `events.jsonl`).
    pub events: Vec<serde_json::Value>,
}

/// One drone's recorded samples, in time order.
#[derive(Default)]
struct Track {
    /// (log time ns, position, attitude wxyz).
    poses: Vec<(u64, [f64; 3], [f64; 4])>,
    /// (log time ns, state letter).
    states: Vec<(u64, u8)>,
}

/// Reads a run's recording (`mcap`: the file's bytes) and events (`events_jsonl`), for the
/// drones `names` (by global index, the plan's order), at `rate_hz` frames per simulated
/// second.
///
/// # Errors
/// [`ReplayError`]: an unreadable file, a drone without poses, a bad rate.
pub fn replay(mcap: &[u8], events_jsonl: &str, names: &[String], rate_hz: f64) -> Result<Replay, ReplayError> {
    if !(rate_hz > 0.0 && rate_hz <= 1000.0) {
        return Err(ReplayError::Rate(rate_hz));
    }
    let index: HashMap<&str, usize> = names.iter().enumerate().map(|(i, n)| (n.as_str(), i)).collect();
    let mut tracks: Vec<Track> = names.iter().map(|_| Track::default()).collect();
    let stream = mcap::MessageStream::new(mcap).map_err(|e| ReplayError::Mcap(e.to_string()))?;
    for message in stream {
        let message = message.map_err(|e| ReplayError::Mcap(e.to_string()))?;
        let topic = &message.channel.topic;
        let Some(rest) = topic.strip_prefix("/drones/") else { continue };
        let Some((name, stream)) = rest.rsplit_once('/') else { continue };
        let Some(&i) = index.get(name) else { continue };
        let bad = |reason: String| ReplayError::Message { topic: topic.clone(), log_time_ns: message.log_time, reason };
        match stream {
            "pose" => {
                let (p, q) = decode_pose(&message.data).map_err(bad)?;
                tracks[i].poses.push((message.log_time, p, q));
            }
            "status" => {
                let status: Status = serde_json::from_slice(&message.data).map_err(|e| bad(e.to_string()))?;
                tracks[i].states.push((message.log_time, state_letter(status.on_ground, status.crashed)));
            }
            _ => {}
        }
    }
    for (track, name) in tracks.iter_mut().zip(names) {
        if track.poses.is_empty() {
            return Err(ReplayError::NoPose { drone: name.clone() });
        }
        // MCAP readers yield chunk order; a file written by another tool may interleave.
        track.poses.sort_by_key(|s| s.0);
        track.states.sort_by_key(|s| s.0);
    }
    let end_ns = tracks.iter().filter_map(|t| t.poses.last()).map(|s| s.0).max().unwrap_or(0);
    let end_s = end_ns as f64 * 1e-9;
    let step_ns = 1e9 / rate_hz;
    let count = (end_ns as f64 / step_ns).floor() as u64 + 1;
    let mut cursors = vec![(0usize, 0usize); tracks.len()];
    let mut frames = Vec::with_capacity(count as usize + 1);
    let mut poses =
        vec![Pose { position_enu_m: [0.0; 3], attitude_wxyz: [1.0, 0.0, 0.0, 0.0], state: b'G' }; names.len()];
    let times = (0..count).map(|k| (k as f64 * step_ns).round() as u64).chain(
        // The last recorded instant, when the rate's grid does not land on it.
        ((count - 1) as f64 * step_ns).round().lt(&(end_ns as f64)).then_some(end_ns),
    );
    for t in times {
        for ((track, cursor), pose) in tracks.iter().zip(&mut cursors).zip(&mut poses) {
            // The latest sample at or before t (the first one before the drone's first).
            while cursor.0 + 1 < track.poses.len() && track.poses[cursor.0 + 1].0 <= t {
                cursor.0 += 1;
            }
            while cursor.1 + 1 < track.states.len() && track.states[cursor.1 + 1].0 <= t {
                cursor.1 += 1;
            }
            let (_, p, q) = track.poses[cursor.0];
            pose.position_enu_m = p;
            pose.attitude_wxyz = q;
            pose.state = track.states.get(cursor.1).map_or(b'G', |s| s.1);
        }
        let json = encode_frame(t as f64 * 1e-9, None, &poses);
        frames.push(serde_json::from_str(&json).expect("encode_frame writes JSON"));
    }
    let events = events_jsonl
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| serde_json::from_str(l).map_err(|e| ReplayError::Event { line: i + 1, reason: e.to_string() }))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Replay { rate_hz, end_s, frames, events })
}

/// The fields of `sadesim.Status` the view reads.
#[derive(serde::Deserialize)]
struct Status {
    on_ground: bool,
    crashed: bool,
}

/// `foxglove.PoseInFrame` (protobuf): `pose` (3) = `Pose { position (1): Vector3 {x 1, y 2,
/// z 3}, orientation (2): Quaternion {x 1, y 2, z 3, w 4} }`; doubles, proto3 defaults (an
/// absent component is 0, an absent orientation the identity). Errors name the byte in the
/// message (in the embedded message for errors inside one).
fn decode_pose(data: &[u8]) -> Result<([f64; 3], [f64; 4]), String> {
    let mut position = [0.0; 3];
    let mut orientation = [0.0, 0.0, 0.0, 1.0]; // x, y, z, w
    let mut fields = Fields::new(data);
    while let Some(field) = fields.next().map_err(|e| e.to_string())? {
        if let (3, Value::Bytes(pose)) = field {
            let mut pose = Fields::new(pose);
            while let Some(field) = pose.next().map_err(|e| format!("pose: {e}"))? {
                match field {
                    (1, Value::Bytes(v)) => read_doubles(v, &mut position).map_err(|e| format!("position: {e}"))?,
                    (2, Value::Bytes(q)) => {
                        orientation = [0.0; 4];
                        read_doubles(q, &mut orientation).map_err(|e| format!("orientation: {e}"))?;
                    }
                    _ => {}
                }
            }
        }
    }
    let [x, y, z, w] = orientation;
    Ok((position, [w, x, y, z]))
}

/// Doubles of fields 1..=N of a message into `out[0..N]`.
fn read_doubles(data: &[u8], out: &mut [f64]) -> Result<(), Bad> {
    let mut fields = Fields::new(data);
    while let Some(field) = fields.next()? {
        if let (n @ 1.., Value::Fixed64(bits)) = field
            && let Some(slot) = out.get_mut(n as usize - 1)
        {
            *slot = f64::from_bits(bits);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::mcap_file::messages;
    use sadesim_engine::protocol::DroneSnapshot;

    #[test]
    fn a_pose_reads_back_as_written() {
        let mut s = DroneSnapshot::climbing(0, 12.25, 3.5);
        s.attitude_wxyz = [0.5, 0.5, -0.5, 0.5];
        let mut bytes = Vec::new();
        messages::pose(&mut bytes, 1_500_000_000, &s);
        let (p, q) = decode_pose(&bytes).unwrap();
        assert_eq!(p, [12.25, 0.0, 3.5]);
        assert_eq!(q, [0.5, 0.5, -0.5, 0.5]);
    }

    #[test]
    fn a_truncated_pose_names_the_byte() {
        let mut bytes = Vec::new();
        messages::pose(&mut bytes, 1, &DroneSnapshot::climbing(0, 1.0, 1.0));
        bytes.truncate(bytes.len() - 3);
        let e = decode_pose(&bytes).unwrap_err();
        // The pose (field 3) after the timestamp and frame id claims more bytes than remain.
        assert!(
            e.starts_with("field 3: length ") && e.contains("runs past the message's") && e.contains(" at byte "),
            "{e}"
        );
    }

    #[test]
    fn bad_rates_are_refused() {
        for rate in [0.0, -1.0, f64::NAN, 5000.0] {
            assert!(matches!(replay(&[], "", &[], rate), Err(ReplayError::Rate(_))), "{rate}");
        }
    }
}
