//! `sadesim-operator`: the Kubernetes operator binary the Helm chart runs (the same as
//! `sadesim operator`, without the simulation engine linked in). Exit codes as `sadesim`:
//! 0 after SIGTERM/SIGINT, 2 when it cannot start or go on (the message says the fix).

use std::process::ExitCode;

use clap::Parser;
use sadesim_operator::OperatorArgs;

fn main() -> ExitCode {
    let args = OperatorArgs::parse();
    match sadesim_operator::k8s::controller::run(args.options()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}
