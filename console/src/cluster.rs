//! The cluster backend: SimulationRuns through the Kubernetes API server, every call made
//! **with the user's own identity**, so RBAC and namespaces apply exactly as with kubectl.
//!
//! - In the chart's console pod (`--user-tokens`), each request must carry the user's
//!   bearer token (`Authorization: Bearer ...`, sent by the page). The console builds a
//!   client with the cluster's address and CA and that token only: its own ServiceAccount's
//!   token is never used, so it needs no rights at all. A refusal is the API server's own
//!   (401/403 with its message), passed to the page.
//! - On a user's machine (`sadesim console --cluster`), the kubeconfig's identity is used
//!   (a token in the request, when given, replaces it).
//!
//! Run ids are `<namespace>.<name>`. The archive of a run is read with the console's own
//! object-store credentials, but only for runs the user can `get`.

use std::collections::BTreeMap;
use std::path::PathBuf;

use axum::http::StatusCode;
use axum::response::sse::Event as SseEvent;
use futures_util::StreamExt;
use kube::api::{Api, ListParams, Patch, PatchParams, PostParams};
use kube::config::{AuthInfo, KubeConfigOptions, Kubeconfig};
use kube::runtime::watcher;
use kube::{Client, Config};
use serde_json::{Value, json};

use sadesim_crds::SimulationRun;

use crate::archive::ArchiveBrowser;
use crate::model::{
    ArchiveEntry, Condition, CriterionState, EventLine, MAX_EVENTS, RunDetail, RunView, criteria_states,
};
use crate::server::{ApiError, async_stream};

/// The cluster backend's settings and the cluster's address.
#[derive(Clone)]
pub struct ClusterBackend {
    /// The API server's address and CA, with the kubeconfig's or pod's credentials (used
    /// only when `user_tokens` is false).
    base: Config,
    /// Each request must carry the user's token.
    user_tokens: bool,
    /// The namespaces the page offers, and lists when the request names none. Any other
    /// may be asked for: the API server's RBAC decides, not the console.
    namespaces: Vec<String>,
}

impl std::fmt::Debug for ClusterBackend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ClusterBackend")
            .field("cluster", &self.base.cluster_url)
            .field("user_tokens", &self.user_tokens)
            .field("namespaces", &self.namespaces)
            .finish()
    }
}

fn kube_error(e: kube::Error) -> ApiError {
    match e {
        kube::Error::Api(s) => {
            let status = StatusCode::from_u16(s.code).unwrap_or(StatusCode::BAD_GATEWAY);
            ApiError::new(status, format!("the Kubernetes API server refused: {}", s.message))
        }
        other => ApiError::new(StatusCode::BAD_GATEWAY, format!("the Kubernetes API server: {other}")),
    }
}

/// `<namespace>.<name>` -> (namespace, name).
fn split_id(id: &str) -> Result<(&str, &str), ApiError> {
    id.split_once('.')
        .ok_or_else(|| ApiError::new(StatusCode::NOT_FOUND, format!("no run {id:?}: ids are <namespace>.<name>")))
}

impl ClusterBackend {
    /// The cluster of `kubeconfig` (else the usual inference: `$KUBECONFIG`,
    /// `~/.kube/config`, or in-cluster), offering `namespaces` (default: the config's
    /// default namespace).
    ///
    /// # Errors
    /// No cluster configuration could be read.
    pub async fn new(kubeconfig: Option<PathBuf>, user_tokens: bool, namespaces: Vec<String>) -> Result<Self, String> {
        let base = match kubeconfig {
            Some(path) => {
                let file = Kubeconfig::read_from(&path).map_err(|e| format!("{}: {e}", path.display()))?;
                Config::from_custom_kubeconfig(file, &KubeConfigOptions::default())
                    .await
                    .map_err(|e| format!("{}: {e}", path.display()))?
            }
            None => Config::infer().await.map_err(|e| format!("no Kubernetes configuration: {e}"))?,
        };
        let namespaces = match namespaces.is_empty() {
            true => vec![base.default_namespace.clone()],
            false => namespaces,
        };
        Ok(Self { base, user_tokens, namespaces })
    }

    pub fn needs_token(&self) -> bool {
        self.user_tokens
    }

    pub async fn namespaces(&self, _token: Option<String>) -> Vec<String> {
        self.namespaces.clone()
    }

