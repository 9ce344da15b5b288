//! Orbit Mean-Elements Messages (OMM, CCSDS 502.0-B): the successor of the TLE, in the four
//! encodings CelesTrak and Space-Track serve their general-perturbations element sets in
//! (`FORMAT=kvn`, `xml`, `json`, `csv`). An OMM carries the same SGP4 mean elements as a TLE,
//! with a full UTC epoch and catalogue numbers beyond 99 999, which a TLE cannot hold: the
//! element sets of objects catalogued beyond that number exist only as OMM.
//!
//! Reading is in two steps, so that a catalogue's thousands of other objects are not checked
//! field by field: [`records`] splits a file into element sets of `KEY`/value pairs (a syntax
//! error fails the whole file), then [`Record::elements`] turns one set into SGP4 elements,
//! naming the set and the key of anything wrong. Keys are the CCSDS ones (`OBJECT_NAME`,
//! `EPOCH`, `MEAN_MOTION`, ...), in every encoding.
//!
//! What is checked beyond the numbers: the set must be for SGP4 (`MEAN_ELEMENT_THEORY`
//! `SGP4` or `SGP/SGP4`, `EPHEMERIS_TYPE` 0), in TEME about the Earth (`REF_FRAME`,
//! `CENTER_NAME`) with a UTC epoch (`TIME_SYSTEM`), where those keys are given: elements of
//! another theory or frame would propagate to a wrong sky. Comments, `CREATION_DATE`,
//! `ORIGINATOR`, `OBJECT_ID` and user-defined parameters are metadata: read past.

use std::collections::BTreeMap;
use std::fmt;

use crate::orbits::OrbitError;

/// Where in a file an element set or a problem is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum At {
    /// A line of the file, from 1.
    Line(usize),
    /// An object of a JSON file's top-level array, from 1.
    Object(usize),
}

impl fmt::Display for At {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            At::Line(n) => write!(f, "line {n}"),
            At::Object(n) => write!(f, "object {n} of the JSON array"),
        }
    }
}

/// An OMM encoding.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Encoding {
    /// `KEY = value` lines, each message opening with `CCSDS_OMM_VERS`.
    Kvn,
    /// The CCSDS NDM/XML schema: `<ndm><omm>...<segment>` per element set.
    Xml,
    /// An array of objects (or one object) keyed as in KVN, as CelesTrak serves it.
    Json,
    /// A header row of keys, then one element set per row.
    Csv,
}

impl Encoding {
    /// The OMM encoding `text` is in, `None` when it is none of them (a TLE file, or
    /// anything else).
    pub fn of(text: &str) -> Option<Encoding> {
        let text = text.trim_start_matches('\u{feff}');
        let first = text.lines().map(str::trim).find(|l| !l.is_empty() && !is_kvn_comment(l))?;
        if first.starts_with('[') || first.starts_with('{') {
            Some(Encoding::Json)
        } else if first.starts_with("<?xml") || first.starts_with("<ndm") || first.starts_with("<omm") {
            Some(Encoding::Xml)
        } else if first.split('=').next().is_some_and(|key| key.trim() == "CCSDS_OMM_VERS") {
            Some(Encoding::Kvn)
        } else if csv_fields(first).is_ok_and(|keys| keys.iter().any(|k| k.trim() == "NORAD_CAT_ID")) {
            Some(Encoding::Csv)
        } else {
            None
        }
    }
}

/// One element set as the file gives it: its keys and their values.
#[derive(Clone, Debug, PartialEq)]
pub struct Record {
    /// Where the element set starts.
    pub at: At,
    fields: BTreeMap<String, String>,
}

/// Keys that may repeat in a message (and carry nothing the elements need).
const REPEATABLE: [&str; 2] = ["COMMENT", "USER_DEFINED"];

impl Record {
    fn new(at: At) -> Self {
        Self { at, fields: BTreeMap::new() }
    }

    /// Adds `key`, found on `line`; a repeated key (other than comments) is refused: which
    /// value is meant?
    fn insert(&mut self, key: &str, value: &str, line: usize) -> Result<(), OrbitError> {
        if REPEATABLE.contains(&key) {
            return Ok(());
        }
        if self.fields.contains_key(key) {
            return Err(OrbitError::Line {
                line,
                reason: format!("{} given twice in the element set of {}", shown_key(key), self.at),
            });
        }
        self.fields.insert(key.to_string(), value.to_string());
        Ok(())
    }

