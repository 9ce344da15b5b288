//! Real buildings and open areas from an OpenStreetMap extract (`.osm.pbf`), as prisms and
//! polygons in world ENU metres around the run origin.
//!
//! Pure: the caller reads the file and passes its bytes (the world library does no I/O).
//!
//! # What is read (documented filters)
//! - **Buildings**: closed ways and `type=multipolygon` relations tagged `building=*` (not
//!   `building=no`). A multipolygon's `outer` (or role-less) member ways are joined end to
//!   end into rings, its `inner` ways into holes of the outer ring that contains them. One
//!   prism per outer ring.
//! - **Building parts** (Simple 3D Buildings): closed ways and multipolygons tagged
//!   `building:part=*` (not `no`; also when tagged `building` too) are prisms with their own
//!   heights (the rules below), like buildings. A building outline that holds a part is no
//!   prism of its own: its parts replace it, as 3D renderers draw it. A part belongs to the
//!   outline that holds its interior point (GEOS' `PointOnSurface`, see `parts`), decided on
//!   the whole extract before clipping; `type=building` relations are not read. An outline
//!   without parts stays a prism, and a part inside no outline is a building of its own.
//!   Parts are not given their outline's tags: a part without height tags gets the
//!   defaults.
//! - **Heights** (metres above the ground): roof from `height`, else `building:height`, else
//!   (`building:levels` + `roof:levels`) x [`STOREY_HEIGHT_M`] + `roof:height`, else
//!   [`DEFAULT_HEIGHT_M`]; base from `min_height`, else `building:min_height`, else
//!   `building:min_level` x [`STOREY_HEIGHT_M`], else 0. Lengths may carry `m`, `ft` or
//!   feet-and-inches (`40'6"`). [`OsmStats`] counts how many roofs came from each rule
//!   (parts included: every prism has one roof).
//! - **Open areas**: closed ways and multipolygons with `leisure` = park, garden, common,
//!   playground, dog_park, recreation_ground or `landuse` = grass, meadow,
//!   recreation_ground, village_green, park.
//! - **Clipping**: every ring is clipped to the world's square `[-extent, extent]²`
//!   (`world.extentM` is its half-width); what lies wholly outside is dropped.
//! - **Skipped, and counted**: open ways tagged as areas, elements cut by the extract (a
//!   node or member way missing from the file), rings that do not close, and polygons that
//!   are not valid footprints after clipping (self-touching rings, holes outside).
//!
//! Coordinates: the reader's WGS84 latitude/longitude go through the run's
//! [`LocalFrame::to_plane`] (ellipsoidal ENU at the origin's altitude).

mod assemble;
mod parts;
mod pbf;

#[cfg(test)]
mod tests;

use sadesim_crds::geo::LocalFrame;
use serde::{Deserialize, Serialize};

pub use assemble::parse_length_m;
pub use pbf::PbfError;

use crate::building::Building;
use crate::footprint::Footprint;

/// Height of one storey (`building:levels`), metres: a common value for residential and
/// office floors (2.8 to 3.5 m floor to floor).
pub const STOREY_HEIGHT_M: f64 = 3.0;
/// Roof height of a building with no height or level tags, metres (three storeys).
pub const DEFAULT_HEIGHT_M: f64 = 9.0;

/// The OSM element a shape came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
#[serde(tag = "type", content = "id", rename_all = "camelCase")]
pub enum ElementId {
    Way(i64),
    Relation(i64),
}

impl std::fmt::Display for ElementId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ElementId::Way(id) => write!(f, "way {id}"),
            ElementId::Relation(id) => write!(f, "relation {id}"),
        }
    }
}

/// Which rule gave a building its roof height.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "camelCase")]
pub enum HeightSource {
    /// `height` or `building:height`.
    Tagged,
    /// `building:levels` x [`STOREY_HEIGHT_M`].
    Levels,
    /// No tag: [`DEFAULT_HEIGHT_M`].
    Default,
}

/// One building of the extract: a prism standing on flat ground at z = 0 (its base at
/// `min_height` above it).
#[derive(Clone, Debug, PartialEq)]
pub struct OsmBuilding {
    pub id: ElementId,
    pub building: Building,
    pub height_source: HeightSource,
    /// Tagged `building:part`: one part of a building (Simple 3D Buildings), whose outline,
    /// if any, is not a prism.
    pub part: bool,
}

/// One open area (park, grass, ...).
#[derive(Clone, Debug, PartialEq)]
pub struct OsmOpenArea {
    pub id: ElementId,
    /// The tag that made it open, e.g. `leisure=park`.
    pub kind: String,
    /// `name`, when tagged.
    pub name: Option<String>,
    pub footprint: Footprint,
}