    /// A client acting as the user: their token, else (not in `user_tokens` mode) the
    /// kubeconfig's identity.
    fn client(&self, token: Option<String>) -> Result<Client, ApiError> {
        let mut config = self.base.clone();
        match (token, self.user_tokens) {
            (Some(token), _) => {
                config.auth_info = serde_json::from_value::<AuthInfo>(json!({"token": token}))
                    .map_err(|e| ApiError::new(StatusCode::BAD_REQUEST, format!("bad token: {e}")))?;
            }
            (None, true) => {
                return Err(ApiError::new(
                    StatusCode::UNAUTHORIZED,
                    "log in with your Kubernetes token: this console acts with your identity (Authorization: Bearer <token>)",
                ));
            }
            (None, false) => {}
        }
        Client::try_from(config).map_err(|e| ApiError::new(StatusCode::BAD_GATEWAY, format!("Kubernetes client: {e}")))
    }

    /// The namespaces a list covers: the one asked for, else those offered.
    fn scope(&self, namespace: Option<String>) -> Vec<String> {
        match namespace.filter(|n| !n.is_empty()) {
            Some(n) => vec![n],
            None => self.namespaces.clone(),
        }
    }

    /// The runs of every offered namespace the user can list. A refusal in every
    /// namespace is returned as the API server's error.
    pub async fn list(&self, token: Option<String>, namespace: Option<String>) -> Result<Vec<RunView>, ApiError> {
        let client = self.client(token)?;
        let mut views = Vec::new();
        let mut refused = None;
        for ns in &self.scope(namespace) {
            match Api::<SimulationRun>::namespaced(client.clone(), ns).list(&ListParams::default()).await {
                Ok(list) => views.extend(list.items.iter().map(view)),
                Err(e) => refused = Some(kube_error(e)),
            }
        }
        match (views.is_empty(), refused) {
            (true, Some(e)) => Err(e),
            _ => {
                views.sort_by(|a, b| b.started_at.cmp(&a.started_at).then_with(|| a.id.cmp(&b.id)));
                Ok(views)
            }
        }
    }

    /// Creates the SimulationRun in `namespace` (default: the first offered), with
    /// `spec.queue` when given.
    pub async fn create(
        &self,
        token: Option<String>,
        mut run: SimulationRun,
        namespace: Option<String>,
        queue: Option<String>,
    ) -> Result<RunView, ApiError> {
        let namespace = namespace.filter(|n| !n.is_empty()).unwrap_or_else(|| self.namespaces[0].clone());
        run.metadata.namespace = Some(namespace.clone());
        if let Some(q) = queue.filter(|q| !q.is_empty()) {
            run.spec.queue = Some(q);
        }
        let created = Api::<SimulationRun>::namespaced(self.client(token)?, &namespace)
            .create(&PostParams::default(), &run)
            .await
            .map_err(kube_error)?;
        Ok(view(&created))
    }

    async fn get(&self, client: &Client, id: &str) -> Result<SimulationRun, ApiError> {
        let (ns, name) = split_id(id)?;
        Api::<SimulationRun>::namespaced(client.clone(), ns).get(name).await.map_err(kube_error)
    }

    /// A run's page: status conditions, its Kubernetes Events, criteria.
    pub async fn detail(&self, token: Option<String>, id: &str) -> Result<RunDetail, ApiError> {
        let client = self.client(token)?;
        let run = self.get(&client, id).await?;
        Ok(self.detail_of(&client, &run).await)
    }