    /// The value of `key`, `None` when absent or empty.
    pub fn get(&self, key: &str) -> Option<&str> {
        self.fields.get(key).map(String::as_str).filter(|v| !v.is_empty())
    }

    /// The object's name (`OBJECT_NAME`).
    pub fn name(&self) -> Option<&str> {
        self.get("OBJECT_NAME")
    }

    /// The SGP4 elements of this set.
    ///
    /// # Errors
    /// [`OrbitError::Set`] naming the set and the key: a required key missing, a value
    /// that is not a number in range, an epoch that is not a UTC date, a theory, frame or
    /// time system other than SGP4's.
    pub fn elements(&self) -> Result<sgp4::Elements, OrbitError> {
        for (key, allowed) in [
            ("MEAN_ELEMENT_THEORY", &["SGP4", "SGP/SGP4"][..]),
            ("REF_FRAME", &["TEME"]),
            ("CENTER_NAME", &["EARTH"]),
            ("TIME_SYSTEM", &["UTC"]),
        ] {
            if let Some(value) = self.get(key)
                && !allowed.iter().any(|a| a.eq_ignore_ascii_case(value.trim()))
            {
                return Err(self.error(
                    key,
                    format!("{value:?} is not supported: sadesim propagates SGP4 elements ({})", allowed.join(" or ")),
                ));
            }
        }
        let ephemeris_type = self.optional_integer("EPHEMERIS_TYPE", 0)?;
        crate::orbits::check_ephemeris_type(ephemeris_type).map_err(|reason| self.error("EPHEMERIS_TYPE", reason))?;
        let classification = match self.get("CLASSIFICATION_TYPE").map(str::trim) {
            None | Some("U") => sgp4::Classification::Unclassified,
            Some("C") => sgp4::Classification::Classified,
            Some("S") => sgp4::Classification::Secret,
            Some(other) => {
                return Err(self.error("CLASSIFICATION_TYPE", format!("expected U, C or S, found {other:?}")));
            }
        };
        Ok(sgp4::Elements {
            object_name: self.name().map(str::to_string),
            international_designator: self.get("OBJECT_ID").map(str::to_string),
            norad_id: self.integer("NORAD_CAT_ID")?,
            classification,
            datetime: self.epoch()?,
            mean_motion_dot: self.optional_number("MEAN_MOTION_DOT", 0.0)?,
            mean_motion_ddot: self.optional_number("MEAN_MOTION_DDOT", 0.0)?,
            drag_term: self.number("BSTAR", f64::MIN..=f64::MAX, "")?,
            element_set_number: self.optional_integer("ELEMENT_SET_NO", 0)?,
            inclination: self.number("INCLINATION", 0.0..=180.0, " degrees")?,
            right_ascension: self.number("RA_OF_ASC_NODE", -360.0..=360.0, " degrees")?,
            eccentricity: self.number("ECCENTRICITY", 0.0..=0.999_999_9, "")?,
            argument_of_perigee: self.number("ARG_OF_PERICENTER", -360.0..=360.0, " degrees")?,
            mean_anomaly: self.number("MEAN_ANOMALY", -360.0..=360.0, " degrees")?,
            mean_motion: self.number("MEAN_MOTION", 1e-3..=100.0, " revolutions per day")?,
            revolution_number: self.optional_integer("REV_AT_EPOCH", 0)?,
            ephemeris_type: 0,
        })
    }

    fn error(&self, key: &str, reason: String) -> OrbitError {
        OrbitError::Set { at: self.at, name: self.name().map(str::to_string), reason: format!("{key}: {reason}") }
    }

    fn required(&self, key: &str) -> Result<&str, OrbitError> {
        self.get(key).map(str::trim).ok_or_else(|| self.error(key, "missing: an SGP4 element set needs it".into()))
    }

    fn number(&self, key: &str, range: std::ops::RangeInclusive<f64>, unit: &str) -> Result<f64, OrbitError> {
        let text = self.required(key)?;
        self.parse_number(key, text, range, unit)
    }

    fn optional_number(&self, key: &str, default: f64) -> Result<f64, OrbitError> {
        match self.get(key) {
            Some(text) => self.parse_number(key, text.trim(), f64::MIN..=f64::MAX, ""),
            None => Ok(default),
        }
    }

