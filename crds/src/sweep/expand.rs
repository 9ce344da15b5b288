//! A sweep's runs: the base run with each cell's values set, once per repetition, each a
//! complete `SimulationRun` checked by the run's own validation. A problem is reported
//! against the sweep's field that caused it: the parameter value, or the base.

use std::collections::BTreeMap;

use serde_json::{Value, json};

use super::path::{self, Step};
use super::space::{self, Cell};
use super::{
    CELL_LABEL, MAX_REPETITIONS, MAX_SWEEP_NAME_LEN, MAX_SWEEP_RUNS, REPETITION_LABEL, SWEEP_LABEL, SimulationSweep,
};
use crate::document::{API_VERSION, KIND, to_run};
use crate::run::{SimulationRun, SimulationRunSpec};
use crate::validate::{FieldError, ValidationErrors, is_dns_label, validate};

/// Most problems reported for one sweep (a bad base repeats in every run).
const MAX_PROBLEMS: usize = 50;

/// One run of a sweep.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepRun {
    /// Index into [`Expansion::cells`].
    pub cell: u32,
    /// 0-based.
    pub repetition: u32,
    /// The run, named `<sweep>-c<cell>-r<repetition>` and labelled with the sweep, cell
    /// and repetition.
    pub run: SimulationRun,
}

impl SweepRun {
    /// The run's name.
    pub fn name(&self) -> &str {
        self.run.metadata.name.as_deref().unwrap_or_default()
    }

    /// The run's `spec.seed` (0 when unset).
    pub fn seed(&self) -> u64 {
        self.run.spec.seed.unwrap_or(0)
    }
}

/// Everything a sweep runs.
#[derive(Clone, Debug, PartialEq)]
pub struct Expansion {
    pub cells: Vec<Cell>,
    /// Cell by cell, repetitions in order.
    pub runs: Vec<SweepRun>,
}

/// The name of run `repetition` of cell `cell` of sweep `sweep`.
pub fn run_name(sweep: &str, cell: u32, repetition: u32) -> String {
    format!("{sweep}-c{cell}-r{repetition}")
}

