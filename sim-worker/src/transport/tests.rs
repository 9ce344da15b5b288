use std::io::Cursor;
use std::net::{TcpListener, TcpStream};

use super::*;
use sadesim_engine::protocol::DroneSnapshot;

fn frames(messages: &[FromShard]) -> Vec<u8> {
    let (mut out, mut buf) = (Vec::new(), Vec::new());
    for m in messages {
        write_message(&mut out, m, &mut buf).unwrap();
    }
    out
}

#[test]
fn frames_follow_each_other_and_the_stream_ends_between_them() {
    let sent = [
        FromShard::Hello { version: sadesim_engine::protocol::PROTOCOL_VERSION, shard: 1, drones: 2 },
        FromShard::Advanced {
            shard: 1,
            step: 10,
            ready: true,
            drones: vec![DroneSnapshot::climbing(2, 5.0, 0.01), DroneSnapshot::climbing(3, 9.0, 0.01)],
            events: vec![],
        },
    ];
    let bytes = frames(&sent);
    let (mut r, mut buf) = (Cursor::new(bytes), Vec::new());
    for m in &sent {
        assert_eq!(read_message::<FromShard>(&mut r, &mut buf).unwrap().as_ref(), Some(m));
    }
    assert!(read_message::<FromShard>(&mut r, &mut buf).unwrap().is_none(), "a clean end");
}

#[test]
fn a_frame_whose_length_starts_with_the_byte_of_a_brace_is_a_frame() {
    // A payload of 123 bytes: its length's first byte is 0x7b, `{`, as a JSON line's.
    let reason = |n: usize| FromShard::Failed { shard: 0, reason: "x".repeat(n) };
    let base = frames(&[reason(0)]).len() - 4;
    let msg = reason(123 - base);
    let bytes = frames(std::slice::from_ref(&msg));
    assert_eq!(bytes[..4], [b'{', 0, 0, 0]);
    assert_eq!(read_message::<FromShard>(&mut Cursor::new(bytes), &mut Vec::new()).unwrap(), Some(msg));
}

#[test]
fn a_stream_cut_inside_a_frame_or_a_frame_too_long_is_an_error_naming_it() {
    let bytes = frames(&[FromShard::Stopped { shard: 0 }]);
    let mut buf = Vec::new();
    let err = read_message::<FromShard>(&mut Cursor::new(&bytes[..2]), &mut buf).unwrap_err().to_string();
    assert!(err.contains("the stream ended inside a frame's length (2 of 4 bytes)"), "{err}");
    let err = read_message::<FromShard>(&mut Cursor::new(&bytes[..bytes.len() - 1]), &mut buf).unwrap_err().to_string();
    let (n, got) = (bytes.len() - 4, bytes.len() - 5);
    assert!(
        err.contains(&format!("the stream ended inside a frame of {n} bytes ({got} of them received, a JSON")),
        "{err}"
    );
    let huge = (MAX_FRAME_BYTES as u32 + 1).to_le_bytes();
    let err = read_message::<FromShard>(&mut Cursor::new(huge), &mut buf).unwrap_err().to_string();
    assert!(err.contains("over the 67108864-byte limit"), "{err}");
    // A peer of an older version starts with a JSON line.
    let line = b"{\"type\":\"hello\",\"version\":3,\"shard\":0,\"drones\":1}\n".to_vec();
    let err = read_message::<FromShard>(&mut Cursor::new(line), &mut buf).unwrap_err().to_string();
    assert!(err.contains("before version 4"), "{err}");
}

/// The coordinator's link and a shard's end on a real loopback connection: every message
/// arrives as sent, in order, both ways.
#[test]
fn a_tcp_link_carries_both_directions_exactly() {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let address = listener.local_addr().unwrap();
    let shard = std::thread::spawn(move || {
        let stream = TcpStream::connect(address).unwrap();
        let (mut reader, mut writer) = (BufReader::new(stream.try_clone().unwrap()), BufWriter::new(stream));
        let (mut incoming, mut outgoing) = (Vec::new(), Vec::new());
        let mut seen = Vec::new();
        while let Some(msg) = read_message::<ToShard>(&mut reader, &mut incoming).unwrap() {
            let done = msg == ToShard::Stop;
            seen.push(msg);
            if done {
                break;
            }
            let drones = (0..500).map(|i| DroneSnapshot::climbing(i, f64::from(i) * 0.1, 1.0 / 3.0)).collect();
            let reply = FromShard::Advanced { shard: 0, step: seen.len() as u64, ready: true, drones, events: vec![] };
            write_message(&mut writer, &reply, &mut outgoing).unwrap();
        }
        seen
    });
    let (stream, _) = listener.accept().unwrap();
    let mut link = TcpLink::new(stream).unwrap();
    let sent = [
        ToShard::Advance { until_step: 10, release_pilots: false, leases: None },
        ToShard::Advance { until_step: 20, release_pilots: true, leases: Some(vec![[1, 0]]) },
    ];
    for (i, m) in sent.iter().enumerate() {
        link.send(m).unwrap();
        let FromShard::Advanced { step, drones, .. } = link.recv().unwrap() else { panic!("not a window") };
        assert_eq!(step, i as u64 + 1);
        assert_eq!(drones.len(), 500);
        assert_eq!(drones[499], DroneSnapshot::climbing(499, 49.900000000000006, 1.0 / 3.0));
    }
    link.send(&ToShard::Stop).unwrap();
    let seen = shard.join().unwrap();
    assert_eq!(seen, [sent[0].clone(), sent[1].clone(), ToShard::Stop]);
}
