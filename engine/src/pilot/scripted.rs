//! Turns a group's scenario `mission` into the mission the autopilot flies.
//!
//! Altitudes in the scenario are above ground level at each waypoint (`altitudeAglM`); the
//! autopilot flies relative to home (PX4 convention), so each is shifted by the ground
//! height difference between the waypoint and home. Random waypoints are drawn from the
//! drone's own `(seed, drone index, Mission)` stream, so they do not depend on sharding.

use nalgebra::Vector2;
use sadesim_crds::fleet::{Area, LatLon, Mission, MissionItem as SpecItem};
use sadesim_crds::geo::LocalFrame;
use sadesim_crds::random::{Purpose, Rng};

use crate::autopilot::mission::{DEFAULT_CRUISE_MPS, MissionItem, MissionPlan};

/// Ground height under a horizontal ENU position, metres (the world's terrain query).
pub trait GroundHeight {
    fn ground_up_m(&self, east_m: f64, north_m: f64) -> f64;
}

/// Expands a scenario mission for one drone. `home_area` is the disc the drone's home was
/// drawn in (for random waypoints without an area of their own).
pub fn expand(
    mission: &Mission,
    frame: &LocalFrame,
    ground: &dyn GroundHeight,
    home_en_m: Vector2<f64>,
    home_area: Option<&Area>,
    seed: u64,
    drone_index: u32,
) -> MissionPlan {
    let home_ground = ground.ground_up_m(home_en_m.x, home_en_m.y);
    let rel = |en: Vector2<f64>, agl: f64| agl + ground.ground_up_m(en.x, en.y) - home_ground;
    let mut rng = Rng::stream(seed, drone_index.into(), Purpose::Mission);
    let mut items = Vec::new();
    for item in &mission.items {
        match item {
            // Takeoff climbs over home: AGL there is relative to home by definition.
            SpecItem::Takeoff { altitude_agl_m } => {
                items.push(MissionItem::Takeoff { alt_rel_home_m: *altitude_agl_m })
            }
            SpecItem::Waypoint { latitude_deg, longitude_deg, altitude_agl_m, hold_s } => {
                let (e, n) = frame.to_plane(*latitude_deg, *longitude_deg);
                let en = Vector2::new(e, n);
                items.push(MissionItem::Waypoint {
                    target_en_m: en,
                    alt_rel_home_m: rel(en, *altitude_agl_m),
                    hold_s: hold_s.unwrap_or(0.0),
                });
            }
            SpecItem::Loiter { hold_s } => items.push(MissionItem::Loiter { hold_s: *hold_s }),
            SpecItem::RandomWaypoints { area, count, min_altitude_agl_m, max_altitude_agl_m, hold_s } => {
                // Validation guarantees an area for explicit homes; a missing one falls back
                // to a 30 m disc around home rather than panicking.
                let fallback = Area { name: None, center: frame_latlon(frame, home_en_m), radius_m: 30.0 };
                let area = area.as_ref().or(home_area).unwrap_or(&fallback);
                let (cx, cy) = frame.to_plane(area.center.latitude_deg, area.center.longitude_deg);
                for _ in 0..*count {
                    let (dx, dy) = rng.in_disc(area.radius_m);
                    let en = Vector2::new(cx + dx, cy + dy);
                    let agl = rng.uniform(*min_altitude_agl_m, *max_altitude_agl_m);
                    items.push(MissionItem::Waypoint {
                        target_en_m: en,
                        alt_rel_home_m: rel(en, agl),
                        hold_s: hold_s.unwrap_or(0.0),
                    });
                }
            }
            SpecItem::ReturnToLaunch {} => items.push(MissionItem::ReturnToLaunch),
            SpecItem::Land {} => items.push(MissionItem::Land),
        }
    }
    MissionPlan { items, speed_mps: mission.speed_mps.unwrap_or(DEFAULT_CRUISE_MPS) }
}

fn frame_latlon(frame: &LocalFrame, en: Vector2<f64>) -> LatLon {
    let g = frame.to_geodetic(sadesim_crds::geo::Enu::new(en.x, en.y, 0.0));
    LatLon { latitude_deg: g.latitude_deg, longitude_deg: g.longitude_deg }
}

