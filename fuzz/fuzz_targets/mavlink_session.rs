//! One drone's MAVLink session (`sadesim_engine::mavlink::session::Session`, with its
//! mission, parameter and command protocols) fed an arbitrary sequence of frames: the input
//! is a MAVLink byte stream whose CRCs are repaired (`sadesim_fuzz::repair`), so every
//! mutation reaches the session as a frame; each frame's sequence byte advances the sim
//! clock by that many 10 ms (timeouts and retries happen), and the session is polled after
//! every frame, as a shard does at every window end.
//!
//! What is asserted: never a panic; every message the session sends encodes to one whole
//! frame; no poll returns more than the parameter table and a few replies (a request cannot
//! make the session answer without bound), and once the peers fall silent the session's
//! queues drain to its telemetry alone; the mission protocol, driven with the same frames,
//! keeps its counts consistent: its stored count is its items' and at most
//! `MAX_MISSION_ITEMS`, its id is 0 exactly when it is empty, a `MISSION_COUNT` it answers a
//! download with is its stored count, and an accepted upload loads a plan.
#![no_main]

use ::mavlink::MavHeader;
use ::mavlink::dialects::common::{MavMessage, MavMissionResult, MavMissionType};
use libfuzzer_sys::fuzz_target;
use nalgebra::{UnitQuaternion, Vector3};
use sadesim_crds::geo::{GeoPoint, LocalFrame};
use sadesim_engine::autopilot::navigator::{Command, NavigatorConfig, Rejection};
use sadesim_engine::events::{EventKind, FlightMode};
use sadesim_engine::mavlink::frame::{Decoded, FrameParser, encode_command_ack, encode_into};
use sadesim_engine::mavlink::mission_protocol::{MAX_MISSION_ITEMS, MissionContext, MissionProtocol};
use sadesim_engine::mavlink::params::ParamTable;
use sadesim_engine::mavlink::session::{Outgoing, Session, Vehicle};
use sadesim_engine::mavlink::telemetry::{
    BatteryView, MissionProgress, PositionEstimate, VehicleIdentity, VehicleView, attitude_ned_frd,
};
use sadesim_engine::preset::Preset;
use sadesim_fuzz::repaired;

/// The drone's system id (the seeds address it).
const SYSTEM_ID: u8 = 1;
/// Most frames of one input handled (a few hundred reach every protocol's end).
const MAX_FRAMES: usize = 2000;

/// An autopilot that accepts every command and keeps the mission it was given.
#[derive(Default)]
struct FakeVehicle {
    config: NavigatorConfig,
    mission: Option<usize>,
    commands: usize,
}

impl Vehicle for FakeVehicle {
    fn command(&mut self, cmd: Command) -> Result<(), Rejection> {
        self.commands += 1;
        if let Command::LoadMission(plan) = &cmd {
            self.mission = Some(plan.items.len());
        }
        Ok(())
    }
    fn navigator_config(&self) -> NavigatorConfig {
        self.config
    }
    fn set_navigator_config(&mut self, config: NavigatorConfig) {
        self.config = config;
    }
}

fn view(t: f64, mission_count: usize) -> VehicleView {
    VehicleView {
        time_s: t,
        armed: true,
        mode: FlightMode::Hold,
        on_ground: false,
        crashed: false,
        armable: true,
        estimate: Some(PositionEstimate {
            position_enu_m: Vector3::new(10.0, 20.0, 32.0),
            velocity_enu_mps: Vector3::new(1.0, 0.0, 0.0),
            eph_m: 0.5,
            epv_m: 0.8,
        }),
        attitude: UnitQuaternion::identity(),
        attitude_ned: attitude_ned_frd(&UnitQuaternion::identity()),
        rate_body_rps: Vector3::zeros(),
        gnss: None,
        battery: BatteryView { voltage_v: 16.0, current_a: 10.0, remaining: 0.9, consumed_mah: 100.0 },
        home_enu_m: Vector3::new(0.0, 0.0, 2.0),
        local_origin_enu_m: Vector3::new(0.0, 0.0, 2.0),
        mission: MissionProgress { current: 0, count: mission_count, finished: false },
        throttle: 0.5,
        airspeed_mps: 3.0,
        ground_up_m: 1.9,
    }
}

