use sadesim_crds::environment::GnssBias;

use super::*;

const OPEN_SKY: GnssCondition = GnssCondition { available: true, sigma_scale: 1.0, satellites: 14, hdop: 0.8 };

/// Fixes over `duration_s` of physics steps of `dt_s`, at rest at `truth`.
fn fixes(rx: &mut GnssReceiver, duration_s: f64, dt_s: f64, cond: &GnssCondition) -> Vec<GnssFix> {
    let steps = (duration_s / dt_s).round() as u64;
    let truth = Vector3::new(100.0, -50.0, 30.0);
    (0..steps).filter_map(|k| rx.update(k as f64 * dt_s, truth, Vector3::zeros(), cond)).collect()
}

#[test]
fn fix_rate_is_honoured_whatever_the_physics_rate() {
    for (rate_hz, dt_s, want) in [(5.0, 0.001, 50), (5.0, 1.0 / 250.0, 50), (10.0, 0.001, 100), (1.0, 0.003, 10)] {
        let config = GnssConfig { rate_hz, ..GnssConfig::default() };
        let got = fixes(&mut GnssReceiver::new(config, 1, 0), 10.0, dt_s, &OPEN_SKY);
        assert!((got.len() as i64 - want).abs() <= 1, "{rate_hz} Hz at dt {dt_s}: {} fixes", got.len());
        assert!(got.windows(2).all(|p| ((p[1].time_s - p[0].time_s) - 1.0 / rate_hz).abs() < dt_s + 1e-9));
    }
}

#[test]
fn white_noise_matches_the_sigmas_and_scales_with_the_condition() {
    let config = GnssConfig { bias_walk_m_per_sqrt_s: 0.0, ..GnssConfig::default() };
    for scale in [1.0, 3.0] {
        let cond = GnssCondition { sigma_scale: scale, ..OPEN_SKY };
        let got = fixes(&mut GnssReceiver::new(config, 2, 0), 2000.0, 0.01, &cond);
        let truth = Vector3::new(100.0, -50.0, 30.0);
        let std = |axis: usize| {
            (got.iter().map(|f| (f.position_enu_m[axis] - truth[axis]).powi(2)).sum::<f64>() / got.len() as f64).sqrt()
        };
        let (east, up) = (std(0), std(2));
        eprintln!(
            "scale {scale}: {} fixes, std east {east:.3} m (want {}), up {up:.3} m (want {})",
            got.len(),
            0.5 * scale,
            0.8 * scale
        );
        assert!((east / (0.5 * scale) - 1.0).abs() < 0.05 && (up / (0.8 * scale) - 1.0).abs() < 0.05);
        assert!(got.iter().all(|f| f.has_3d_fix() && f.eph_m == 0.5 * scale && f.satellites == 14));
    }
}

#[test]
fn bias_random_walk_grows_like_sqrt_time() {
    // No white noise: the fix error is the bias. Over 400 seeds, the spread after 100 s is
    // twice the spread after 25 s, and both are q·√t.
    let config = GnssConfig { horizontal_sigma_m: 0.0, vertical_sigma_m: 0.0, ..GnssConfig::default() };
    let truth = Vector3::new(100.0, -50.0, 30.0);
    let (mut var_25, mut var_100, mut n) = (0.0, 0.0, 0.0);
    for seed in 0..400 {
        let mut rx = GnssReceiver::new(config, seed, 0);
        for k in 0..=500u32 {
            let t = f64::from(k) * 0.2;
            let fix = rx.update(t, truth, Vector3::zeros(), &OPEN_SKY).expect("5 Hz grid");
            let err2 = (fix.position_enu_m - truth).norm_squared();
            if k == 125 {
                var_25 += err2;
            } else if k == 500 {
                var_100 += err2;
            }
        }
        n += 3.0; // three axes
    }
    let (std_25, std_100) = ((var_25 / n).sqrt(), (var_100 / n).sqrt());
    eprintln!(
        "bias std after 25 s {std_25:.4} m (want 0.05), after 100 s {std_100:.4} m (want 0.10), ratio {:.3}",
        std_100 / std_25
    );
    assert!((std_25 / 0.05 - 1.0).abs() < 0.1, "{std_25}");
    assert!((std_100 / 0.1 - 1.0).abs() < 0.1, "{std_100}");
    assert!((std_100 / std_25 - 2.0).abs() < 0.3);
}

