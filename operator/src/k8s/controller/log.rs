//! Structured logs: one JSON object per line on stderr (`{"ts":..,"level":..,"msg":..,
//! <fields>}`), what log collectors in a cluster parse without configuration.

use std::io::Write;

use k8s_openapi::jiff::Timestamp;

/// One log line as JSON (no trailing newline).
pub fn line(ts: Timestamp, level: &str, msg: &str, fields: &[(&str, &str)]) -> String {
    let mut map = serde_json::Map::new();
    map.insert("ts".into(), ts.to_string().into());
    map.insert("level".into(), level.into());
    map.insert("msg".into(), msg.into());
    for (k, v) in fields {
        map.insert((*k).into(), (*v).into());
    }
    serde_json::Value::Object(map).to_string()
}

fn emit(level: &str, msg: &str, fields: &[(&str, &str)]) {
    let text = line(Timestamp::now(), level, msg, fields);
    let mut err = std::io::stderr().lock();
    let _ = writeln!(err, "{text}");
}

pub fn info(msg: &str, fields: &[(&str, &str)]) {
    emit("info", msg, fields);
}

pub fn warn(msg: &str, fields: &[(&str, &str)]) {
    emit("warn", msg, fields);
}

pub fn error(msg: &str, fields: &[(&str, &str)]) {
    emit("error", msg, fields);
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_line_is_one_json_object_with_escaped_fields() {
        let ts = k8s_openapi::jiff::Timestamp::from_second(1_800_000_000).unwrap();
        let l = super::line(ts, "info", "reconciled", &[("run", "a\"b"), ("phase", "Running")]);
        let v: serde_json::Value = serde_json::from_str(&l).unwrap();
        assert_eq!(v["ts"], "2027-01-15T08:00:00Z");
        assert_eq!(v["run"], "a\"b");
        assert_eq!(v["phase"], "Running");
        assert!(!l.contains('\n'));
    }
}
