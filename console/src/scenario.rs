//! The plan page's work on a scenario document, pure apart from reading the world's files:
//! parse a file's text, validate an edited document, write it back as YAML, and the world's
//! map layers.
//!
//! The page holds the document as JSON exactly as the user wrote it (no defaults filled
//! in), so what it exports is what the user wrote plus their edits.

use serde::Serialize;
use serde_json::{Value, json};

use sadesim_crds::SimulationRun;
use sadesim_crds::document::{self, DocumentError};
use sadesim_crds::validate::{FieldError, validate};

/// A problem with one field of the document, as `sadesim validate` prints it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Problem {
    /// Path from the document root, e.g. `spec.fleet[2].count`; `""` for the whole document.
    pub field: String,
    pub message: String,
}

impl From<FieldError> for Problem {
    fn from(e: FieldError) -> Self {
        Self { field: e.path, message: e.message }
    }
}

/// What the page learns of a valid document.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(rename_all = "camelCase")]
pub struct Outline {
    pub drones: u64,
    pub duration_s: f64,
}

/// A document that is not a SimulationRun at all: not YAML/JSON, empty, several documents,
/// another kind.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct NotAScenario(pub String);

/// The run in `document` and its problems: structural ones (unknown field, wrong type) or,
/// when it is well-formed, the validator's. `Err` when it is not a SimulationRun at all.
///
/// # Errors
/// [`NotAScenario`].
pub fn check(document: &Value) -> Result<(Option<SimulationRun>, Vec<Problem>), NotAScenario> {
    let text = serde_json::to_string(document).map_err(|e| NotAScenario(e.to_string()))?;
    match document::parse_run(&text) {
        Ok(run) => {
            let problems =
                validate(&run).err().map(|e| e.0.into_iter().map(Problem::from).collect()).unwrap_or_default();
            Ok((Some(run), problems))
        }
        Err(DocumentError::Field { path, message, .. }) => Ok((None, vec![Problem { field: path, message }])),
        Err(DocumentError::Fields { problems, .. }) => Ok((None, problems.0.into_iter().map(Problem::from).collect())),
        Err(e) => Err(NotAScenario(e.to_string())),
    }
}

/// The outline of a valid run.
pub fn outline(run: &SimulationRun) -> Outline {
    Outline { drones: run.spec.total_drones(), duration_s: run.spec.duration_s() }
}

/// A file's text (YAML or JSON) as the JSON document the page edits, with its problems.
///
/// # Errors
/// [`NotAScenario`]: not YAML/JSON, not exactly one document, or not a SimulationRun.
pub fn parse(text: &str) -> Result<(Value, Vec<Problem>), NotAScenario> {
    let mut runs = document::parse_runs(text).map_err(|e| NotAScenario(e.to_string()))?;
    if runs.len() != 1 {
        return Err(NotAScenario(format!("expected one SimulationRun, found {} documents", runs.len())));
    }
    match runs.pop().expect("one document") {
        Err(DocumentError::Syntax { message, .. }) => return Err(NotAScenario(message)),
        Err(e @ DocumentError::WrongKind { .. }) => return Err(NotAScenario(e.to_string())),
        _ => {}
    }
    let document = as_json(text)?;
    let (_, problems) = check(&document)?;
    Ok((document, problems))
}

/// YAML or JSON text as JSON, as written (YAML's merge keys and tags are not used by
/// scenarios; anchors are expanded).
fn as_json(text: &str) -> Result<Value, NotAScenario> {
    serde_yaml::from_str::<Value>(text).map_err(|e| NotAScenario(format!("invalid YAML: {e}")))
}

/// `document` as YAML for a GitOps repository. When `original` (the imported file's text)
/// holds the same document, it is returned as it was: its comments and layout are kept,
/// and an unedited import exports byte for byte. Otherwise the document is written afresh
/// (comments are not kept).
pub fn to_yaml(document: &Value, original: Option<&str>) -> String {
    if let Some(original) = original
        && as_json(original).is_ok_and(|o| same(&o, document))
    {
        return original.to_string();
    }
    serde_yaml::to_string(document).expect("JSON values are YAML")
}