    async fn detail_of(&self, client: &Client, run: &SimulationRun) -> RunDetail {
        let status = run.status.clone().unwrap_or_default();
        let conditions = status
            .conditions
            .iter()
            .map(|c| Condition {
                kind: c.type_.clone(),
                status: c.status.clone(),
                reason: c.reason.clone(),
                message: c.message.clone(),
            })
            .collect();
        let ns = run.metadata.namespace.clone().unwrap_or_default();
        let name = run.metadata.name.clone().unwrap_or_default();
        let selector = format!("involvedObject.kind=SimulationRun,involvedObject.name={name}");
        let events = Api::<k8s_openapi::api::core::v1::Event>::namespaced(client.clone(), &ns)
            .list(&ListParams::default().fields(&selector))
            .await
            .map(|l| {
                let mut lines: Vec<EventLine> = l
                    .items
                    .iter()
                    .map(|e| EventLine {
                        time_s: None,
                        kind: e.reason.clone().unwrap_or_default(),
                        drone: None,
                        text: e.message.clone().unwrap_or_default(),
                    })
                    .collect();
                let start = lines.len().saturating_sub(MAX_EVENTS);
                lines.drain(..start);
                lines
            })
            .unwrap_or_default();
        let spec_criteria: Vec<Value> =
            serde_json::to_value(&run.spec.criteria).ok().and_then(|v| v.as_array().cloned()).unwrap_or_default();
        // Each criterion's judgement is in the archived summary.json; the status holds the
        // run's verdict only.
        let archived = match (&status.verdict, &status.archive) {
            (Some(_), Some(a)) => match split_archive_url(&a.url) {
                Some((root, folder)) => tokio::task::spawn_blocking(move || {
                    let bytes =
                        ArchiveBrowser::new(&root).file(&folder, sadesim_crds::outcome::run_folder::SUMMARY).ok()?;
                    serde_json::from_slice::<Value>(&bytes).ok()?.get("verdict").cloned()
                })
                .await
                .ok()
                .flatten(),
                None => None,
            },
            _ => None,
        };
        let criteria = match (&status.verdict, archived) {
            (_, Some(verdict)) => criteria_states(&spec_criteria, Some(&verdict)),
            (None, None) => criteria_states(&spec_criteria, None),
            (Some(v), None) => vec![CriterionState {
                name: format!("all {} criteria", spec_criteria.len()),
                state: if v.passed { "passed" } else { "failed" }.into(),
                detail: Some(v.failures.join("; ")).filter(|f| !f.is_empty()),
            }],
        };
        // A cluster run's live view and cameras are not proxied by the console (yet): the
        // page says how to reach them (`kubectl port-forward`), rather than a broken frame.
        let (view_url, cameras) = (None, Vec::new());
        RunDetail { run: view(run), conditions, events, criteria, view_url, cameras }
    }

    /// A cluster run's live view through the console: not supported yet (501, saying how to
    /// reach it with kubectl).
    pub async fn live_view(
        &self,
        token: Option<String>,
        id: &str,
        _rest: &str,
    ) -> Result<axum::response::Response, ApiError> {
        let client = self.client(token)?;
        let run = self.get(&client, id).await?;
        let name = run.metadata.name.unwrap_or_default();
        let ns = run.metadata.namespace.unwrap_or_default();
        Err(ApiError::new(
            StatusCode::NOT_IMPLEMENTED,
            format!(
                "not supported: the console does not proxy a cluster run's live view yet; reach it with `kubectl -n {ns} port-forward svc/{name}-renderer 8490` and http://127.0.0.1:8490/"
            ),
        ))
    }

    /// Sets `spec.abort` (the run stops: pilot, shards, then the archive is written).
    pub async fn stop(&self, token: Option<String>, id: &str) -> Result<RunView, ApiError> {
        let (ns, name) = split_id(id)?;
        let patched = Api::<SimulationRun>::namespaced(self.client(token)?, ns)
            .patch(name, &PatchParams::default(), &Patch::Merge(json!({"spec": {"abort": true}})))
            .await
            .map_err(kube_error)?;
        Ok(view(&patched))
    }

    /// The runs list as a stream: a watch per namespace (the API server pushes changes),
    /// the whole list sent at each one.
    pub async fn watch(
        &self,
        token: Option<String>,
        namespace: Option<String>,
    ) -> Result<crate::server_stream::EventStream, ApiError> {
        let client = self.client(token)?;
        let scope = self.scope(namespace);
        // The first list answers refusals at once, as an HTTP error rather than a stream.
        list_check(&client, &scope).await?;
        let apis: Vec<Api<SimulationRun>> =
            scope.iter().map(|ns| Api::<SimulationRun>::namespaced(client.clone(), ns)).collect();
        Ok(Box::pin(async_stream(move |tx| async move {
            let streams = apis.into_iter().map(|api| watcher(api, watcher::Config::default()).boxed());
            let mut merged = futures_util::stream::select_all(streams);
            let mut runs: BTreeMap<String, RunView> = BTreeMap::new();
            while let Some(event) = merged.next().await {
                let changed = match event {
                    Ok(watcher::Event::Apply(r) | watcher::Event::InitApply(r)) => {
                        let v = view(&r);
                        runs.insert(v.id.clone(), v);
                        true
                    }
                    Ok(watcher::Event::Delete(r)) => runs.remove(&view(&r).id).is_some(),
                    Ok(watcher::Event::Init) => false,
                    Ok(watcher::Event::InitDone) => true,
                    Err(e) => {
                        let data = json!({"error": e.to_string()}).to_string();
                        if tx.send(SseEvent::default().event("error").data(data)).await.is_err() {
                            break;
                        }
                        false
                    }
                };
                if changed {
                    let mut list: Vec<&RunView> = runs.values().collect();
                    list.sort_by(|a, b| b.started_at.cmp(&a.started_at).then_with(|| a.id.cmp(&b.id)));
                    let data = json!({"runs": list}).to_string();
                    if tx.send(SseEvent::default().event("runs").data(data)).await.is_err() {
                        break;
                    }
                }
            }
        })))
    }