/// Expands `sweep` over `base`, the base run's spec (`spec.base.spec`, or the run read from
/// `spec.base.file` by the caller).
///
/// # Errors
/// Every problem at once, each naming the sweep's field: the sweep's own fields
/// (`spec.parameters[1].field`, `spec.repetitions`), a parameter's value the run would
/// refuse (`spec.parameters[0].values[3]`), or the base (`spec.base.spec.duration`).
pub fn expand(sweep: &SimulationSweep, base: &SimulationRunSpec) -> Result<Expansion, ValidationErrors> {
    let mut problems = Vec::new();
    let name = sweep.metadata.name.clone().unwrap_or_default();
    if name.is_empty() {
        push(&mut problems, "metadata.name", "is required (a DNS label such as `chicago-wind`)".into());
    } else if !is_dns_label(&name, MAX_SWEEP_NAME_LEN) {
        push(
            &mut problems,
            "metadata.name",
            format!(
                "must be a DNS label of at most {MAX_SWEEP_NAME_LEN} characters (its runs are named `<sweep>-c<cell>-r<repetition>`), got {name:?}"
            ),
        );
    }
    let spec = &sweep.spec;
    let given = [spec.base.spec.is_some(), spec.base.file.is_some()].iter().filter(|g| **g).count();
    if given != 1 {
        push(
            &mut problems,
            "spec.base",
            format!("give exactly one of spec (the run inline) and file (a scenario file); got {given}"),
        );
    }
    let repetitions = spec.repetitions();
    if !(1..=MAX_REPETITIONS).contains(&repetitions) {
        push(&mut problems, "spec.repetitions", format!("must be between 1 and {MAX_REPETITIONS}, got {repetitions}"));
    }
    if let Some(p) = spec.parallelism.filter(|p| !(1..=1000).contains(p)) {
        push(&mut problems, "spec.parallelism", format!("must be between 1 and 1000, got {p}"));
    }
    if let Some(q) = spec.queue.as_deref().filter(|q| !is_dns_label(q, 63)) {
        push(&mut problems, "spec.queue", format!("must be a DNS label (a Kueue LocalQueue's name), got {q:?}"));
    }
    if spec.parameters.is_empty() {
        push(
            &mut problems,
            "spec.parameters",
            "is empty: name at least one run field to vary (to repeat one run over seeds, vary `spec.seed`)".into(),
        );
    }
    let mut overrides = Vec::new();
    for (i, o) in spec.overrides.iter().enumerate() {
        match path::parse(&o.field) {
            Ok(_) if o.field == "spec.seed" && repetitions > 1 => {
                push(
                    &mut problems,
                    &format!("spec.overrides[{i}].field"),
                    format!("sets spec.seed, which repetitions also set: use repetitions 1 (got {repetitions})"),
                );
            }
            Ok(steps) => overrides.push((i, steps)),
            Err(e) => push(&mut problems, &format!("spec.overrides[{i}].field"), e),
        }
    }
    let mut fields: Vec<Vec<Step>> = Vec::new();
    let mut names = BTreeMap::new();
    let mut values = Vec::new();
    let sweep_seed = spec.seed.unwrap_or(0);
    for (i, p) in spec.parameters.iter().enumerate() {
        if !is_dns_label(&p.name, 63) {
            push(
                &mut problems,
                &format!("spec.parameters[{i}].name"),
                format!("must be a DNS label such as `wind`, got {:?}", p.name),
            );
        } else if let Some(first) = names.insert(p.name.clone(), i) {
            push(
                &mut problems,
                &format!("spec.parameters[{i}].name"),
                format!("{:?} is already the name of parameters[{first}]", p.name),
            );
        }
        match path::parse(&p.field) {
            Ok(steps) if fields.contains(&steps) => {
                push(
                    &mut problems,
                    &format!("spec.parameters[{i}].field"),
                    format!("{} is varied by another parameter already", p.field),
                );
                fields.push(Vec::new());
            }
            Ok(steps) => fields.push(steps),
            Err(e) => {
                push(&mut problems, &format!("spec.parameters[{i}].field"), e);
                fields.push(Vec::new());
            }
        }
        if p.field == "spec.seed" && repetitions > 1 {
            push(
                &mut problems,
                &format!("spec.parameters[{i}].field"),
                format!(
                    "varies spec.seed, which repetitions also set: use repetitions 1 (got {repetitions}) or drop this parameter"
                ),
            );
        }
        match space::values_of(p, i, sweep_seed) {
            Ok(v) => values.push(v),
            Err(e) => {
                problems.extend(e);
                values.push(Vec::new());
            }
        }
    }
    let cells_count: usize = values.iter().map(Vec::len).product();
    let total = cells_count.saturating_mul(repetitions as usize);
    if total > MAX_SWEEP_RUNS {
        problems.push(FieldError {
            path: "spec.parameters".into(),
            message: format!(
                "{cells_count} cells x {repetitions} repetitions = {total} runs, over the limit of {MAX_SWEEP_RUNS}"
            ),
        });
    }
    if let Some(report) = &spec.report {
        check_report(report, &names, &mut problems);
    }
    if base.criteria.is_empty() {
        let at = if spec.base.file.is_some() { "spec.base.file" } else { "spec.base.spec.criteria" };
        push(
            &mut problems,
            at,
            "the base run has no criteria: a sweep counts the runs that pass theirs, so declare at least one (spec.criteria)"
                .into(),
        );
    }
    if !problems.is_empty() {
        return Err(ValidationErrors(problems));
    }

    let cells = space::cells(spec, &values);
    let namespace = sweep.metadata.namespace.clone();
    let base_json = serde_json::to_value(base).expect("a spec always serializes");
    let base_seed = base.seed.unwrap_or(0);
    let base_doc = json!({ "spec": base_json });
    let mut runs = Vec::with_capacity(total);
    let mut seen = std::collections::BTreeSet::new();
    for cell in &cells {
        for repetition in 0..repetitions {
            let run_name = run_name(&name, cell.index, repetition);
            let mut doc = json!({
                "apiVersion": API_VERSION,
                "kind": KIND,
                "metadata": {
                    "name": run_name,
                    "labels": {
                        SWEEP_LABEL: name,
                        CELL_LABEL: cell.index.to_string(),
                        REPETITION_LABEL: repetition.to_string(),
                    },
                },
                "spec": base_json,
            });
            if let Some(ns) = &namespace {
                doc["metadata"]["namespace"] = json!(ns);
            }
            doc["spec"]["seed"] = json!(base_seed + u64::from(repetition));
            if let Some(q) = &spec.queue {
                doc["spec"]["queue"] = json!(q);
            }
            for (i, steps) in &overrides {
                let o = &spec.overrides[*i];
                if let Err(e) = path::set(&mut doc, steps, o.value.clone()) {
                    note(&mut seen, &mut problems, format!("spec.overrides[{i}].value"), format!("{}: {e}", o.field));
                }
            }
            for (i, ((_, value), steps)) in cell.values.iter().zip(&fields).enumerate() {
                if let Err(e) = path::set(&mut doc, steps, value.clone()) {
                    note(
                        &mut seen,
                        &mut problems,
                        value_path(spec, i, value),
                        format!("{}: {e}", spec.parameters[i].field),
                    );
                }
            }
            let checked =
                to_run(1, doc).map_err(document_problems).and_then(|run| validate(&run).map(|()| run).map_err(|e| e.0));
            match checked {
                Ok(run) => runs.push(SweepRun { cell: cell.index, repetition, run }),
                Err(errors) => {
                    for e in errors {
                        let (path, message) = blame(spec, cell, &fields, &e, &base_doc);
                        note(&mut seen, &mut problems, path, message);
                    }
                }
            }
            if problems.len() >= MAX_PROBLEMS {
                return Err(ValidationErrors(problems));
            }
        }
    }
    if problems.is_empty() { Ok(Expansion { cells, runs }) } else { Err(ValidationErrors(problems)) }
}

