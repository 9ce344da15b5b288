//! What shapes the world: origin, world parameters and the areas kept free of buildings.

use sadesim_crds::fleet::{Area, HomePlacement};
use sadesim_crds::geo::{GeoPoint, LocalFrame};
use sadesim_crds::run::{SimulationRunSpec, World as WorldSpec, WorldSource};
use serde::{Deserialize, Serialize};

/// Radius of the building-free disc kept around each explicit home, metres: a few airframe
/// spans plus room for drift during takeoff, small enough to cost at most one lot.
pub const EXPLICIT_HOME_CLEARANCE_M: f64 = 15.0;

/// A building-free disc on the ground (a park, a launch site), world ENU metres.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct OpenArea {
    /// Disc centre, metres east of the origin.
    pub east_m: f64,
    /// Disc centre, metres north of the origin.
    pub north_m: f64,
    /// Disc radius, metres. No building footprint touches the closed disc.
    pub radius_m: f64,
}

/// Everything [`super::World::generate`] reads. Same inputs, same world.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct WorldInputs {
    /// Geodetic origin of the run's ENU frame; its altitude is the ground at (0, 0).
    pub origin: GeoPoint,
    /// World source, extent and city parameters (`spec.world()`).
    pub world: WorldSpec,
    /// Discs kept free of buildings, in order.
    pub open_areas: Vec<OpenArea>,
}

impl WorldInputs {
    /// The inputs of a run: origin, world, the declared open areas
    /// (`spec.world.openAreas`), every park-style home area of the fleet (`areas`), a disc of
    /// [`EXPLICIT_HOME_CLEARANCE_M`] around each explicit home, then `extra_open`. A
    /// `randomInArea` disc is *not* cleared (it may span a whole district): the planner
    /// draws those homes outside buildings instead.
    ///
    /// # Guarantees
    /// Depends on the spec's origin, world and fleet home placements only: not on
    /// `spec.seed`, the clock or missions (the world is a cached asset shared by runs that
    /// differ only in those).
    pub fn from_spec(spec: &SimulationRunSpec, extra_open: &[OpenArea]) -> Self {
        let origin = spec.origin.geo();
        let frame = LocalFrame::new(origin);
        let disc = |area: &Area| {
            let (east_m, north_m) = frame.to_plane(area.center.latitude_deg, area.center.longitude_deg);
            OpenArea { east_m, north_m, radius_m: area.radius_m }
        };
        let world = spec.world();
        let mut open_areas: Vec<OpenArea> = world.open_areas.iter().map(disc).collect();
        for group in &spec.fleet {
            match &group.homes {
                HomePlacement::Explicit(homes) => open_areas.extend(homes.iter().map(|home| {
                    let (east_m, north_m) = frame.to_plane(home.latitude_deg, home.longitude_deg);
                    OpenArea { east_m, north_m, radius_m: EXPLICIT_HOME_CLEARANCE_M }
                })),
                HomePlacement::Areas(areas) => open_areas.extend(areas.iter().map(disc)),
                HomePlacement::RandomInArea(_) => {}
            }
        }
        open_areas.extend_from_slice(extra_open);
        Self { origin, world, open_areas }
    }

    /// The generator's seed: a 64-bit hash of the origin, source, extent and resolved city
    /// parameters. Open areas are left out on purpose: they only remove buildings, so
    /// adding a drone (and its home clearance) does not redraw the whole city.
    ///
    /// Hashed from the values' IEEE-754 bits (with -0.0 folded into 0.0), so it does not
    /// depend on how the spec was written (`city` omitted or spelled out with defaults give
    /// the same seed). Not `spec.seed`: see [`WorldInputs::from_spec`].
    pub fn seed(&self) -> u64 {
        let mut h = Fnv1a::new();
        h.bytes(b"sadesim-world-v1");
        for v in [self.origin.latitude_deg, self.origin.longitude_deg, self.origin.altitude_msl_m] {
            h.f64(v);
        }
        h.bytes(&[match self.world.source {
            WorldSource::Procedural => 1,
            WorldSource::Osm => 2,
        }]);
        h.f64(self.world.extent_m);
        let city = self.world.city();
        for v in [
            city.block_size_m,
            city.street_width_m,
            city.median_building_height_m,
            city.max_building_height_m,
            city.built_fraction,
        ] {
            h.f64(v);
        }
        h.finish()
    }
}

