//! What the console's API answers, the same for both backends (docs/console-api.yaml).

use serde::Serialize;
use serde_json::Value;

/// A run as the runs list shows it.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(rename_all = "camelCase")]
pub struct RunView {
    /// Opaque, URL-safe: `<run>.<UTC time>` locally, `<namespace>.<run>` on a cluster.
    pub id: String,
    pub name: String,
    pub namespace: String,
    /// The SimulationRun phases: Pending, Queued, GeneratingAssets, Starting, Running,
    /// Archiving, Succeeded, Failed, Aborted.
    pub phase: String,
    /// Simulated time reached over the run's length, 0..1.
    pub progress: Option<f64>,
    pub sim_time_s: f64,
    pub duration_s: f64,
    pub real_time_factor: Option<f64>,
    /// Position in its Kueue queue (cluster runs waiting for quota).
    pub queue_position: Option<u32>,
    /// `passed` or `failed` once the criteria were judged.
    pub verdict: Option<String>,
    pub message: Option<String>,
    /// RFC 3339.
    pub started_at: String,
    pub drones: u64,
    /// The run's entry in the archive, once it has one.
    pub archive_id: Option<String>,
}

/// A condition of the run (the SimulationRun's status conditions on a cluster).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Condition {
    #[serde(rename = "type")]
    pub kind: String,
    pub status: String,
    pub reason: String,
    pub message: String,
}

/// An event of the run: one line of `events.jsonl`, or a Kubernetes Event on a cluster.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(rename_all = "camelCase")]
pub struct EventLine {
    pub time_s: Option<f64>,
    pub kind: String,
    pub drone: Option<String>,
    pub text: String,
}

/// A criterion and where its judgement stands.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CriterionState {
    /// `spec.criteria[i]: <kind>`.
    pub name: String,
    /// `pending`, `passed` or `failed`.
    pub state: String,
    pub detail: Option<String>,
}

/// An onboard camera's stream.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CameraStream {
    pub drone: String,
    pub camera: String,
    pub url: String,
}

/// A run's page.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(rename_all = "camelCase")]
pub struct RunDetail {
    pub run: RunView,
    pub conditions: Vec<Condition>,
    /// The newest [`MAX_EVENTS`], oldest first.
    pub events: Vec<EventLine>,
    pub criteria: Vec<CriterionState>,
    /// The live 3D view, while the run flies with `rendering.enabled`.
    pub view_url: Option<String>,
    pub cameras: Vec<CameraStream>,
}

/// How many of a run's newest events its page shows.
pub const MAX_EVENTS: usize = 200;

/// A run in the archive.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(rename_all = "camelCase")]
pub struct ArchiveEntry {
    pub id: String,
    /// The run's name.
    pub scenario: String,
    pub namespace: String,
    /// RFC 3339, from the run folder's name or the run's creation.
    pub date: String,
    pub verdict: Option<String>,
    pub drones: u64,
    pub duration_s: Option<f64>,
    /// Its `manifest.json` is there.
    pub complete: bool,
}

/// A file of an archived run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FileEntry {
    pub path: String,
    pub size: u64,
}

/// An archived run's page.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ArchiveDetail {
    #[serde(flatten)]
    pub entry: ArchiveEntry,
    pub files: Vec<FileEntry>,
    pub summary: Option<Value>,
}

/// What `verify` found.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Verification {
    pub ok: bool,
    pub checked: usize,
    pub problems: Vec<String>,
}

/// The criteria of a finished run from its verdict (`summary.json`'s `verdict`), or every
/// criterion of the spec `pending` while it flies.
pub fn criteria_states(spec_criteria: &[Value], verdict: Option<&Value>) -> Vec<CriterionState> {
    let judged = verdict.and_then(|v| v.get("criteria")).and_then(Value::as_array);
    match judged {
        Some(results) => results
            .iter()
            .map(|c| {
                let s = |k: &str| c.get(k).and_then(Value::as_str).unwrap_or_default().to_string();
                let passed = c.get("passed").and_then(Value::as_bool).unwrap_or(false);
                CriterionState {
                    name: format!("{}: {}", s("path"), s("criterion")),
                    state: if passed { "passed" } else { "failed" }.into(),
                    detail: Some(s("summary")),
                }
            })
            .collect(),
        None => spec_criteria
            .iter()
            .enumerate()
            .map(|(i, c)| {
                let kind = c.as_object().and_then(|o| o.keys().next().cloned()).unwrap_or_default();
                CriterionState { name: format!("spec.criteria[{i}]: {kind}"), state: "pending".into(), detail: None }
            })
            .collect(),
    }
}