fn push(problems: &mut Vec<FieldError>, path: &str, message: String) {
    problems.push(FieldError { path: path.into(), message });
}

fn check_report(report: &super::SweepReportSpec, names: &BTreeMap<String, usize>, problems: &mut Vec<FieldError>) {
    let mut add = |path: &str, message: String| problems.push(FieldError { path: path.into(), message });
    let known = names.keys().cloned().collect::<Vec<_>>().join(", ");
    if let Some(x) = report.x.as_deref().filter(|x| !names.contains_key(*x)) {
        add("spec.report.x", format!("{x:?} is not a parameter's name (parameters: {known})"));
    }
    if let Some(axes) = &report.heat_map {
        if axes.len() != 2 || axes[0] == axes[1] {
            add("spec.report.heatMap", format!("needs two different parameters' names, got {axes:?}"));
        }
        for (k, a) in axes.iter().enumerate().filter(|(_, a)| !names.contains_key(*a)) {
            add(&format!("spec.report.heatMap[{k}]"), format!("{a:?} is not a parameter's name (parameters: {known})"));
        }
    }
    if let Some(c) = report.confidence.filter(|c| !(0.5..1.0).contains(c)) {
        add("spec.report.confidence", format!("must be at least 0.5 and below 1 (e.g. 0.95), got {c}"));
    }
}

/// Records a problem once (the same bad value fails every repetition).
fn note(seen: &mut std::collections::BTreeSet<String>, problems: &mut Vec<FieldError>, path: String, message: String) {
    if seen.insert(format!("{path}\n{message}")) {
        problems.push(FieldError { path, message });
    }
}

/// The sweep field of parameter `i`'s value `value`: `spec.parameters[i].values[k]` for a
/// listed value, else the parameter itself (a range or a random draw).
fn value_path(spec: &super::SimulationSweepSpec, i: usize, value: &Value) -> String {
    let p = &spec.parameters[i];
    match p.values.as_ref().and_then(|vals| vals.iter().position(|v| v == value)) {
        Some(k) => format!("spec.parameters[{i}].values[{k}]"),
        None if p.range.is_some() => format!("spec.parameters[{i}].range"),
        None => format!("spec.parameters[{i}].random"),
    }
}

/// Who is to blame for a problem of an expanded run: the parameter whose field it is in
/// (or under, or on the way to when the base does not have that field: a misspelt name),
/// else the base.
fn blame(
    spec: &super::SimulationSweepSpec,
    cell: &Cell,
    fields: &[Vec<Step>],
    e: &FieldError,
    base: &Value,
) -> (String, String) {
    let under = |a: &str, b: &str| a == b || a.starts_with(&format!("{b}.")) || a.starts_with(&format!("{b}["));
    let not_in_base = || path::parse(&e.path).is_ok_and(|steps| path::get(base, &steps).is_none());
    for (i, steps) in fields.iter().enumerate() {
        let field = &spec.parameters[i].field;
        if !steps.is_empty() && (under(&e.path, field) || (under(field, &e.path) && not_in_base())) {
            let value = &cell.values[i].1;
            return (value_path(spec, i, value), format!("{} = {}: {}: {}", field, value, e.path, e.message));
        }
    }
    for (i, o) in spec.overrides.iter().enumerate() {
        if under(&e.path, &o.field) || (under(&o.field, &e.path) && not_in_base()) {
            return (
                format!("spec.overrides[{i}].value"),
                format!("{} = {}: {}: {}", o.field, o.value, e.path, e.message),
            );
        }
    }
    let path = match e.path.strip_prefix("spec") {
        Some(rest) if rest.starts_with('.') || rest.starts_with('[') => format!("spec.base.spec{rest}"),
        _ if e.path == "metadata.name" => "metadata.name".into(),
        _ => format!("spec.base: {}", e.path),
    };
    (path, e.message.clone())
}

fn document_problems(e: crate::document::DocumentError) -> Vec<FieldError> {
    use crate::document::DocumentError;
    match e {
        DocumentError::Field { path, message, .. } => vec![FieldError { path, message }],
        DocumentError::Fields { problems, .. } => problems.0,
        other => vec![FieldError { path: "spec.base".into(), message: other.to_string() }],
    }
}
