//! Reading scenario documents: YAML (one or many documents, `---`-separated), JSON (one
//! object or an array), and `kind: List` wrappers, as GitOps repositories keep them.
//!
//! # Guarantees
//! - Input larger than [`MAX_DOCUMENT_BYTES`] is refused before parsing.
//! - Nesting deeper than 128 levels is refused by the parsers' recursion limits, and YAML
//!   alias expansion is bounded by serde_yaml, so hostile input cannot hang or crash us.
//! - Type errors name the field path (`spec.fleet[2].count: invalid type: ...`).
//! - A document that fails typed reading is checked against the CRD's schema
//!   ([`schema_problems`]): every missing required field, wrong type, unsupported value
//!   and unknown field is reported at once ([`DocumentError::Fields`]), not one per run.
//! - `.nan` / `.inf` are refused with their path: no non-finite number enters a run.

use serde_json::{Map, Value};

use crate::run::SimulationRun;
use crate::validate::{FieldError, ValidationErrors, schema_problems};

/// Largest accepted scenario input, bytes. A 10 000-drone fleet with explicit homes is
/// about 1 MB of YAML.
pub const MAX_DOCUMENT_BYTES: usize = 4 * 1024 * 1024;
/// Deepest nesting accepted. Scenarios nest about 10 levels; libyaml's time grows with the
/// square of the depth, so deeper input is refused before it reaches the parser.
pub const MAX_NESTING: usize = 128;
/// Most runs in one input.
pub const MAX_RUNS_PER_INPUT: usize = 1024;

/// The API version every document must carry.
pub const API_VERSION: &str = "sadesim.io/v1alpha1";
/// The kind every document must carry.
pub const KIND: &str = "SimulationRun";

/// Why an input or one of its documents could not be read.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum DocumentError {
    /// The whole input is over the size limit.
    #[error("input is {bytes} bytes, over the {limit}-byte limit for scenario files")]
    TooLarge { bytes: usize, limit: usize },
    /// The input holds no document.
    #[error("no SimulationRun found: the input is empty")]
    Empty,
    /// More documents than [`MAX_RUNS_PER_INPUT`].
    #[error("more than {limit} documents in one input")]
    TooManyDocuments { limit: usize },
    /// A document is not well-formed YAML/JSON (or nests too deeply).
    #[error("document {document}: {message}")]
    Syntax { document: usize, message: String },
    /// A document is not a SimulationRun.
    #[error(
        "document {document}: expected apiVersion {API_VERSION:?} and kind {expected:?}, got apiVersion {api_version:?} and kind {kind:?}"
    )]
    WrongKind { document: usize, expected: &'static str, api_version: String, kind: String },
    /// A field has the wrong type, an unknown name, or a non-finite number.
    #[error("document {document}: {path}: {message}")]
    Field { document: usize, path: String, message: String },
    /// Several structural problems (missing, wrong type, unknown), all found in one pass.
    /// Shown as a count, then one `path: message` line each.
    #[error("document {document}: {} structural problems\n{}", problems.0.len(), indented(problems))]
    Fields { document: usize, problems: ValidationErrors },
}

fn indented(problems: &ValidationErrors) -> String {
    problems.0.iter().map(|e| format!("  {e}")).collect::<Vec<_>>().join("\n")
}

/// Parses every SimulationRun in `text`. Documents are numbered from 1 in messages (items
/// of a `kind: List` or JSON array count as documents).
///
/// # Errors
/// The outer error is for the whole input (too large, empty, unreadable stream); the inner
/// results are per document so one bad document does not hide the others.
pub fn parse_runs(text: &str) -> Result<Vec<Result<SimulationRun, DocumentError>>, DocumentError> {
    if text.len() > MAX_DOCUMENT_BYTES {
        return Err(DocumentError::TooLarge { bytes: text.len(), limit: MAX_DOCUMENT_BYTES });
    }
    let values = if looks_like_json(text) { json_documents(text)? } else { yaml_documents(text)? };
    let mut out = Vec::new();
    for value in values {
        match value {
            Err(e) => out.push(Err(e)),
            Ok(v) if is_list(&v) => {
                let items = v.get("items").and_then(Value::as_array).cloned().unwrap_or_default();
                out.extend(items.into_iter().map(Ok));
            }
            Ok(v) => out.push(Ok(v)),
        }
        if out.len() > MAX_RUNS_PER_INPUT {
            return Err(DocumentError::TooManyDocuments { limit: MAX_RUNS_PER_INPUT });
        }
    }
    if out.is_empty() {
        return Err(DocumentError::Empty);
    }
    Ok(out
        .into_iter()
        .enumerate()
        .map(|(i, v)| v.and_then(|v| to_run(i + 1, v)).map_err(|e| renumber(e, i + 1)))
        .collect())
}

