//! A peer that floods the session (`session::flood`): cut to its budget, reported once,
//! and the other peers and the reply queue unaffected.

use super::*;

fn from(system_id: u32, msg: &MavMessage) -> Frame {
    let bytes = encode(MavHeader { system_id, component_id: 190, sequence: 0 }, msg);
    FrameParser::new().push(&bytes).remove(0)
}

fn status_texts(out: &[Outgoing]) -> Vec<String> {
    out.iter()
        .filter_map(|o| match o {
            Outgoing::Message(MavMessage::STATUSTEXT(t)) => Some(t.text.to_str().unwrap_or_default().to_owned()),
            _ => None,
        })
        .collect()
}

#[test]
fn a_command_flood_is_cut_to_its_budget_reported_once_and_another_peer_is_served() {
    let mut s = session();
    let mut v = FakeVehicle::default();
    let arm = from(250, &command_long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]));
    let set_mode = from(
        250,
        &MavMessage::SET_MODE(SET_MODE_DATA {
            custom_mode: 4 << 16 | 3 << 24,
            target_system: 7,
            base_mode: MavModeFlag::empty(),
        }),
    );
    // 20 000 frames in one exchange (20 ms), as a flooding pilot's would arrive.
    for i in 0..20_000 {
        s.handle(if i % 2 == 0 { &arm } else { &set_mode }, &view(1.0), &mut v);
    }
    let burst = INBOUND_BURST as u64;
    assert_eq!(s.stats.handled, burst);
    assert_eq!(s.stats.refused_flood, 20_000 - burst);
    assert_eq!(v.commands.len() as u64, burst, "only the budget reached the autopilot");
    // A well-behaved peer in the same exchange is served.
    s.handle(&from(255, &command_long(MavCmd::MAV_CMD_NAV_LAND, [0.0; 7])), &view(1.0), &mut v);
    assert_eq!(v.commands.last(), Some(&Command::Land));
    let out = s.poll(&view(1.0));
    assert_eq!(status_texts(&out), ["MAVLink flood from 250/190: dropping"]);
    let events = s.take_events();
    assert_eq!(events.len(), 1, "{events:?}");
    let EventKind::CommandRejected { command, reason } = &events[0] else { panic!("{events:?}") };
    assert_eq!(command, "mavlink:250/190");
    assert!(reason.starts_with("flood: over 2500 frames per simulated second"), "{reason}");
    // The next exchange takes the budget's refill, 50 frames, and says nothing new.
    for _ in 0..1000 {
        s.handle(&arm, &view(1.02), &mut v);
    }
    assert_eq!(s.stats.handled, burst + 1 + 50);
    assert!(status_texts(&s.poll(&view(1.02))).is_empty());
    assert!(s.take_events().is_empty());
}

#[test]
fn a_flood_of_parameter_lists_cannot_grow_the_reply_queue_past_its_limit() {
    let mut s = session();
    let mut v = FakeVehicle::default();
    let list =
        from(255, &MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA { target_system: 7, target_component: 1 }));
    for _ in 0..INBOUND_BURST as usize {
        s.handle(&list, &view(1.0), &mut v);
    }
    assert!(s.stats.dropped_replies > 0, "{:?}", s.stats);
    let out = s.poll(&view(1.0));
    let values = out.iter().filter(|o| matches!(o, Outgoing::Message(MavMessage::PARAM_VALUE(_)))).count();
    assert_eq!(values, MAX_PENDING_REPLIES);
}
