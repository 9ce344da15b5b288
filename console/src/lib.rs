//! The web console, `sadesim console`: plan a run on a map, launch it, watch it, and browse
//! the archive, in the browser (docs/console.md).
//!
//! One page (`web/`, MapLibre GL JS from npm, embedded: nothing from the internet) and one
//! HTTP API (docs/console-api.yaml) over two backends:
//!
//! - [`local`]: the local runner on this machine, runs into a runs folder that is also the
//!   archive browsed;
//! - [`cluster`]: SimulationRuns through the Kubernetes API server with each user's own
//!   identity.
//!
//! Modules:
//! - [`server`]: the routes, the page and the Server-Sent Events streams;
//! - [`scenario`]: parse, validate and export a document; the world's map layers;
//! - [`archive`]: listing, files and verification of archived runs;
//! - [`replay`]: a recorded run's 3D replay (shared with `sadesim view`);
//! - [`model`]: what the API answers;
//! - [`time`]: RFC 3339 and run-folder stamps;
//! - [`server_stream`]: the stream type of the watch endpoints.

pub mod archive;
pub mod cluster;
pub mod local;
pub mod model;
pub mod replay;
pub mod scenario;
pub mod server;
pub mod time;

/// The stream type of the watch endpoints.
pub mod server_stream {
    /// Server-Sent Events, ended when the client goes away.
    pub type EventStream = std::pin::Pin<
        Box<dyn futures_util::Stream<Item = Result<axum::response::sse::Event, std::convert::Infallible>> + Send>,
    >;
}