fuzz_target!(|data: &[u8]| {
    let bytes = repaired(data, None);
    let frames = FrameParser::new().push(&bytes);
    let frame = LocalFrame::new(GeoPoint { latitude_deg: 41.88, longitude_deg: -87.62, altitude_msl_m: 180.0 });
    let id = VehicleIdentity { system_id: SYSTEM_ID, frame, unix_epoch_at_start_us: 1_700_000_000_000_000, uid: 1 };
    let preset = Preset::named("x500").expect("the x500 preset");
    let params = ParamTable::px4(SYSTEM_ID, &preset, &NavigatorConfig::default());
    let param_count = params.len();
    let mut session = Session::new(id, params);
    let mut vehicle = FakeVehicle::default();
    let mut missions = MissionProtocol::new();
    let header = MavHeader { system_id: u32::from(SYSTEM_ID), component_id: 1, sequence: 0 };
    // Per poll: every parameter (PARAM_REQUEST_LIST) and a few replies besides.
    let bound = param_count + 64;
    let mut t = 0.0;
    let mut out = Vec::new();
    for f in frames.iter().take(MAX_FRAMES) {
        t += f64::from(f.header.sequence) * 0.01;
        let v = view(t, vehicle.mission.unwrap_or(0));
        session.handle(f, &v, &mut vehicle);
        if f.header.sequence % 16 == 1 {
            session.on_events(&[EventKind::WaypointReached { seq: u32::from(f.header.sequence) }, EventKind::Armed]);
        }
        out.clear();
        session.poll_into(&v, &mut out);
        assert!(out.len() <= bound, "one poll returned {} messages (bound {bound})", out.len());
        for o in &out {
            let frame = encode(o, header);
            let parsed = FrameParser::new().push(&frame);
            assert!(!parsed.is_empty(), "{o:?} did not encode to frames");
            assert_eq!(parsed.iter().map(|p| p.bytes.len()).sum::<usize>(), frame.len(), "{o:?}");
        }
        if let Decoded::Message(m) = &f.message {
            mission_protocol(&mut missions, f.header.system_id as u8, f.header.component_id, m, t, &frame);
        }
    }
    // The peers fall silent: transfers time out, the queues drain, telemetry alone remains.
    let mut last = usize::MAX;
    for k in 1..=3 {
        out.clear();
        session.poll_into(&view(t + 10.0 * f64::from(k), vehicle.mission.unwrap_or(0)), &mut out);
        last = out.iter().filter(|o| !matches!(o, Outgoing::Telemetry(_))).count();
    }
    assert!(last <= 2, "after 30 s of silence the session still sends {last} replies a poll");
});

/// The frames of `o` as a link encodes them (`Outgoing::encode`, which is for tests only).
fn encode(o: &Outgoing, mut header: MavHeader) -> Vec<u8> {
    let mut out = Vec::new();
    match o {
        Outgoing::Message(m) => encode_into(&mut out, header, m),
        Outgoing::UnknownCommandAck { command, result, target } => {
            out.extend(encode_command_ack(header, *command, *result, *target));
        }
        Outgoing::Telemetry(t) => {
            for m in t.messages() {
                encode_into(&mut out, header, &m);
                header.sequence = header.sequence.wrapping_add(1);
            }
        }
    }
    out
}

/// The mission protocol alone, fed the same messages: its counts stay consistent.
fn mission_protocol(p: &mut MissionProtocol, sysid: u8, compid: u8, m: &MavMessage, t: f64, frame: &LocalFrame) {
    let ctx = MissionContext {
        frame,
        home_alt_amsl_m: 180.0,
        cruise_speed_mps: 5.0,
        current_seq: 0,
        our_system: SYSTEM_ID,
        our_component: 1,
    };
    let out = p.handle((sysid, compid), m, t, &ctx);
    let _ = p.poll(t);
    let count = p.count();
    assert_eq!(usize::from(count), p.items().len());
    assert!(count <= MAX_MISSION_ITEMS, "{count} items stored");
    assert_eq!(p.mission_id() == 0, count == 0, "mission id {} for {count} items", p.mission_id());
    if let Some(plan) = &out.loaded {
        assert!(count > 0 || plan.items.is_empty());
        let accepted = out
            .replies
            .iter()
            .any(|r| matches!(r, MavMessage::MISSION_ACK(a) if a.mavtype == MavMissionResult::MAV_MISSION_ACCEPTED));
        assert!(accepted, "a plan was loaded without MISSION_ACK(ACCEPTED)");
    }
    if let MavMessage::MISSION_REQUEST_LIST(r) = m
        && r.mission_type == MavMissionType::MAV_MISSION_TYPE_MISSION
    {
        for reply in &out.replies {
            if let MavMessage::MISSION_COUNT(c) = reply {
                assert_eq!(c.count, count, "a download announces {} items of {count}", c.count);
            }
        }
    }
    assert!(out.replies.len() <= 2, "{} replies to one mission message", out.replies.len());
}
