//! Flight among buildings in a strong wind (issue 17's flight acceptance): drones hover in
//! the lee of a tower, in the open, in a street along the wind and in one across it, and
//! the wind each met (the `wind` detail of its snapshot, what the MCAP wind channel
//! records) and the tilt it needed are compared. The shard flies them exactly as a run
//! does: the real planner, the built-in pilot, the field computed from the world.

use std::sync::Arc;

use nalgebra::{UnitQuaternion, Vector3};
use sadesim_crds::environment::{Environment, Turbulence, UrbanWind, UrbanWindModel, Wind};
use sadesim_crds::fleet::{HomePlacement, LatLon, Mission, MissionItem};
use sadesim_crds::geo::{Enu, LocalFrame};
use sadesim_crds::plan::RunPlan;
use sadesim_world::{Building, Footprint, World, WorldData};

use super::*;
use crate::fixtures::run_with_groups;

/// Wind from the west, 12 m/s at 10 m over open ground: a strong breeze, well within what
/// an x500 holds (its tilt stays far from the limit, so tilt measures the drag it fights).
const WIND_MPS: f64 = 12.0;
const FROM_DEG: f64 = 270.0;
/// Hover height above the ground, metres.
const HOVER_M: f64 = 20.0;
/// The hold is averaged from here to the end: the climb and the settling are over.
const AVERAGE_FROM_S: f64 = 25.0;
const END_S: f64 = 45.0;

/// An axis-aligned block `[e0, e1] x [n0, n1]`, `height_m` tall, on flat ground.
fn block(e0: f64, e1: f64, n0: f64, n1: f64, height_m: f64) -> Building {
    let footprint = Footprint::new(vec![[e0, n0], [e1, n0], [e1, n1], [e0, n1]], vec![]).expect("a square");
    Building::new(footprint, 0.0, height_m).expect("a valid block")
}

/// Where each test drone hovers (ENU east, north), by group name.
const LEE: (&str, [f64; 2]) = ("lee", [45.0, 0.0]);
const OPEN: (&str, [f64; 2]) = ("open", [-220.0, 0.0]);
const ALONG: (&str, [f64; 2]) = ("along", [20.0, 140.0]);
const ACROSS: (&str, [f64; 2]) = ("across", [-10.0, -120.0]);

/// A 300 m square world: a 60 m tower (40 x 40 m) at the origin; north of it an east-west
/// street 20 m wide between two 120 m long, 25 m tall blocks (along the wind); south of it
/// a north-south street 20 m wide between two such blocks (across the wind).
fn world() -> World {
    World::of_buildings(
        300.0,
        vec![
            block(-20.0, 20.0, -20.0, 20.0, 60.0),
            // Along the wind: the street is n in [130, 150].
            block(-60.0, 60.0, 100.0, 130.0, 25.0),
            block(-60.0, 60.0, 150.0, 180.0, 25.0),
            // Across the wind: the street is e in [-20, 0].
            block(-50.0, -20.0, -180.0, -60.0, 25.0),
            block(0.0, 30.0, -180.0, -60.0, 25.0),
        ],
    )
}

/// One drone per spot, each taking off to [`HOVER_M`] over its home and holding there.
fn plan(world: &World, urban: Option<UrbanWind>) -> RunPlan {
    let spots = [LEE, OPEN, ALONG, ACROSS];
    let names: Vec<(&str, u32)> = spots.iter().map(|(n, _)| (*n, 1)).collect();
    let run = run_with_groups(&names)
        .with(|r| {
            let frame = LocalFrame::new(r.spec.origin.geo());
            for (group, (_, [e, n])) in r.spec.fleet.iter_mut().zip(spots) {
                let g = frame.to_geodetic(Enu::new(e, n, 0.0));
                group.homes = HomePlacement::Explicit(vec![LatLon {
                    latitude_deg: g.latitude_deg,
                    longitude_deg: g.longitude_deg,
                }]);
                group.mission = Some(Mission {
                    items: vec![
                        MissionItem::Takeoff { altitude_agl_m: HOVER_M },
                        MissionItem::Loiter { hold_s: 3600.0 },
                    ],
                    speed_mps: None,
                });
            }
            r.spec.environment = Some(Environment {
                wind: Some(Wind {
                    speed_mps: WIND_MPS,
                    direction_from_deg: FROM_DEG,
                    reference_height_m: None,
                    turbulence: Turbulence::None,
                    urban,
                }),
                ..Default::default()
            });
        })
        .build();
    sadesim_planner::plan_in(&run, &WorldData::default(), world).expect("the test run plans")
}

/// Per group: the mean horizontal wind speed the drone met (m/s) and its mean tilt
/// (degrees) over the hold.
struct Hover {
    wind_mps: f64,
    tilt_deg: f64,
}

