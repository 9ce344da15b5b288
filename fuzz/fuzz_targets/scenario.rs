//! The scenario reader down to the plan: arbitrary text read as a scenario file
//! (`sadesim_crds::parse_runs`: YAML or JSON, one or many documents, `kind: List`), each
//! run validated (`sadesim_crds::validate`) and planned (`sadesim_planner::plan`: the world
//! built, homes drawn, shards, segments and ports laid out), as `sadesim validate` and
//! `sadesim run` do.
//!
//! What is asserted: never a panic, a hang or a runaway allocation; every input becomes
//! plans or errors; a document's error names its document, and a field error its field in
//! one line, as does every validation error; a plan is whole: every
//! drone in exactly one shard and one segment, drone `i` at index `i`, system ids 1..=250
//! and unique within a segment.
#![no_main]

use std::collections::HashSet;

use libfuzzer_sys::fuzz_target;
use sadesim_crds::plan::RunPlan;
use sadesim_crds::{DocumentError, parse_runs, validate};
use sadesim_planner::PlanError;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let Ok(runs) = parse_runs(&text) else { return };
    let count = runs.len();
    for run in runs {
        let run = match run {
            Ok(run) => run,
            Err(e) => {
                document_error(&e, count);
                continue;
            }
        };
        if let Err(errors) = validate(&run) {
            assert!(!errors.0.is_empty(), "validation failed without an error");
            for e in &errors.0 {
                field(&e.path, &e.message);
            }
            continue;
        }
        match sadesim_planner::plan(&run) {
            Ok(plan) => whole(&plan),
            Err(PlanError::Invalid(errors)) => panic!("a valid run failed validation when planned: {errors}"),
            Err(e) => assert!(!e.to_string().is_empty()),
        }
    }
});

/// A document's error says which document (numbered from 1), and a field's error names
/// the field, with a message of one line (`sadesim validate` prints one line per field).
fn document_error(e: &DocumentError, count: usize) {
    let document = match e {
        DocumentError::Syntax { document, message } => {
            assert!(!message.is_empty(), "{e:?}");
            *document
        }
        DocumentError::WrongKind { document, .. } => *document,
        DocumentError::Field { document, path, message } => {
            field(path, message);
            *document
        }
        DocumentError::Fields { document, problems } => {
            assert!(problems.0.len() > 1, "one problem listed as several: {e:?}");
            for p in &problems.0 {
                field(&p.path, &p.message);
            }
            *document
        }
        _ => panic!("an error of the whole input in one document: {e}"),
    };
    assert!((1..=count).contains(&document), "document {document} of {count}: {e}");
}

fn field(path: &str, message: &str) {
    assert!(!path.is_empty() && !message.is_empty(), "a field error without a path or message: {path:?} {message:?}");
    assert!(!path.contains('\n') && !message.contains('\n'), "a field error of more than one line: {path}: {message}");
}

fn whole(plan: &RunPlan) {
    for (i, d) in plan.drones.iter().enumerate() {
        assert_eq!(d.index as usize, i);
        assert!((1..=250).contains(&d.system_id), "system id {}", d.system_id);
    }
    for (name, ranges) in [
        ("shard", plan.shards.iter().map(|s| (s.first_drone, s.drone_count)).collect::<Vec<_>>()),
        ("segment", plan.segments.iter().map(|s| (s.first_drone, s.drone_count)).collect()),
    ] {
        let mut next = 0u32;
        for (first, count) in ranges {
            assert_eq!(first, next, "{name}s do not tile the drones");
            next = first + count;
        }
        assert_eq!(next as usize, plan.drones.len(), "{name}s do not cover the drones");
    }
    for s in &plan.shards {
        for d in plan.shard_drones(s) {
            assert_eq!(d.shard, s.index);
        }
    }
    for seg in &plan.segments {
        let drones = &plan.drones[seg.first_drone as usize..(seg.first_drone + seg.drone_count) as usize];
        let mut ids = HashSet::new();
        for d in drones {
            assert_eq!(d.segment, seg.index);
            assert!(ids.insert(d.system_id), "system id {} twice in segment {}", d.system_id, seg.index);
        }
    }
}
