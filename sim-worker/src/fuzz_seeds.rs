//! The seed corpus of the shard protocol fuzz target (`fuzz/fuzz_targets/shard_wire.rs`),
//! written when `SADESIM_FUZZ_SEEDS` names a folder (`tests/fuzz.sh` sets it): payloads of
//! every kind from the protocol's own encoder (`transport::wire`), each checked to decode
//! back to its message. Nothing is committed.

use sadesim_engine::events::{Event, EventKind, FlightMode};
use sadesim_engine::protocol::{DroneSnapshot, FromShard, ToShard};

use crate::transport::wire::Wire;

fn payload(message: &impl Wire) -> Vec<u8> {
    let mut out = Vec::new();
    message.encode(&mut out);
    out
}

#[test]
fn the_fuzz_seeds_are_shard_messages_that_decode() {
    let mut flying = DroneSnapshot::climbing(3, 12.5, 4.0);
    flying.mode = FlightMode::Mission;
    let window = FromShard::Advanced {
        shard: 1,
        step: 4000,
        ready: true,
        drones: vec![DroneSnapshot::climbing(2, 0.0, 4.0), flying],
        events: vec![
            Event { time_s: 1.25, drone: Some(2), kind: EventKind::Takeoff },
            Event { time_s: 2.5, drone: None, kind: EventKind::MissionCompleted },
        ],
    };
    let from_shard = [
        ("window", window),
        (
            "window-empty",
            FromShard::Advanced { shard: 0, step: 1, ready: false, drones: Vec::new(), events: Vec::new() },
        ),
        ("hello", FromShard::Hello { version: sadesim_engine::protocol::PROTOCOL_VERSION, shard: 2, drones: 40 }),
        ("stopped", FromShard::Stopped { shard: 2 }),
        ("failed", FromShard::Failed { shard: 1, reason: "the world did not load".into() }),
    ];
    let to_shard = [
        ("advance", ToShard::Advance { until_step: 8000, release_pilots: true, leases: None }),
        (
            "advance-leases",
            ToShard::Advance { until_step: 12, release_pilots: false, leases: Some(vec![[0, 1], [5, 0]]) },
        ),
        ("stop", ToShard::Stop),
    ];
    let mut seeds = Vec::new();
    for (name, m) in &from_shard {
        let bytes = payload(m);
        assert_eq!(&FromShard::decode(&bytes).unwrap_or_else(|e| panic!("{name}: {e}")), m, "{name}");
        seeds.push((*name, bytes));
    }
    for (name, m) in &to_shard {
        let bytes = payload(m);
        assert_eq!(&ToShard::decode(&bytes).unwrap_or_else(|e| panic!("{name}: {e}")), m, "{name}");
        seeds.push((*name, bytes));
    }
    let Some(root) = std::env::var_os("SADESIM_FUZZ_SEEDS") else { return };
    let dir = std::path::Path::new(&root).join("shard_wire");
    std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    for (name, bytes) in &seeds {
        std::fs::write(dir.join(name), bytes).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    }
}
