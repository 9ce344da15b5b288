//! The console's HTTP server: the page, MapLibre, and the API of docs/console-api.yaml over
//! either backend.
//!
//! | path | what |
//! |---|---|
//! | `/`, `/<file>` | the page (`console/web/`, embedded; `--web-dir` reads it from disk) |
//! | `/vendor/maplibre/...` | MapLibre GL JS from npm, embedded at build time |
//! | `/api/info` | which backend, namespaces, whether a token is needed |
//! | `/api/scenario/{parse,validate,yaml}` | the plan page's document work |
//! | `/api/world` | the world's map layers |
//! | `/api/runs`, `/api/runs/watch` | the runs list, and its Server-Sent Events stream |
//! | `/api/runs/<id>`, `/api/runs/<id>/watch`, `/api/runs/<id>/stop` | one run |
//! | `/api/archive`, `/api/archive/<id>`, `.../files/<path>`, `.../verify` | the archive |
//! | `/replay/<id>/` | the 3D replay of an archived run |
//! | `/healthz` | `ok` |

use std::collections::HashMap;
use std::convert::Infallible;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use axum::Router;
use axum::body::Body;
use axum::extract::{Path, Query, Request, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::sse::{Event as SseEvent, KeepAlive, Sse};
use axum::response::{IntoResponse, Redirect, Response};
use axum::routing::{get, post};
use futures_util::stream::{self, Stream};
use serde::Deserialize;
use serde_json::{Value, json};
use tower::ServiceExt;

use crate::archive::{ArchiveBrowser, BrowseError};
use crate::cluster::ClusterBackend;
use crate::local::LocalBackend;
use crate::scenario::{self, Problem};

mod files {
    include!(concat!(env!("OUT_DIR"), "/console_files.rs"));
}

pub use files::MAPLIBRE_VERSION;

/// Whether this build carries MapLibre GL JS (see `build.rs`).
pub fn has_maplibre() -> bool {
    cfg!(sadesim_maplibre)
}

/// The "not supported" text for a build without MapLibre.
pub const NO_MAPLIBRE: &str = "this build has no MapLibre GL JS for the console's map (npm was not available when sadesim-console was built): run `npm ci --prefix console/web` and rebuild";

/// Who the console acts for.
#[derive(Debug, Clone)]
pub enum Backend {
    /// This machine: the local runner and a runs folder.
    Local(Arc<LocalBackend>),
    /// A cluster, with each user's own Kubernetes identity.
    Cluster(Arc<ClusterBackend>),
}

/// The last world's map layers, by its asset cache key.
type WorldLayers = (String, Arc<Value>);

/// Everything the handlers share.
#[derive(Debug, Clone)]
pub struct Console {
    pub backend: Backend,
    /// Serve the page from this folder instead of the embedded copy (developing the page).
    pub web_dir: Option<PathBuf>,
    worlds: Arc<Mutex<Option<WorldLayers>>>,
    replays: Arc<Mutex<HashMap<String, Router>>>,
}

impl Console {
    pub fn new(backend: Backend, web_dir: Option<PathBuf>) -> Self {
        Self { backend, web_dir, worlds: Arc::default(), replays: Arc::default() }
    }

    /// The folder relative paths in scenarios are resolved against.
    fn scenario_dir(&self) -> PathBuf {
        match &self.backend {
            Backend::Local(l) => l.scenario_dir.clone(),
            Backend::Cluster(_) => std::env::current_dir().unwrap_or_default(),
        }
    }
}

/// An API error: a status and `{"error": ...}` (or `{"errors": [...]}` for validation).
#[derive(Debug)]
pub struct ApiError {
    pub status: StatusCode,
    pub body: Value,
}

impl ApiError {
    pub fn new(status: StatusCode, message: impl Into<String>) -> Self {
        Self { status, body: json!({"error": message.into()}) }
    }

    fn invalid(problems: Vec<Problem>) -> Self {
        Self { status: StatusCode::UNPROCESSABLE_ENTITY, body: json!({"errors": problems}) }
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        (self.status, axum::Json(self.body)).into_response()
    }
}

impl From<BrowseError> for ApiError {
    fn from(e: BrowseError) -> Self {
        match e {
            BrowseError::NotFound(m) => Self::new(StatusCode::NOT_FOUND, m),
            BrowseError::Failed(m) => Self::new(StatusCode::BAD_GATEWAY, m),
        }
    }
}

type ApiResult = Result<Response, ApiError>;

/// Runs blocking work (files, worlds, object stores) off the server's thread.
async fn blocking<T: Send + 'static>(f: impl FnOnce() -> T + Send + 'static) -> Result<T, ApiError> {
    tokio::task::spawn_blocking(f)
        .await
        .map_err(|e| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, format!("the request's work failed: {e}")))
}