    /// One run's page as a stream: a watch on that object, the page sent at each change.
    pub async fn watch_one(
        &self,
        token: Option<String>,
        id: &str,
    ) -> Result<crate::server_stream::EventStream, ApiError> {
        let client = self.client(token)?;
        self.get(&client, id).await?;
        let (ns, name) = split_id(id)?;
        let api = Api::<SimulationRun>::namespaced(client.clone(), ns);
        let config = watcher::Config::default().fields(&format!("metadata.name={name}"));
        let this = self.clone();
        Ok(Box::pin(async_stream(move |tx| async move {
            let mut events = watcher(api, config).boxed();
            while let Some(event) = events.next().await {
                if let Ok(watcher::Event::Apply(r) | watcher::Event::InitApply(r)) = event {
                    let detail = this.detail_of(&client, &r).await;
                    let data = serde_json::to_string(&detail).expect("JSON");
                    if tx.send(SseEvent::default().event("run").data(data)).await.is_err() {
                        break;
                    }
                }
            }
        })))
    }

    /// The archived runs among those the user can list.
    pub async fn archive_list(
        &self,
        token: Option<String>,
        namespace: Option<String>,
    ) -> Result<Vec<ArchiveEntry>, ApiError> {
        let client = self.client(token)?;
        let mut entries = Vec::new();
        for ns in &self.scope(namespace) {
            let list = Api::<SimulationRun>::namespaced(client.clone(), ns)
                .list(&ListParams::default())
                .await
                .map_err(kube_error)?;
            entries.extend(list.items.iter().filter_map(archive_entry));
        }
        entries.sort_by(|a, b| b.date.cmp(&a.date));
        Ok(entries)
    }

    /// The archive holding run `id` and the run's folder id in it, once the user may `get`
    /// the run.
    pub async fn archive_of(&self, token: Option<String>, id: &str) -> Result<(ArchiveBrowser, String), ApiError> {
        let client = self.client(token)?;
        let run = self.get(&client, id).await?;
        let url = run
            .status
            .and_then(|s| s.archive)
            .map(|a| a.url)
            .ok_or_else(|| ApiError::new(StatusCode::NOT_FOUND, format!("run {id} has no archive yet")))?;
        let (root, folder) = split_archive_url(&url).ok_or_else(|| {
            ApiError::new(
                StatusCode::BAD_GATEWAY,
                format!("run {id}: archive URL {url} is not <archive>/<namespace>/<run>/<uid>"),
            )
        })?;
        Ok((ArchiveBrowser::new(&root), folder))
    }
}

/// `<archive>/<namespace>/<run>/<uid>/` -> the archive's root and the run's entry id in it.
fn split_archive_url(url: &str) -> Option<(String, String)> {
    let parts: Vec<&str> = url.trim_end_matches('/').rsplitn(4, '/').collect();
    match parts.as_slice() {
        [uid, run, ns, root]
            if root.contains("://") && !root.ends_with(':') && ![uid, run, ns].iter().any(|s| s.is_empty()) =>
        {
            Some((root.to_string(), format!("{ns}.{run}.{uid}")))
        }
        _ => None,
    }
}

/// Answers a refusal to list in any of `scope` as the API server's error.
async fn list_check(client: &Client, scope: &[String]) -> Result<(), ApiError> {
    for ns in scope {
        Api::<SimulationRun>::namespaced(client.clone(), ns)
            .list(&ListParams::default().limit(1))
            .await
            .map_err(kube_error)?;
    }
    Ok(())
}

