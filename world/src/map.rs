//! [`World`]: the generated ground and buildings, and the queries physics, sensors and the
//! environment ask of them.

use nalgebra::Vector3;
use sadesim_crds::random::{Purpose, Rng};
use sadesim_crds::run::WorldSource;
use serde::{Deserialize, Serialize};
use std::fmt;

use super::building::Building;
use super::city::{self, CityLayout};
use super::dem::{Dem, DemError};
use super::index::{GridIndex, Rect};
use super::inputs::WorldInputs;
use super::osm::OsmCity;
use super::stats::WorldStats;
use super::terrain::GroundGrid;
use super::terrain::Terrain;
use sadesim_crds::geo::{Enu, LocalFrame};

/// Ground lattice intervals per side for [`WorldStats`]' ground range: 201 x 201 samples
/// cost about a millisecond; the lattice is 40 m at a 4 km extent, finer than the relief's
/// shortest waves (600 m); coarser at huge extents, which is fine for a log line.
const GROUND_SAMPLES_PER_SIDE: usize = 200;

/// Index cell for mapped cities, metres: about a city block, so a point query looks at a
/// few dozen footprints at most in a dense centre.
const OSM_INDEX_CELL_M: f64 = 50.0;

/// An open space of a mapped world: a park, garden or lawn as the map draws it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OpenSpace {
    /// The tag that made it open, e.g. `leisure=park`.
    pub kind: String,
    /// Its `name`, when tagged.
    pub name: Option<String>,
    /// Its outline, world ENU metres.
    pub footprint: crate::footprint::Footprint,
}

/// Why a world cannot be built.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum WorldError {
    /// `world.source: osm` needs its extract read first (the world library does no I/O).
    #[error("world.source osm: the extract world.osm.file must be read before the world is built")]
    MissingExtract,
    /// `world.terrain.dem` needs its file read first.
    #[error("world.terrain.dem: the DEM file must be read before the world is built")]
    MissingDem,
    #[error("world.terrain.dem: {0}")]
    Dem(#[from] DemError),
}

/// What a world is built from besides its inputs: the files it names, read at the I/O
/// edge.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct WorldData {
    /// The extract of `world.source: osm`.
    pub osm: Option<OsmCity>,
    /// The DEM of `world.terrain.dem`.
    pub dem: Option<Dem>,
}

/// Largest ground grid resampled from a DEM, samples per side.
const MAX_GROUND_SAMPLES: usize = 1025;
/// Finest ground grid spacing, metres (SRTM 1" is ~30 m; national lidar DEMs 1-2 m).
const MIN_GROUND_CELL_M: f64 = 2.0;

/// The DEM as the world's ground: elevations minus the origin's altitude (z = 0 is
/// `origin.altitudeMslM`), resampled on a grid over the world square.
fn dem_terrain(inputs: &WorldInputs, dem: &Dem) -> Result<Terrain, DemError> {
    let frame = LocalFrame::new(inputs.origin);
    let extent_m = inputs.world.extent_m.max(1.0);
    dem.check_covers(&frame, extent_m)?;
    let n = ((2.0 * extent_m / MIN_GROUND_CELL_M) as usize + 1).clamp(2, MAX_GROUND_SAMPLES);
    let origin_alt = inputs.origin.altitude_msl_m;
    let mut missing = None;
    let grid = GroundGrid::sample(extent_m, n, |e, north| {
        let p = frame.to_geodetic(Enu { east_m: e, north_m: north, up_m: 0.0 });
        match dem.elevation_m(p.latitude_deg, p.longitude_deg) {
            Some(z) => z - origin_alt,
            None => {
                missing.get_or_insert((p.latitude_deg, p.longitude_deg));
                0.0
            }
        }
    });
    if let Some((latitude_deg, longitude_deg)) = missing {
        return Err(DemError::NotCovering { extent_m, latitude_deg, longitude_deg, what: "a no-data value" });
    }
    Ok(Terrain::from_grid(grid))
}