/// Parses exactly one SimulationRun (the common case for tools and tests).
///
/// # Errors
/// As [`parse_runs`], plus an error when the input holds more than one run.
pub fn parse_run(text: &str) -> Result<SimulationRun, DocumentError> {
    let mut runs = parse_runs(text)?;
    if runs.len() != 1 {
        return Err(DocumentError::Syntax {
            document: 2,
            message: format!("expected one SimulationRun, found {} documents", runs.len()),
        });
    }
    runs.remove(0)
}

fn renumber(e: DocumentError, document: usize) -> DocumentError {
    match e {
        DocumentError::Syntax { message, .. } => DocumentError::Syntax { document, message },
        other => other,
    }
}

pub(crate) fn looks_like_json(text: &str) -> bool {
    matches!(text.trim_start().as_bytes().first(), Some(b'{') | Some(b'['))
}

/// An over-estimate of YAML nesting depth, linear time: open flow collections (`[`, `{`
/// outside quotes and comments) plus block sequence indicators stacked on one line
/// (`- - - x`). Block mappings need one more indentation column per level, so their depth
/// is bounded by the line length and the size limit and needs no check here.
fn yaml_nesting_estimate(text: &str) -> usize {
    let mut flow: usize = 0;
    let mut max = 0;
    for line in text.lines() {
        let rest = line.trim_start_matches(' ');
        let mut stacked = 0;
        let mut r = rest;
        while let Some(after) = r.strip_prefix("- ").or_else(|| r.strip_prefix("? ")) {
            stacked += 1;
            r = after.trim_start_matches(' ');
        }
        let mut quote: Option<char> = None;
        let mut prev = ' ';
        let mut escaped = false;
        for c in rest.chars() {
            match quote {
                Some('"') if escaped => escaped = false,
                Some('"') if c == '\\' => escaped = true,
                Some(q) if c == q => quote = None,
                Some(_) => {}
                None => match c {
                    '#' if prev == ' ' || prev == '\t' => break,
                    '"' | '\'' if matches!(prev, ' ' | '[' | '{' | ',' | ':' | '-') => quote = Some(c),
                    '[' | '{' => flow += 1,
                    ']' | '}' => flow = flow.saturating_sub(1),
                    _ => {}
                },
            }
            prev = c;
            max = max.max(flow + stacked);
        }
        max = max.max(flow + stacked);
    }
    max
}

fn is_list(v: &Value) -> bool {
    v.get("kind").and_then(Value::as_str) == Some("List") && v.get("items").is_some_and(Value::is_array)
}

pub(crate) fn json_documents(text: &str) -> Result<Vec<Result<Value, DocumentError>>, DocumentError> {
    let value: Value = serde_json::from_str(text)
        .map_err(|e| DocumentError::Syntax { document: 1, message: format!("invalid JSON: {e}") })?;
    Ok(match value {
        Value::Array(items) => items.into_iter().map(Ok).collect(),
        other => vec![Ok(other)],
    })
}

