//! The world as bytes: what the asset role writes once (`world.bin` in the asset bundle)
//! and every other role (shards, coordinator, report, renderer) loads instead of building
//! the world again from the map, the DEM or the generator.
//!
//! Layout: the 8-byte magic `SADEWRLD`, the format version as a little-endian `u32`
//! ([`FORMAT_VERSION`]), then the [`World`] in postcard's wire format
//! (<https://postcard.jamesmunns.com/wire-format>): varint integers and lengths, `f64` as
//! its 8 IEEE-754 bytes, so a loaded world is bit for bit the one that was saved and a
//! run over it is byte-identical to a run over a freshly built one.
//!
//! Integrity (checksums) is the bundle manifest's job, at the I/O edge; decoding here only
//! guarantees that what it returns is consistent enough to query without panicking (index
//! entries name existing buildings, the ground grid has its n x n samples).

use super::map::World;

/// First bytes of every encoded world.
pub const MAGIC: &[u8; 8] = b"SADEWRLD";
/// Bumped whenever [`World`]'s fields (or any type inside it) change.
pub const FORMAT_VERSION: u32 = 2;

/// Why bytes are not a world this build can load.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum BundleError {
    #[error("not a SADE-SIM world: expected the magic bytes \"SADEWRLD\" at byte 0")]
    NotAWorld,
    #[error("world format version {found} at byte 8; this build reads version {expected} (rebuild the assets)")]
    Version { found: u32, expected: u32 },
    #[error("world data from byte 12: {reason}")]
    Decode { reason: String },
    #[error("world data: {0} bytes after the end of the world")]
    Trailing(usize),
    #[error("world data: inconsistent: {0}")]
    Inconsistent(&'static str),
}