/// The cookie the page sets with the user's token, for what the browser fetches by itself
/// (the report, downloads, the replay and live view frames) where it sends no header.
pub const TOKEN_COOKIE: &str = "sadesim_token";

/// The user's bearer token: the `Authorization: Bearer` header, else the
/// [`TOKEN_COOKIE`].
pub fn bearer(headers: &HeaderMap) -> Option<String> {
    let from_header = headers
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.strip_prefix("Bearer ").or_else(|| v.strip_prefix("bearer ")))
        .map(str::trim);
    let from_cookie = || {
        headers
            .get_all(header::COOKIE)
            .iter()
            .filter_map(|v| v.to_str().ok())
            .flat_map(|v| v.split(';'))
            .filter_map(|kv| kv.trim().split_once('='))
            .find(|(k, _)| *k == TOKEN_COOKIE)
            .map(|(_, v)| v.trim())
    };
    from_header.or_else(from_cookie).filter(|t| !t.is_empty()).map(String::from)
}

/// The console's routes.
pub fn router(console: Console) -> Router {
    Router::new()
        .route("/", get(|State(c): State<Console>| async move { page_file(&c, "index.html") }))
        .route("/{file}", get(|State(c): State<Console>, Path(file): Path<String>| async move { page_file(&c, &file) }))
        .route("/vendor/maplibre/{file}", get(vendor))
        .route("/healthz", get(|| async { "ok" }))
        .route("/api/info", get(info))
        .route("/api/scenario/parse", post(parse))
        .route("/api/scenario/validate", post(validate))
        .route("/api/scenario/yaml", post(to_yaml))
        .route("/api/world", post(world))
        .route("/api/runs", get(runs).post(launch))
        .route("/api/runs/watch", get(watch_runs))
        .route("/api/runs/{id}", get(run))
        .route("/api/runs/{id}/watch", get(watch_run))
        .route("/api/runs/{id}/stop", post(stop))
        .route(
            "/api/runs/{id}/view/",
            get(|state, headers, Path(id): Path<String>| live_view(state, headers, Path((id, String::new())))),
        )
        .route("/api/runs/{id}/view/{*rest}", get(live_view))
        .route("/api/archive", get(archive_list))
        .route("/api/archive/{id}", get(archive_entry))
        .route("/api/archive/{id}/files/{*path}", get(archive_file))
        .route("/api/archive/{id}/verify", post(archive_verify))
        .route(
            "/replay/{id}",
            get(|Path(id): Path<String>| async move { Redirect::permanent(&format!("/replay/{id}/")) }),
        )
        .route("/replay/{id}/", get(replay))
        .route("/replay/{id}/{*rest}", get(replay))
        .with_state(console)
}

fn content_type(name: &str) -> &'static str {
    match name.rsplit('.').next().unwrap_or_default() {
        "html" => "text/html; charset=utf-8",
        "js" => "text/javascript; charset=utf-8",
        "css" => "text/css; charset=utf-8",
        "svg" => "image/svg+xml",
        "png" => "image/png",
        "json" => "application/json",
        "jsonl" | "csv" | "log" | "txt" => "text/plain; charset=utf-8",
        "geojson" => "application/geo+json",
        _ => "application/octet-stream",
    }
}