/// The world around the run origin: terrain and buildings, in world ENU metres (x east,
/// y north, z up; z = 0 is the ground at the origin, `spec.origin.altitudeMslM`).
///
/// # Guarantees
/// - Deterministic: the same [`WorldInputs`] give a bit-for-bit identical world with the same
///   build of the simulator (the seed is a hash of the inputs, see [`WorldInputs::seed`]).
/// - Procedural buildings are disjoint, lie inside `[-extent, extent]^2`, off the street
///   corridors and off every open area; each stands on the ground at its footprint's centre.
///   Mapped buildings lie inside the square and may overlap where the map stacks them
///   (`building:part` prisms over one another): the queries consider every prism.
///
/// # Caveats
/// `sin`, `exp` and `ln` come from the platform's math library, whose last-bit rounding may
/// differ between platforms: generate the world once (the `assets` role) and share it rather
/// than regenerating it on machines of different kinds.
#[derive(Clone, PartialEq, Serialize, Deserialize)]
pub struct World {
    extent_m: f64,
    seed: u64,
    /// Mapped open spaces (parks, grass) of an OpenStreetMap world, for maps and previews;
    /// empty for the procedural city (its parks are blocks without buildings).
    open_spaces: Vec<OpenSpace>,
    terrain: Terrain,
    buildings: Vec<Building>,
    index: GridIndex,
    /// Lowest base and highest roof over all buildings: segments outside this band skip
    /// the index walk.
    z_band_up_m: (f64, f64),
    stats: WorldStats,
}

impl World {
    /// Generates the procedural world for `inputs`. O(blocks + lots + open areas); a
    /// 4 km-extent city with default parameters (~23 000 buildings) takes ~30 ms in a
    /// release build.
    ///
    /// # Assumptions
    /// `inputs.world` passed `sadesim_crds` validation (positive sizes, fraction in 0..1);
    /// out-of-range values are clamped rather than rejected.
    ///
    /// # Panics
    /// When the world needs files (`source: osm`, `terrain.dem`): those are read at the I/O
    /// edge and built with [`World::build`] (calling this for them is a bug).
    pub fn generate(inputs: &WorldInputs) -> Self {
        assert!(
            inputs.world.source == WorldSource::Procedural && inputs.world.terrain.is_none(),
            "World::generate builds procedural worlds without a DEM; use World::build with the files' data"
        );
        Self::procedural(inputs, None)
    }

    fn procedural(inputs: &WorldInputs, dem: Option<Terrain>) -> Self {
        let seed = inputs.seed();
        let mut rng = Rng::stream(seed, 0, Purpose::World);
        let extent_m = inputs.world.extent_m.max(0.0);
        // Terrain first: it draws a fixed number of values, so the city's draws do not
        // depend on it (nor on whether a DEM replaces it).
        let relief = Terrain::generate(&mut rng);
        let terrain = dem.unwrap_or(relief);
        let city = inputs.world.city();
        let layout = city::generate(&city, extent_m, &inputs.open_areas, &terrain, &mut rng);
        let cell_m = city::StreetGrid::new(&city, extent_m).pitch_m;
        Self::assemble(seed, extent_m, terrain, layout, cell_m, inputs.open_areas.len())
    }

    /// The world of `inputs` with the files' `data` read at the I/O edge: the extract of
    /// `source: osm`, the DEM of `terrain.dem` (the procedural city needs neither).
    ///
    /// # Errors
    /// [`WorldError::MissingExtract`] / [`WorldError::MissingDem`] when a file the inputs
    /// name was not read; [`WorldError::Dem`] when the DEM has no elevation somewhere in
    /// the world square.
    pub fn build(inputs: &WorldInputs, data: &WorldData) -> Result<Self, WorldError> {
        let dem = match (&inputs.world.terrain, &data.dem) {
            (None, _) => None,
            (Some(_), None) => return Err(WorldError::MissingDem),
            (Some(_), Some(dem)) => Some(dem_terrain(inputs, dem)?),
        };
        match (inputs.world.source, &data.osm) {
            (WorldSource::Procedural, _) => Ok(Self::procedural(inputs, dem)),
            (WorldSource::Osm, Some(city)) => Ok(Self::from_osm(inputs, city, dem.unwrap_or_else(Terrain::flat))),
            (WorldSource::Osm, None) => Err(WorldError::MissingExtract),
        }
    }