/// Every YAML document of `text` as JSON values. Deep nesting is refused before the YAML
/// parser sees it (its time grows with the square of the depth: 200 000 brackets took
/// minutes).
pub(crate) fn yaml_documents(text: &str) -> Result<Vec<Result<Value, DocumentError>>, DocumentError> {
    use serde::Deserialize;
    let depth = yaml_nesting_estimate(text);
    if depth > MAX_NESTING {
        return Err(DocumentError::Syntax {
            document: 1,
            message: format!("nesting is about {depth} levels deep, over the limit of {MAX_NESTING} (recursion limit)"),
        });
    }
    let mut out = Vec::new();
    for (i, doc) in serde_yaml::Deserializer::from_str(text).enumerate() {
        if i >= MAX_RUNS_PER_INPUT {
            return Err(DocumentError::TooManyDocuments { limit: MAX_RUNS_PER_INPUT });
        }
        let document = i + 1;
        let parsed = serde_yaml::Value::deserialize(doc)
            .map_err(|e| DocumentError::Syntax { document, message: format!("invalid YAML: {e}") });
        match parsed {
            // A stream that fails to parse cannot be resumed: stop at the first broken document.
            Err(e) => {
                out.push(Err(e));
                break;
            }
            Ok(serde_yaml::Value::Null) => {} // empty document, e.g. a trailing `---`
            Ok(mut v) => {
                let converted = v
                    .apply_merge()
                    .map_err(|e| DocumentError::Syntax { document, message: format!("invalid YAML merge key: {e}") })
                    .and_then(|()| yaml_to_json(&v, &mut String::new(), document));
                out.push(converted);
            }
        }
    }
    Ok(out)
}

/// YAML value -> JSON value, refusing what JSON cannot hold (non-string keys, tags, NaN).
/// `path` is the dotted path of `v`, for messages. Recursion depth is bounded by
/// serde_yaml's recursion limit on the value we were given.
fn yaml_to_json(v: &serde_yaml::Value, path: &mut String, document: usize) -> Result<Value, DocumentError> {
    use serde_yaml::Value as Y;
    let field_error = |path: &str, message: String| {
        let FieldError { path, message } =
            FieldError::quoting(if path.is_empty() { "(document root)" } else { path }, &message);
        DocumentError::Field { document, path, message }
    };
    Ok(match v {
        Y::Null => Value::Null,
        Y::Bool(b) => Value::Bool(*b),
        Y::String(s) => Value::String(s.clone()),
        Y::Number(n) => {
            if let Some(u) = n.as_u64() {
                Value::from(u)
            } else if let Some(i) = n.as_i64() {
                Value::from(i)
            } else {
                let f = n.as_f64().unwrap_or(f64::NAN);
                match serde_json::Number::from_f64(f) {
                    Some(num) => Value::Number(num),
                    None => return Err(field_error(path, format!("must be a finite number, got {n}"))),
                }
            }
        }
        Y::Sequence(items) => {
            let mut out = Vec::with_capacity(items.len());
            for (i, item) in items.iter().enumerate() {
                let len = path.len();
                path.push_str(&format!("[{i}]"));
                out.push(yaml_to_json(item, path, document)?);
                path.truncate(len);
            }
            Value::Array(out)
        }
        Y::Mapping(map) => {
            let mut out = Map::with_capacity(map.len());
            for (k, item) in map {
                let Some(key) = k.as_str() else {
                    return Err(field_error(path, format!("mapping keys must be strings, got {k:?}")));
                };
                let len = path.len();
                if !path.is_empty() {
                    path.push('.');
                }
                path.push_str(key);
                out.insert(key.to_string(), yaml_to_json(item, path, document)?);
                path.truncate(len);
            }
            Value::Object(out)
        }
        Y::Tagged(t) => return Err(field_error(path, format!("YAML tags are not supported, got {}", t.tag))),
    })
}