fn page_file(c: &Console, name: &str) -> Response {
    let bytes = match &c.web_dir {
        Some(dir) if !name.contains('/') && !name.starts_with('.') => std::fs::read(dir.join(name)).ok(),
        Some(_) => None,
        None => files::PAGE_FILES.iter().find(|(n, _)| *n == name).map(|(_, b)| b.to_vec()),
    };
    match bytes {
        Some(b) => {
            ([(header::CONTENT_TYPE, content_type(name)), (header::CACHE_CONTROL, "no-cache")], b).into_response()
        }
        None => (StatusCode::NOT_FOUND, format!("no /{name}")).into_response(),
    }
}

async fn vendor(Path(file): Path<String>) -> Response {
    match files::MAPLIBRE_FILES.iter().find(|(n, _)| *n == file) {
        Some((n, b)) => {
            ([(header::CONTENT_TYPE, content_type(n)), (header::CACHE_CONTROL, "max-age=86400")], *b).into_response()
        }
        None => (StatusCode::NOT_FOUND, format!("no /vendor/maplibre/{file} in this build")).into_response(),
    }
}

async fn info(State(c): State<Console>, headers: HeaderMap) -> ApiResult {
    let body = match &c.backend {
        Backend::Local(l) => json!({
            "backend": "local",
            "version": env!("CARGO_PKG_VERSION"),
            "namespaces": null,
            "needsToken": false,
            "archive": l.runs_root.display().to_string(),
        }),
        Backend::Cluster(k) => {
            let namespaces = k.namespaces(bearer(&headers)).await;
            json!({
                "backend": "cluster",
                "version": env!("CARGO_PKG_VERSION"),
                "namespaces": namespaces,
                "needsToken": k.needs_token(),
                "archive": "the archives of the SimulationRuns you can read",
            })
        }
    };
    Ok(axum::Json(body).into_response())
}

async fn parse(body: String) -> ApiResult {
    let (document, errors) = scenario::parse(&body).map_err(|e| ApiError::new(StatusCode::BAD_REQUEST, e.0))?;
    Ok(axum::Json(json!({"document": document, "errors": errors})).into_response())
}

#[derive(Deserialize)]
struct DocumentBody {
    document: Value,
    #[serde(default)]
    original: Option<String>,
    #[serde(default)]
    namespace: Option<String>,
    #[serde(default)]
    queue: Option<String>,
}

async fn validate(axum::Json(body): axum::Json<DocumentBody>) -> ApiResult {
    let (run, errors) = scenario::check(&body.document).map_err(|e| ApiError::new(StatusCode::BAD_REQUEST, e.0))?;
    let plan = run.filter(|_| errors.is_empty()).map(|r| scenario::outline(&r));
    Ok(axum::Json(json!({"errors": errors, "plan": plan})).into_response())
}

async fn to_yaml(axum::Json(body): axum::Json<DocumentBody>) -> ApiResult {
    let text = scenario::to_yaml(&body.document, body.original.as_deref());
    Ok(([(header::CONTENT_TYPE, "text/yaml; charset=utf-8")], text).into_response())
}

async fn world(State(c): State<Console>, axum::Json(body): axum::Json<DocumentBody>) -> ApiResult {
    let (run, errors) = scenario::check(&body.document).map_err(|e| ApiError::new(StatusCode::BAD_REQUEST, e.0))?;
    // The world is drawn while other parts of the document are still wrong; a document
    // that does not even parse (`run` is None) says why.
    let world_errors: Vec<Problem> = errors
        .iter()
        .filter(|p| ["spec.origin", "spec.world"].iter().any(|f| p.field.starts_with(f)))
        .cloned()
        .collect();
    let mut run = match run {
        Some(run) if world_errors.is_empty() => run,
        Some(_) => return Err(ApiError::invalid(world_errors)),
        None => return Err(ApiError::invalid(errors)),
    };
    sadesim_sources::world::resolve_paths(&mut run, &c.scenario_dir());
    let cache = c.worlds.clone();
    let layers = blocking(move || -> Result<Arc<Value>, ApiError> {
        let unprocessable = |m: String| ApiError::new(StatusCode::UNPROCESSABLE_ENTITY, m);
        let data = sadesim_sources::world::read_data(&run.spec).map_err(|e| unprocessable(e.to_string()))?;
        // The cache key covers everything the world is made of, origin included.
        let key = sadesim_planner::world_key(&run, &data);
        if let Some((k, layers)) = cache.lock().expect("world cache").as_ref()
            && *k == key
        {
            return Ok(layers.clone());
        }
        let cached = sadesim_sources::assets::local_cache_url(&|k| std::env::var(k).ok())
            .ok()
            .and_then(|url| sadesim_sources::assets::load_bundle(&sadesim_sources::assets::entry_url(&url, &key)).ok());
        let world = match cached {
            Some(w) => w,
            None => sadesim_world::World::build(&sadesim_world::WorldInputs::from_spec(&run.spec, &[]), &data)
                .map_err(|e| unprocessable(e.to_string()))?,
        };
        let layers = Arc::new(scenario::world_layers(&run, &world));
        *cache.lock().expect("world cache") = Some((key, layers.clone()));
        Ok(layers)
    })
    .await??;
    Ok(([(header::CONTENT_TYPE, "application/json")], serde_json::to_vec(&*layers).expect("JSON")).into_response())
}

