//! `sim-worker <role>`: one runtime role of a run as its own process (DESIGN §3). The local
//! runner (`sadesim run --processes`) and the Kubernetes pods start these.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use clap::{Parser, Subcommand};
use sim_worker::roles;

/// SADE-SIM runtime roles.
#[derive(Debug, Parser)]
#[command(name = "sim-worker", version, max_term_width = 100)]
struct Cli {
    #[command(subcommand)]
    role: Role,
}

#[derive(Debug, Subcommand)]
enum Role {
    /// Simulate one shard of the plan's drones and serve it to the coordinator over TCP.
    Shard {
        /// RunPlan JSON written by the planner.
        #[arg(long)]
        plan: PathBuf,
        /// Shard index (on Kubernetes: JOB_COMPLETION_INDEX).
        #[arg(long, env = "JOB_COMPLETION_INDEX")]
        shard: u32,
        /// Coordinator address, host:port.
        #[arg(long)]
        coordinator: String,
    },
    /// Accept every shard, run the lockstep clock, record the run into --out.
    Coordinator {
        /// RunPlan JSON written by the planner.
        #[arg(long)]
        plan: PathBuf,
        /// Address to listen on for shards (port 0: any free port, printed on stdout).
        #[arg(long, default_value = "127.0.0.1:7400")]
        listen: String,
        /// Output folder (created if missing).
        #[arg(long)]
        out: PathBuf,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.role {
        Role::Shard { plan, shard, coordinator } => {
            // Ctrl-C in a terminal reaches every process of the group. A shard stops when
            // the coordinator says so (or its connection closes), so the coordinator can
            // finish the run and write its files first.
            let _ = ctrlc::set_handler(|| {});
            roles::read_plan(&plan).and_then(|plan| roles::shard::run(&plan, shard, &coordinator))
        }
        Role::Coordinator { plan, listen, out } => {
            let stop = Arc::new(AtomicBool::new(false));
            let flag = stop.clone();
            let _ = ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed));
            roles::read_plan(&plan).and_then(|plan| {
                std::fs::create_dir_all(&out)?;
                roles::coordinator::run(&plan, listen.as_str(), &out, &stop).map(|_| ())
            })
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}
