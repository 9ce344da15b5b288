//! `chicago-pilot`: the SADE-SIM case-study pilot (see the crate docs and docs/pilots.md).
//!
//! Exit status: 0 when every drone landed and disarmed without trouble; 1 when any drone
//! failed (a `FAILED <drone>: <reason>` line each on stderr); 2 when the pilot could not
//! start (bad fleet file, authority unreachable, bad arguments).

use std::path::PathBuf;
use std::process::ExitCode;

use chicago_pilot::pilot::{self, Options};
use clap::Parser;

/// Flies the Chicago museum case study: public safety drones ask for the zone and watch
/// from inside, news crews and hobbyists are denied and stay out.
#[derive(Parser, Debug)]
#[command(name = "chicago-pilot", version)]
struct Args {
    /// The fleet file (`sadesim run` sets SADESIM_FLEET).
    #[arg(long, env = "SADESIM_FLEET", value_name = "FILE")]
    fleet: PathBuf,
    /// The scenario file: its parks (`world.openAreas`, park-style home `areas`) are where
    /// hobbyists fly, the only ground known to be free of buildings at hobby altitudes, and
    /// its wind is the forecast for the way home. Without it hobbyists wander within 300 m
    /// of home and every way home is planned against a headwind. `sadesim run` and the
    /// operator set SADESIM_SCENARIO to the run's own.
    #[arg(long, env = "SADESIM_SCENARIO", value_name = "FILE")]
    scenario: Option<PathBuf>,
    /// The zone of the case study. Default: the first zone the authority lists.
    #[arg(long, value_name = "NAME")]
    zone: Option<String>,
    /// Non-compliant variant: journalists enter the zone after being denied (the run must
    /// then fail its criteria).
    #[arg(long)]
    journalists_ignore_denials: bool,
    /// A worse pilot version (for sweeps comparing versions): each journalist ignores its
    /// denial with this probability, drawn from the run's seed and the drone's index.
    #[arg(long, value_name = "P", default_value_t = 0.0, value_parser = share)]
    ignore_denials_share: f64,
    /// Seed of the hobbyists' random waypoints (each drone's stream also depends on its
    /// index).
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

/// A probability: 0 to 1.
fn share(text: &str) -> Result<f64, String> {
    let p: f64 = text.parse().map_err(|e| format!("{text:?}: {e}"))?;
    if (0.0..=1.0).contains(&p) { Ok(p) } else { Err(format!("must be between 0 and 1, got {p}")) }
}

fn main() -> ExitCode {
    let args = Args::parse();
    let options = Options {
        fleet: args.fleet,
        scenario: args.scenario,
        zone: args.zone,
        journalists_ignore_denials: args.journalists_ignore_denials,
        ignore_denials_share: args.ignore_denials_share,
        seed: args.seed,
    };
    match pilot::run(&options) {
        Ok(report) if report.failures.is_empty() => {
            println!("chicago-pilot: all {} drones landed and disarmed", report.flown);
            ExitCode::SUCCESS
        }
        Ok(report) => {
            for (drone, reason) in &report.failures {
                eprintln!("FAILED {drone}: {reason}");
            }
            ExitCode::from(1)
        }
        Err(e) => {
            eprintln!("chicago-pilot: error: {e}");
            ExitCode::from(2)
        }
    }
}
