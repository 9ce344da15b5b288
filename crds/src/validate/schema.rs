//! The document against the CRD's OpenAPI schema, before typed reading: every missing
//! required field, wrong type, unsupported enum value and unknown field at once, each with
//! its path, as the Kubernetes API server lists them (`spec.fleet[0].homes: Required
//! value`).
//!
//! Typed reading (serde) stops at the first problem; this pass is what lets a scenario
//! written from scratch be fixed in one go. It checks only the structure (what serde
//! would refuse): ranges, lengths and patterns are [`super::validate`]'s, with its own
//! messages.
//!
//! # Rules (of the structural schema `crate::crd::crd` generates)
//! - `required`: a missing property, or one set to `null` without `nullable: true` (the
//!   API server prunes such nulls), is `Required value`.
//! - `type`: `object`, `array`, `string`, `boolean`, `number`, `integer` (a JSON number
//!   without a fraction or exponent); `null` is allowed where `nullable: true`.
//! - `enum`: the value must be one of the listed strings.
//! - `properties`: an object admits only its listed properties (an object without
//!   `properties`, such as `land: {}`, admits none), unless `additionalProperties` gives
//!   a schema for every value.
//! - `oneOf` of `required` alternatives (Rust enums: `homes`, mission items, criteria):
//!   exactly one of the keys.
//! - The document root admits `apiVersion`, `kind` and `metadata` besides the schema's
//!   properties: the API server handles those itself.

use std::sync::OnceLock;

use serde_json::{Map, Value};

use super::problems::FieldError;

/// Fields every Kubernetes object has, outside the CRD's schema.
const OBJECT_FIELDS: [&str; 3] = ["apiVersion", "kind", "metadata"];

/// The CRD's `openAPIV3Schema`, built once.
fn root_schema() -> &'static Value {
    static SCHEMA: OnceLock<Value> = OnceLock::new();
    SCHEMA.get_or_init(|| {
        let crd = serde_json::to_value(crate::crd::crd()).expect("a CRD always serializes");
        crd.pointer("/spec/versions/0/schema/openAPIV3Schema").cloned().expect("the CRD has a v1alpha1 schema")
    })
}

/// Every structural problem of one document (a whole `SimulationRun` as JSON), in a
/// stable order: per object, missing required fields first, then its fields in key order.
pub fn schema_problems(document: &Value) -> Vec<FieldError> {
    let mut out = Vec::new();
    check(root_schema(), document, "", &mut out);
    out
}

/// Paths hold the document's keys and messages quote its values: both as one line
/// ([`FieldError::quoting`]).
fn add(out: &mut Vec<FieldError>, path: &str, message: impl Into<String>) {
    let path = if path.is_empty() { "(document root)" } else { path };
    out.push(FieldError::quoting(path, &message.into()));
}

fn child_path(path: &str, key: &str) -> String {
    if path.is_empty() { key.to_string() } else { format!("{path}.{key}") }
}

/// A value's JSON type, as the schema names it.
fn type_name(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "boolean",
        Value::Number(n) if n.is_i64() || n.is_u64() => "integer",
        Value::Number(_) => "number",
        Value::String(_) => "string",
        Value::Array(_) => "array",
        Value::Object(_) => "object",
    }
}

/// The value for a message: strings quoted, containers named, at most 40 characters.
fn shown(v: &Value) -> String {
    let text = match v {
        Value::Array(_) => "a list".to_string(),
        Value::Object(_) => "a mapping".to_string(),
        other => other.to_string(),
    };
    if text.chars().count() > 40 { format!("{}...", text.chars().take(40).collect::<String>()) } else { text }
}

fn type_matches(expected: &str, v: &Value) -> bool {
    match (expected, v) {
        ("object", Value::Object(_)) | ("array", Value::Array(_)) | ("string", Value::String(_)) => true,
        ("boolean", Value::Bool(_)) | ("number", Value::Number(_)) => true,
        ("integer", Value::Number(n)) => n.is_i64() || n.is_u64(),
        _ => false,
    }
}

