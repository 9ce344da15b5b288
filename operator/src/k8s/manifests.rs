//! `sadesim manifests FILE`: the objects the operator would create for a run, as YAML
//! (like `helm template`), for review in GitOps pull requests.
//!
//! Every object of the run's life is printed ([`Stage::ALL`]): the assets Job exists on a
//! cluster only while the asset cache misses; with Kueue, the Workload comes first and the
//! rest only once Kueue admits it.
//! Comment lines at the top of each run's output say what a cluster would do differently
//! (placeholder uid, missing archive, a run the operator refuses).

use std::io::Write;

use sadesim_crds::document::parse_runs;

use super::children::{ClusterSettings, Stage, children, problems, workload};
use super::controller::planning::{ObjectStoreFiles, PlanFailure, plan_blocking};
use sadesim_planner::{DEFAULT_NAMESPACE, PlanError};

/// The uid used when a document has none (documents in Git never do): obviously not a real
/// one, and a valid value for `ownerReferences[].uid`.
pub const PLACEHOLDER_UID: &str = "00000000-0000-0000-0000-000000000000";

/// Writes the manifests of every run in `text` to `out`: for each run, comment lines, then
/// one YAML document per child in apply order. `namespace` overrides the documents'.
///
/// # Errors
/// A message naming the document and field when a document cannot be read or planned
/// (nothing is written then), or when writing fails.
pub fn write_manifests(
    text: &str,
    namespace: Option<&str>,
    settings: &ClusterSettings,
    out: &mut dyn Write,
) -> Result<(), String> {
    let docs = parse_runs(text).map_err(|e| e.to_string())?;
    let mut rendered = String::new();
    let mut errors = Vec::new();
    for (i, doc) in docs.into_iter().enumerate() {
        let mut run = match doc {
            Ok(run) => run,
            Err(e) => {
                errors.push(e.to_string());
                continue;
            }
        };
        if let Some(ns) = namespace {
            run.metadata.namespace = Some(ns.to_string());
        }
        run.metadata.namespace.get_or_insert_with(|| DEFAULT_NAMESPACE.to_string());
        let placeholder = run.metadata.uid.is_none();
        if placeholder {
            run.metadata.uid = Some(PLACEHOLDER_UID.to_string());
        }
        // As the operator plans: a local world file is refused; files in object storage are
        // read here, with this machine's credentials.
        let plan = match plan_blocking(&run, &ObjectStoreFiles) {
            Ok(plan) => plan,
            Err(PlanFailure::Plan(PlanError::Invalid(problems))) => {
                errors.push(format!("document {}: {problems}", i + 1));
                continue;
            }
            Err(e) => {
                errors.push(format!("document {}: {e}", i + 1));
                continue;
            }
        };
        rendered.push_str(&format!(
            "# sadesim manifests: the children of SimulationRun {}/{}, in apply order.\n",
            plan.run.namespace, plan.run.name
        ));
        rendered.push_str("# The assets Job exists only while the asset cache misses.\n");
        if super::children::kueue_queue(&plan, settings).is_some() {
            rendered.push_str(
                "# With Kueue, only the Workload exists until Kueue admits the whole run; then the rest is created.\n",
            );
        }
        if placeholder {
            rendered.push_str(&format!(
                "# ownerReferences[].uid and SADESIM_RUN_UID are the placeholder {PLACEHOLDER_UID}: the document has no metadata.uid; on a cluster the operator uses the run's real uid.\n"
            ));
        }
        for p in problems(&plan, settings) {
            let what = if p.fatal {
                "error (the operator fails this run with Valid=False and creates none of these)"
            } else {
                "warning"
            };
            rendered.push_str(&format!("# {what}: {p}\n"));
        }
        for child in workload(&run, &plan, settings).into_iter().chain(children(&run, &plan, settings, Stage::ALL)) {
            let yaml = serde_yaml::to_string(&child)
                .map_err(|e| format!("failed to write {} {} as YAML: {e}", child.kind(), child.name()))?;
            rendered.push_str("---\n");
            rendered.push_str(&yaml);
        }
    }
    if !errors.is_empty() {
        return Err(errors.join("\n"));
    }
    out.write_all(rendered.as_bytes()).map_err(|e| format!("failed to write the manifests: {e}"))
}

#[cfg(test)]
mod tests;
