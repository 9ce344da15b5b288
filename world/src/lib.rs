//! The world as a pure library: ground, buildings and open areas around the run origin (a
//! procedural city, or real geometry from a map and an elevation model), with the ground and
//! line-of-sight queries every role reads.
//!
//! No I/O and no physics-engine types: the planner, the shards (whose building contacts
//! are [`World::ball_touches_building`]), the asset role and every test use the same
//! values.
//!
//! Frame: world **ENU** metres from the run origin (x east, y north, z up); z = 0 is the
//! ground altitude at the origin (`spec.origin.altitudeMslM`), so an MSL altitude is
//! `altitudeMslM + z`. Build a [`World`] from [`WorldInputs`] (usually
//! [`WorldInputs::from_spec`]) and ask it for ground heights, buildings and line-of-sight
//! hits.
//!
//! - `inputs`: what shapes the world, and its seed (a hash of the inputs, not `spec.seed`).
//! - `terrain`: the smooth seeded ground relief.
//! - `city`: street grid, blocks, lots, buildings and their heights.
//! - `building`: one building, a prism over a footprint, and its geometry.
//! - `footprint`: the footprint polygon (holes allowed) and its 2D geometry.
//! - `index`: the uniform grid behind the fast queries.
//! - `map`: [`World`] and its queries; `stats`: [`WorldStats`] for logs.
//! - `ground`: the [`Ground`] height query, with [`FlatGround`] for tests.
//! - [`dem`]: terrain from a GeoTIFF or SRTM elevation model (bytes), sampled at WGS84 positions.
//! - [`bundle`]: the world as bytes, saved once in the asset bundle and loaded by every role.
//! - [`mesh`]: the world as triangle meshes (buildings, ground) for glTF, recordings, renderers.
//! - [`osm`]: real buildings and open areas from an OpenStreetMap extract (`.osm.pbf` bytes).
//! - [`protobuf`]: a minimal Protocol Buffers reader, for the OSM extract and recorded poses.

mod building;
pub mod bundle;
mod city;
pub mod dem;
mod footprint;
mod ground;
mod index;
mod inputs;
mod map;
pub mod mesh;
pub mod osm;
pub mod protobuf;
mod stats;
mod terrain;

#[cfg(test)]
mod fuzz;
#[cfg(test)]
mod tests;

pub use building::{Building, BuildingError};
pub use city::{MIN_HEIGHT_M, PARK_FRACTION};
pub use footprint::{AxisRect, Footprint, FootprintError, Point2};
pub use ground::{FlatGround, Ground};
pub use inputs::{EXPLICIT_HOME_CLEARANCE_M, OpenArea, WorldInputs};
pub use map::{OpenSpace, World, WorldData, WorldError};
pub use stats::WorldStats;
pub use terrain::{GroundGrid, Terrain};