    /// The buildings of an OpenStreetMap extract, each standing on `terrain` at its
    /// footprint's centre (flat ground without a DEM: no invented relief). Open areas of the
    /// inputs (home clearances) remove nothing: real buildings stay where the map puts them.
    fn from_osm(inputs: &WorldInputs, city: &OsmCity, terrain: Terrain) -> Self {
        let extent_m = inputs.world.extent_m.max(0.0);
        let side_m = 2.0 * extent_m;
        let default_roof_m = inputs.world.osm.as_ref().and_then(|o| o.default_height_m);
        let buildings = city
            .buildings
            .iter()
            .map(|ob| {
                let b = &ob.building;
                let [e, n] = b.footprint().bounds_center();
                let base_up_m = terrain.up_m(e, n) + b.base_up_m();
                // `osm.defaultHeightM` replaces the import's default roof (untagged buildings),
                // keeping at least a storey above a tagged base, as the import does.
                let height_m = match (ob.height_source, default_roof_m) {
                    (crate::osm::HeightSource::Default, Some(roof_m)) => {
                        roof_m.max(b.base_up_m() + crate::osm::STOREY_HEIGHT_M) - b.base_up_m()
                    }
                    _ => b.height_m(),
                };
                Building::new(b.footprint().clone(), base_up_m, height_m).unwrap_or_else(|_| b.clone())
            })
            .collect();
        let layout = CityLayout {
            buildings,
            block_count: 0,
            park_count: city.open_areas.len(),
            // The built fraction is then over the whole square.
            block_area_m2: side_m * side_m,
            dropped_for_open_areas: 0,
        };
        let mut world = Self::assemble(inputs.seed(), extent_m, terrain, layout, OSM_INDEX_CELL_M, 0);
        world.stats.osm = Some(city.stats.clone());
        world.open_spaces = city
            .open_areas
            .iter()
            .map(|a| OpenSpace { kind: a.kind.clone(), name: a.name.clone(), footprint: a.footprint.clone() })
            .collect();
        world
    }

    /// A world of exactly `buildings` on flat ground at 0 m, in the square of half-side
    /// `extent_m`: synthetic scenes for the consumers of buildings (a street canyon for the
    /// GNSS model's tests, the contact tests).
    pub fn of_buildings(extent_m: f64, buildings: Vec<Building>) -> Self {
        Self::of_buildings_on(extent_m, Terrain::flat(), buildings)
    }

    /// As [`World::of_buildings`], on `terrain` (e.g. [`Terrain::from_grid`] of a
    /// [`crate::GroundGrid::sample`]d function):
    /// synthetic hills for the consumers of the ground. The buildings keep their bases.
    pub fn of_buildings_on(extent_m: f64, terrain: Terrain, buildings: Vec<Building>) -> Self {
        let side_m = 2.0 * extent_m;
        let layout = CityLayout {
            buildings,
            block_count: 0,
            park_count: 0,
            block_area_m2: side_m * side_m,
            dropped_for_open_areas: 0,
        };
        Self::assemble(0, extent_m, terrain, layout, OSM_INDEX_CELL_M, 0)
    }

