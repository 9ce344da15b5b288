//! `sadesim`: parse flags, run the command, map the outcome to an exit code.
//! Exit codes: 0 success, 1 problems found (invalid scenario, failed criteria), 2 error.

use std::process::ExitCode;

use clap::Parser;
use sadesim::cli::{Cli, CliError, Outcome, execute};

fn main() -> ExitCode {
    let cli = Cli::parse();
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    match execute(cli, &mut out) {
        Ok(Outcome::Success) => ExitCode::SUCCESS,
        Ok(Outcome::Problems) => ExitCode::from(1),
        Ok(Outcome::Interrupted) => ExitCode::from(130),
        // `sadesim plan ... | head`: the reader left; that is not an error worth reporting.
        Err(CliError::Write(e)) if e.kind() == std::io::ErrorKind::BrokenPipe => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}