#[test]
fn dropout_gives_no_fix_and_a_fresh_fix_when_the_signal_returns() {
    let mut rx = GnssReceiver::new(GnssConfig::default(), 3, 0);
    let lost = GnssCondition { available: false, ..OPEN_SKY };
    let truth = Vector3::new(1.0, 2.0, 3.0);
    let mut out = Vec::new();
    for k in 0..3000u32 {
        let t = f64::from(k) * 0.001;
        let cond = if (1.0..2.0).contains(&t) { lost } else { OPEN_SKY };
        out.extend(rx.update(t, truth, Vector3::zeros(), &cond).map(|f| (t, f)));
    }
    for (t, fix) in &out {
        let in_outage = (1.0..2.0).contains(t);
        assert_eq!(fix.has_3d_fix(), !in_outage, "t {t}");
        if in_outage {
            assert_eq!((fix.fix_type, fix.satellites), (GPS_FIX_TYPE_NO_FIX, 0));
            assert!(fix.eph_m.is_infinite());
        }
    }
    let back = out.iter().find(|(t, _)| *t >= 2.0).expect("fix after the outage");
    assert!(back.0 < 2.0 + 1e-9 && (back.1.position_enu_m - truth).norm() < 5.0, "{back:?}");
    // Too few satellites is no fix either.
    let mut rx = GnssReceiver::new(GnssConfig::default(), 3, 0);
    let sparse = GnssCondition { satellites: 3, ..OPEN_SKY };
    assert!(!rx.update(0.0, truth, Vector3::zeros(), &sparse).expect("due").has_3d_fix());
}

#[test]
fn same_seed_same_fixes_other_drone_other_fixes() {
    let run = |seed, drone| fixes(&mut GnssReceiver::new(GnssConfig::default(), seed, drone), 5.0, 0.001, &OPEN_SKY);
    assert_eq!(run(9, 0), run(9, 0));
    assert_ne!(run(9, 0), run(9, 1));
    assert_ne!(run(9, 0), run(10, 0));
}

#[test]
fn config_comes_from_the_spec_with_defaults() {
    let spec = Gnss {
        constellation: None,
        rate_hz: Some(10.0),
        horizontal_sigma_m: None,
        vertical_sigma_m: Some(2.0),
        bias_walk_m_per_sqrt_s: None,
        bias: Some(GnssBias { east_m: 3.0, north_m: -4.0, up_m: 0.0 }),
        dropouts: Vec::new(),
    };
    let c = GnssConfig::from_spec(Some(&spec));
    assert_eq!((c.rate_hz, c.horizontal_sigma_m, c.vertical_sigma_m, c.bias_walk_m_per_sqrt_s), (10.0, 0.5, 2.0, 0.01));
    assert_eq!(c.fixed_bias_enu_m, Vector3::new(3.0, -4.0, 0.0));
    assert_eq!(GnssConfig::default().rate_hz, 5.0);
    assert_eq!(GnssConfig::default().fixed_bias_enu_m, Vector3::zeros());
}

#[test]
fn a_fixed_bias_shifts_every_fix_of_both_receivers_by_exactly_the_bias() {
    let bias = Vector3::new(3.5, -2.0, 1.0);
    let plain = GnssConfig::default();
    let biased = GnssConfig { fixed_bias_enu_m: bias, ..plain };
    // Same seed with and without the bias: the noise is identical, so each fix moves by
    // exactly the bias.
    let assert_shifted = |without: Vec<GnssFix>, with: Vec<GnssFix>| {
        assert_eq!(without.len(), with.len());
        assert!(with.iter().filter(|f| f.has_3d_fix()).count() > 20);
        for (a, b) in without.iter().zip(&with) {
            assert!((b.position_enu_m - a.position_enu_m - bias).norm() < 1e-9, "{a:?} {b:?}");
            assert_eq!(a.velocity_enu_mps, b.velocity_enu_mps);
        }
    };
    // The statistical receiver.
    let statistical = |config| fixes(&mut GnssReceiver::new(config, 4, 0), 5.0, 0.001, &OPEN_SKY);
    assert_shifted(statistical(plain), statistical(biased));
    // The ranging receiver, in open sky.
    let sky = {
        let c = sadesim_gnss::Constellation::from_tle(&sadesim_gnss::synthetic::walker_gps_galileo_tle()).unwrap();
        let epoch = c.satellites[0].epoch_unix_s;
        Arc::new(RunSky::new(c, sadesim_crds::geo::GeoPoint::new(60.17, 24.94, 10.0), epoch, 10.0))
    };
    let world = Arc::new(World::of_buildings(600.0, vec![]));
    let ranging =
        |config| fixes(&mut GnssReceiver::ranging(config, 4, 0, sky.clone(), world.clone()), 10.0, 0.001, &OPEN_SKY);
    assert_shifted(ranging(plain), ranging(biased));
}