    /// Builds the index and stats around the geometry. `cell_m` is the index's cell:
    /// the street pitch, so each building falls in exactly one cell.
    fn assemble(
        seed: u64,
        extent_m: f64,
        terrain: Terrain,
        layout: CityLayout,
        cell_m: f64,
        open_area_count: usize,
    ) -> Self {
        let rects: Vec<Rect> = layout.buildings.iter().map(|b| b.footprint().bounds()).collect();
        let index = GridIndex::new(cell_m, &rects);
        let z_band_up_m = layout
            .buildings
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), b| (lo.min(b.base_up_m()), hi.max(b.roof_up_m())));
        let ground = ground_range(&terrain, extent_m);
        let stats = WorldStats::new(seed, extent_m, &layout, open_area_count, ground);
        Self {
            extent_m,
            seed,
            open_spaces: Vec::new(),
            terrain,
            buildings: layout.buildings,
            index,
            z_band_up_m,
            stats,
        }
    }

    /// The mapped open spaces (parks, grass) of an OpenStreetMap world; none for the
    /// procedural city.
    pub fn open_spaces(&self) -> &[OpenSpace] {
        &self.open_spaces
    }

    /// Half-width of the square world centred on the origin, metres.
    pub fn extent_m(&self) -> f64 {
        self.extent_m
    }

    /// The generator's seed (hash of the inputs).
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// All buildings; [`World::segment_hits_building`] returns indices into this slice.
    pub fn buildings(&self) -> &[Building] {
        &self.buildings
    }

    /// The ground relief (for renderers that mesh it).
    pub fn terrain(&self) -> &Terrain {
        &self.terrain
    }

    /// Counts and heights, for logs.
    pub fn stats(&self) -> &WorldStats {
        &self.stats
    }

    /// Ground height (ENU up, metres above the origin's ground) at a horizontal position.
    /// MSL altitude of the ground = `spec.origin.altitudeMslM + ground_up_m`.
    pub fn ground_up_m(&self, east_m: f64, north_m: f64) -> f64 {
        self.terrain.up_m(east_m, north_m)
    }

    /// The building whose footprint contains the horizontal position (edges included); the
    /// first in [`World::buildings`] where several do (stacked `building:part` prisms).
    pub fn building_at(&self, east_m: f64, north_m: f64) -> Option<&Building> {
        self.buildings_at(east_m, north_m).next()
    }

    /// Every building whose footprint contains the horizontal position, in index order.
    fn buildings_at(&self, east_m: f64, north_m: f64) -> impl Iterator<Item = &Building> {
        self.index
            .at(east_m, north_m)
            .iter()
            .map(|&k| &self.buildings[k as usize])
            .filter(move |b| b.footprint_contains(east_m, north_m))
    }

    /// What a falling object would land on (ENU up, metres): the highest roof over the
    /// position, else the ground.
    pub fn surface_up_m(&self, east_m: f64, north_m: f64) -> f64 {
        self.buildings_at(east_m, north_m)
            .map(Building::roof_up_m)
            .reduce(f64::max)
            .unwrap_or_else(|| self.ground_up_m(east_m, north_m))
    }

    /// Height above the ground directly below, metres (`pos.z - ground`); roofs do not
    /// count: AGL as altitude limits and zones define it. `pos` in world ENU metres.
    pub fn height_agl_m(&self, pos: Vector3<f64>) -> f64 {
        pos.z - self.ground_up_m(pos.x, pos.y)
    }

    /// Whether the ENU point is inside a building's prism (faces included).
    pub fn is_inside_building(&self, pos: Vector3<f64>) -> bool {
        self.buildings_at(pos.x, pos.y).any(|b| b.contains(&pos))
    }

    /// The first building (index into [`World::buildings`]) that the closed ball of
    /// `radius_m` around the ENU point `center` touches: a drone's rotor disc meeting a wall
    /// or a roof. Exact for prisms: the ball touches when the squared horizontal distance
    /// to the footprint (0 over it) plus the squared vertical distance to the prism's
    /// `[base, roof]` (0 within it) is at most `radius_m²`. Courtyards and notches are open
    /// (the footprint's own distance). The buildings whose bounding rectangles the ball's
    /// square meets come from the grid index, so a query costs a few footprint distances,
    /// however big the city.
    pub fn ball_touches_building(&self, center: Vector3<f64>, radius_m: f64) -> Option<usize> {
        let (z_lo, z_hi) = self.z_band_up_m;
        if center.z + radius_m < z_lo || center.z - radius_m > z_hi {
            return None;
        }
        let square = [center.x - radius_m, center.y - radius_m, center.x + radius_m, center.y + radius_m];
        let mut hits = self.index.in_rect(&square).map(|k| k as usize).filter(|&k| {
            let b = &self.buildings[k];
            let vertical_m = (b.base_up_m() - center.z).max(center.z - b.roof_up_m()).max(0.0);
            if vertical_m > radius_m {
                return false;
            }
            // The ball's horizontal section at the prism's nearest height; its square must
            // meet the footprint's bounds before the polygon is looked at (an index cell
            // holds the buildings of a whole block).
            let section_m = (radius_m * radius_m - vertical_m * vertical_m).sqrt();
            let [e0, n0, e1, n1] = b.footprint().bounds();
            center.x + section_m >= e0
                && center.x - section_m <= e1
                && center.y + section_m >= n0
                && center.y - section_m <= n1
                && b.footprint().touches_disc(center.x, center.y, section_m)
        });
        // An item spanning several cells is yielded once per cell: the lowest index wins,
        // whichever cell it came from, so the answer does not depend on the index layout.
        let first = hits.next()?;
        Some(hits.fold(first, usize::min))
    }

    /// Indices (into [`World::buildings`]) of the buildings whose footprint bounds meet the
    /// rectangle `[east0, north0, east1, north1]` (metres), each once, ascending: the
    /// candidates for a question about a neighbourhood (which facades may reflect a
    /// satellite's signal to an antenna).
    pub fn buildings_in_rect(&self, rect: &[f64; 4]) -> Vec<usize> {
        let mut found: Vec<usize> = self
            .index
            .in_rect(rect)
            .map(|k| k as usize)
            .filter(|&k| {
                let [e0, n0, e1, n1] = self.buildings[k].footprint().bounds();
                e0 <= rect[2] && e1 >= rect[0] && n0 <= rect[3] && n1 >= rect[1]
            })
            .collect();
        found.sort_unstable();
        found.dedup();
        found
    }

    /// Lowest base and highest roof over all buildings, ENU up, metres (`(inf, -inf)`
    /// without buildings): above the band nothing can block a line of sight.
    pub fn building_band_up_m(&self) -> (f64, f64) {
        self.z_band_up_m
    }

    /// The first building the segment `a -> b` meets, with the ENU point where it enters:
    /// `(index into buildings(), point)`. A segment starting inside a building returns that
    /// building at `a`. For line of sight (drone to drone, drone to satellite: pass a point
    /// far along the line of sight; only the part below the tallest roof is walked).
    pub fn segment_hits_building(&self, a: Vector3<f64>, b: Vector3<f64>) -> Option<(usize, Vector3<f64>)> {
        let (z_lo, z_hi) = self.z_band_up_m;
        let (k, t) =
            self.index.first_hit(&a, &b, z_lo, z_hi, |k| self.buildings[k as usize].segment_entry_t(&a, &b))?;
        Some((k as usize, a + (b - a) * t))
    }
}

