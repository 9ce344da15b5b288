//! The sweep's expansion: names, seeds, values set where the parameters say, and every
//! problem reported against the sweep field that caused it.

use serde_json::json;

use super::*;
use crate::fixtures::RunBuilder;

/// A base run with one criterion and wind, and a sweep over `parameters` (YAML list).
fn sweep(parameters: &str, extra: &str) -> (SimulationSweep, SimulationRunSpec) {
    let base = RunBuilder::test()
        .with(|r| {
            r.spec.criteria = serde_json::from_value(json!([{"noCrashes": {}}])).unwrap();
            r.spec.environment =
                Some(serde_json::from_value(json!({"wind": {"speedMps": 2, "directionFromDeg": 270}})).unwrap());
            r.spec.seed = Some(40);
        })
        .build()
        .spec;
    let text = format!(
        "apiVersion: sadesim.io/v1alpha1\nkind: SimulationSweep\nmetadata: {{name: gusty, namespace: team-a}}\nspec:\n  base: {{file: base.yaml}}\n  parameters:\n{parameters}\n{extra}"
    );
    (parse_sweep(&text).unwrap(), base)
}

fn problems(s: &SimulationSweep, base: &SimulationRunSpec) -> Vec<String> {
    expand(s, base).unwrap_err().0.iter().map(ToString::to_string).collect()
}

#[test]
fn every_cell_runs_every_repetition_with_its_values_and_seed() {
    let (s, base) = sweep(
        "    - {name: wind, field: spec.environment.wind.speedMps, values: [0, 6]}\n    - {name: drones, field: 'spec.fleet[0].count', range: {from: 1, to: 3, step: 1}}",
        "  repetitions: 2\n  queue: team-a-queue",
    );
    let e = expand(&s, &base).unwrap();
    assert_eq!(e.cells.len(), 6);
    assert_eq!(e.runs.len(), 12);
    assert_eq!(e.cells[4].label(), "wind=6, drones=2", "the last parameter varies fastest");
    let run = &e.runs[9]; // cell 4, repetition 1
    assert_eq!((run.cell, run.repetition, run.name()), (4, 1, "gusty-c4-r1"));
    assert_eq!(run.seed(), 41, "repetition r runs with the base seed + r");
    assert_eq!(run.run.spec.fleet[0].count, 2);
    assert_eq!(run.run.spec.environment.as_ref().unwrap().wind.as_ref().unwrap().speed_mps, 6.0);
    assert_eq!(run.run.spec.queue.as_deref(), Some("team-a-queue"));
    assert_eq!(run.run.metadata.namespace.as_deref(), Some("team-a"));
    let labels = run.run.metadata.labels.clone().unwrap();
    assert_eq!(labels[SWEEP_LABEL], "gusty");
    assert_eq!(labels[CELL_LABEL], "4");
    assert_eq!(labels[REPETITION_LABEL], "1");
    assert_eq!(e.runs[0].seed(), 40);
    assert_eq!(expand(&s, &base).unwrap(), e, "the same sweep expands to the same runs");
}

#[test]
fn a_value_the_run_refuses_is_reported_against_the_parameter() {
    let (s, base) = sweep("    - {name: wind, field: spec.environment.wind.speedMps, values: [3, -5, 500]}", "");
    let p = problems(&s, &base);
    assert_eq!(p.len(), 2, "{p:?}");
    assert!(p[0].starts_with("spec.parameters[0].values[1]: spec.environment.wind.speedMps = -5"), "{p:?}");
    assert!(p[1].starts_with("spec.parameters[0].values[2]: spec.environment.wind.speedMps = 500"), "{p:?}");
}

#[test]
fn a_field_that_does_not_exist_is_named() {
    let (s, base) = sweep("    - {name: wind, field: spec.environment.wnd.speedMps, values: [3]}", "");
    let p = problems(&s, &base);
    assert!(p[0].starts_with("spec.parameters[0].values[0]: spec.environment.wnd.speedMps = 3"), "{p:?}");
    assert!(p[0].contains("unknown field `wnd`"), "{p:?}");
    let (s, base) = sweep("    - {name: n, field: 'spec.fleet[7].count', values: [3]}", "");
    assert_eq!(
        problems(&s, &base),
        ["spec.parameters[0].values[0]: spec.fleet[7].count: spec.fleet has 1 item(s), so there is no [7]"]
    );
    let (s, base) = sweep("    - {name: n, field: metadata.name, values: [x]}", "");
    assert!(
        problems(&s, &base)[0]
            .starts_with("spec.parameters[0].field: \"metadata.name\" must name a field of the run's spec")
    );
}