impl World {
    /// The world as bytes (see the module docs for the layout).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(12 + 64 * self.buildings().len());
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        // Serializing plain structs of numbers and vectors into a Vec cannot fail.
        out.extend_from_slice(&postcard::to_allocvec(self).expect("a world always encodes"));
        out
    }

    /// The world [`World::to_bytes`] wrote.
    ///
    /// # Errors
    /// [`BundleError`] naming the byte where the data stops being a world of this format.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, BundleError> {
        if bytes.len() < 8 || &bytes[..8] != MAGIC {
            return Err(BundleError::NotAWorld);
        }
        let version =
            bytes.get(8..12).ok_or_else(|| BundleError::Decode { reason: "truncated in the header".into() })?;
        let found = u32::from_le_bytes(version.try_into().expect("four bytes"));
        if found != FORMAT_VERSION {
            return Err(BundleError::Version { found, expected: FORMAT_VERSION });
        }
        let (world, rest): (World, _) =
            postcard::take_from_bytes(&bytes[12..]).map_err(|e| BundleError::Decode { reason: e.to_string() })?;
        if !rest.is_empty() {
            return Err(BundleError::Trailing(rest.len()));
        }
        world.check()?;
        Ok(world)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dem::Dem;
    use crate::osm::{ElementId, HeightSource, OsmBuilding, OsmCity};
    use crate::{Building, Footprint, WorldData, WorldInputs};
    use nalgebra::Vector3;
    use sadesim_crds::fixtures::{CHICAGO, RunBuilder};
    use sadesim_crds::run::{TerrainSpec, WorldSource};

    fn procedural() -> World {
        let run = RunBuilder::test().build();
        World::generate(&WorldInputs::from_spec(&run.spec, &[]))
    }

    /// An SRTM tile under Chicago rising 1 m per sample eastwards and northwards.
    fn slope_dem() -> Dem {
        let side = 1201usize;
        let mut bytes = Vec::with_capacity(side * side * 2);
        for j in 0..side {
            for i in 0..side {
                bytes.extend_from_slice(&((i + (side - 1 - j)) as i16).to_be_bytes());
            }
        }
        Dem::read(&bytes, "N41W088.hgt").expect("a valid tile")
    }

    /// A mapped world on a DEM: one courtyard building and one plain one.
    fn mapped() -> World {
        mapped_in(300.0, true)
    }

    /// [`mapped`] in a square of half-width `extent_m`, on the DEM or on flat ground.
    fn mapped_in(extent_m: f64, on_dem: bool) -> World {
        let mut run = RunBuilder::test().build();
        run.spec.origin.latitude_deg = CHICAGO.latitude_deg;
        run.spec.origin.longitude_deg = CHICAGO.longitude_deg;
        let world = run.spec.world.get_or_insert_with(Default::default);
        world.source = WorldSource::Osm;
        world.extent_m = extent_m;
        world.terrain = on_dem.then(|| TerrainSpec { dem: sadesim_crds::run::DemFile { file: "N41W088.hgt".into() } });
        let square = |c: f64, h: f64| vec![[c - h, c - h], [c + h, c - h], [c + h, c + h], [c - h, c + h]];
        let courtyard = Footprint::new(square(0.0, 40.0), vec![square(0.0, 10.0)]).expect("a footprint");
        let plain = Footprint::new(vec![[100.0, 100.0], [130.0, 100.0], [115.0, 140.0]], vec![]).expect("a triangle");
        let buildings = [(courtyard, 25.0), (plain, 12.5)]
            .into_iter()
            .enumerate()
            .map(|(k, (f, h))| OsmBuilding {
                id: ElementId::Way(k as i64 + 1),
                building: Building::new(f, 0.0, h).expect("a building"),
                height_source: HeightSource::Tagged,
                part: false,
            })
            .collect();
        let city = OsmCity { source_sha256: "00".into(), buildings, open_areas: vec![], stats: Default::default() };
        let data = WorldData { osm: Some(city), dem: on_dem.then(slope_dem) };
        World::build(&WorldInputs::from_spec(&run.spec, &[]), &data).expect("the mapped world builds")
    }

    #[test]
    fn a_world_loads_back_bit_for_bit_and_answers_the_same_queries() {
        for world in [procedural(), mapped()] {
            let bytes = world.to_bytes();
            let loaded = World::from_bytes(&bytes).expect("loads");
            assert!(loaded == world, "the loaded world equals the saved one");
            assert_eq!(loaded.to_bytes(), bytes, "and encodes to the same bytes");
            let e = world.extent_m();
            for k in 0..200 {
                let (x, y) = ((k as f64 * 37.1) % (2.0 * e) - e, (k as f64 * 53.3) % (2.0 * e) - e);
                assert_eq!(loaded.ground_up_m(x, y).to_bits(), world.ground_up_m(x, y).to_bits());
                assert_eq!(loaded.surface_up_m(x, y).to_bits(), world.surface_up_m(x, y).to_bits());
                let (a, b) = (Vector3::new(x, y, 5.0), Vector3::new(-y, x, 40.0));
                assert_eq!(loaded.segment_hits_building(a, b), world.segment_hits_building(a, b));
            }
        }
        let mapped = mapped();
        assert!(mapped.building_at(0.0, 0.0).is_none(), "the courtyard survives the round trip");
        assert!(World::from_bytes(&mapped.to_bytes()).expect("loads").building_at(25.0, 0.0).is_some());
    }

    #[test]
    fn bytes_that_are_not_a_world_of_this_format_are_refused_naming_where() {
        let bytes = mapped().to_bytes();
        let err = |b: &[u8]| World::from_bytes(b).expect_err("refused").to_string();
        assert!(err(b"PK\x03\x04 a zip").contains("expected the magic bytes"), "{}", err(b"PK"));
        let mut newer = bytes.clone();
        newer[8..12].copy_from_slice(&(FORMAT_VERSION + 1).to_le_bytes());
        assert!(err(&newer).contains(&format!("version {} at byte 8", FORMAT_VERSION + 1)), "{}", err(&newer));
        assert!(err(&bytes[..bytes.len() - 3]).starts_with("world data from byte 12"), "{}", err(&bytes[..40]));
        let mut longer = bytes.clone();
        longer.extend_from_slice(b"xx");
        assert_eq!(err(&longer), "world data: 2 bytes after the end of the world");
    }

    #[test]
    fn the_fuzz_seeds_are_small_worlds_that_load() {
        // The seed corpus of fuzz/fuzz_targets/bundle.rs: a procedural city, a mapped one on
        // flat ground and one on a DEM, each in a small square (a small file).
        let mut run = RunBuilder::test().build();
        let world = run.spec.world.get_or_insert_with(Default::default);
        world.extent_m = 150.0;
        world.open_areas.clear();
        let procedural = World::generate(&WorldInputs::from_spec(&run.spec, &[]));
        let seeds = [
            ("procedural.bin", procedural.to_bytes()),
            ("mapped-flat.bin", mapped_in(140.0, false).to_bytes()),
            // The DEM's ground grid is resampled every 2 m: 31 x 31 samples here.
            ("mapped-dem.bin", mapped_in(30.0, true).to_bytes()),
        ];
        for (name, bytes) in &seeds {
            let world = World::from_bytes(bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert!(!world.buildings().is_empty(), "{name}");
            assert!(bytes.len() < 20_000, "{name}: {} bytes", bytes.len());
        }
        crate::fuzz::write_seeds("bundle", &seeds);
    }

    #[test]
    fn truncated_or_mutated_worlds_never_panic() {
        let bytes = mapped().to_bytes();
        for n in (0..bytes.len()).step_by(97) {
            assert!(World::from_bytes(&bytes[..n]).is_err(), "cut at {n}");
        }
        for case in crate::fuzz::mutations(&bytes, 400, 11, |r| r as usize) {
            // A mutated world may decode (the manifest's checksum catches that); it must
            // not panic, and what decodes must answer queries.
            if let Ok(world) = World::from_bytes(&case) {
                let _ = world.surface_up_m(1.0, 2.0);
                let _ = world.segment_hits_building(Vector3::new(-50.0, 0.0, 5.0), Vector3::new(50.0, 0.0, 5.0));
            }
        }
    }
}
