//! Field paths as validation errors write them (`spec.environment.wind.speedMps`,
//! `spec.fleet[1].count`), read and written on a run's JSON document.

use serde_json::{Map, Value};

/// One step of a path: an object key or an array index.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Step {
    Key(String),
    Index(usize),
}

/// Parses `spec.a.b[2].c`. The path must start at `spec`.
///
/// # Errors
/// What is wrong with the path's syntax.
pub fn parse(path: &str) -> Result<Vec<Step>, String> {
    let mut steps = Vec::new();
    for part in path.split('.') {
        let (key, mut rest) = match part.find('[') {
            Some(i) => (&part[..i], &part[i..]),
            None => (part, ""),
        };
        if key.is_empty() || !key.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
            return Err(format!(
                "{path:?} is not a field path like `spec.environment.wind.speedMps` or `spec.fleet[1].count`"
            ));
        }
        steps.push(Step::Key(key.to_string()));
        while !rest.is_empty() {
            let Some(close) = rest.find(']').filter(|_| rest.starts_with('[')) else {
                return Err(format!("{path:?}: an index is written `[n]`"));
            };
            let index =
                rest[1..close].parse().map_err(|_| format!("{path:?}: {:?} is not an index", &rest[1..close]))?;
            steps.push(Step::Index(index));
            rest = &rest[close + 1..];
        }
    }
    if steps.first() != Some(&Step::Key("spec".into())) || steps.len() < 2 {
        return Err(format!("{path:?} must name a field of the run's spec, starting with `spec.`"));
    }
    Ok(steps)
}

/// The value at `steps` in `doc`, if there is one.
pub fn get<'a>(doc: &'a Value, steps: &[Step]) -> Option<&'a Value> {
    steps.iter().try_fold(doc, |here, step| match step {
        Step::Key(key) => here.get(key.as_str()),
        Step::Index(i) => here.get(*i),
    })
}

/// Sets the field at `steps` in `doc` to `value`. Missing objects on the way are created
/// (setting `spec.environment.gnss.rateHz` in a run without `gnss`); array elements must
/// exist.
///
/// # Errors
/// Where the path leaves the document: an index past the end of a list, or a step into a
/// number or string.
pub fn set(doc: &mut Value, steps: &[Step], value: Value) -> Result<(), String> {
    let mut here = doc;
    let mut walked = String::new();
    for (i, step) in steps.iter().enumerate() {
        let last = i + 1 == steps.len();
        here = match step {
            Step::Key(key) => {
                if here.is_null() {
                    *here = Value::Object(Map::new());
                }
                let Value::Object(map) = here else {
                    return Err(format!("{walked} is not an object, so it has no field {key:?}"));
                };
                if last {
                    map.insert(key.clone(), value);
                    return Ok(());
                }
                map.entry(key.clone()).or_insert(Value::Null)
            }
            Step::Index(index) => {
                let Value::Array(items) = here else {
                    return Err(format!("{walked} is not a list, so it has no item [{index}]"));
                };
                let len = items.len();
                let Some(item) = items.get_mut(*index) else {
                    return Err(format!("{walked} has {len} item(s), so there is no [{index}]"));
                };
                if last {
                    *item = value;
                    return Ok(());
                }
                item
            }
        };
        match step {
            Step::Key(k) if walked.is_empty() => walked.push_str(k),
            Step::Key(k) => walked.push_str(&format!(".{k}")),
            Step::Index(n) => walked.push_str(&format!("[{n}]")),
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn paths_parse_like_validation_errors_write_them() {
        let steps = parse("spec.fleet[1].count").unwrap();
        assert_eq!(
            steps,
            [Step::Key("spec".into()), Step::Key("fleet".into()), Step::Index(1), Step::Key("count".into())]
        );
        assert!(parse("metadata.name").unwrap_err().contains("starting with `spec.`"));
        assert!(parse("spec").unwrap_err().contains("starting with `spec.`"));
        assert!(parse("spec..x").unwrap_err().contains("is not a field path"));
        assert!(parse("spec.fleet[x].count").unwrap_err().contains("is not an index"));
        assert!(parse("spec.fleet[1.count").unwrap_err().contains("written `[n]`"));
    }

    #[test]
    fn set_creates_missing_objects_but_not_list_items() {
        let mut doc = json!({"spec": {"fleet": [{"count": 1}], "environment": {}}});
        set(&mut doc, &parse("spec.environment.gnss.rateHz").unwrap(), json!(5)).unwrap();
        set(&mut doc, &parse("spec.fleet[0].count").unwrap(), json!(3)).unwrap();
        assert_eq!(doc, json!({"spec": {"fleet": [{"count": 3}], "environment": {"gnss": {"rateHz": 5}}}}));
        let e = set(&mut doc, &parse("spec.fleet[4].count").unwrap(), json!(3)).unwrap_err();
        assert_eq!(e, "spec.fleet has 1 item(s), so there is no [4]");
        let e = set(&mut doc, &parse("spec.fleet[0].count.x").unwrap(), json!(3)).unwrap_err();
        assert_eq!(e, "spec.fleet[0].count is not an object, so it has no field \"x\"");
    }
}
