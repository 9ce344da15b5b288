//! What a command reports back to `main`: its outcome, or the error that stopped it.

use sadesim_crds::document::DocumentError;

/// What a command reports back to `main`.
#[derive(Debug, PartialEq, Eq)]
pub enum Outcome {
    Success,
    /// The command ran but found problems (exit code 1).
    Problems,
    /// Ctrl-C ended a run early; its output was kept (exit code 130).
    Interrupted,
}

/// Errors that stop a command (exit code 2 from `main`).
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// A file could not be read.
    #[error("failed to read {path}: {source}")]
    Read { path: String, source: std::io::Error },
    /// A file is too large to be a scenario.
    #[error("{path}: larger than {limit} bytes: not a scenario file")]
    TooLarge { path: String, limit: usize },
    /// The input was unreadable as a whole.
    #[error("{path}: {source}")]
    Document { path: String, source: DocumentError },
    /// `plan` and `run` need exactly one run.
    #[error("{path}: holds {count} runs; this command takes a file with exactly one")]
    NotOneRun { path: String, count: usize },
    /// A run could not start or finish.
    #[error("{path}: {source}")]
    Run { path: String, source: crate::runner::RunError },
    /// The airspace benchmark could not start.
    #[error("bench --airspace: {0}")]
    AirspaceBench(#[from] crate::bench::AirspaceBenchError),
    /// An archive command could not be carried out.
    #[error(transparent)]
    Archive(#[from] sadesim_evidence::archive::ArchiveError),
    /// `archive put` without `--run`/`--uid` on a folder whose names cannot supply them.
    #[error("{dir}: cannot take --{flag} from the folder's name; give --{flag}")]
    ArchiveName { dir: String, flag: &'static str },
    /// Writing the output failed.
    #[error("failed to write output: {0}")]
    Write(#[from] std::io::Error),
    /// A report, manifests or operator command failed (the message names what and why).
    #[error("{0}")]
    Failed(String),
}