fn check(schema: &Value, v: &Value, path: &str, out: &mut Vec<FieldError>) {
    if v.is_null() {
        if !schema.get("nullable").is_some_and(|n| n == true)
            && let Some(t) = schema.get("type").and_then(Value::as_str)
        {
            add(out, path, format!("must be of type {t}, got null"));
        }
        return;
    }
    if let Some(t) = schema.get("type").and_then(Value::as_str)
        && !type_matches(t, v)
    {
        add(out, path, format!("must be of type {t}, got {} {}", type_name(v), shown(v)));
        return;
    }
    if let Some(allowed) = schema.get("enum").and_then(Value::as_array)
        && !allowed.contains(v)
    {
        let names: Vec<String> = allowed.iter().map(Value::to_string).collect();
        add(out, path, format!("Unsupported value: {}: supported values: {}", shown(v), names.join(", ")));
    }
    match v {
        Value::Object(map) => check_object(schema, map, path, out),
        Value::Array(items) => {
            if let Some(item_schema) = schema.get("items") {
                for (i, item) in items.iter().enumerate() {
                    check(item_schema, item, &format!("{path}[{i}]"), out);
                }
            }
        }
        _ => {}
    }
}

fn check_object(schema: &Value, map: &Map<String, Value>, path: &str, out: &mut Vec<FieldError>) {
    let empty = Map::new();
    let properties = schema.get("properties").and_then(Value::as_object).unwrap_or(&empty);
    let additional = schema.get("additionalProperties").filter(|a| a.is_object());
    for name in schema.get("required").and_then(Value::as_array).into_iter().flatten().filter_map(Value::as_str) {
        let nullable = properties.get(name).and_then(|p| p.get("nullable")).is_some_and(|n| n == true);
        match map.get(name) {
            None => add(out, &child_path(path, name), "Required value"),
            Some(Value::Null) if !nullable => add(out, &child_path(path, name), "Required value"),
            Some(_) => {}
        }
    }
    check_one_of(schema, map, path, out);
    for (key, value) in map {
        let key_path = child_path(path, key);
        match (properties.get(key), additional) {
            (Some(s), _) | (None, Some(s)) => {
                let required_null = value.is_null()
                    && schema.get("required").and_then(Value::as_array).is_some_and(|r| r.iter().any(|n| n == key));
                if !required_null {
                    check(s, value, &key_path, out);
                }
            }
            (None, None) if path.is_empty() && OBJECT_FIELDS.contains(&key.as_str()) => {}
            (None, None) if properties.is_empty() => {
                add(out, &key_path, format!("unknown field `{key}`: this mapping takes no fields (write `{{}}`)"));
            }
            (None, None) => {
                let names: Vec<String> = properties.keys().map(|k| format!("`{k}`")).collect();
                add(out, &key_path, format!("unknown field `{key}`, expected one of {}", names.join(", ")));
            }
        }
    }
}

/// `oneOf` alternatives that each require one key: exactly one of those keys is set.
fn check_one_of(schema: &Value, map: &Map<String, Value>, path: &str, out: &mut Vec<FieldError>) {
    let Some(alternatives) = schema.get("oneOf").and_then(Value::as_array) else { return };
    let keys: Vec<&str> = alternatives
        .iter()
        .filter_map(|a| a.get("required").and_then(Value::as_array))
        .filter(|r| r.len() == 1)
        .filter_map(|r| r[0].as_str())
        .collect();
    if keys.len() != alternatives.len() {
        return; // not the enum shape this check knows
    }
    let set: Vec<&str> = keys.iter().copied().filter(|k| map.get(*k).is_some_and(|v| !v.is_null())).collect();
    let what = |list: &[&str]| list.iter().map(|k| format!("`{k}`")).collect::<Vec<_>>().join(", ");
    match set.len() {
        1 => {}
        0 if map.keys().any(|k| !keys.contains(&k.as_str())) => {} // an unknown key says it already
        0 => add(out, path, format!("Required value: exactly one of {}", what(&keys))),
        _ => add(out, path, format!("must set exactly one of {}, got {}", what(&keys), what(&set))),
    }
}