/// `?namespace=` of the list endpoints (cluster only).
#[derive(Deserialize, Default)]
struct Scope {
    namespace: Option<String>,
}

async fn runs(State(c): State<Console>, headers: HeaderMap, Query(scope): Query<Scope>) -> ApiResult {
    let runs = match &c.backend {
        Backend::Local(l) => l.list(),
        Backend::Cluster(k) => k.list(bearer(&headers), scope.namespace).await?,
    };
    Ok(axum::Json(json!({"runs": runs})).into_response())
}

async fn launch(State(c): State<Console>, headers: HeaderMap, axum::Json(body): axum::Json<DocumentBody>) -> ApiResult {
    let (run, errors) = scenario::check(&body.document).map_err(|e| ApiError::new(StatusCode::BAD_REQUEST, e.0))?;
    let run = match run {
        Some(run) if errors.is_empty() => run,
        _ => return Err(ApiError::invalid(errors)),
    };
    let view = match &c.backend {
        Backend::Local(l) => {
            if body.namespace.is_some() || body.queue.is_some() {
                return Err(ApiError::new(
                    StatusCode::BAD_REQUEST,
                    "namespace and queue: not supported by the local console (they are for a cluster: `sadesim console --cluster`)",
                ));
            }
            let text = scenario::to_yaml(&body.document, None);
            let (l, run) = (l.clone(), run.clone());
            blocking(move || l.launch(run, &text))
                .await?
                .map_err(|e| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, e))?
                .view()
        }
        Backend::Cluster(k) => k.create(bearer(&headers), run, body.namespace, body.queue).await?,
    };
    Ok((StatusCode::CREATED, axum::Json(json!({"run": view}))).into_response())
}

fn no_run(id: &str) -> ApiError {
    ApiError::new(StatusCode::NOT_FOUND, format!("no run {id:?}"))
}

async fn run(State(c): State<Console>, headers: HeaderMap, Path(id): Path<String>) -> ApiResult {
    let detail = match &c.backend {
        Backend::Local(l) => {
            let live = l.get(&id).ok_or_else(|| no_run(&id))?;
            blocking(move || live.detail()).await?
        }
        Backend::Cluster(k) => k.detail(bearer(&headers), &id).await?,
    };
    Ok(axum::Json(detail).into_response())
}

async fn stop(State(c): State<Console>, headers: HeaderMap, Path(id): Path<String>) -> ApiResult {
    let view = match &c.backend {
        Backend::Local(l) => {
            let live = l.get(&id).ok_or_else(|| no_run(&id))?;
            live.stop();
            live.view()
        }
        Backend::Cluster(k) => k.stop(bearer(&headers), &id).await?,
    };
    Ok((StatusCode::ACCEPTED, axum::Json(json!({"run": view}))).into_response())
}

use crate::server_stream::EventStream;

fn sse(events: EventStream) -> Response {
    Sse::new(events).keep_alive(KeepAlive::new().interval(Duration::from_secs(15))).into_response()
}