#[cfg(test)]
mod tests {
    use sadesim_crds::geo::GeoPoint;

    use super::*;

    /// Ground rising 1 m per 100 m eastward.
    struct Slope;
    impl GroundHeight for Slope {
        fn ground_up_m(&self, east_m: f64, _north_m: f64) -> f64 {
            east_m / 100.0
        }
    }

    fn frame() -> LocalFrame {
        LocalFrame::new(GeoPoint::new(41.8796, -87.6237, 181.0))
    }

    #[test]
    fn waypoint_altitudes_follow_the_ground_under_them() {
        let f = frame();
        let g = f.to_geodetic(sadesim_crds::geo::Enu::new(500.0, 0.0, 0.0));
        let mission = Mission {
            items: vec![
                SpecItem::Takeoff { altitude_agl_m: 30.0 },
                SpecItem::Waypoint {
                    latitude_deg: g.latitude_deg,
                    longitude_deg: g.longitude_deg,
                    altitude_agl_m: 40.0,
                    hold_s: Some(2.0),
                },
                SpecItem::Land {},
            ],
            speed_mps: Some(7.0),
        };
        let plan = expand(&mission, &f, &Slope, Vector2::new(0.0, 0.0), None, 1, 0);
        assert_eq!(plan.speed_mps, 7.0);
        match &plan.items[1] {
            MissionItem::Waypoint { target_en_m, alt_rel_home_m, hold_s } => {
                assert!((target_en_m.x - 500.0).abs() < 0.01);
                assert!((alt_rel_home_m - 45.0).abs() < 0.01, "40 m AGL where the ground is 5 m above home");
                assert_eq!(*hold_s, 2.0);
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn random_waypoints_without_an_area_stay_in_the_home_area() {
        let f = frame();
        let park =
            Area { name: None, center: LatLon { latitude_deg: 41.8826, longitude_deg: -87.6225 }, radius_m: 50.0 };
        let mission = Mission {
            items: vec![SpecItem::RandomWaypoints {
                area: None,
                count: 30,
                min_altitude_agl_m: 10.0,
                max_altitude_agl_m: 20.0,
                hold_s: None,
            }],
            speed_mps: None,
        };
        let plan = expand(&mission, &f, &Slope, Vector2::zeros(), Some(&park), 2, 5);
        let (cx, cy) = f.to_plane(park.center.latitude_deg, park.center.longitude_deg);
        for item in &plan.items {
            let MissionItem::Waypoint { target_en_m, .. } = item else { panic!() };
            assert!((target_en_m.x - cx).hypot(target_en_m.y - cy) <= 50.0 + 1e-6, "{target_en_m:?}");
        }
    }

    #[test]
    fn random_waypoints_are_seeded_per_drone_and_stay_in_area() {
        let f = frame();
        let mission = Mission {
            items: vec![SpecItem::RandomWaypoints {
                area: Some(Area {
                    name: None,
                    center: LatLon { latitude_deg: 41.8796, longitude_deg: -87.6237 },
                    radius_m: 200.0,
                }),
                count: 20,
                min_altitude_agl_m: 10.0,
                max_altitude_agl_m: 30.0,
                hold_s: None,
            }],
            speed_mps: None,
        };
        let a = expand(&mission, &f, &Slope, Vector2::zeros(), None, 9, 3);
        assert_eq!(a, expand(&mission, &f, &Slope, Vector2::zeros(), None, 9, 3));
        assert_ne!(a, expand(&mission, &f, &Slope, Vector2::zeros(), None, 9, 4));
        assert_eq!(a.items.len(), 20);
        for item in &a.items {
            let MissionItem::Waypoint { target_en_m, alt_rel_home_m, .. } = item else { panic!() };
            assert!(target_en_m.norm() <= 200.0 + 1e-6);
            let agl = alt_rel_home_m - target_en_m.x / 100.0;
            assert!((10.0..=30.0).contains(&agl), "{agl}");
        }
    }
}