/// Flies `plan` in `world` and averages each drone's hold.
fn fly(plan: &RunPlan, world: World) -> Vec<Hover> {
    let surroundings = Surroundings::new(plan, Arc::new(world), None);
    let mut shard = Shard::new(plan, 0, &surroundings).expect("the shard builds");
    let steps_per_s = u64::from(plan.spec.physics_rate_hz());
    let window = steps_per_s / 100;
    let n = shard.drones().len();
    let (mut wind, mut tilt, mut samples) = (vec![0.0; n], vec![0.0; n], 0.0);
    let mut step = 0;
    while step < (END_S * steps_per_s as f64) as u64 {
        step += window;
        let reply = shard.handle(ToShard::Advance { until_step: step, release_pilots: true, leases: None });
        let Some(FromShard::Advanced { drones, .. }) = reply else { panic!("the shard stopped") };
        if (step as f64 / steps_per_s as f64) < AVERAGE_FROM_S {
            continue;
        }
        for (d, s) in drones.iter().enumerate() {
            assert!(!s.crashed && !s.on_ground, "drone {d} is flying: {s:?}");
            let w = s.detail.wind_enu_mps;
            wind[d] += w[0].hypot(w[1]);
            let [qw, qx, qy, qz] = s.attitude_wxyz;
            let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(qw, qx, qy, qz));
            tilt[d] += (q * Vector3::z()).z.clamp(-1.0, 1.0).acos().to_degrees();
        }
        samples += 1.0;
    }
    (0..n).map(|d| Hover { wind_mps: wind[d] / samples, tilt_deg: tilt[d] / samples }).collect()
}

/// The hovers of the four groups in [`plan`]'s order: lee, open, along, across.
fn hovers(urban: Option<UrbanWind>) -> Vec<Hover> {
    let world = world();
    let plan = plan(&world, urban);
    let names: Vec<&str> = plan.spec.fleet.iter().map(|g| g.name.as_str()).collect();
    assert_eq!(names, ["lee", "open", "along", "across"]);
    fly(&plan, world)
}

#[test]
fn in_the_lee_of_a_tower_the_wind_is_weaker_and_the_drone_tilts_less_than_in_the_open() {
    let h = hovers(None);
    let (lee, open) = (&h[0], &h[1]);
    eprintln!(
        "lee: wind {:.2} m/s, tilt {:.2}°; open: wind {:.2} m/s, tilt {:.2}°",
        lee.wind_mps, lee.tilt_deg, open.wind_mps, open.tilt_deg
    );
    // In the open the drone meets the profile's wind at its height.
    let profile = crate::env::MeanWind::urban(WIND_MPS, FROM_DEG, None).speed_at_mps(HOVER_M);
    assert!((open.wind_mps - profile).abs() < 0.1 * profile, "open {:.2} vs profile {profile:.2}", open.wind_mps);
    // 25 m behind a 60 m tower is deep in its cavity.
    assert!(lee.wind_mps < 0.5 * open.wind_mps, "lee {:.2} vs open {:.2}", lee.wind_mps, open.wind_mps);
    assert!(lee.tilt_deg < 0.6 * open.tilt_deg, "tilt lee {:.2}° vs open {:.2}°", lee.tilt_deg, open.tilt_deg);
    assert!(open.tilt_deg > 3.0, "holding against 12 m/s takes a visible tilt: {:.2}°", open.tilt_deg);
}

#[test]
fn a_street_along_the_wind_channels_it_and_one_across_it_shelters() {
    let h = hovers(None);
    let (open, along, across) = (&h[1], &h[2], &h[3]);
    eprintln!(
        "open {:.2} m/s; street along the wind {:.2} m/s (tilt {:.2}°); across {:.2} m/s (tilt {:.2}°)",
        open.wind_mps, along.wind_mps, along.tilt_deg, across.wind_mps, across.tilt_deg
    );
    // At 20 m, below the 25 m roofs: the street along the wind carries at least the open
    // wind (the flow the blocks push aside goes down the street); across, it is sheltered.
    assert!(along.wind_mps > 0.95 * open.wind_mps, "along {:.2} vs open {:.2}", along.wind_mps, open.wind_mps);
    assert!(across.wind_mps < 0.6 * along.wind_mps, "across {:.2} vs along {:.2}", across.wind_mps, along.wind_mps);
    assert!(across.tilt_deg < along.tilt_deg, "tilt across {:.2}° vs along {:.2}°", across.tilt_deg, along.tilt_deg);
}

#[test]
fn without_the_urban_model_every_drone_meets_the_same_profile() {
    let h = hovers(Some(UrbanWind { model: UrbanWindModel::None, case: None, spacing_m: None, sectors: None }));
    let open = h[1].wind_mps;
    for (name, hover) in ["lee", "open", "along", "across"].iter().zip(&h) {
        assert!((hover.wind_mps - open).abs() < 0.02 * open, "{name}: {:.2} vs {open:.2}", hover.wind_mps);
    }
}