/// A stream of `name` events: `render()` at the start and after every change, sent only
/// when it differs from what was sent last.
fn local_stream(
    mut changes: tokio::sync::watch::Receiver<u64>,
    name: &'static str,
    render: impl Fn() -> Option<String> + Send + 'static,
) -> EventStream {
    let stream = async_stream(move |tx| async move {
        let mut last = String::new();
        while let Some(now) = render() {
            if now != last {
                if tx.send(SseEvent::default().event(name).data(now.clone())).await.is_err() {
                    break;
                }
                last = now;
            }
            if changes.changed().await.is_err() {
                break;
            }
        }
    });
    Box::pin(stream)
}

/// A stream fed by a task through a channel (the task ends when the client goes away).
pub(crate) fn async_stream<F, Fut>(body: F) -> impl Stream<Item = Result<SseEvent, Infallible>> + Send
where
    F: FnOnce(tokio::sync::mpsc::Sender<SseEvent>) -> Fut,
    Fut: std::future::Future<Output = ()> + Send + 'static,
{
    let (tx, rx) = tokio::sync::mpsc::channel(16);
    tokio::spawn(body(tx));
    stream::unfold(rx, |mut rx| async move { rx.recv().await.map(|e| (Ok(e), rx)) })
}

async fn watch_runs(State(c): State<Console>, headers: HeaderMap, Query(scope): Query<Scope>) -> ApiResult {
    match &c.backend {
        Backend::Local(l) => {
            let l2 = l.clone();
            Ok(sse(local_stream(l.changes(), "runs", move || Some(json!({"runs": l2.list()}).to_string()))))
        }
        Backend::Cluster(k) => Ok(sse(k.watch(bearer(&headers), scope.namespace).await?)),
    }
}

async fn watch_run(State(c): State<Console>, headers: HeaderMap, Path(id): Path<String>) -> ApiResult {
    match &c.backend {
        Backend::Local(l) => {
            let live = l.get(&id).ok_or_else(|| no_run(&id))?;
            Ok(sse(local_stream(l.changes(), "run", move || serde_json::to_string(&live.detail()).ok())))
        }
        Backend::Cluster(k) => Ok(sse(k.watch_one(bearer(&headers), &id).await?)),
    }
}

/// The archive the request may read: the local runs folder, or on a cluster the archive of
/// a run the user can read.
async fn archive_of(c: &Console, headers: &HeaderMap, id: &str) -> Result<(ArchiveBrowser, String), ApiError> {
    match &c.backend {
        Backend::Local(l) => Ok((ArchiveBrowser::new(&l.runs_root.display().to_string()), id.to_string())),
        Backend::Cluster(k) => k.archive_of(bearer(headers), id).await,
    }
}

async fn archive_list(State(c): State<Console>, headers: HeaderMap, Query(scope): Query<Scope>) -> ApiResult {
    let entries = match &c.backend {
        Backend::Local(l) => {
            let browser = ArchiveBrowser::new(&l.runs_root.display().to_string());
            blocking(move || browser.list()).await??
        }
        Backend::Cluster(k) => k.archive_list(bearer(&headers), scope.namespace).await?,
    };
    Ok(axum::Json(json!({"runs": entries})).into_response())
}

async fn archive_entry(State(c): State<Console>, headers: HeaderMap, Path(id): Path<String>) -> ApiResult {
    let (browser, folder_id) = archive_of(&c, &headers, &id).await?;
    let mut detail = blocking(move || browser.detail(&folder_id)).await??;
    detail.entry.id = id;
    Ok(axum::Json(detail).into_response())
}

async fn archive_file(
    State(c): State<Console>,
    headers: HeaderMap,
    Path((id, path)): Path<(String, String)>,
) -> ApiResult {
    let (browser, folder_id) = archive_of(&c, &headers, &id).await?;
    let name = path.clone();
    let bytes = blocking(move || browser.file(&folder_id, &name)).await??;
    let file_name = path.rsplit('/').next().unwrap_or_default().to_string();
    let mut response = ([(header::CONTENT_TYPE, content_type(&path))], Body::from(bytes)).into_response();
    if matches!(path.rsplit('.').next(), Some("mcap" | "ulg")) {
        let disposition = format!("attachment; filename=\"{file_name}\"");
        response.headers_mut().insert(header::CONTENT_DISPOSITION, disposition.parse().expect("a header value"));
    }
    Ok(response)
}

