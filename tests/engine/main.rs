//! Cross-crate integration tests, in one test binary.
//!
//! Each module was its own `[[test]]` target once; every target links the whole engine
//! (kube, mavlink, object_store), so six targets meant six links of about 500 MB each with debug
//! info. One binary links once: faster builds on two cores and a target directory CI's
//! disk can hold. Filter by module as usual: `cargo nextest run -p sadesim-integration-tests
//! chicago::`.

mod acceptance;
mod airspace;
mod chicago;
mod flight;
mod local;
mod pilot;
mod pilot_failure;
mod pilot_hold;
mod run;
mod sweep;
mod urban_gnss;
