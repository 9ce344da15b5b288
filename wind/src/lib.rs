//! Urban wind (the paper's first environment factor, §3.3): the wind around the world's
//! buildings on a 3-D grid aligned with the run's ENU frame.
//!
//! - [`openfoam`]: OpenFOAM ASCII vector fields (cell centres `C`, velocity `U`) of a case
//!   computed elsewhere, read from their text.

pub mod openfoam;