pub(crate) fn to_run(document: usize, v: Value) -> Result<SimulationRun, DocumentError> {
    let field = |v: &Value, name: &str| v.get(name).and_then(Value::as_str).unwrap_or("").to_string();
    let (api_version, kind) = (field(&v, "apiVersion"), field(&v, "kind"));
    if api_version != API_VERSION || kind != KIND {
        return Err(DocumentError::WrongKind { document, expected: KIND, api_version, kind });
    }
    let typed = serde_path_to_error::deserialize::<_, SimulationRun>(&v);
    let e = match typed {
        Ok(run) => return Ok(run),
        Err(e) => e,
    };
    let path = e.path().to_string();
    let first = FieldError::quoting(if path == "." { "(document root)" } else { &path }, &e.into_inner().to_string());
    let mut problems = schema_problems(&v);
    // Typed reading may stop at something the schema cannot see (a bad duration string, a
    // negative count): keep it unless a schema problem is about the same field (serde names
    // the object of a missing field, the schema the field itself).
    let covered = |p: &FieldError| {
        first.path == "(document root)"
            || p.path == first.path
            || p.path.starts_with(&format!("{}.", first.path))
            || p.path.starts_with(&format!("{}[", first.path))
    };
    if !problems.iter().any(covered) {
        problems.push(first);
    }
    Err(match problems.len() {
        1 => {
            let FieldError { path, message } = problems.remove(0);
            DocumentError::Field { document, path, message }
        }
        _ => DocumentError::Fields { document, problems: ValidationErrors(problems) },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const MINIMAL: &str = r#"
apiVersion: sadesim.io/v1alpha1
kind: SimulationRun
metadata: {name: tiny}
spec:
  origin: {latitudeDeg: 41.8796, longitudeDeg: -87.6237, altitudeMslM: 181}
  duration: 2m
  fleet:
    - name: solo
      count: 1
      airframe: x500
      operator: acme
      homes: {explicit: [{latitudeDeg: 41.8796, longitudeDeg: -87.6237}]}
      altitude: {maxAglM: 100}
      mission: {items: [{takeoff: {altitudeAglM: 20}}, {land: {}}]}
"#;

    fn field_error(text: &str) -> (String, String) {
        match parse_runs(text).unwrap().remove(0) {
            Err(DocumentError::Field { path, message, .. }) => (path, message),
            other => panic!("expected a field error, got {other:?}"),
        }
    }

    /// A key, a tag or a value an error quotes is shown with its line breaks escaped, so
    /// that every problem is one line (found by fuzz/scenario: the tag `!%0a!` decodes to
    /// a line break, and the error spanned two lines).
    #[test]
    fn quoted_text_keeps_each_problem_on_one_line() {
        let cases = [
            ("!%0a! x".to_string(), "YAML tags are not supported, got !\\n!"),
            (MINIMAL.replace("duration: 2m", "duration: 2m\n  clock: {mode: \"as\\nFast\"}"), "as\\nFast"),
            (MINIMAL.replace("count: 1", "count: 1\n      \"col\\nour\": red"), "col\\nour"),
        ];
        for (text, quoted) in cases {
            let problems = match parse_runs(&text).unwrap().remove(0) {
                Err(DocumentError::Field { path, message, .. }) => vec![FieldError { path, message }],
                Err(DocumentError::Fields { problems, .. }) => problems.0,
                other => panic!("expected field errors, got {other:?}"),
            };
            for p in &problems {
                assert!(!p.to_string().contains('\n'), "{p:?}");
            }
            assert!(problems.iter().any(|p| p.to_string().contains(quoted)), "{quoted} not in {problems:?}");
        }
    }

    #[test]
    fn parses_yaml_and_defaults_apply() {
        let run = parse_run(MINIMAL).unwrap();
        assert_eq!(run.metadata.name.as_deref(), Some("tiny"));
        assert_eq!(run.spec.physics_rate_hz(), 1000);
        assert_eq!(run.spec.duration_s(), 120.0);
        assert_eq!(run.spec.total_drones(), 1);
    }

    #[test]
    fn multi_document_yaml_and_lists_and_json_arrays() {
        let two = format!("{MINIMAL}\n---\n{}\n---\n", MINIMAL.replace("tiny", "other"));
        let runs = parse_runs(&two).unwrap();
        assert_eq!(runs.len(), 2);
        assert_eq!(runs[1].as_ref().unwrap().metadata.name.as_deref(), Some("other"));

        let one: serde_json::Value = serde_yaml::from_str(MINIMAL).unwrap();
        let list = serde_json::json!({"apiVersion": "v1", "kind": "List", "items": [one.clone(), one.clone()]});
        assert_eq!(parse_runs(&serde_yaml::to_string(&list).unwrap()).unwrap().len(), 2);
        let array = serde_json::to_string_pretty(&serde_json::json!([one.clone(), one])).unwrap();
        assert_eq!(parse_runs(&array).unwrap().len(), 2);
    }

    #[test]
    fn type_errors_name_the_field_path() {
        let (path, message) = field_error(&MINIMAL.replace("count: 1", "count: -3"));
        assert_eq!(path, "spec.fleet[0].count");
        assert!(message.contains("-3"), "{message}");
        let (path, message) = field_error(&MINIMAL.replace("airframe: x500", "airframe: x500\n      colour: red"));
        assert!(path.starts_with("spec.fleet[0]"), "{path}");
        assert!(message.contains("colour"), "{message}");
        let (path, _) = field_error(&MINIMAL.replace("duration: 2m", "duration: two minutes"));
        assert_eq!(path, "spec.duration");
    }

    /// A first scenario written from scratch: four required fields left out (a group's
    /// `operator`, `homes` and `altitude`, the origin's `altitudeMslM`) are all named in
    /// one pass, in the API server's words.
    #[test]
    fn every_missing_required_field_is_listed_at_once() {
        let text = MINIMAL
            .replace("      operator: acme\n", "")
            .replace("      homes: {explicit: [{latitudeDeg: 41.8796, longitudeDeg: -87.6237}]}\n", "")
            .replace("      altitude: {maxAglM: 100}\n", "")
            .replace(", altitudeMslM: 181", "");
        let err = parse_run(&text).unwrap_err();
        let DocumentError::Fields { document: 1, problems } = &err else { panic!("expected all problems, got {err}") };
        let listed: Vec<String> = problems.0.iter().map(ToString::to_string).collect();
        for path in
            ["spec.fleet[0].operator", "spec.fleet[0].homes", "spec.fleet[0].altitude", "spec.origin.altitudeMslM"]
        {
            assert!(listed.contains(&format!("{path}: Required value")), "{path} missing from {listed:?}");
        }
        assert_eq!(listed.len(), 4, "{listed:?}");
        let shown = err.to_string();
        assert!(shown.starts_with("document 1: 4 structural problems\n  "), "{shown}");
    }

    #[test]
    fn wrong_types_unknown_fields_and_bad_values_are_listed_together() {
        let text = MINIMAL
            .replace("count: 1", "count: many")
            .replace("airframe: x500", "airframe: x500\n      colour: red")
            .replace("{land: {}}", "{land: {now: true}}")
            .replace("duration: 2m", "duration: 2m\n  clock: {mode: fast}");
        let err = parse_run(&text).unwrap_err();
        let DocumentError::Fields { problems, .. } = &err else { panic!("expected all problems, got {err}") };
        let paths: Vec<&str> = problems.0.iter().map(|p| p.path.as_str()).collect();
        assert_eq!(
            paths,
            [
                "spec.clock.mode",
                "spec.fleet[0].colour",
                "spec.fleet[0].count",
                "spec.fleet[0].mission.items[1].land.now"
            ],
            "{err}"
        );
        assert!(problems.0[0].message.contains(r#"Unsupported value: "fast""#), "{err}");
        assert!(problems.0[2].message.contains(r#"must be of type integer, got string "many""#), "{err}");
    }

    #[test]
    fn homes_need_exactly_one_placement() {
        let both = MINIMAL.replace(
            "homes: {explicit: [{latitudeDeg: 41.8796, longitudeDeg: -87.6237}]}",
            "homes: {explicit: [{latitudeDeg: 41.8796, longitudeDeg: -87.6237}], randomInArea: {center: {latitudeDeg: 41.8796, longitudeDeg: -87.6237}, radiusM: 50}}",
        );
        let (path, message) = field_error(&both);
        assert_eq!(path, "spec.fleet[0].homes");
        assert!(message.contains("exactly one of"), "{message}");
        let (path, message) =
            field_error(&MINIMAL.replace("{explicit: [{latitudeDeg: 41.8796, longitudeDeg: -87.6237}]}", "{}"));
        assert_eq!((path.as_str(), message.contains("Required value")), ("spec.fleet[0].homes", true), "{message}");
    }

    /// What only typed reading sees (a bad duration string) is kept next to the schema's
    /// problems, not hidden by them.
    #[test]
    fn a_typed_reading_error_the_schema_cannot_see_is_kept() {
        let text = MINIMAL.replace("duration: 2m", "duration: two minutes").replace("      operator: acme\n", "");
        let err = parse_run(&text).unwrap_err();
        let DocumentError::Fields { problems, .. } = &err else { panic!("expected all problems, got {err}") };
        let paths: Vec<&str> = problems.0.iter().map(|p| p.path.as_str()).collect();
        assert_eq!(paths, ["spec.fleet[0].operator", "spec.duration"], "{err}");
    }

    #[test]
    fn non_finite_numbers_are_refused_with_their_path() {
        let (path, message) = field_error(&MINIMAL.replace("maxAglM: 100", "maxAglM: .nan"));
        assert_eq!(path, "spec.fleet[0].altitude.maxAglM");
        assert!(message.contains("finite"), "{message}");
        let (path, _) = field_error(&MINIMAL.replace("altitudeMslM: 181", "altitudeMslM: -.inf"));
        assert_eq!(path, "spec.origin.altitudeMslM");
    }

    #[test]
    fn nesting_estimate_ignores_brackets_in_strings_and_comments() {
        assert_eq!(yaml_nesting_estimate("a: \"[[[[\"\nb: '{{{{' # [[[[\n"), 0);
        assert_eq!(yaml_nesting_estimate("a: [1, [2, {b: 3}]]\n"), 3);
        assert_eq!(yaml_nesting_estimate("- - - x\n"), 3);
        assert!(yaml_nesting_estimate(MINIMAL) < 5);
    }

    #[test]
    fn other_kinds_are_refused_by_name() {
        let err = parse_run(&MINIMAL.replace("kind: SimulationRun", "kind: Pod")).unwrap_err();
        assert!(matches!(err, DocumentError::WrongKind { ref kind, .. } if kind == "Pod"), "{err}");
    }

    #[test]
    fn hostile_inputs_are_refused_quickly() {
        let big = "#".repeat(MAX_DOCUMENT_BYTES + 1);
        assert!(matches!(parse_runs(&big), Err(DocumentError::TooLarge { .. })));
        let deep_yaml = format!("spec: {}{}", "[".repeat(100_000), "]".repeat(100_000));
        let e = parse_runs(&deep_yaml).unwrap_err();
        assert!(e.to_string().contains("recursion"), "{e}");
        let dashes = format!("spec:\n{}x\n", "- ".repeat(100_000));
        assert!(parse_runs(&dashes).unwrap_err().to_string().contains("recursion"));
        let deep_json = format!("{{\"a\":{}1{}}}", "[".repeat(100_000), "]".repeat(100_000));
        let e = parse_runs(&deep_json).unwrap_err();
        assert!(e.to_string().contains("recursion"), "{e}");
        let laughs = "a: &a [x,x,x,x,x,x,x,x,x]\nb: &b [*a,*a,*a,*a,*a,*a,*a,*a,*a]\nc: &c [*b,*b,*b,*b,*b,*b,*b,*b,*b]\nd: &d [*c,*c,*c,*c,*c,*c,*c,*c,*c]\ne: &e [*d,*d,*d,*d,*d,*d,*d,*d,*d]\nf: &f [*e,*e,*e,*e,*e,*e,*e,*e,*e]\ng: &g [*f,*f,*f,*f,*f,*f,*f,*f,*f]\nh: [*g,*g,*g,*g,*g,*g,*g,*g,*g]\n";
        assert!(parse_runs(laughs).unwrap().remove(0).is_err());
        assert_eq!(parse_runs("  \n# only a comment\n"), Err(DocumentError::Empty));
    }
}
