//! The shard core's MAVLink queues, with no socket anywhere.

use std::sync::Arc;

use ::mavlink::MavHeader;
use ::mavlink::dialects::common::{
    COMMAND_ACK_DATA, COMMAND_LONG_DATA, MavCmd, MavMessage, MavResult, PARAM_REQUEST_READ_DATA,
};
use ::mavlink::types::CharArray;
use sadesim_crds::plan::RunPlan;
use sadesim_world::{World, WorldInputs};

use super::*;
use crate::fixtures::{plan_of, run_with_groups};
use crate::mavlink::frame::{Frame, FrameParser, encode};
use crate::mavlink::session::Outgoing;

/// One drone (system id 1) in shard 0.
fn plan() -> RunPlan {
    plan_of(run_with_groups(&[("a", 1)]).build())
}

/// Shard 0 of `plan` with MAVLink sessions and no sockets.
fn shard(plan: &RunPlan) -> Shard {
    let world = Arc::new(World::generate(&WorldInputs::from_spec(&plan.spec, &[])));
    let mut shard = Shard::new(plan, 0, &Surroundings::new(plan, world, None)).expect("the shard builds");
    shard.enable_mavlink(plan, 0).expect("every preset has a parameter table");
    shard
}

/// A frame from a ground station (255/190) as an endpoint would deliver it.
fn from_gcs(message: &MavMessage) -> Frame {
    FrameParser::new().push(&encode(MavHeader { system_id: 255, component_id: 190, sequence: 0 }, message)).remove(0)
}

fn param_request(name: &str) -> MavMessage {
    MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
        param_index: -1,
        target_system: 1,
        target_component: 1,
        param_id: CharArray::from(name),
    })
}

fn command_long(command: MavCmd, param1: f32, param7: f32) -> MavMessage {
    MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        param1,
        param2: 0.0,
        param3: 0.0,
        param4: f32::NAN,
        param5: f32::NAN,
        param6: f32::NAN,
        param7,
        command,
        target_system: 1,
        target_component: 1,
        confirmation: 0,
    })
}

/// Takes drone 0's outbound queue, as the I/O side would.
fn take_outbound(shard: &mut Shard) -> Vec<MavMessage> {
    std::mem::take(&mut shard.mavlink_queues()[0].outbound).into_iter().flat_map(Outgoing::into_messages).collect()
}

/// (name, raw bits of the value: an INT32 parameter travels as its bytes in the float).
fn param_values(messages: &[MavMessage]) -> Vec<(String, u32)> {
    messages
        .iter()
        .filter_map(|m| match m {
            MavMessage::PARAM_VALUE(v) => {
                Some((v.param_id.to_str().unwrap_or("?").to_string(), v.param_value.to_bits()))
            }
            _ => None,
        })
        .collect()
}

fn acks(messages: &[MavMessage]) -> Vec<COMMAND_ACK_DATA> {
    messages
        .iter()
        .filter_map(|m| match m {
            MavMessage::COMMAND_ACK(a) => Some(a.clone()),
            _ => None,
        })
        .collect()
}

#[test]
fn a_param_request_in_the_inbound_queue_is_answered_in_the_outbound_queue() {
    let plan = plan();
    let mut shard = shard(&plan);
    shard.mavlink_queues()[0].inbound.push(from_gcs(&param_request("SYS_AUTOSTART")));
    // The first window end (t = 10 ms) is an exchange.
    shard.advance(10);
    assert!(shard.mavlink_queues()[0].inbound.is_empty(), "the session took the frame");
    let out = take_outbound(&mut shard);
    assert_eq!(param_values(&out), [("SYS_AUTOSTART".to_string(), 4001)]);
    // Telemetry rides in the same queue (the first HEARTBEAT is due at once).
    assert!(out.iter().any(|m| matches!(m, MavMessage::HEARTBEAT(_))), "{out:?}");
}

#[test]
fn arm_and_takeoff_commands_from_the_queue_are_acked_and_the_drone_climbs() {
    let plan = plan();
    let mut shard = shard(&plan);
    // Warm-up: a GNSS fix, a position estimate and a settled height before arming.
    shard.advance(5_000);
    assert!(shard.drones()[0].is_ready());
    take_outbound(&mut shard);
    let inbound = &mut shard.mavlink_queues()[0].inbound;
    inbound.push(from_gcs(&command_long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, 1.0, 0.0)));
    inbound.push(from_gcs(&command_long(MavCmd::MAV_CMD_NAV_TAKEOFF, 0.0, f32::NAN)));
    // The warm-up ended with an exchange at 5.00 s; the next is due at 5.02 s.
    shard.advance(5_030);
    let answered = acks(&take_outbound(&mut shard));
    let results: Vec<_> = answered.iter().map(|a| (a.command, a.result)).collect();
    assert_eq!(
        results,
        [
            (MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, MavResult::MAV_RESULT_ACCEPTED),
            (MavCmd::MAV_CMD_NAV_TAKEOFF, MavResult::MAV_RESULT_ACCEPTED)
        ]
    );
    shard.advance(10_030);
    let snapshot = shard.drones()[0].snapshot();
    assert!(snapshot.armed && !snapshot.on_ground, "{snapshot:?}");
    assert!(snapshot.height_agl_m > 1.0, "climbed to {} m", snapshot.height_agl_m);
}

/// Counts the visits of the I/O side.
#[derive(Default)]
struct Recorder {
    receives: Vec<u64>,
    sends: Vec<(u64, bool)>,
    window: u64,
}

impl MavlinkIo for Recorder {
    fn receive(&mut self, _queues: &mut [MavlinkQueues]) {
        self.receives.push(self.window);
    }
    fn send(&mut self, queues: &mut [MavlinkQueues], flush: bool) {
        self.sends.push((self.window, flush));
        queues.iter_mut().for_each(|q| q.outbound.clear());
    }
}

#[test]
fn frames_are_read_and_sent_only_at_exchanges_every_20_ms_of_sim_time() {
    let plan = plan();
    let mut shard = shard(&plan);
    let mut io = Recorder::default();
    for window in 1..=5 {
        io.window = window;
        shard.advance_with(window * 10, &mut io);
    }
    // Windows of 10 ms: exchanges at 10, 30 and 50 ms; the I/O side sees every window.
    assert_eq!(io.receives, [1, 3, 5]);
    assert_eq!(io.sends, [(1, true), (2, false), (3, true), (4, false), (5, true)]);

    // A frame queued after an exchange waits for the next one (70 ms).
    shard.mavlink_queues()[0].inbound.push(from_gcs(&param_request("SYS_AUTOSTART")));
    shard.advance(60);
    assert_eq!(shard.mavlink_queues()[0].inbound.len(), 1, "60 ms is no exchange");
    assert!(param_values(&take_outbound(&mut shard)).is_empty());
    shard.advance(70);
    assert!(shard.mavlink_queues()[0].inbound.is_empty());
    assert_eq!(param_values(&take_outbound(&mut shard)).len(), 1);
}

#[test]
fn a_shard_without_mavlink_has_no_queues() {
    let plan = plan();
    let world = Arc::new(World::generate(&WorldInputs::from_spec(&plan.spec, &[])));
    let mut shard = Shard::new(&plan, 0, &Surroundings::new(&plan, world, None)).unwrap();
    let mut io = Recorder::default();
    shard.advance_with(10, &mut io);
    assert!(shard.mavlink_queues().is_empty());
    // The I/O side is still visited (with nothing to carry).
    assert_eq!(io.sends, [(0, true)]);
}
