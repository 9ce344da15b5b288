use super::*;

/// Emissions of `id` over calls at `start_s + k * dt_s` for `duration_s`.
fn count(s: &mut StreamScheduler, id: u32, start_s: f64, duration_s: f64, dt_s: f64) -> usize {
    let steps = (duration_s / dt_s).round() as u64;
    (0..steps).filter(|&k| s.due(start_s + k as f64 * dt_s).contains(&id)).count()
}

fn assert_about(got: usize, want: f64, what: &str) {
    assert!((got as f64 - want).abs() <= 1.0, "{what}: {got} emissions, want {want} ± 1");
}

#[test]
fn px4_onboard_defaults() {
    let s = StreamScheduler::px4_default();
    let hz = |id: u32| 1e6 / f64::from(s.interval_us(id).expect("a stream"));
    assert_eq!(s.message_ids().count(), 14);
    assert!(s.message_ids().collect::<Vec<_>>().windows(2).all(|w| w[0] < w[1]));
    for (id, want) in [
        (HEARTBEAT_DATA::ID, 1.0),
        (ATTITUDE_DATA::ID, 100.0),
        (ATTITUDE_QUATERNION_DATA::ID, 50.0),
        (GLOBAL_POSITION_INT_DATA::ID, 50.0),
        (LOCAL_POSITION_NED_DATA::ID, 30.0),
        (BATTERY_STATUS_DATA::ID, 0.5),
        (HOME_POSITION_DATA::ID, 0.5),
        (SYS_STATUS_DATA::ID, 5.0),
    ] {
        assert!((hz(id) - want).abs() < 1e-3, "message {id}: {} Hz, want {want}", hz(id));
    }
    assert_eq!(s.interval_us(HEARTBEAT_DATA::ID), Some(1_000_000));
    assert_eq!(s.interval_us(LOCAL_POSITION_NED_DATA::ID), Some(33_333));
    assert_eq!(s.interval_us(MISSION_CURRENT_DATA::ID), Some(1_000_000));
    assert_eq!(s.interval_us(9999), None);
}

#[test]
fn everything_is_due_at_the_first_call() {
    let mut s = StreamScheduler::px4_default();
    assert_eq!(s.due(3.0), s.message_ids().collect::<Vec<_>>());
    // ATTITUDE is 100 Hz: due again 10 ms later, the 1 Hz streams are not.
    assert_eq!(s.due(3.01), vec![ATTITUDE_DATA::ID]);
}

#[test]
fn rates_hold_over_10_s_of_10_ms_windows() {
    // 1, 4, 10 and 50 Hz through set_interval, plus the 30 and 100 Hz defaults.
    for hz in [1.0, 4.0, 10.0, 50.0] {
        let mut s = StreamScheduler::px4_default();
        s.set_interval(GLOBAL_POSITION_INT_DATA::ID, (1e6 / hz) as f32).expect("a stream");
        assert_about(count(&mut s, GLOBAL_POSITION_INT_DATA::ID, 0.0, 10.0, 0.01), hz * 10.0, &format!("{hz} Hz"));
    }
    let mut s = StreamScheduler::px4_default();
    assert_about(count(&mut s, LOCAL_POSITION_NED_DATA::ID, 0.0, 10.0, 0.01), 300.0, "30 Hz");
    let mut s = StreamScheduler::px4_default();
    assert_about(count(&mut s, ATTITUDE_DATA::ID, 0.0, 10.0, 0.01), 1000.0, "100 Hz");
    let mut s = StreamScheduler::px4_default();
    assert_about(count(&mut s, BATTERY_STATUS_DATA::ID, 0.0, 10.0, 0.01), 5.0, "0.5 Hz");
}

#[test]
fn accumulated_float_time_does_not_drop_or_double_emissions() {
    // now_s built by summing 0.01 (not k * 0.01) carries rounding error; the grid must not
    // slip by a window because of it.
    let mut s = StreamScheduler::px4_default();
    let mut now_s = 1234.5;
    let mut n = 0;
    for _ in 0..10_000 {
        n += usize::from(s.due(now_s).contains(&ATTITUDE_QUATERNION_DATA::ID));
        now_s += 0.01;
    }
    assert_about(n, 5000.0, "50 Hz over 100 s");
}

#[test]
fn irregular_steps_keep_the_rate() {
    // 13 ms windows do not divide the 20 ms interval; 10 s still gives 500.
    let mut s = StreamScheduler::px4_default();
    assert_about(count(&mut s, GLOBAL_POSITION_INT_DATA::ID, 0.0, 10.0, 0.013), 500.0, "50 Hz at 13 ms");
    let mut s = StreamScheduler::px4_default();
    assert_about(count(&mut s, VFR_HUD_DATA::ID, 0.0, 10.0, 0.037), 100.0, "10 Hz at 37 ms");
}

