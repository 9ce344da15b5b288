use std::sync::Arc;

use nalgebra::Vector3;
use sadesim_crds::geo::GeoPoint;
use sadesim_world::{Building, Footprint, World};

use super::*;
use crate::orbits::Constellation;
use crate::synthetic::walker_gps_galileo_tle;

fn sky() -> Arc<RunSky> {
    let c = Constellation::from_tle(&walker_gps_galileo_tle()).unwrap();
    let epoch = c.satellites[0].epoch_unix_s;
    Arc::new(RunSky::new(c, GeoPoint::new(60.17, 24.94, 10.0), epoch, 10.0))
}

fn slab(e0: f64, e1: f64, roof_m: f64) -> Building {
    let square = vec![[e0, -300.0], [e1, -300.0], [e1, 300.0], [e0, 300.0]];
    Building::new(Footprint::new(square, vec![]).unwrap(), 0.0, roof_m).unwrap()
}

/// A north-south street 16 m wide between 60 m slabs.
fn canyon() -> Arc<World> {
    Arc::new(World::of_buildings(600.0, vec![slab(-48.0, -8.0, 60.0), slab(8.0, 48.0, 60.0)]))
}

fn open() -> Arc<World> {
    Arc::new(World::of_buildings(600.0, vec![]))
}

/// Horizontal errors (m) and the epochs of a receiver held at `antenna` for 10 minutes
/// at 1 Hz.
fn hold(world: Arc<World>, antenna: Vector3<f64>, seed: u64) -> (Vec<f64>, Vec<ReceiverEpoch>) {
    let mut rx = RangingReceiver::new(sky(), world, seed, 3);
    let epochs: Vec<ReceiverEpoch> = (0..600).map(|k| rx.measure(f64::from(k), antenna, Vector3::zeros())).collect();
    let errors = epochs.iter().filter_map(|e| e.solution).map(|s| (s.position_enu_m - antenna).xy().norm()).collect();
    (errors, epochs)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[test]
fn exact_measurements_give_the_truth_and_the_clock() {
    let truth = Vector3::new(120.0, -40.0, 35.0);
    let v = Vector3::new(3.0, -1.0, 0.5);
    let states = sky().at(0.0);
    let m: Vec<Measurement> = states
        .iter()
        .filter(|s| (s.position_enu_m - truth).normalize().z > 0.2)
        .map(|s| {
            let u = (s.position_enu_m - truth).normalize();
            Measurement {
                satellite_enu_m: s.position_enu_m,
                satellite_velocity_enu_mps: s.velocity_enu_mps,
                pseudorange_m: (s.position_enu_m - truth).norm() + 12_345.0,
                range_rate_mps: u.dot(&(s.velocity_enu_mps - v)) + 7.0,
                sigma_m: 1.0,
                rate_sigma_mps: 0.1,
            }
        })
        .collect();
    assert!(m.len() >= 5, "{} satellites", m.len());
    let s = solve(&m, Vector3::zeros(), None).unwrap();
    assert!((s.position_enu_m - truth).norm() < 1e-3, "{:?}", s.position_enu_m);
    assert!((s.velocity_enu_mps - v).norm() < 1e-6, "{:?}", s.velocity_enu_mps);
    assert!((s.clock_bias_m - 12_345.0).abs() < 1e-3 && s.three_d);
    assert!(s.dop.hdop > 0.3 && s.dop.hdop < 3.0, "{:?}", s.dop);
    // Three satellites: a 2D fix with the height held, none without a height to hold.
    let two_d = solve(&m[..3], Vector3::zeros(), Some(35.0)).unwrap();
    assert!(!two_d.three_d && (two_d.position_enu_m - truth).norm() < 1e-3 && two_d.dop.vdop.is_infinite());
    assert_eq!(solve(&m[..3], Vector3::zeros(), None), None);
    assert_eq!(solve(&m[..2], Vector3::zeros(), Some(35.0)), None);
}

#[test]
fn an_open_sky_fix_matches_a_u_blox_m8_class_receiver() {
    let antenna = Vector3::new(0.0, 0.0, 30.0);
    let (errors, epochs) = hold(open(), antenna, 1);
    assert_eq!(errors.len(), 600, "a fix every epoch");
    assert!(epochs.iter().all(|e| e.reflected == 0 && e.line_of_sight == e.above_mask && e.tracked >= 5));
    // Per-axis 1-sigma: the RMS horizontal error over sqrt(2).
    let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
    let per_axis = rms / 2f64.sqrt();
    eprintln!("open sky: per-axis 1-sigma {per_axis:.2} m, median horizontal {:.2} m", median(errors.clone()));
    assert!((0.3..=0.9).contains(&per_axis), "{per_axis}");
}

#[test]
fn a_deep_street_canyon_loses_satellites_and_its_fix_errs_by_metres() {
    let in_street = Vector3::new(0.0, 0.0, 20.0);
    let (open_errors, open_epochs) = hold(open(), in_street, 2);
    let (canyon_errors, canyon_epochs) = hold(canyon(), in_street, 2);
    let mean = |e: &[ReceiverEpoch], f: fn(&ReceiverEpoch) -> f64| e.iter().map(f).sum::<f64>() / e.len() as f64;
    let tracked = |e: &ReceiverEpoch| f64::from(e.tracked);
    let reflected = |e: &ReceiverEpoch| f64::from(e.reflected);
    assert!(mean(&canyon_epochs, tracked) < mean(&open_epochs, tracked) - 1.0);
    assert!(mean(&canyon_epochs, reflected) > 0.5, "the facades reflect satellites of the other side");
    let hdop = |e: &[ReceiverEpoch]| median(e.iter().filter_map(|e| e.solution).map(|s| s.dop.hdop).collect());
    assert!(hdop(&canyon_epochs) > hdop(&open_epochs), "{} vs {}", hdop(&canyon_epochs), hdop(&open_epochs));
    let (m_open, m_canyon) = (median(open_errors), median(canyon_errors));
    eprintln!("median horizontal error: open {m_open:.2} m, canyon {m_canyon:.2} m");
    assert!(m_canyon > 3.0 * m_open, "{m_canyon} vs {m_open}");
    // Above the roofs the sky is open again.
    let (above, _) = hold(canyon(), Vector3::new(0.0, 0.0, 90.0), 2);
    assert!(median(above) < 2.0 * m_open);
}

#[test]
fn the_same_seed_gives_the_same_measurements() {
    let a = hold(canyon(), Vector3::new(0.0, 0.0, 20.0), 9).1;
    let b = hold(canyon(), Vector3::new(0.0, 0.0, 20.0), 9).1;
    assert_eq!(a, b);
    let c = hold(canyon(), Vector3::new(0.0, 0.0, 20.0), 10).1;
    assert_ne!(a, c);
}