    fn parse_number(
        &self,
        key: &str,
        text: &str,
        range: std::ops::RangeInclusive<f64>,
        unit: &str,
    ) -> Result<f64, OrbitError> {
        match text.parse::<f64>() {
            Ok(v) if v.is_finite() && range.contains(&v) => Ok(v),
            Ok(v) if v.is_finite() => {
                Err(self
                    .error(key, format!("{v} is out of range: expected {} to {}{unit}", range.start(), range.end())))
            }
            _ => Err(self.error(key, format!("expected a number, found {}", quoted(text)))),
        }
    }

    fn integer(&self, key: &str) -> Result<u64, OrbitError> {
        let text = self.required(key)?;
        text.parse().map_err(|_| self.error(key, format!("expected a whole number 0 or more, found {}", quoted(text))))
    }

    fn optional_integer(&self, key: &str, default: u64) -> Result<u64, OrbitError> {
        match self.get(key) {
            Some(_) => self.integer(key),
            None => Ok(default),
        }
    }

    /// `EPOCH`: a UTC calendar date and time (`2020-12-01T12:00:00.000000`, optionally with
    /// `Z`) or an ordinal date (`2020-336T12:00:00`), as CCSDS allows.
    fn epoch(&self) -> Result<sgp4::chrono::NaiveDateTime, OrbitError> {
        let text = self.required("EPOCH")?;
        let bare = text.strip_suffix('Z').unwrap_or(text);
        let parsed = ["%Y-%m-%dT%H:%M:%S%.f", "%Y-%jT%H:%M:%S%.f"]
            .iter()
            .find_map(|format| sgp4::chrono::NaiveDateTime::parse_from_str(bare, format).ok());
        match parsed {
            Some(t) if (1957..=2199).contains(&sgp4::chrono::Datelike::year(&t)) => Ok(t),
            Some(_) => Err(self.error("EPOCH", format!("{} is outside the years 1957 to 2199", quoted(text)))),
            None => Err(self.error(
                "EPOCH",
                format!(
                    "expected a UTC date and time such as 2020-12-01T12:00:00.000000 (or 2020-336T12:00:00), found {}",
                    quoted(text)
                ),
            )),
        }
    }
}

/// A key as the file gives it: bare when it is a CCSDS-style key (capitals, digits, `_`),
/// else quoted on one line.
fn shown_key(key: &str) -> String {
    let plain = !key.is_empty() && key.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_');
    if plain { key.to_string() } else { quoted(key) }
}

/// `text` quoted on one line, cut to 40 characters.
fn quoted(text: &str) -> String {
    let cut: String = text.chars().take(40).collect();
    format!("{cut:?}")
}

fn is_kvn_comment(line: &str) -> bool {
    line == "COMMENT" || line.starts_with("COMMENT ") || line.starts_with("COMMENT\t")
}

/// The element sets of an OMM file in `encoding`.
///
/// # Errors
/// [`OrbitError::Line`] naming the line of a syntax error (a KVN line without `=`, a CSV row
/// of the wrong width, malformed XML or JSON), a repeated key, or a file without element sets.
pub fn records(text: &str, encoding: Encoding) -> Result<Vec<Record>, OrbitError> {
    let text = text.trim_start_matches('\u{feff}');
    let records = match encoding {
        Encoding::Kvn => kvn(text)?,
        Encoding::Xml => xml(text)?,
        Encoding::Json => json(text)?,
        Encoding::Csv => csv(text)?,
    };
    if records.is_empty() {
        return Err(OrbitError::Line { line: 1, reason: format!("an OMM file ({encoding:?}) without element sets") });
    }
    Ok(records)
}