#[test]
fn far_behind_skips_ahead_instead_of_bursting() {
    let mut s = StreamScheduler::px4_default();
    assert!(s.due(0.0).contains(&SYSTEM_TIME_DATA::ID));
    // Five seconds pass unpolled: one emission now, not five.
    assert!(s.due(5.0).contains(&SYSTEM_TIME_DATA::ID));
    assert!(!s.due(5.01).contains(&SYSTEM_TIME_DATA::ID));
    // Still on the original grid: next at 6.0.
    assert!(!s.due(5.99).contains(&SYSTEM_TIME_DATA::ID));
    assert!(s.due(6.0).contains(&SYSTEM_TIME_DATA::ID));
}

#[test]
fn disable_and_restore() {
    let mut s = StreamScheduler::px4_default();
    let id = ATTITUDE_DATA::ID;
    let _ = s.due(0.0);
    s.set_interval(id, -1.0).expect("a stream");
    assert_eq!(s.interval_us(id), Some(-1));
    assert_eq!(count(&mut s, id, 0.01, 1.0, 0.01), 0);
    // Any negative value disables, as in PX4.
    s.set_interval(id, -5.0).expect("a stream");
    assert_eq!(s.interval_us(id), Some(-1));

    s.set_interval(id, 0.0).expect("a stream");
    assert_eq!(s.interval_us(id), Some(10_000));
    // Back at once, then at the default rate.
    assert!(s.due(1.015).contains(&id));
    assert_about(count(&mut s, id, 1.02, 1.0, 0.01), 100.0, "restored 100 Hz");

    // A custom rate, then the default again.
    s.set_interval(GLOBAL_POSITION_INT_DATA::ID, 500_000.0).expect("a stream");
    assert_eq!(s.interval_us(GLOBAL_POSITION_INT_DATA::ID), Some(500_000));
    s.set_interval(GLOBAL_POSITION_INT_DATA::ID, 0.0).expect("a stream");
    assert_eq!(s.interval_us(GLOBAL_POSITION_INT_DATA::ID), Some(20_000));
}

#[test]
fn changing_the_interval_keeps_the_phase() {
    let mut s = StreamScheduler::px4_default();
    let id = GLOBAL_POSITION_INT_DATA::ID;
    assert!(s.due(0.0).contains(&id));
    // Slow down to 1 Hz just after an emission: next one a second after it, not at once.
    s.set_interval(id, 1_000_000.0).expect("a stream");
    assert!(!s.due(0.01).contains(&id));
    assert!(!s.due(0.99).contains(&id));
    assert!(s.due(1.0).contains(&id));
}

#[test]
fn intervals_are_clamped_to_what_a_10_ms_window_can_carry() {
    let mut s = StreamScheduler::px4_default();
    s.set_interval(VFR_HUD_DATA::ID, 1000.0).expect("a stream");
    assert_eq!(s.interval_us(VFR_HUD_DATA::ID), Some(10_000));
    assert_about(count(&mut s, VFR_HUD_DATA::ID, 0.0, 1.0, 0.01), 100.0, "clamped to 100 Hz");
    s.set_interval(VFR_HUD_DATA::ID, 1e12).expect("a stream");
    assert_eq!(s.interval_us(VFR_HUD_DATA::ID), Some(i32::MAX));
}

#[test]
fn refusals_leave_the_stream_unchanged() {
    let mut s = StreamScheduler::px4_default();
    let before = s.clone();
    assert_eq!(s.set_interval(HEARTBEAT_DATA::ID, -1.0), Err(StreamError::Fixed(HEARTBEAT_DATA::ID)));
    assert_eq!(s.set_interval(9999, 1e5), Err(StreamError::Unknown(9999)));
    assert_eq!(s.set_interval(ATTITUDE_DATA::ID, f32::NAN), Err(StreamError::NotANumber(ATTITUDE_DATA::ID)));
    assert_eq!(s, before);
    assert!(s.due(f64::NAN).is_empty());
    assert_eq!(s, before);
}

#[test]
fn heartbeat_is_1_hz_always() {
    let mut s = StreamScheduler::px4_default();
    assert_about(count(&mut s, HEARTBEAT_DATA::ID, 0.0, 10.0, 0.01), 10.0, "HEARTBEAT");
}
