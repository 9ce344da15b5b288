use super::*;

fn ctx(drone: usize, height_agl_m: f64, time_s: f64) -> SampleContext {
    SampleContext {
        drone,
        position_enu_m: Vector3::new(0.0, 0.0, height_agl_m),
        height_agl_m,
        airspeed_mps: 8.0,
        time_s,
        dt_s: 0.01,
    }
}

fn wind(direction_from_deg: f64, turbulence: Turbulence) -> Wind {
    Wind { speed_mps: 6.0, direction_from_deg, reference_height_m: None, turbulence, urban: None }
}

fn sample(factor: &mut WindFactor, c: &SampleContext) -> Vector3<f64> {
    let mut out = EnvSample::default();
    factor.apply(c, &mut out);
    out.wind_enu_mps
}

#[test]
fn without_turbulence_the_wind_is_the_mean_profile() {
    let mut factor = WindFactor::from_spec(&wind(270.0, Turbulence::None), 1, &[0], None);
    let at_10m = sample(&mut factor, &ctx(0, 10.0, 0.0));
    assert!((at_10m - Vector3::new(6.0, 0.0, 0.0)).norm() < 1e-12, "{at_10m}");
    let at_100m = sample(&mut factor, &ctx(0, 100.0, 0.01));
    assert!((at_100m.x - 12.0).abs() < 1e-12, "doubles from 10 m to 100 m for z0 = 1 m: {at_100m}");
}

#[test]
fn gust_is_the_dryden_output_rotated_into_the_mean_wind_frame() {
    // From 0° (north): the air moves south, so u is -north, v (left of downwind) is +east.
    let mut factor = WindFactor::from_spec(&wind(0.0, Turbulence::Moderate), 9, &[4], None);
    let mut reference = DrydenFilter::new(Rng::stream(9, 4, Purpose::Turbulence));
    let mean = MeanWind::urban(6.0, 0.0, None);
    let w20 = wind_speed_at_20ft_mps(Turbulence::Moderate).expect("moderate");
    for k in 0..100 {
        let c = ctx(0, 40.0, f64::from(k) * 0.01);
        let got = sample(&mut factor, &c) - mean.velocity_enu_mps(40.0);
        let uvw = reference.step(&DrydenScales::low_altitude(40.0, w20), c.airspeed_mps, c.dt_s);
        let expected = Vector3::new(uvw.y, -uvw.x, uvw.z);
        assert!((got - expected).norm() < 1e-12, "step {k}: {got} vs {expected}");
    }
}

#[test]
fn sampling_twice_at_one_time_steps_the_filter_once() {
    let mut factor = WindFactor::from_spec(&wind(90.0, Turbulence::Severe), 2, &[0], None);
    let first = sample(&mut factor, &ctx(0, 30.0, 1.0));
    assert_eq!(sample(&mut factor, &ctx(0, 30.0, 1.0)), first);
    assert_ne!(sample(&mut factor, &ctx(0, 30.0, 1.01)), first);
}

#[test]
fn a_drone_on_the_ground_feels_no_wind() {
    let mut factor = WindFactor::from_spec(&wind(200.0, Turbulence::Severe), 3, &[0], None);
    for k in 0..50 {
        assert_eq!(sample(&mut factor, &ctx(0, 0.3, f64::from(k) * 0.01)), Vector3::zeros());
    }
}