#[test]
fn the_sweeps_own_fields_are_checked_all_at_once() {
    let (s, base) = sweep(
        "    - {name: Wind, field: spec.seed, values: []}\n    - {name: w2, field: spec.seed, range: {from: 1, to: 0, step: 1}}",
        "  repetitions: 3\n  parallelism: 0\n  report: {x: speed, confidence: 2}",
    );
    let p = problems(&s, &base);
    for expected in [
        "spec.parallelism: must be between 1 and 1000, got 0",
        "spec.parameters[0].name: must be a DNS label",
        "spec.parameters[0].field: varies spec.seed, which repetitions also set",
        "spec.parameters[0].values: is empty",
        "spec.parameters[1].field: spec.seed is varied by another parameter already",
        "spec.parameters[1].range: needs finite from <= to and step > 0",
        "spec.report.x: \"speed\" is not a parameter's name",
        "spec.report.confidence: must be at least 0.5",
    ] {
        assert!(p.iter().any(|l| l.starts_with(expected)), "missing {expected:?} in {p:#?}");
    }
}

#[test]
fn an_empty_space_and_a_base_without_criteria_are_refused() {
    let (s, base) = sweep("    []", "");
    assert!(problems(&s, &base)[0].starts_with("spec.parameters: is empty"));
    let (s, mut base) = sweep("    - {name: wind, field: spec.environment.wind.speedMps, values: [3]}", "");
    base.criteria.clear();
    assert!(problems(&s, &base)[0].starts_with("spec.base.file: the base run has no criteria"));
}

#[test]
fn a_problem_of_the_base_is_reported_once_against_the_base() {
    let (s, mut base) =
        sweep("    - {name: wind, field: spec.environment.wind.speedMps, values: [1, 2, 3]}", "  repetitions: 4");
    base.physics_rate_hz = Some(5);
    assert_eq!(problems(&s, &base), ["spec.base.spec.physicsRateHz: must be between 50 and 10000, got 5"]);
}

#[test]
fn long_names_and_oversized_sweeps_are_refused() {
    let (mut s, base) =
        sweep("    - {name: n, field: spec.seed, range: {from: 0, to: 999, step: 1}}", "  repetitions: 11");
    s.metadata.name = Some("a-name-that-is-far-too-long-for-runs".into());
    let p = problems(&s, &base);
    assert!(p.iter().any(|l| l.starts_with("metadata.name: must be a DNS label of at most 28")), "{p:?}");
    assert!(p.iter().any(|l| l.contains("1000 cells x 11 repetitions = 11000 runs")), "{p:?}");
}

#[test]
fn list_values_set_whole_fields() {
    let (s, base) = sweep("    - {name: pilot, field: spec.pilot.command, values: [[a, '1'], [b]]}", "");
    let mut base = base;
    base.pilot = Some(serde_json::from_value(json!({"command": ["x"]})).unwrap());
    let e = expand(&s, &base).unwrap();
    assert_eq!(e.runs[0].run.spec.pilot.as_ref().unwrap().command, ["a", "1"]);
    assert_eq!(e.cells[1].label(), "pilot=[\"b\"]");
}

#[test]
fn overrides_set_every_run_and_name_themselves_when_refused() {
    let (s, base) = sweep(
        "    - {name: wind, field: spec.environment.wind.speedMps, values: [1, 2]}",
        "  overrides:\n    - {field: spec.clock, value: {mode: asFastAsPossible}}\n    - {field: spec.duration, value: 90s}",
    );
    let e = expand(&s, &base).unwrap();
    for r in &e.runs {
        assert_eq!(r.run.spec.clock.as_ref().unwrap().mode, crate::run::ClockMode::AsFastAsPossible);
        assert_eq!(crate::validate::duration_s(&r.run.spec.duration), 90.0);
    }
    let (s, base) = sweep(
        "    - {name: wind, field: spec.environment.wind.speedMps, values: [1]}",
        "  overrides:\n    - {field: spec.physicsRateHz, value: 3}",
    );
    let p = problems(&s, &base);
    assert!(
        p[0].starts_with("spec.overrides[0].value: spec.physicsRateHz = 3: spec.physicsRateHz: must be between 50"),
        "{p:?}"
    );
}

#[test]
fn deeply_nested_sweep_files_are_refused_by_the_nesting_limit_not_parsed() {
    // 200 000 brackets took the YAML parser minutes before the limit was checked first.
    let deep = format!("kind: SimulationSweep\nspec: {}{}\n", "[".repeat(200_000), "]".repeat(200_000));
    assert_eq!(document::first_kind(&deep), None);
    let e = document::parse_sweep(&deep).unwrap_err().to_string();
    assert!(e.contains("recursion limit"), "{e}");
}
