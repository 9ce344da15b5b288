//! Urban wind (the paper's first environment factor, §3.3): the wind around the world's
//! buildings on a 3-D grid aligned with the run's ENU frame, each cell holding the wind
//! vector.
//!
//! - [`grid`]: the cells over the world square and which are solid;
//! - [`profile`]: the undisturbed log profile the field is a factor of;
//! - [`rockle`]: the diagnostic first guess (upwind displacement, cavity, wake);
//! - [`solver`]: the mass-consistent adjustment that makes it divergence free;
//! - [`compare`]: measures comparing two fields (correlation);
//! - [`field`]: per inflow sector, the adjusted field; sampling and sector blending;
//! - [`openfoam`]: OpenFOAM ASCII vector fields (cell centres `C`, velocity `U`) of a case
//!   computed elsewhere, read from their text;
//! - [`foam_case`]: the files of an OpenFOAM case of the wind over the world's buildings;
//! - [`foam_import`]: an OpenFOAM case's cells mapped onto the wind grid as a sector field;
//! - [`request`]: which field a run needs (grid, sectors, direction, model), from its
//!   scenario and world.
//!
//! Pure: the world (and the scenario) in, numbers out; the same inputs give the same bits.

pub mod compare;
pub mod field;
pub mod foam_case;
pub mod foam_import;
pub mod grid;
pub mod openfoam;
pub mod profile;
pub mod request;
pub mod rockle;
pub mod solver;

#[cfg(test)]
mod fuzz_seeds;

pub use field::{DEFAULT_SECTORS, DIAGNOSTIC_MODEL_VERSION, SectorBlend, SectorField, UrbanWindField};
pub use grid::{GridSpec, WindGrid};

#[cfg(test)]
mod tests;
