//! Reading a `SimulationSweep` from YAML or JSON, with field paths in errors, under the
//! same limits as scenario documents.

use serde_json::Value;

use super::SimulationSweep;
use crate::document::{
    API_VERSION, DocumentError, MAX_DOCUMENT_BYTES, json_documents, looks_like_json, yaml_documents,
};

/// The kind of a sweep document.
pub const SWEEP_KIND: &str = "SimulationSweep";

/// The `kind` of the first document in `text` (`SimulationRun`, `SimulationSweep`, ...),
/// for tools that take either; `None` when it cannot be read.
pub fn first_kind(text: &str) -> Option<String> {
    if text.len() > MAX_DOCUMENT_BYTES {
        return None;
    }
    let docs = if looks_like_json(text) { json_documents(text).ok()? } else { yaml_documents(text).ok()? };
    docs.into_iter().next()?.ok()?.get("kind").and_then(Value::as_str).map(String::from)
}

/// Parses exactly one SimulationSweep.
///
/// # Errors
/// The input is too large, not YAML/JSON, not one SimulationSweep, or a field has the
/// wrong type or an unknown name (named by its path, `spec.parameters[0].range.step`).
pub fn parse_sweep(text: &str) -> Result<SimulationSweep, DocumentError> {
    if text.len() > MAX_DOCUMENT_BYTES {
        return Err(DocumentError::TooLarge { bytes: text.len(), limit: MAX_DOCUMENT_BYTES });
    }
    let mut docs = if looks_like_json(text) { json_documents(text)? } else { yaml_documents(text)? };
    if docs.is_empty() {
        return Err(DocumentError::Empty);
    }
    if docs.len() > 1 {
        return Err(DocumentError::Syntax {
            document: 2,
            message: format!("expected one SimulationSweep, found {} documents", docs.len()),
        });
    }
    let v = docs.remove(0)?;
    let field = |name: &str| v.get(name).and_then(Value::as_str).unwrap_or("").to_string();
    let (api_version, kind) = (field("apiVersion"), field("kind"));
    if api_version != API_VERSION || kind != SWEEP_KIND {
        return Err(DocumentError::WrongKind { document: 1, expected: SWEEP_KIND, api_version, kind });
    }
    serde_path_to_error::deserialize::<_, SimulationSweep>(&v).map_err(|e| {
        let path = e.path().to_string();
        DocumentError::Field {
            document: 1,
            path: if path == "." { "(document root)".into() } else { path },
            message: e.into_inner().to_string(),
        }
    })
}
