//! Chainable builders for tests (feature `fixtures`): `RunBuilder::test().with_drones(32)`.

use kube::core::{Duration, ObjectMeta};

use crate::camera::{Camera, CameraMount};
use crate::fleet::{AltitudeLimits, Area, FleetGroup, HomePlacement, LatLon, Mission, MissionItem, Role};
use crate::geo::{Enu, GeoPoint, LocalFrame};
use crate::run::{Origin, Pilot, SimulationRun, SimulationRunSpec};
use crate::zones::{AltitudeReference, Zone, ZoneAltitude, ZonePolicy};

/// The Art Institute of Chicago, ground level: the case study's origin.
pub const CHICAGO: LatLon = LatLon { latitude_deg: 41.8796, longitude_deg: -87.6237 };

/// Centre of the fixture's home area: 1 km south of the origin.
pub const HOMES: LatLon = LatLon { latitude_deg: 41.8706, longitude_deg: -87.6237 };

/// Builds valid runs; each `with_*` changes one aspect.
#[derive(Clone, Debug)]
pub struct RunBuilder {
    run: SimulationRun,
}

impl RunBuilder {
    /// One scripted x500 over Chicago for two minutes.
    pub fn test() -> Self {
        let spec = SimulationRunSpec {
            origin: Origin {
                latitude_deg: CHICAGO.latitude_deg,
                longitude_deg: CHICAGO.longitude_deg,
                altitude_msl_m: 181.0,
            },
            duration: "2m".parse::<Duration>().expect("valid duration"),
            clock: None,
            physics_rate_hz: None,
            seed: Some(7),
            // The home area is parkland: flights near home meet no buildings.
            world: Some(crate::run::World {
                open_areas: vec![Area { name: Some("fixture park".into()), center: HOMES, radius_m: 500.0 }],
                ..Default::default()
            }),
            environment: None,
            fleet: vec![group("alpha", 1)],
            zones: vec![],
            pilot: None,
            rendering: None,
            sharding: None,
            recording: None,
            archive: None,
            criteria: vec![],
            queue: None,
            ground_stations: None,
            abort: false,
        };
        let mut run = SimulationRun::new("test-run", spec);
        run.metadata =
            ObjectMeta { name: Some("test-run".into()), namespace: Some("default".into()), ..Default::default() };
        Self { run }
    }

    /// Replaces the fleet with one scripted group of `n` drones placed randomly 1 km south of
    /// the origin.
    pub fn with_drones(mut self, n: u32) -> Self {
        self.run.spec.fleet = vec![group("alpha", n)];
        self
    }

    /// Adds a scripted group of `n` drones.
    pub fn with_group(mut self, name: &str, n: u32) -> Self {
        self.run.spec.fleet.push(group(name, n));
        self
    }

    pub fn with_drones_per_shard(mut self, n: u32) -> Self {
        self.run.spec.sharding = Some(crate::run::Sharding { drones_per_shard: n, ..Default::default() });
        self
    }

    pub fn with_seed(mut self, seed: u64) -> Self {
        self.run.spec.seed = Some(seed);
        self
    }

    /// Makes every group MAVLink-driven by an external pilot command.
    pub fn with_pilot(mut self, command: &[&str]) -> Self {
        for g in &mut self.run.spec.fleet {
            g.mission = None;
        }
        self.run.spec.pilot = Some(Pilot {
            image: None,
            command: command.iter().map(|s| s.to_string()).collect(),
            container_command: None,
            ..Pilot::default()
        });
        self
    }

    /// Adds a 200 m square zone centred on the origin, 0-150 m AGL.
    pub fn with_zone(mut self, name: &str) -> Self {
        let d = 0.0009; // ~100 m of latitude
        let (la, lo) = (CHICAGO.latitude_deg, CHICAGO.longitude_deg);
        let corner = |dla: f64, dlo: f64| LatLon { latitude_deg: la + dla, longitude_deg: lo + dlo };
        self.run.spec.zones.push(zone(name, vec![corner(-d, -d), corner(-d, d), corner(d, d), corner(d, -d)], 150.0));
        self
    }

    /// Gives the first group's drones `camera` and turns the renderer on (cameras need it).
    pub fn with_camera(mut self, camera: Camera) -> Self {
        let rendering = self.run.spec.rendering.get_or_insert_with(Default::default);
        rendering.enabled = true;
        self.run.spec.fleet[0].cameras.push(camera);
        self
    }

    /// Applies any other change.
    pub fn with(mut self, f: impl FnOnce(&mut SimulationRun)) -> Self {
        f(&mut self.run);
        self
    }

    pub fn build(self) -> SimulationRun {
        self.run
    }
}

/// A downward RGB camera named `down`: 160x120, 90° wide, 10 frames per second.
pub fn down_camera() -> Camera {
    Camera {
        name: "down".into(),
        width_px: 160,
        height_px: 120,
        horizontal_fov_deg: 90.0,
        rate_hz: 10.0,
        record_rate_hz: None,
        mount: CameraMount { pitch_deg: 90.0, ..CameraMount::default() },
        depth: false,
    }
}

fn group(name: &str, count: u32) -> FleetGroup {
    FleetGroup {
        name: name.into(),
        count,
        airframe: "x500".into(),
        operator: "acme".into(),
        role: Role::Other,
        credential: None,
        // 1 km south of the origin, clear of `with_zone`'s zone around the origin.
        homes: HomePlacement::RandomInArea(Area { name: None, center: HOMES, radius_m: 500.0 }),
        altitude: AltitudeLimits { max_agl_m: 120.0, min_agl_m: None },
        mission: Some(Mission {
            items: vec![MissionItem::Takeoff { altitude_agl_m: 30.0 }, MissionItem::Land {}],
            speed_mps: None,
        }),
        geofence: None,
        cameras: Vec::new(),
    }
}

/// A zone over `polygon` from the ground to `ceiling_agl_m` AGL, always active, open to
/// operator `acme`, without lease altitude limits; a test changes what it needs.
pub fn zone(name: &str, polygon: Vec<LatLon>, ceiling_agl_m: f64) -> Zone {
    Zone {
        name: name.into(),
        polygon,
        floor: None,
        ceiling: ZoneAltitude { height_m: ceiling_agl_m, reference: AltitudeReference::Agl },
        active_from: None,
        active_until: None,
        policy: ZonePolicy {
            authorized_operators: vec!["acme".into()],
            capacity: None,
            lease_duration: None,
            min_altitude_agl_m: None,
            max_altitude_agl_m: None,
        },
    }
}

/// Ground points near the fixture's homes: `at(east_m, north_m)` is that far from
/// [`HOMES`] (at 181 m MSL, the fixture origin's ground) in the local frame of `origin`.
pub fn near_homes(origin: GeoPoint) -> impl Fn(f64, f64) -> LatLon {
    let frame = LocalFrame::new(origin);
    let c = frame.to_enu(GeoPoint::new(HOMES.latitude_deg, HOMES.longitude_deg, 181.0));
    move |east_m, north_m| {
        let g = frame.to_geodetic(Enu::new(c.east_m + east_m, c.north_m + north_m, 0.0));
        LatLon { latitude_deg: g.latitude_deg, longitude_deg: g.longitude_deg }
    }
}