/// The MJPEG stream of every onboard camera of a run (`plan.json`: each drone's group's
/// `cameras`), served by its live view at `view` (`http://host:port/`).
pub fn camera_streams(plan: &Value, view: &str) -> Vec<CameraStream> {
    let groups = plan.pointer("/spec/fleet").and_then(Value::as_array).cloned().unwrap_or_default();
    let drones = plan.get("drones").and_then(Value::as_array).cloned().unwrap_or_default();
    let base = view.trim_end_matches('/');
    drones
        .iter()
        .flat_map(|d| {
            let drone = d.get("name").and_then(Value::as_str).unwrap_or_default().to_string();
            let group = d.get("group").and_then(Value::as_str).unwrap_or_default();
            let cameras = groups
                .iter()
                .find(|g| g.get("name").and_then(Value::as_str) == Some(group))
                .and_then(|g| g.get("cameras"))
                .and_then(Value::as_array)
                .cloned()
                .unwrap_or_default();
            cameras.into_iter().filter_map(move |c| {
                let camera = c.get("name")?.as_str()?.to_string();
                let url = format!("{base}/cameras/{drone}/{camera}/stream.mjpg");
                Some(CameraStream { drone: drone.clone(), camera, url })
            })
        })
        .collect()
}

/// One `events.jsonl` line for the page: its time, kind, drone name and other fields.
pub fn event_line(line: &str, drone_names: &[String]) -> Option<EventLine> {
    let Value::Object(mut fields) = serde_json::from_str::<Value>(line).ok()? else { return None };
    let time_s = fields.remove("timeS").and_then(|t| t.as_f64());
    let kind = fields.remove("event").and_then(|k| k.as_str().map(String::from)).unwrap_or_default();
    let drone = fields
        .remove("drone")
        .and_then(|d| d.as_u64())
        .map(|i| drone_names.get(i as usize).cloned().unwrap_or_else(|| format!("drone {i}")));
    let text = match fields.is_empty() {
        true => String::new(),
        false => Value::Object(fields).to_string(),
    };
    Some(EventLine { time_s, kind, drone, text })
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn criteria_are_pending_until_the_verdict_then_as_judged() {
        let spec = [json!({"allLanded": {}}), json!({"noCrashes": {}})];
        let pending = criteria_states(&spec, None);
        assert_eq!(pending.len(), 2);
        assert!(pending.iter().all(|c| c.state == "pending"));
        assert_eq!(pending[1].name, "spec.criteria[1]: noCrashes");
        let verdict = json!({"passed": false, "criteria": [
            {"path": "spec.criteria[0]", "criterion": "allLanded", "passed": true, "summary": "4 of 4 landed", "failures": []},
            {"path": "spec.criteria[1]", "criterion": "noCrashes", "passed": false, "summary": "1 crash", "failures": ["x"]}]});
        let judged = criteria_states(&spec, Some(&verdict));
        assert_eq!(judged.iter().map(|c| c.state.as_str()).collect::<Vec<_>>(), ["passed", "failed"]);
        assert_eq!(judged[1].detail.as_deref(), Some("1 crash"));
    }

    #[test]
    fn every_drone_of_a_group_with_cameras_has_their_streams() {
        let plan = json!({
            "spec": {"fleet": [{"name": "scouts", "cameras": [{"name": "down"}, {"name": "front"}]}, {"name": "carriers"}]},
            "drones": [{"name": "scouts-0", "group": "scouts"}, {"name": "carriers-0", "group": "carriers"}],
        });
        let streams = camera_streams(&plan, "http://127.0.0.1:8490/");
        assert_eq!(streams.len(), 2);
        assert_eq!(streams[1].url, "http://127.0.0.1:8490/cameras/scouts-0/front/stream.mjpg");
        assert!(streams.iter().all(|s| s.drone == "scouts-0"));
    }

    #[test]
    fn event_lines_name_their_drone() {
        let names = vec!["scouts-0".to_string()];
        let e = event_line(r#"{"timeS":1.5,"drone":0,"event":"takeoff","altitudeM":2.0}"#, &names).unwrap();
        assert_eq!(e.time_s, Some(1.5));
        assert_eq!(e.kind, "takeoff");
        assert_eq!(e.drone.as_deref(), Some("scouts-0"));
        assert_eq!(e.text, r#"{"altitudeM":2.0}"#);
        assert!(event_line("not json", &names).is_none());
    }
}