fn kvn(text: &str) -> Result<Vec<Record>, OrbitError> {
    let mut records: Vec<Record> = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let (n, line) = (i + 1, raw.trim());
        if line.is_empty() || is_kvn_comment(line) {
            continue;
        }
        let Some((key, value)) = line.split_once('=') else {
            return Err(OrbitError::Line { line: n, reason: format!("expected KEY = value, found {}", quoted(line)) });
        };
        let key = key.trim();
        if key.is_empty() || !key.bytes().all(|b| b.is_ascii_uppercase() || b.is_ascii_digit() || b == b'_') {
            return Err(OrbitError::Line {
                line: n,
                reason: format!("expected a key of capitals, digits and _, found {}", quoted(key)),
            });
        }
        // A value may carry its unit in brackets: `MEAN_MOTION = 2.00562032 [rev/day]`.
        let value = value.trim();
        let value = match (value.ends_with(']'), value.rfind('[')) {
            (true, Some(open)) => value[..open].trim_end(),
            _ => value,
        };
        if key == "CCSDS_OMM_VERS" {
            records.push(Record::new(At::Line(n)));
            continue;
        }
        let Some(record) = records.last_mut() else {
            return Err(OrbitError::Line {
                line: n,
                reason: "expected CCSDS_OMM_VERS = 2.0 before the first key".into(),
            });
        };
        record.insert(key, value, n)?;
    }
    Ok(records)
}

fn csv(text: &str) -> Result<Vec<Record>, OrbitError> {
    let mut lines =
        text.lines().enumerate().map(|(i, l)| (i + 1, l.trim_end_matches('\r'))).filter(|(_, l)| !l.trim().is_empty());
    let Some((header_line, header)) = lines.next() else { return Ok(Vec::new()) };
    let keys = csv_fields(header).map_err(|reason| OrbitError::Line { line: header_line, reason })?;
    let keys: Vec<String> = keys.into_iter().map(|k| k.trim().to_string()).collect();
    let mut records = Vec::new();
    for (n, line) in lines {
        let values = csv_fields(line).map_err(|reason| OrbitError::Line { line: n, reason })?;
        if values.len() != keys.len() {
            return Err(OrbitError::Line {
                line: n,
                reason: format!(
                    "{} values for the {} columns of the header (line {header_line})",
                    values.len(),
                    keys.len()
                ),
            });
        }
        let mut record = Record::new(At::Line(n));
        for (key, value) in keys.iter().zip(&values) {
            // A repeated column is refused against the header's line.
            record.insert(key, value.trim(), header_line)?;
        }
        records.push(record);
    }
    Ok(records)
}

/// The fields of one CSV row (RFC 4180: fields in double quotes may hold commas, `""` is a
/// quote).
fn csv_fields(line: &str) -> Result<Vec<String>, String> {
    let mut fields = Vec::new();
    let mut chars = line.chars().peekable();
    loop {
        let mut field = String::new();
        if chars.peek() == Some(&'"') {
            chars.next();
            loop {
                match chars.next() {
                    Some('"') if chars.peek() == Some(&'"') => {
                        chars.next();
                        field.push('"');
                    }
                    Some('"') => break,
                    Some(c) => field.push(c),
                    None => return Err("a quoted field is not closed on its line".into()),
                }
            }
            match chars.next() {
                None => {
                    fields.push(field);
                    return Ok(fields);
                }
                Some(',') => fields.push(field),
                Some(c) => return Err(format!("expected a comma after a quoted field, found {c:?}")),
            }
        } else {
            loop {
                match chars.next() {
                    None => {
                        fields.push(field);
                        return Ok(fields);
                    }
                    Some(',') => break,
                    Some(c) => field.push(c),
                }
            }
            fields.push(field);
        }
    }
}

fn json(text: &str) -> Result<Vec<Record>, OrbitError> {
    let value: serde_json::Value = serde_json::from_str(text).map_err(|e| OrbitError::Line {
        line: e.line().clamp(1, last_line(text)),
        reason: format!("column {}: not JSON: {}", e.column(), one_line(&e.to_string())),
    })?;
    let objects = match value {
        serde_json::Value::Array(items) => items,
        object @ serde_json::Value::Object(_) => vec![object],
        _ => return Err(OrbitError::Line { line: 1, reason: "expected a JSON array of element sets, or one".into() }),
    };
    let mut records = Vec::new();
    for (i, item) in objects.into_iter().enumerate() {
        let at = At::Object(i + 1);
        let serde_json::Value::Object(map) = item else {
            return Err(OrbitError::Set { at, name: None, reason: "expected an object of OMM keys".into() });
        };
        let mut record = Record::new(at);
        for (key, value) in map {
            let text = match value {
                serde_json::Value::String(s) => s,
                serde_json::Value::Number(n) => n.to_string(),
                serde_json::Value::Null => continue,
                _ => {
                    return Err(OrbitError::Set {
                        at,
                        name: None,
                        reason: format!("{}: expected a number or text", shown_key(&key)),
                    });
                }
            };
            // serde_json keeps one value per key: no repeats to refuse here.
            record.fields.insert(key, text);
        }
        records.push(record);
    }
    Ok(records)
}