/// FNV-1a, 64 bit (Fowler, Noll, Vo): tiny and specified bit for bit, so the seed never
/// changes under a dependency upgrade (unlike `std`'s `DefaultHasher`, which may).
struct Fnv1a(u64);

impl Fnv1a {
    fn new() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }

    fn bytes(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    fn f64(&mut self, v: f64) {
        // `+ 0.0` turns -0.0 into 0.0: equal values, equal bits.
        self.bytes(&(v + 0.0).to_bits().to_le_bytes());
    }

    /// FNV's low bits mix poorly; a final murmur3 avalanche spreads every input bit.
    fn finish(&self) -> u64 {
        let mut z = self.0;
        z = (z ^ (z >> 33)).wrapping_mul(0xff51_afd7_ed55_8ccd);
        z = (z ^ (z >> 33)).wrapping_mul(0xc4ce_b9fe_1a85_ec53);
        z ^ (z >> 33)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sadesim_crds::fixtures::{CHICAGO, RunBuilder};
    use sadesim_crds::fleet::LatLon;
    use sadesim_crds::run::City;

    #[test]
    fn home_areas_and_explicit_homes_become_open_discs_in_enu() {
        let park = Area { name: None, center: CHICAGO, radius_m: 80.0 };
        let north = LatLon { latitude_deg: CHICAGO.latitude_deg + 0.001, longitude_deg: CHICAGO.longitude_deg };
        let run = RunBuilder::test()
            .with(|r| r.spec.world = None) // no declared open areas: only the fleet's
            .with(|r| r.spec.fleet[0].homes = HomePlacement::Areas(vec![park.clone(), park.clone()]))
            .with_group("bravo", 1)
            .with(|r| r.spec.fleet[1].homes = HomePlacement::Explicit(vec![north]))
            .build();
        let extra = OpenArea { east_m: 500.0, north_m: -500.0, radius_m: 40.0 };
        let inputs = WorldInputs::from_spec(&run.spec, &[extra]);
        assert_eq!(inputs.open_areas.len(), 4);
        let at_origin = inputs.open_areas[0];
        assert!(at_origin.east_m.abs() < 1e-6 && at_origin.north_m.abs() < 1e-6 && at_origin.radius_m == 80.0);
        let home = inputs.open_areas[2];
        // 0.001 deg of latitude at 41.9 N is ~111.1 m.
        assert!(home.east_m.abs() < 0.01 && (home.north_m - 111.1).abs() < 0.5, "{home:?}");
        assert_eq!(home.radius_m, EXPLICIT_HOME_CLEARANCE_M);
        assert_eq!(inputs.open_areas[3], extra);
    }

    #[test]
    fn seed_ignores_the_run_seed_but_not_the_world() {
        let a = WorldInputs::from_spec(&RunBuilder::test().with_seed(1).build().spec, &[]);
        let b = WorldInputs::from_spec(&RunBuilder::test().with_seed(2).build().spec, &[]);
        assert_eq!(a.seed(), b.seed());

        let mut spelled_out = a.clone();
        spelled_out.world.city = Some(City::default());
        assert_eq!(a.seed(), spelled_out.seed(), "defaults written out are the same world");

        let mut moved = a.clone();
        moved.origin.latitude_deg += 1e-6;
        assert_ne!(a.seed(), moved.seed());
        // Open areas only remove buildings: the rest of the city stays as it was.
        let mut opened = a.clone();
        opened.open_areas.push(OpenArea { east_m: 0.0, north_m: 0.0, radius_m: 1.0 });
        assert_eq!(a.seed(), opened.seed());
    }
}