/// Lowest and highest ground over the world square on a lattice of at most
/// `GROUND_SAMPLES_PER_SIDE + 1` points per side.
fn ground_range(terrain: &Terrain, extent_m: f64) -> (f64, f64) {
    let n = GROUND_SAMPLES_PER_SIDE;
    let step = 2.0 * extent_m / n as f64;
    let mut range = (f64::INFINITY, f64::NEG_INFINITY);
    for j in 0..=n {
        for i in 0..=n {
            let h = terrain.up_m(-extent_m + i as f64 * step, -extent_m + j as f64 * step);
            range = (range.0.min(h), range.1.max(h));
        }
    }
    range
}

impl World {
    /// That a decoded world can be queried without panicking (see [`crate::bundle`]).
    pub(crate) fn check(&self) -> Result<(), crate::bundle::BundleError> {
        use crate::bundle::BundleError::Inconsistent;
        if !self.index.is_consistent(self.buildings.len()) {
            return Err(Inconsistent("the building index names buildings that are not there"));
        }
        if !self.terrain.is_consistent() {
            return Err(Inconsistent("the ground grid does not hold n x n samples"));
        }
        Ok(())
    }
}

impl fmt::Debug for World {
    /// A summary: the full building list is too long to print.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("World").field("stats", &self.stats).finish_non_exhaustive()
    }
}

impl crate::ground::Ground for World {
    fn ground_up_m(&self, east_m: f64, north_m: f64) -> f64 {
        World::ground_up_m(self, east_m, north_m)
    }
}