fn one_line(text: &str) -> String {
    text.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// The line numbers of byte positions, counted incrementally: positions asked in increasing
/// order cost one pass over the text in all.
/// The end of the file (after its last line break) counts as its last line.
struct Lines<'a> {
    text: &'a [u8],
    position: usize,
    line: usize,
    last: usize,
}

impl<'a> Lines<'a> {
    fn new(text: &'a str) -> Self {
        Self { text: text.as_bytes(), position: 0, line: 1, last: last_line(text) }
    }

    fn at(&mut self, position: u64) -> usize {
        let end = usize::try_from(position).unwrap_or(usize::MAX).min(self.text.len());
        if end < self.position {
            (self.position, self.line) = (0, 1);
        }
        self.line += self.text[self.position..end].iter().filter(|&&b| b == b'\n').count();
        self.position = end;
        self.line.min(self.last)
    }
}

/// The number of the file's last line (1 for an empty file).
fn last_line(text: &str) -> usize {
    text.lines().count().max(1)
}

fn xml(text: &str) -> Result<Vec<Record>, OrbitError> {
    use quick_xml::events::Event;
    let mut lines = Lines::new(text);
    let mut reader = quick_xml::Reader::from_str(text);
    let mut records: Vec<Record> = Vec::new();
    // The open elements and the lines they open on.
    let mut open: Vec<(String, usize)> = Vec::new();
    let mut in_segment = false;
    // The text of the innermost element, and the line that element starts on.
    let mut content = String::new();
    let mut content_line = 1;
    loop {
        let line = lines.at(reader.buffer_position());
        let event = reader.read_event().map_err(|e| OrbitError::Line {
            line: lines.at(reader.error_position()),
            reason: format!("not well-formed XML: {}", one_line(&e.to_string())),
        })?;
        let bad_text =
            |e: &dyn fmt::Display| OrbitError::Line { line, reason: format!("XML text: {}", one_line(&e.to_string())) };
        match event {
            Event::Start(start) => {
                let name = String::from_utf8_lossy(start.local_name().as_ref()).into_owned();
                if name == "segment" {
                    if in_segment {
                        return Err(OrbitError::Line { line, reason: "a <segment> inside a <segment>".into() });
                    }
                    in_segment = true;
                    records.push(Record::new(At::Line(line)));
                }
                open.push((name, line));
                content.clear();
                content_line = line;
            }
            Event::End(_) => {
                let Some((name, _)) = open.pop() else { break };
                if name == "segment" {
                    in_segment = false;
                } else if in_segment && !content.trim().is_empty() {
                    let record = records.last_mut().expect("a segment opened a record");
                    record.insert(&name, content.trim(), content_line)?;
                }
                content.clear();
            }
            Event::Text(t) => {
                content.push_str(&t.xml_content(quick_xml::XmlVersion::Implicit1_0).map_err(|e| bad_text(&e))?)
            }
            Event::CData(t) => content.push_str(&t.decode().map_err(|e| bad_text(&e))?),
            Event::GeneralRef(r) => {
                let resolved = match r.resolve_char_ref().map_err(|e| bad_text(&e))? {
                    Some(c) => c.to_string(),
                    None => {
                        let name = r.decode().map_err(|e| bad_text(&e))?;
                        quick_xml::escape::resolve_predefined_entity(&name)
                            .ok_or_else(|| bad_text(&format!("unknown entity &{name};")))?
                            .to_string()
                    }
                };
                content.push_str(&resolved);
            }
            Event::Eof => break,
            Event::Empty(_) | Event::Comment(_) | Event::Decl(_) | Event::PI(_) | Event::DocType(_) => {}
        }
    }
    if let Some((name, line)) = open.last() {
        return Err(OrbitError::Line {
            line: *line,
            reason: format!("the element {} opened here is not closed", shown_key(name)),
        });
    }
    Ok(records)
}

#[cfg(test)]
pub(crate) mod tests;