async fn archive_verify(State(c): State<Console>, headers: HeaderMap, Path(id): Path<String>) -> ApiResult {
    let (browser, folder_id) = archive_of(&c, &headers, &id).await?;
    let verification = blocking(move || browser.verify(&folder_id)).await??;
    Ok(axum::Json(verification).into_response())
}

/// `/api/runs/<id>/view/...`: a cluster run's live view, not proxied yet (501 saying how to
/// reach it); local runs serve theirs themselves (`viewUrl`).
async fn live_view(
    State(c): State<Console>,
    headers: HeaderMap,
    Path((id, rest)): Path<(String, String)>,
) -> ApiResult {
    match &c.backend {
        Backend::Local(_) => {
            Err(ApiError::new(StatusCode::NOT_FOUND, "local runs serve their live view themselves (viewUrl)"))
        }
        Backend::Cluster(k) => k.live_view(bearer(&headers), &id, &rest).await,
    }
}

/// Replays kept in memory at once.
const MAX_REPLAYS: usize = 4;

/// `/replay/<id>/...`: the live view's routes on the archived run, built once per run.
async fn replay(State(c): State<Console>, headers: HeaderMap, request: Request) -> ApiResult {
    let path = request.uri().path().to_string();
    let rest = path.strip_prefix("/replay/").unwrap_or_default();
    let (id, inner) = rest.split_once('/').unwrap_or((rest, ""));
    let id = id.to_string();
    let known = c.replays.lock().expect("replays").get(&id).cloned();
    let view = match known {
        Some(v) => v,
        None => {
            let (browser, folder_id) = archive_of(&c, &headers, &id).await?;
            let built = blocking(move || {
                crate::replay::replay(&|name| browser.file(&folder_id, name).map_err(|e| e.to_string()), 20.0)
            })
            .await?
            .map_err(|e| ApiError::new(StatusCode::UNPROCESSABLE_ENTITY, format!("replay of {id}: {e}")))?;
            let view = sim_worker::view::server::router(built.content);
            let mut replays = c.replays.lock().expect("replays");
            // A replay holds its whole recording in memory: keep the last few opened.
            if replays.len() >= MAX_REPLAYS {
                replays.clear();
            }
            replays.insert(id.clone(), view.clone());
            view
        }
    };
    let inner_uri = format!("/{inner}");
    let request = Request::builder()
        .uri(inner_uri)
        .body(Body::empty())
        .map_err(|e| ApiError::new(StatusCode::BAD_REQUEST, e.to_string()))?;
    Ok(view.oneshot(request).await.unwrap_or_else(|never| match never {}))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn headers(pairs: &[(header::HeaderName, &str)]) -> HeaderMap {
        let mut h = HeaderMap::new();
        for (k, v) in pairs {
            h.append(k.clone(), v.parse().unwrap());
        }
        h
    }

    #[test]
    fn the_token_comes_from_the_header_else_the_cookie() {
        assert_eq!(bearer(&headers(&[(header::AUTHORIZATION, "Bearer abc")])).as_deref(), Some("abc"));
        let cookie = headers(&[(header::COOKIE, "theme=dark; sadesim_token=xyz; other=1")]);
        assert_eq!(bearer(&cookie).as_deref(), Some("xyz"));
        let both = headers(&[(header::AUTHORIZATION, "Bearer abc"), (header::COOKIE, "sadesim_token=xyz")]);
        assert_eq!(bearer(&both).as_deref(), Some("abc"));
        assert_eq!(bearer(&headers(&[(header::AUTHORIZATION, "Basic abc")])), None);
        assert_eq!(bearer(&headers(&[(header::AUTHORIZATION, "Bearer  ")])), None);
        assert_eq!(bearer(&HeaderMap::new()), None);
    }
}
