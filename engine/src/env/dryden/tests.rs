use sadesim_crds::random::Purpose;

use super::*;

fn light_at(height_agl_m: f64) -> DrydenScales {
    DrydenScales::low_altitude(height_agl_m, wind_speed_at_20ft_mps(Turbulence::Light).expect("light"))
}

/// Sample standard deviation and normalised autocorrelation at `lag` of a zero-mean series.
fn std_and_autocorrelation(xs: &[f64], lag: usize) -> (f64, f64) {
    let var = xs.iter().map(|x| x * x).sum::<f64>() / xs.len() as f64;
    let cov = xs.iter().zip(&xs[lag..]).map(|(a, b)| a * b).sum::<f64>() / (xs.len() - lag) as f64;
    (var.sqrt(), cov / var)
}

/// Gusts of `steps` steps at fixed height and airspeed, as (u, v, w) series.
fn run(scales: &DrydenScales, airspeed_mps: f64, dt_s: f64, steps: usize, seed: u64) -> [Vec<f64>; 3] {
    let mut filter = DrydenFilter::new(Rng::stream(seed, 0, Purpose::Turbulence));
    let mut out = [Vec::with_capacity(steps), Vec::with_capacity(steps), Vec::with_capacity(steps)];
    for _ in 0..steps {
        let g = filter.step(scales, airspeed_mps, dt_s);
        for (series, value) in out.iter_mut().zip(g.iter()) {
            series.push(*value);
        }
    }
    out
}

#[test]
fn low_altitude_scales_match_mil_f_8785c_in_si_units() {
    // 100 ft = 30.48 m; hand-computed from the spec formulas in feet, converted to SI.
    let s = light_at(30.48);
    assert!((s.length_w_m - 30.48).abs() < 1e-9);
    assert!((s.length_u_m - 153.975_6).abs() < 1e-3, "{}", s.length_u_m);
    assert_eq!(s.length_u_m, s.length_v_m);
    assert!((s.sigma_w_mps - 0.771_667).abs() < 1e-5, "15 kt / 10 = {}", s.sigma_w_mps);
    assert!((s.sigma_u_mps - 1.324_063).abs() < 1e-5, "{}", s.sigma_u_mps);
    // Above 1000 ft the isotropic limit of the formula: σ_u = σ_w, L_u = L_w = 1000 ft.
    let high = light_at(2000.0);
    assert!((high.sigma_u_mps - high.sigma_w_mps).abs() < 1e-12);
    assert!((high.length_u_m - 304.8).abs() < 1e-9 && (high.length_w_m - 304.8).abs() < 1e-9);
    assert_eq!(wind_speed_at_20ft_mps(Turbulence::None), None);
    let severe = wind_speed_at_20ft_mps(Turbulence::Severe).expect("severe");
    assert!((severe - 23.15).abs() < 1e-9, "45 kt = {severe} m/s");
}

#[test]
fn noise_moments_are_continuous_and_reach_the_stationary_values() {
    let below = moments(0.5 - 1e-12);
    let above = moments(0.5);
    for k in 0..3 {
        assert!((below[k] - above[k]).abs() < 1e-12, "I{k}: {} vs {}", below[k], above[k]);
    }
    let small = moments(1e-4);
    // Leading terms h, h²/2, h³/3.
    assert!((small[2] / (1e-12 / 3.0) - 1.0).abs() < 1e-3, "{}", small[2]);
    let far = moments(60.0);
    assert!((far[0] - 0.5).abs() < 1e-15 && (far[1] - 0.25).abs() < 1e-15 && (far[2] - 0.25).abs() < 1e-15);
}

#[test]
fn long_run_statistics_match_sigma_and_scale_length() {
    // 20 m AGL (65.6 ft): L_u = L_v = 116.1 m, L_w = 20 m; σ_u = σ_v = 1.797 σ_w.
    let scales = light_at(20.0);
    let (airspeed, dt) = (10.0, 0.05);
    let [u, v, w] = run(&scales, airspeed, dt, 400_000, 11); // 20 000 s
    let lag = |length_m: f64| (length_m / airspeed / dt).round() as usize;
    let (std_u, rho_u) = std_and_autocorrelation(&u, lag(scales.length_u_m));
    let (std_v, rho_v) = std_and_autocorrelation(&v, lag(scales.length_v_m));
    let (std_w, rho_w) = std_and_autocorrelation(&w, lag(scales.length_w_m));
    eprintln!(
        "σ_u {:.3} got {std_u:.3}; σ_v {:.3} got {std_v:.3}; σ_w {:.3} got {std_w:.3}",
        scales.sigma_u_mps, scales.sigma_v_mps, scales.sigma_w_mps
    );
    eprintln!("ρ(L/V): u {rho_u:.3} (theory e^-1 = 0.368), v {rho_v:.3}, w {rho_w:.3} (theory e^-1/2 = 0.184)");
    for (got, want) in [(std_u, scales.sigma_u_mps), (std_v, scales.sigma_v_mps), (std_w, scales.sigma_w_mps)] {
        assert!((got / want - 1.0).abs() < 0.2, "std {got} vs σ {want}");
    }
    // Dryden correlations: R_u(τ) = e^{-τV/L}; R_v,w(τ) = (1 - τV/(2L)) e^{-τV/L}.
    assert!((rho_u - (-1.0_f64).exp()).abs() < 0.1, "ρ_u {rho_u}");
    assert!((rho_v - 0.5 * (-1.0_f64).exp()).abs() < 0.1, "ρ_v {rho_v}");
    assert!((rho_w - 0.5 * (-1.0_f64).exp()).abs() < 0.1, "ρ_w {rho_w}");
    // e-folding time of u is of order L/V.
    let e_fold =
        (1..u.len()).find(|&k| std_and_autocorrelation(&u[..100_000], k).1 < (-1.0_f64).exp()).expect("decorrelates");
    let ratio = e_fold as f64 * dt / (scales.length_u_m / airspeed);
    eprintln!("u e-folding time / (L_u/V) = {ratio:.3}");
    assert!((0.6..1.6).contains(&ratio), "{ratio}");
}

#[test]
fn exact_discretisation_keeps_sigma_at_coarse_steps() {
    // dt of 2 s is 1.7 L_w/V: a forward-Euler filter would be unstable here.
    let scales = light_at(20.0);
    let [u, v, w] = run(&scales, 10.0, 2.0, 50_000, 12);
    let stds: Vec<f64> = [u, v, w].iter().map(|s| std_and_autocorrelation(s, 1).0).collect();
    eprintln!("dt = 2 s: std u {:.3} v {:.3} w {:.3}", stds[0], stds[1], stds[2]);
    for (got, want) in stds.iter().zip([scales.sigma_u_mps, scales.sigma_v_mps, scales.sigma_w_mps]) {
        assert!((got / want - 1.0).abs() < 0.1, "std {got} vs σ {want}");
    }
}

#[test]
fn hovering_uses_the_airspeed_floor_and_zero_dt_holds_the_gust() {
    let scales = light_at(30.0);
    let mut a = DrydenFilter::new(Rng::stream(3, 0, Purpose::Turbulence));
    let mut b = a.clone();
    assert_eq!(a.step(&scales, 0.0, 0.01), b.step(&scales, MIN_AIRSPEED_MPS, 0.01));
    let gust = a.step(&scales, 5.0, 0.01);
    assert_eq!(a.step(&scales, 5.0, 0.0), gust);
}
