use std::f64::consts::FRAC_PI_2;

use super::*;

const NOISELESS: ImuConfig = ImuConfig {
    accel_noise_density: 0.0,
    accel_bias_walk: 0.0,
    accel_bias_tau_s: f64::INFINITY,
    gyro_noise_density: 0.0,
    gyro_bias_walk: 0.0,
    gyro_bias_tau_s: f64::INFINITY,
};

fn mean_and_std(xs: &[f64]) -> (f64, f64) {
    let mean = xs.iter().sum::<f64>() / xs.len() as f64;
    let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (xs.len() - 1) as f64;
    (mean, var.sqrt())
}

#[test]
fn at_rest_and_level_it_reads_plus_g_up_and_no_rotation() {
    let mut imu = Imu::new(ImuConfig::default(), 1, 0);
    let dt = 0.001;
    let samples: Vec<ImuSample> =
        (0..2000).map(|_| imu.measure(Vector3::zeros(), Vector3::zeros(), &UnitQuaternion::identity(), dt)).collect();
    let accel_sigma = 0.004 / dt.sqrt(); // 0.126 m/s²
    for axis in 0..3 {
        let (mean, _) = mean_and_std(&samples.iter().map(|s| s.accel_body_mps2[axis]).collect::<Vec<_>>());
        let want = if axis == 2 { STANDARD_GRAVITY_MPS2 } else { 0.0 };
        assert!((mean - want).abs() < 0.02, "accel axis {axis}: {mean}");
        let (gyro_mean, _) = mean_and_std(&samples.iter().map(|s| s.gyro_body_rps[axis]).collect::<Vec<_>>());
        assert!(gyro_mean.abs() < 0.002, "gyro axis {axis}: {gyro_mean}");
    }
    assert!(samples.iter().all(|s| (s.accel_body_mps2.z - STANDARD_GRAVITY_MPS2).abs() < 6.0 * accel_sigma));
}

#[test]
fn readings_rotate_with_the_attitude() {
    let mut imu = Imu::new(NOISELESS, 1, 0);
    // Yawed 90° left: forward = north, left = west. Accelerating east is accelerating right.
    let yaw_90 = UnitQuaternion::from_euler_angles(0.0, 0.0, FRAC_PI_2);
    let s = imu.measure(Vector3::new(1.0, 0.0, 0.0), Vector3::new(0.0, 0.0, 0.3), &yaw_90, 0.001);
    assert!(
        (s.accel_body_mps2 - Vector3::new(0.0, -1.0, STANDARD_GRAVITY_MPS2)).norm() < 1e-12,
        "{}",
        s.accel_body_mps2
    );
    assert_eq!(s.gyro_body_rps, Vector3::new(0.0, 0.0, 0.3), "gyro is already body frame");
    // Pitched 90° nose down (positive rotation about body y = left): x points down, so the
    // upward specific force reads -g on x.
    let nose_down = UnitQuaternion::from_euler_angles(0.0, FRAC_PI_2, 0.0);
    let s = imu.measure(Vector3::zeros(), Vector3::zeros(), &nose_down, 0.001);
    assert!(
        (s.accel_body_mps2 - Vector3::new(-STANDARD_GRAVITY_MPS2, 0.0, 0.0)).norm() < 1e-12,
        "{}",
        s.accel_body_mps2
    );
    // Free fall reads zero.
    let s = imu.measure(Vector3::new(0.0, 0.0, -STANDARD_GRAVITY_MPS2), Vector3::zeros(), &yaw_90, 0.001);
    assert!(s.accel_body_mps2.norm() < 1e-12);
}

#[test]
fn white_noise_std_matches_the_density_at_the_step() {
    let config = ImuConfig { accel_bias_walk: 0.0, gyro_bias_walk: 0.0, ..ImuConfig::default() };
    for dt in [0.001, 0.004] {
        let mut imu = Imu::new(config, 2, 0);
        let samples: Vec<ImuSample> = (0..20_000)
            .map(|_| imu.measure(Vector3::zeros(), Vector3::zeros(), &UnitQuaternion::identity(), dt))
            .collect();
        let (_, accel_std) = mean_and_std(&samples.iter().map(|s| s.accel_body_mps2.x).collect::<Vec<_>>());
        let (_, gyro_std) = mean_and_std(&samples.iter().map(|s| s.gyro_body_rps.y).collect::<Vec<_>>());
        let (want_accel, want_gyro) = (config.accel_noise_density / dt.sqrt(), config.gyro_noise_density / dt.sqrt());
        eprintln!(
            "dt {dt}: accel std {accel_std:.5} (want {want_accel:.5}), gyro std {gyro_std:.6} (want {want_gyro:.6})"
        );
        assert!((accel_std / want_accel - 1.0).abs() < 0.03);
        assert!((gyro_std / want_gyro - 1.0).abs() < 0.03);
    }
}

#[test]
fn bias_wanders_slowly() {
    let mut imu = Imu::new(ImuConfig::default(), 3, 0);
    for _ in 0..60_000 {
        imu.measure(Vector3::zeros(), Vector3::zeros(), &UnitQuaternion::identity(), 0.001);
    }
    let (accel_bias, gyro_bias) = imu.biases();
    // After 60 s: expected std 0.006·√60 = 0.046 m/s² and 3.9e-5·√60 = 3e-4 rad/s.
    assert!(accel_bias.norm() > 0.0 && accel_bias.amax() < 0.25, "{accel_bias}");
    assert!(gyro_bias.norm() > 0.0 && gyro_bias.amax() < 1.5e-3, "{gyro_bias}");
}

#[test]
fn same_seed_same_readings_other_drone_other_readings() {
    let run = |seed, drone| {
        let mut imu = Imu::new(ImuConfig::default(), seed, drone);
        (0..100)
            .map(|_| imu.measure(Vector3::zeros(), Vector3::zeros(), &UnitQuaternion::identity(), 0.001))
            .collect::<Vec<_>>()
    };
    assert_eq!(run(7, 1), run(7, 1));
    assert_ne!(run(7, 1), run(7, 2));
    assert_ne!(run(7, 1), run(8, 1));
}

#[test]
fn biases_step_every_tenth_sample_with_the_random_walk_of_the_whole_interval() {
    // Held between steps, redrawn every BIAS_STEP_SAMPLES samples.
    let config = ImuConfig { gyro_bias_walk: 1e-3, gyro_bias_tau_s: f64::INFINITY, ..ImuConfig::default() };
    let mut imu = Imu::new(config, 5, 0);
    let level = UnitQuaternion::identity();
    let mut changes = Vec::new();
    let mut last = imu.biases().1;
    for k in 1..=100u32 {
        imu.measure(Vector3::zeros(), Vector3::zeros(), &level, 0.001);
        let now = imu.biases().1;
        if now != last {
            changes.push(k);
        }
        last = now;
    }
    assert_eq!(changes, (1..=10).map(|i| i * BIAS_STEP_SAMPLES).collect::<Vec<_>>());
    // The walk over many drones' 10 s: std q·√t per axis, as if stepped every sample.
    let ends: Vec<f64> = (0..400)
        .map(|drone| {
            let mut imu = Imu::new(config, 9, drone);
            for _ in 0..10_000 {
                imu.measure(Vector3::zeros(), Vector3::zeros(), &level, 0.001);
            }
            imu.biases().1.x
        })
        .collect();
    let (_, std) = mean_and_std(&ends);
    let expected = 1e-3 * 10f64.sqrt();
    assert!((std / expected - 1.0).abs() < 0.15, "std {std:e} vs {expected:e}");
}