/// Whether two documents hold the same values, numbers compared by value: a browser sends
/// the YAML's `3.0` back as `3` (JavaScript has one number type).
fn same(a: &Value, b: &Value) -> bool {
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => x == y || x.as_f64() == y.as_f64(),
        (Value::Array(x), Value::Array(y)) => x.len() == y.len() && x.iter().zip(y).all(|(x, y)| same(x, y)),
        (Value::Object(x), Value::Object(y)) => {
            x.len() == y.len() && x.iter().all(|(k, v)| y.get(k).is_some_and(|w| same(v, w)))
        }
        _ => a == b,
    }
}

/// The map layers of a world, WGS84: buildings (`heightM`), parks, the world's square and
/// the origin.
pub fn world_layers(run: &SimulationRun, world: &sadesim_world::World) -> Value {
    let frame = sadesim_crds::geo::LocalFrame::new(run.spec.origin.geo());
    let buildings = sadesim_sources::assets::buildings_geojson(world, &frame);
    let parks: Vec<Value> = world
        .open_spaces()
        .iter()
        .map(|o| {
            json!({
                "type": "Feature",
                "geometry": sadesim_sources::assets::footprint_polygon(&o.footprint, &frame, 0.0),
                "properties": {"kind": o.kind, "name": o.name},
            })
        })
        .collect();
    let half = world.extent_m();
    let corner = |east_m: f64, north_m: f64| frame.to_geodetic(sadesim_crds::geo::Enu { east_m, north_m, up_m: 0.0 });
    let (sw, ne) = (corner(-half, -half), corner(half, half));
    let origin = run.spec.origin.geo();
    json!({
        "origin": {"latitude": origin.latitude_deg, "longitude": origin.longitude_deg},
        "extentM": world.extent_m(),
        "bounds": [sw.longitude_deg, sw.latitude_deg, ne.longitude_deg, ne.latitude_deg],
        "buildings": buildings,
        "parks": {"type": "FeatureCollection", "features": parks},
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const QUICKSTART: &str = include_str!("../../examples/quickstart.yaml");

    #[test]
    fn an_unedited_import_exports_byte_for_byte_and_an_edit_is_written_afresh() {
        let (document, problems) = parse(QUICKSTART).unwrap();
        assert!(problems.is_empty(), "{problems:?}");
        assert_eq!(to_yaml(&document, Some(QUICKSTART)), QUICKSTART);
        let mut edited = document.clone();
        edited["spec"]["fleet"][0]["count"] = json!(3);
        let yaml = to_yaml(&edited, Some(QUICKSTART));
        assert_ne!(yaml, QUICKSTART);
        assert_eq!(as_json(&yaml).unwrap(), edited);
    }

    #[test]
    fn a_float_sent_back_as_an_integer_is_the_same_document() {
        let original = "a: 3.0\nb: [1.5, 2]\n";
        let from_browser = json!({"a": 3, "b": [1.5, 2.0]});
        assert_eq!(to_yaml(&from_browser, Some(original)), original);
        assert_ne!(to_yaml(&json!({"a": 3.5, "b": [1.5, 2.0]}), Some(original)), original);
        assert_ne!(to_yaml(&json!({"a": 3, "b": [1.5, 2.0], "c": null}), Some(original)), original);
    }

    #[test]
    fn problems_name_the_field() {
        let (mut document, _) = parse(QUICKSTART).unwrap();
        document["spec"]["fleet"][0]["count"] = json!(0);
        let (_, problems) = check(&document).unwrap();
        assert!(problems.iter().any(|p| p.field == "spec.fleet[0].count"), "{problems:?}");
        document["spec"]["fleet"][0]["cuont"] = json!(1);
        let (run, problems) = check(&document).unwrap();
        assert!(run.is_none());
        assert!(
            problems.iter().any(|p| p.field.starts_with("spec.fleet[0]") && p.message.contains("cuont")),
            "{problems:?}"
        );
    }

    #[test]
    fn other_documents_are_refused_with_what_they_are() {
        assert!(parse("kind: Pod\napiVersion: v1\n").unwrap_err().0.contains("kind"));
        assert!(parse("a: [").unwrap_err().0.contains("YAML"));
        assert!(parse(&format!("{QUICKSTART}\n---\n{QUICKSTART}")).unwrap_err().0.contains("2 documents"));
    }
}