/// What the import kept and skipped.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct OsmStats {
    /// Building prisms (one per outer ring inside the extent), parts included.
    pub buildings: usize,
    /// Of `buildings`, prisms of `building:part` areas.
    pub parts: usize,
    /// Building outlines inside the extent not built because parts replace them.
    pub outlines_replaced_by_parts: usize,
    /// Roofs from `height` / `building:height` (these three add up to `buildings`).
    pub heights_tagged: usize,
    /// Roofs from `building:levels`.
    pub heights_from_levels: usize,
    /// Roofs at [`DEFAULT_HEIGHT_M`].
    pub heights_defaulted: usize,
    pub open_areas: usize,
    /// Elements with a node or member way missing from the file (cut by the extract).
    pub skipped_incomplete: usize,
    /// Ways tagged as buildings or open areas that do not close.
    pub skipped_open_ways: usize,
    /// Polygons that are not valid footprints or prisms (self-touching, roof under base).
    pub skipped_invalid: usize,
}

impl OsmStats {
    fn count(&mut self, source: HeightSource) {
        match source {
            HeightSource::Tagged => self.heights_tagged += 1,
            HeightSource::Levels => self.heights_from_levels += 1,
            HeightSource::Default => self.heights_defaulted += 1,
        }
    }
}

/// The buildings and open areas of an extract within the world's square.
#[derive(Clone, Debug, PartialEq)]
pub struct OsmCity {
    /// SHA-256 of the extract's bytes, hex: part of the asset cache key (a changed file is a
    /// new world).
    pub source_sha256: String,
    pub buildings: Vec<OsmBuilding>,
    pub open_areas: Vec<OsmOpenArea>,
    pub stats: OsmStats,
}

/// Why an extract cannot be a world. The caller adds the file's name.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum OsmError {
    /// Not a readable PBF file (the byte and what is wrong).
    #[error(transparent)]
    Pbf(#[from] PbfError),
    /// The extract's bounding box does not hold the world's square.
    #[error(
        "the extract covers longitude {:.5}..{:.5}, latitude {:.5}..{:.5}, but world.extentM {extent_m} m around the origin needs longitude {:.5}..{:.5}, latitude {:.5}..{:.5}: use a larger extract or a smaller extent",
        have[0], have[2], have[1], have[3], need[0], need[2], need[1], need[3]
    )]
    NotCovering { have: [f64; 4], need: [f64; 4], extent_m: f64 },
    /// A tag value the import cannot use.
    #[error("{element}: tag {key}={value:?}: expected {expected}")]
    Tag { element: ElementId, key: String, value: String, expected: String },
    /// Nothing to fly among. `skipped` is empty, or says how many areas were incomplete and
    /// why the first was (`; 1 area of the file skipped as incomplete, the first relation 3:
    /// member way 999 is not in the file`).
    #[error(
        "no building within world.extentM {extent_m} m of the origin: check spec.origin (is it inside the extract?) and the extent{skipped}"
    )]
    NoBuildings { extent_m: f64, skipped: String },
}

/// Reads the buildings and open areas of the `.osm.pbf` file `bytes` within `extent_m`
/// (half-width of the world square) of `frame`'s origin.
///
/// # Errors
/// [`OsmError`]: the bytes are not a PBF file, the extract does not cover the square, a
/// height tag is negative, or no building is left.
pub fn read_pbf(bytes: &[u8], frame: &LocalFrame, extent_m: f64) -> Result<OsmCity, OsmError> {
    let raw = pbf::read(bytes, &assemble::is_read_tag)?;
    let need = square_bounds(frame, extent_m);
    let have = raw.bbox.or_else(|| node_bounds(&raw)).unwrap_or([0.0; 4]);
    let covers = have[0] <= need[0] && have[1] <= need[1] && have[2] >= need[2] && have[3] >= need[3];
    if !covers {
        return Err(OsmError::NotCovering { have, need, extent_m });
    }
    let mut city = assemble::city(&raw, frame, extent_m)?;
    city.source_sha256 = sadesim_crds::parts::sha256_hex(bytes);
    Ok(city)
}

/// `[min_lon, min_lat, max_lon, max_lat]` of the world square (its corners and edge
/// midpoints: the square is small enough that its sides are straight in degrees to
/// well under a metre).
fn square_bounds(frame: &LocalFrame, extent_m: f64) -> [f64; 4] {
    let mut b = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];
    for e in [-extent_m, 0.0, extent_m] {
        for n in [-extent_m, 0.0, extent_m] {
            let p = frame.to_geodetic(sadesim_crds::geo::Enu { east_m: e, north_m: n, up_m: 0.0 });
            b = [
                b[0].min(p.longitude_deg),
                b[1].min(p.latitude_deg),
                b[2].max(p.longitude_deg),
                b[3].max(p.latitude_deg),
            ];
        }
    }
    b
}

fn node_bounds(raw: &pbf::RawOsm) -> Option<[f64; 4]> {
    if raw.nodes.is_empty() {
        return None;
    }
    Some(
        raw.nodes
            .values()
            .fold([f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY], |b, &[lat, lon]| {
                [b[0].min(lon), b[1].min(lat), b[2].max(lon), b[3].max(lat)]
            }),
    )
}
