use nalgebra::Vector3;
use sadesim_crds::fixtures::RunBuilder;
use sadesim_crds::fleet::GeofenceAction;
use sadesim_crds::geo::LocalFrame;

use super::*;
use crate::airspace::volume::{FlatGround, ZoneVolume};

/// The fixture's zone centred on the origin: ±0.0009° (about ±100 m north-south, ±75 m
/// east-west at Chicago's latitude), 0-150 m AGL.
fn zones() -> Vec<ZoneVolume> {
    let run = RunBuilder::test().with_zone("square").build();
    let frame = LocalFrame::new(run.spec.origin.geo());
    run.spec.zones.iter().map(|z| ZoneVolume::new(z, &frame)).collect()
}

/// North of the zone's centre at `north_m`, 50 m up, flying south at `speed` m/s.
fn approach(fence: &mut Geofence, north_m: f64, speed: f64, mode: FlightMode) -> Option<Breach> {
    fence.check(
        10.0,
        Vector3::new(0.0, north_m, 50.0),
        Vector3::new(0.0, -speed, 0.0),
        mode,
        &zones(),
        &FlatGround(0.0),
    )
}

#[test]
fn a_drone_far_from_the_zone_is_left_alone_and_one_within_its_stopping_distance_is_stopped() {
    let mut fence = Geofence::new(GeofenceAction::Hold, 1);
    // 10 m/s: 10²/(2·2.5) + 10·1 = 30 m of look-ahead.
    assert_eq!(approach(&mut fence, 200.0, 10.0, FlightMode::Mission), None);
    assert_eq!(approach(&mut fence, 135.0, 10.0, FlightMode::Mission), None);
    assert_eq!(
        approach(&mut fence, 125.0, 10.0, FlightMode::Mission),
        Some(Breach { zone: 0, action: GeofenceAction::Hold })
    );
}

#[test]
fn faster_drones_are_stopped_further_out() {
    let mut fence = Geofence::new(GeofenceAction::Hold, 1);
    // 20 m/s: 80 + 20 = 100 m of look-ahead.
    assert!(approach(&mut fence, 190.0, 20.0, FlightMode::Mission).is_some());
    let mut slow = Geofence::new(GeofenceAction::Hold, 1);
    assert!(approach(&mut slow, 190.0, 5.0, FlightMode::Mission).is_none());
}

#[test]
fn a_lease_opens_the_zone_and_losing_it_closes_it_again() {
    let mut fence = Geofence::new(GeofenceAction::ReturnToLaunch, 1);
    fence.set_permitted([0]);
    assert_eq!(approach(&mut fence, 110.0, 10.0, FlightMode::Mission), None);
    assert_eq!(approach(&mut fence, 0.0, 10.0, FlightMode::Mission), None, "inside with a lease");
    fence.set_permitted([]);
    assert_eq!(
        approach(&mut fence, 0.0, 10.0, FlightMode::Mission),
        Some(Breach { zone: 0, action: GeofenceAction::ReturnToLaunch }),
        "inside without a lease: act at once"
    );
}

#[test]
fn a_hold_fires_once_then_again_when_the_pilot_steers_back_in() {
    let mut fence = Geofence::new(GeofenceAction::Hold, 1);
    assert!(approach(&mut fence, 120.0, 10.0, FlightMode::Mission).is_some());
    // Braking in HOLD: still heading in, no second trigger.
    assert_eq!(approach(&mut fence, 115.0, 6.0, FlightMode::Hold), None);
    // Standing still 6 m away: clear.
    assert_eq!(approach(&mut fence, 106.0, 0.0, FlightMode::Hold), None);
    // The pilot repositions towards the zone again (PX4 reposition flies in HOLD).
    assert!(approach(&mut fence, 106.0, 6.0, FlightMode::Hold).is_some());
}

#[test]
fn during_a_geofence_return_nothing_re_triggers() {
    let mut fence = Geofence::new(GeofenceAction::ReturnToLaunch, 1);
    assert!(approach(&mut fence, 120.0, 10.0, FlightMode::Mission).is_some());
    assert_eq!(approach(&mut fence, 118.0, 8.0, FlightMode::ReturnToLaunch), None);
    // The pilot takes over (MISSION again) still heading in: the fence acts again.
    assert!(approach(&mut fence, 118.0, 8.0, FlightMode::Mission).is_some());
}

#[test]
fn over_the_ceiling_or_before_activation_the_zone_does_not_count() {
    let mut fence = Geofence::new(GeofenceAction::Hold, 1);
    let high = fence.check(
        10.0,
        Vector3::new(0.0, 120.0, 170.0),
        Vector3::new(0.0, -10.0, 0.0),
        FlightMode::Mission,
        &zones(),
        &FlatGround(0.0),
    );
    assert_eq!(high, None, "150 m ceiling, flying at 170 m");
    let mut later = zones();
    later[0].active_from_s = 60.0;
    let early = fence.check(
        10.0,
        Vector3::new(0.0, 120.0, 50.0),
        Vector3::new(0.0, -10.0, 0.0),
        FlightMode::Mission,
        &later,
        &FlatGround(0.0),
    );
    assert_eq!(early, None);
}