/// The runs list's row of a SimulationRun.
fn view(run: &SimulationRun) -> RunView {
    let status = run.status.clone().unwrap_or_default();
    let ns = run.metadata.namespace.clone().unwrap_or_default();
    let name = run.metadata.name.clone().unwrap_or_default();
    let duration_s = run.spec.duration_s();
    let sim = status.sim_time_s.unwrap_or(0.0);
    let phase = status.phase.and_then(|p| serde_json::to_value(p).ok().and_then(|v| v.as_str().map(String::from)));
    let over = phase.as_deref().is_some_and(crate::local::is_over);
    RunView {
        id: format!("{ns}.{name}"),
        name: name.clone(),
        namespace: ns.clone(),
        phase: phase.unwrap_or_else(|| "Pending".into()),
        progress: Some(if over { 1.0 } else { (sim / duration_s.max(1e-9)).clamp(0.0, 1.0) }),
        sim_time_s: sim,
        duration_s,
        real_time_factor: status.real_time_factor,
        queue_position: status
            .kueue
            .as_ref()
            .and_then(|k| k.position_in_local_queue.or(k.position_in_cluster_queue))
            .and_then(|p| u32::try_from(p).ok()),
        verdict: status.verdict.as_ref().map(|v| crate::local::verdict_word(v.passed)),
        message: status.message.clone(),
        started_at: run.metadata.creation_timestamp.as_ref().map(|t| t.0.to_string()).unwrap_or_default(),
        drones: status.drones.map(u64::from).unwrap_or_else(|| run.spec.total_drones()),
        archive_id: status.archive.as_ref().map(|_| format!("{ns}.{name}")),
    }
}

fn archive_entry(run: &SimulationRun) -> Option<ArchiveEntry> {
    let status = run.status.as_ref()?;
    let archive = status.archive.as_ref()?;
    let v = view(run);
    Some(ArchiveEntry {
        id: v.id,
        scenario: v.name,
        namespace: v.namespace,
        date: status.completion_time.as_ref().map(|t| t.0.to_string()).unwrap_or(v.started_at),
        verdict: v.verdict,
        drones: v.drones,
        duration_s: status.sim_time_s,
        complete: archive.files.is_some(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use sadesim_crds::status::{ArchiveStatus, KueueStatus, Phase, SimulationRunStatus, Verdict};

    fn run(status: Option<SimulationRunStatus>) -> SimulationRun {
        let mut r = sadesim_crds::fixtures::RunBuilder::test().build();
        r.metadata.name = Some("chicago".into());
        r.metadata.namespace = Some("team-a".into());
        r.status = status;
        r
    }

    #[test]
    fn a_new_run_is_pending_with_its_spec_s_drones() {
        let v = view(&run(None));
        assert_eq!((v.id.as_str(), v.phase.as_str()), ("team-a.chicago", "Pending"));
        assert_eq!(v.drones, run(None).spec.total_drones());
        assert_eq!(v.progress, Some(0.0));
        assert_eq!((v.verdict, v.archive_id, v.queue_position), (None, None, None));
    }

    #[test]
    fn status_fields_reach_the_row() {
        let status = SimulationRunStatus {
            phase: Some(Phase::Queued),
            kueue: Some(KueueStatus { position_in_local_queue: Some(3), ..Default::default() }),
            ..Default::default()
        };
        assert_eq!(view(&run(Some(status))).queue_position, Some(3));
        let done = SimulationRunStatus {
            phase: Some(Phase::Failed),
            sim_time_s: Some(12.0),
            drones: Some(7),
            verdict: Some(Verdict {
                passed: false,
                failures: vec!["noCrashes".into()],
                unauthorized_entries: None,
                crashes: Some(1),
            }),
            archive: Some(ArchiveStatus { url: "s3://b/team-a/chicago/u1/".into(), files: Some(20), bytes: None }),
            ..Default::default()
        };
        let v = view(&run(Some(done)));
        assert_eq!((v.phase.as_str(), v.progress, v.drones), ("Failed", Some(1.0), 7));
        assert_eq!(v.verdict.as_deref(), Some("failed"));
        assert_eq!(v.archive_id.as_deref(), Some("team-a.chicago"));
    }

    #[test]
    fn an_archive_url_splits_into_its_root_and_the_run_s_folder() {
        assert_eq!(
            split_archive_url("s3://runs/prefix/team-a/chicago/0f3a-11/"),
            Some(("s3://runs/prefix".into(), "team-a.chicago.0f3a-11".into()))
        );
        assert_eq!(
            split_archive_url("s3://runs/team-a/chicago/u"),
            Some(("s3://runs".into(), "team-a.chicago.u".into()))
        );
        assert_eq!(split_archive_url("s3://team-a/chicago/u"), None);
        assert_eq!(split_archive_url("chicago/u"), None);
    }
}
