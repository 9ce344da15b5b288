//! The scenario reference, `docs/scenario-reference.md`: user documentation generated from
//! the CRD's `openAPIV3Schema`, so field names, limits, defaults, rules and descriptions (the
//! doc comments of the types) cannot drift from what the API server and `sadesim` accept.
//!
//! A generator, not a contract: it lives beside the contracts crate's tests (nothing ships
//! it). `checked_in_reference_is_up_to_date` compares the checked-in file with
//! [`scenario_reference_markdown`]; regenerate it with
//! `SADESIM_BLESS=1 cargo test -p sadesim-crds --test reference`.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;

use serde_json::Value;

use sadesim_crds::airframe::AIRFRAME_PRESETS;
use sadesim_crds::document::{API_VERSION, KIND};
use sadesim_crds::fleet::MAX_DRONES;
use sadesim_crds::ground_stations::MIN_PASSPHRASE_CHARS;
use sadesim_crds::validate::{MAX_DURATION_S, MAX_RUN_NAME_LEN};
use sadesim_crds::zones::MAX_POLYGON_VERTICES;

/// Fields of type `kube::core::Duration`. The schema cannot tell them apart from free-form
/// strings (`type: string`, no `format`), so they are listed here; a test checks the list
/// against the schema (every unconstrained string must be one of these).
const DURATION_FIELDS: &[&str] = &[
    "spec.duration",
    "spec.criteria[].reachZone.within",
    "spec.environment.gnss.dropouts[].duration",
    "spec.environment.gnss.dropouts[].start",
    "spec.zones[].activeFrom",
    "spec.zones[].activeUntil",
    "spec.zones[].policy.leaseDuration",
];

/// Where the generated file lives, relative to the workspace root.
const REFERENCE_PATH: &str = "docs/scenario-reference.md";

/// The command that regenerates [`REFERENCE_PATH`].
const BLESS_COMMAND: &str = "SADESIM_BLESS=1 cargo test -p sadesim-crds --test reference";

/// The scenario reference as Markdown. Deterministic: same types, same text.
fn scenario_reference_markdown() -> String {
    let crd = serde_json::to_value(sadesim_crds::crd::crd()).expect("a CRD always serializes");
    let spec = crd
        .pointer("/spec/versions/0/schema/openAPIV3Schema/properties/spec")
        .expect("the CRD has a spec schema")
        .clone();
    let sections = Sections::collect(&spec);

    let mut out = String::new();
    intro(&mut out);
    contents(&mut out, &sections);
    writing_a_scenario(&mut out);
    out.push_str("## Fields\n\n");
    out.push_str(
        "One section per object, starting at `spec`. `[]` in a path means \"each item of the list\". \
         Optional fields may be left out; a default in the table is filled in by the API server, \
         other defaults are described in the field's description and applied by the simulator.\n\n",
    );
    for section in &sections.list {
        render_section(&mut out, section, &sections);
    }
    airframe_presets(&mut out);
    semantic_checks(&mut out);
    // Exactly one trailing newline.
    while out.ends_with("\n\n") {
        out.pop();
    }
    out
}

fn intro(out: &mut String) {
    out.push_str("# SimulationRun scenario reference\n\n");
    let _ = writeln!(
        out,
        "<!-- Generated from the Rust types in crds/src by crds/tests/reference.rs. Do not edit: \
         change the types' doc comments and regenerate with `{BLESS_COMMAND}`. -->\n"
    );
    out.push_str(
        "A **SimulationRun** is one YAML (or JSON) document that declares a whole simulation run: \
         where it happens (`origin`, `world`), how long it lasts (`duration`, `clock`), which drones \
         fly (`fleet`) and who flies them (a scripted `mission` or your software `pilot`), the weather \
         and sensors (`environment`), the airspace rules (`zones`), how the result is judged \
         (`criteria`) and where the evidence is kept (`archive`).\n\n\
         The same document runs locally with the `sadesim` command line and on Kubernetes as a \
         custom resource. This page lists every field with its type, limits and default, the rules \
         that tie fields together, the airframe presets, and the checks `sadesim validate` makes \
         beyond the schema.\n\n",
    );
}

fn contents(out: &mut String, sections: &Sections) {
    out.push_str("## Contents\n\n");
    out.push_str("- [Writing a scenario](#writing-a-scenario)\n");
    out.push_str("- [Fields](#fields)\n");
    for s in &sections.list {
        let depth = s.path.matches('.').count();
        let _ = writeln!(out, "{}- [`{}`](#{})", "  ".repeat(depth + 1), s.path, s.anchor);
    }
    out.push_str("- [Airframe presets](#airframe-presets)\n");
    out.push_str("- [Semantic checks](#semantic-checks)\n\n");
}

/// A minimal, valid scenario (a test parses and validates it).
const EXAMPLE: &str = "\
apiVersion: sadesim.io/v1alpha1
kind: SimulationRun
metadata:
  name: hello-chicago
spec:
  origin: {latitudeDeg: 41.8796, longitudeDeg: -87.6237, altitudeMslM: 181}
  duration: 10m
  clock: {mode: asFastAsPossible}
  seed: 42
  environment:
    wind: {speedMps: 6, directionFromDeg: 270, turbulence: light}
  fleet:
    - name: couriers
      count: 20
      airframe: x500
      operator: acme
      role: delivery
      homes:
        randomInArea:
          center: {latitudeDeg: 41.8781, longitudeDeg: -87.6298}
          radiusM: 300
      altitude: {maxAglM: 120}
      mission:            # every group has a mission, so no spec.pilot is needed
        speedMps: 10
        items:
          - takeoff: {altitudeAglM: 40}
          - waypoint: {latitudeDeg: 41.8850, longitudeDeg: -87.6350, altitudeAglM: 90, holdS: 5}
          - loiter: {holdS: 30}
          - returnToLaunch: {}
  zones:
    - name: museum
      polygon:
        - {latitudeDeg: 41.8787, longitudeDeg: -87.6246}
        - {latitudeDeg: 41.8787, longitudeDeg: -87.6228}
        - {latitudeDeg: 41.8805, longitudeDeg: -87.6228}
        - {latitudeDeg: 41.8805, longitudeDeg: -87.6246}
      ceiling: {heightM: 150, reference: agl}
      policy:
        authorizedOperators: [city-police]
  criteria:
    - noCrashes: {}
    - noUnauthorizedEntries: {}
    - minSeparation: {distanceM: 3}
";

fn writing_a_scenario(out: &mut String) {
    out.push_str("## Writing a scenario\n\n");
    let _ = writeln!(
        out,
        "Every document has `apiVersion: {API_VERSION}`, `kind: {KIND}`, a `metadata.name` (a DNS \
         label of at most {MAX_RUN_NAME_LEN} characters: lowercase letters, digits and `-`) and a \
         `spec`. A small complete scenario:\n"
    );
    let _ = writeln!(out, "```yaml\n{EXAMPLE}```\n");
    out.push_str(
        "A scenario file may hold several runs: YAML documents separated by `---`, a `kind: List`, \
         or a JSON array. Check a file with `sadesim validate scenario.yaml`: it reports every \
         problem at once, each with its field path (`spec.fleet[0].count: must be between 1 and \
         10000, got 0`).\n\n",
    );
    out.push_str("### Conventions\n\n");
    out.push_str(
        "- **Durations** are Go-style strings, as everywhere in Kubernetes: `90s`, `15m`, `1h30m`, \
         `500ms`. They are shown as type `duration` below. Times such as `activeFrom` are measured \
         in simulated time from the start of the run.\n\
         - **Units are part of the field name**, so a number never needs a unit:\n\n\
         \x20 | Suffix | Unit | Example |\n\
         \x20 |---|---|---|\n\
         \x20 | `M` | metres | `radiusM` |\n\
         \x20 | `AglM` | metres above ground level (the ground under the drone) | `maxAglM` |\n\
         \x20 | `MslM` | metres above mean sea level | `altitudeMslM` |\n\
         \x20 | `Deg` | degrees (positions are WGS84 latitude/longitude) | `latitudeDeg` |\n\
         \x20 | `Mps` | metres per second | `speedMps` |\n\
         \x20 | `Hz` | per second | `physicsRateHz` |\n\
         \x20 | `S` | seconds (a number; durations are strings, see above) | `holdS` |\n\
         \x20 | `Millis`, `Mib` | CPU millicores, mebibytes | `cpuMillis`, `memoryMib` |\n\n\
         - **One-of objects** (home placement, mission items, criteria, credentials) are written as \
         an object with a single key naming the variant, e.g. `- takeoff: {altitudeAglM: 30}` or \
         `- noCrashes: {}`. Variants without fields take an empty object `{}`.\n\
         - **Optional fields** can be left out. Names of groups and zones are DNS labels (lowercase \
         letters, digits and `-`), unique within the run.\n\
         - **Rules** listed under a table are checked by the Kubernetes API server (CEL \
         `x-kubernetes-validations`) and by `sadesim validate`.\n\n",
    );
    out.push_str("### On Kubernetes\n\n");
    out.push_str(
        "The same document is a `SimulationRun` custom resource (short name `simrun`). Install the \
         CRD once, then apply scenarios with kubectl:\n\n\
         ```sh\n\
         sadesim crd | kubectl apply -f -\n\
         kubectl apply -f scenario.yaml\n\
         kubectl get simruns   # PHASE, DRONES, SHARDS, SIMTIME, RTF, AGE\n\
         ```\n\n\
         The API server enforces the types, limits, defaults and rules on this page; the semantic \
         checks at the end need `sadesim validate`, so run it before applying. Some fields only \
         matter on Kubernetes: `pilot.image`, `pilot.resources`, `queue`, \
         `credential.secretKeyRef`, `groundStations.allowFrom` and \
         `groundStations.signing.key.secretKeyRef`.\n\n",
    );
}

/// One object with fields: a section of the reference.
struct Section {
    path: String,
    anchor: String,
    schema: Value,
    /// Other paths with the same object (its first path is `path`).
    also_at: Vec<String>,
}

/// Every object section in document order (parents before children), with the anchor of
/// each object path (including paths that share another path's section).
struct Sections {
    list: Vec<Section>,
    anchor_of: BTreeMap<String, String>,
}

impl Sections {
    fn collect(spec: &Value) -> Self {
        let mut s = Self { list: Vec::new(), anchor_of: BTreeMap::new() };
        s.visit("spec".to_string(), spec);
        s
    }

    fn visit(&mut self, path: String, schema: &Value) {
        match type_of(schema) {
            "array" => {
                if let Some(items) = schema.get("items") {
                    self.visit(format!("{path}[]"), items);
                }
            }
            "object" if has_fields(schema) => {
                let key = without_docs(schema);
                if let Some(existing) = self.list.iter_mut().find(|s| without_docs(&s.schema) == key) {
                    existing.also_at.push(path.clone());
                    let anchor = existing.anchor.clone();
                    self.anchor_of.insert(path, anchor);
                    return;
                }
                let anchor = self.unique_anchor(&path);
                self.anchor_of.insert(path.clone(), anchor.clone());
                self.list.push(Section { path: path.clone(), anchor, schema: schema.clone(), also_at: Vec::new() });
                for (name, child) in fields(schema) {
                    self.visit(format!("{path}.{name}"), child);
                }
            }
            _ => {}
        }
    }

    /// `spec.fleet[].homes` -> `spec-fleet-homes`, made unique.
    fn unique_anchor(&self, path: &str) -> String {
        let mut base = String::new();
        for c in path.chars() {
            if c.is_ascii_alphanumeric() {
                base.push(c.to_ascii_lowercase());
            } else if !base.ends_with('-') {
                base.push('-');
            }
        }
        let base = base.trim_end_matches('-').to_string();
        let taken: BTreeSet<&str> = self.list.iter().map(|s| s.anchor.as_str()).collect();
        let mut anchor = base.clone();
        let mut n = 2;
        while taken.contains(anchor.as_str()) || RESERVED_ANCHORS.contains(&anchor.as_str()) {
            anchor = format!("{base}-{n}");
            n += 1;
        }
        anchor
    }
}

/// Anchors of the hand-written headings.
const RESERVED_ANCHORS: &[&str] = &[
    "contents",
    "writing-a-scenario",
    "conventions",
    "on-kubernetes",
    "fields",
    "airframe-presets",
    "semantic-checks",
];

fn type_of(schema: &Value) -> &str {
    schema.get("type").and_then(Value::as_str).unwrap_or("")
}

fn has_fields(schema: &Value) -> bool {
    schema.get("properties").and_then(Value::as_object).is_some_and(|p| !p.is_empty())
}

/// The schema without what differs between uses of the same type.
fn without_docs(schema: &Value) -> Value {
    let mut v = schema.clone();
    if let Some(obj) = v.as_object_mut() {
        obj.remove("description");
        obj.remove("nullable");
    }
    v
}

fn strings(v: Option<&Value>) -> Vec<&str> {
    v.and_then(Value::as_array).map(|a| a.iter().filter_map(Value::as_str).collect()).unwrap_or_default()
}

/// Keys of a one-of object (`oneOf: [{required: [k]}, ...]`), in declaration order.
fn one_of_keys(schema: &Value) -> Vec<&str> {
    schema
        .get("oneOf")
        .and_then(Value::as_array)
        .map(|branches| {
            branches
                .iter()
                .filter_map(|b| match strings(b.get("required")).as_slice() {
                    [k] => Some(*k),
                    _ => None,
                })
                .collect()
        })
        .unwrap_or_default()
}

/// Fields in reading order: one-of variants in declaration order, then required fields,
/// then optional ones, each alphabetically (independent of the JSON map's order).
fn fields(schema: &Value) -> Vec<(&str, &Value)> {
    let Some(props) = schema.get("properties").and_then(Value::as_object) else { return Vec::new() };
    let variants = one_of_keys(schema);
    let required = strings(schema.get("required"));
    let mut out: Vec<(&str, &Value)> = props.iter().map(|(k, v)| (k.as_str(), v)).collect();
    out.sort_by_key(|(k, _)| {
        let variant = variants.iter().position(|v| v == k).unwrap_or(usize::MAX);
        (variant, !required.contains(k), *k)
    });
    out
}

/// The first paragraph of a description on one line, safe in a table cell.
fn first_paragraph(description: &str) -> String {
    let para = description.split("\n\n").next().unwrap_or_default();
    cell(&join_lines(para))
}

fn join_lines(text: &str) -> String {
    text.lines().map(str::trim).filter(|l| !l.is_empty()).collect::<Vec<_>>().join(" ")
}

fn cell(text: &str) -> String {
    text.replace('|', "\\|").replace('\n', " ")
}

fn number(v: &Value) -> String {
    match v.as_f64() {
        Some(f) if f.fract() == 0.0 && f.abs() < 1e15 => format!("{}", f as i64),
        Some(f) => format!("{f}"),
        None => v.to_string(),
    }
}

fn inline_value(v: &Value) -> String {
    match v {
        Value::String(s) => format!("`{s}`"),
        Value::Number(_) => format!("`{}`", number(v)),
        other => format!("`{other}`"),
    }
}

fn description_of(schema: &Value) -> Option<&str> {
    schema.get("description").or_else(|| schema.get("items").and_then(|i| i.get("description"))).and_then(Value::as_str)
}

fn type_cell(schema: &Value, path: &str, sections: &Sections) -> String {
    if schema.get("enum").is_some() {
        return "enum".into();
    }
    match type_of(schema) {
        "string" if DURATION_FIELDS.contains(&path) => "duration".into(),
        "array" => match schema.get("items") {
            Some(items) => format!("list of {}", type_cell(items, &format!("{path}[]"), sections)),
            None => "list".into(),
        },
        "object" => match sections.anchor_of.get(path) {
            Some(anchor) => format!("[object](#{anchor})"),
            None if !has_fields(schema) => "`{}`".into(),
            None => "object".into(),
        },
        "" => "any".into(),
        other => other.into(),
    }
}

fn range(schema: &Value, lo: &str, hi: &str, unit: &str) -> Option<String> {
    let lo = schema.get(lo).map(number);
    let hi = schema.get(hi).map(number);
    let unit = if unit.is_empty() { String::new() } else { format!(" {unit}") };
    match (lo, hi) {
        (Some(l), Some(h)) => Some(format!("{l} to {h}{unit}")),
        (Some(l), None) => Some(format!("≥ {l}{unit}")),
        (None, Some(h)) => Some(format!("≤ {h}{unit}")),
        (None, None) => None,
    }
}

fn limits(schema: &Value) -> Vec<String> {
    let mut out = Vec::new();
    if let Some(values) = schema.get("enum").and_then(Value::as_array) {
        let values: Vec<String> = values.iter().map(inline_value).collect();
        out.push(format!("one of {}", values.join(", ")));
    }
    match type_of(schema) {
        "integer" | "number" => {
            out.extend(range(schema, "minimum", "maximum", ""));
            if let Some(x) = schema.get("exclusiveMinimum").filter(|x| x.is_number()) {
                out.push(format!("> {}", number(x)));
            }
            if let Some(x) = schema.get("exclusiveMaximum").filter(|x| x.is_number()) {
                out.push(format!("< {}", number(x)));
            }
        }
        "string" => {
            out.extend(range(schema, "minLength", "maxLength", "characters"));
            if let Some(p) = schema.get("pattern").and_then(Value::as_str) {
                out.push(format!("pattern `{p}`"));
            }
        }
        "array" => {
            out.extend(range(schema, "minItems", "maxItems", "items"));
            let keys = strings(schema.get("x-kubernetes-list-map-keys"));
            if !keys.is_empty() {
                let keys: Vec<String> = keys.iter().map(|k| format!("`{k}`")).collect();
                out.push(format!("unique {}", keys.join(", ")));
            }
            if let Some(items) = schema.get("items").filter(|i| type_of(i) != "object") {
                let each = limits(items);
                if !each.is_empty() {
                    out.push(format!("each {}", each.join(", ")));
                }
            }
        }
        _ => {}
    }
    out
}

fn render_section(out: &mut String, section: &Section, sections: &Sections) {
    let schema = &section.schema;
    let _ = writeln!(out, "<a id=\"{}\"></a>\n", section.anchor);
    let _ = writeln!(out, "### `{}`\n", section.path);
    if let Some(d) = schema.get("description").and_then(Value::as_str) {
        let paragraphs: Vec<String> = d.split("\n\n").map(join_lines).filter(|p| !p.is_empty()).collect();
        let _ = writeln!(out, "{}\n", paragraphs.join("\n\n"));
    }
    if !section.also_at.is_empty() {
        let paths: Vec<String> = section.also_at.iter().map(|p| format!("`{p}`")).collect();
        let _ = writeln!(out, "The same object is used at {}.\n", paths.join(", "));
    }
    let variants = one_of_keys(schema);
    if !variants.is_empty() {
        let what = if section.path.ends_with("[]") { "Each item sets" } else { "Set" };
        let _ = writeln!(out, "{what} exactly one of these keys.\n");
    }
    let required = strings(schema.get("required"));
    out.push_str("| Field | Type | Required | Default | Limits | Description |\n");
    out.push_str("|---|---|---|---|---|---|\n");
    for (name, child) in fields(schema) {
        let path = format!("{}.{name}", section.path);
        let req = if variants.contains(&name) {
            "one of"
        } else if required.contains(&name) {
            "yes"
        } else {
            "no"
        };
        let default = child.get("default").map(inline_value).unwrap_or_default();
        let _ = writeln!(
            out,
            "| `{name}` | {} | {req} | {} | {} | {} |",
            type_cell(child, &path, sections),
            cell(&default),
            cell(&limits(child).join("; ")),
            description_of(child).map(first_paragraph).unwrap_or_default(),
        );
    }
    out.push('\n');
    let rules: Vec<&str> = schema
        .get("x-kubernetes-validations")
        .and_then(Value::as_array)
        .map(|rules| {
            rules.iter().filter_map(|r| r.get("message").or_else(|| r.get("rule")).and_then(Value::as_str)).collect()
        })
        .unwrap_or_default();
    if !rules.is_empty() {
        out.push_str("Rules:\n\n");
        for r in rules {
            let _ = writeln!(out, "- {}", join_lines(r));
        }
        out.push('\n');
    }
}

fn airframe_presets(out: &mut String) {
    out.push_str("## Airframe presets\n\n");
    out.push_str(
        "Values for [`spec.fleet[].airframe`](#spec-fleet). The physical parameters (mass, inertia, \
         motors) come with the simulator.\n\n",
    );
    out.push_str("| Name | Description |\n|---|---|\n");
    for p in AIRFRAME_PRESETS {
        let _ = writeln!(out, "| `{}` | {} |", p.name, cell(p.description));
    }
    out.push('\n');
}

fn semantic_checks(out: &mut String) {
    let max_h = MAX_DURATION_S / 3600.0;
    out.push_str("## Semantic checks\n\n");
    out.push_str(
        "`sadesim validate` reads a document with the types above (missing required fields, unknown \
         fields, wrong types and unsupported values are errors, all listed at once), checks the numeric limits and the rules, and also checks what the schema \
         cannot express. It reports every problem at once, each with its field path.\n\n",
    );
    let checks = [
        format!("`metadata.name` is set and is a DNS label of at most {MAX_RUN_NAME_LEN} characters (the run's pods are named after it)."),
        "All numbers are finite (no `.nan` or `.inf`).".to_string(),
        format!("Every duration (`duration`, `reachZone.within`, GNSS dropout `duration`, `leaseDuration`) is positive and at most {MAX_DURATION_S} s ({max_h} h)."),
        "`clock.factor` is set exactly when `clock.mode` is `scaled`.".to_string(),
        "`world.city.maxBuildingHeightM` is at least `medianBuildingHeightM`.".to_string(),
        format!("The fleet has at least one group, group names are unique, and all groups together have at most {MAX_DRONES} drones."),
        "`airframe` names one of the [airframe presets](#airframe-presets).".to_string(),
        "`homes.explicit` lists exactly `count` positions.".to_string(),
        "Homes, waypoints, home areas and `randomWaypoints` areas (with their whole radius) and zone vertices lie inside the world: the square of half-width `world.extentM` around the origin.".to_string(),
        "`altitude.minAglM` is below `altitude.maxAglM`.".to_string(),
        "A mission starts with `takeoff`; no mission altitude (`takeoff`, `waypoint`, `randomWaypoints`) exceeds the group's `altitude.maxAglM`; `randomWaypoints.minAltitudeAglM` does not exceed `maxAltitudeAglM`.".to_string(),
        format!("Zone names are unique; a zone polygon has 3 to {MAX_POLYGON_VERTICES} vertices, no two consecutive vertices at the same place, no self-intersection, and encloses at least 1 m²."),
        "A zone's floor is below its ceiling (an AGL height is compared with an MSL one using the origin's ground altitude).".to_string(),
        "`activeFrom` is not negative and before the run ends; `activeUntil` is after `activeFrom`.".to_string(),
        "`policy.minAltitudeAglM` is below `policy.maxAltitudeAglM` and below an AGL ceiling; `authorizedOperators` entries are not empty.".to_string(),
        "GNSS dropouts do not start before the run and name existing groups.".to_string(),
        "`spec.pilot` is present when any group has no `mission`; it has a `command` (local runs) or an `image` (Kubernetes), and `command[0]` names a program.".to_string(),
        "Pilot environment variable names are valid (`[A-Za-z_][A-Za-z0-9_]*`), unique, and do not start with `SADESIM_` (reserved for variables the platform sets).".to_string(),
        "`archive.url` uses `file`, `s3`, `gs` or `az`; `file://` needs a folder and the others a bucket or container.".to_string(),
        "`queue` is a DNS label.".to_string(),
        format!("`groundStations.allowFrom` entries are CIDR ranges; an inline `groundStations.signing.key.value` has at least {MIN_PASSPHRASE_CHARS} characters."),
        "`reachZone` and `zoneVerdicts` criteria name existing groups and zones; `landedNear` names an existing marker of `world.markers`.".to_string(),
    ];
    for c in checks {
        let _ = writeln!(out, "- {c}");
    }
    out.push('\n');
}

#[cfg(test)]
mod tests {
    use super::*;

    fn reference_file() -> &'static str {
        concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/scenario-reference.md")
    }

    #[test]
    fn checked_in_reference_is_up_to_date() {
        let generated = scenario_reference_markdown();
        let path = reference_file();
        if std::env::var("SADESIM_BLESS").as_deref() == Ok("1") {
            let dir = std::path::Path::new(path).parent().expect("the path has a folder");
            std::fs::create_dir_all(dir).expect("create docs/");
            std::fs::write(path, &generated).expect("write docs/scenario-reference.md");
            return;
        }
        let Ok(on_disk) = std::fs::read_to_string(path) else {
            panic!("{REFERENCE_PATH} is missing. Generate it with `{BLESS_COMMAND}` and commit the result.");
        };
        if on_disk != generated {
            let line = on_disk
                .lines()
                .zip(generated.lines())
                .position(|(a, b)| a != b)
                .map_or_else(|| on_disk.lines().count().min(generated.lines().count()) + 1, |i| i + 1);
            panic!(
                "{REFERENCE_PATH} is stale (first difference at line {line}): the CRD types changed. \
                 Regenerate it with `{BLESS_COMMAND}` and commit the result."
            );
        }
    }

    /// The row of `field` in the section titled `section`.
    fn row<'a>(doc: &'a str, section: &str, field: &str) -> &'a str {
        let heading = format!("### `{section}`\n");
        let start = doc.find(&heading).unwrap_or_else(|| panic!("no section {section}"));
        let body = &doc[start + heading.len()..];
        let body = &body[..body.find("\n### ").unwrap_or(body.len())];
        let prefix = format!("| `{field}` |");
        body.lines().find(|l| l.starts_with(&prefix)).unwrap_or_else(|| panic!("no row {field} in {section}"))
    }

    #[test]
    fn reference_mentions_every_spec_field_and_their_limits() {
        let doc = scenario_reference_markdown();
        let top = [
            "origin",
            "duration",
            "clock",
            "physicsRateHz",
            "seed",
            "world",
            "environment",
            "fleet",
            "zones",
            "pilot",
            "rendering",
            "sharding",
            "recording",
            "archive",
            "criteria",
            "queue",
            "abort",
        ];
        for field in top {
            row(&doc, "spec", field);
        }
        let count = row(&doc, "spec.fleet[]", "count");
        assert!(count.contains("| yes |") && count.contains("1 to 10000"), "{count}");
        assert!(row(&doc, "spec", "physicsRateHz").contains("50 to 10000"));
        assert!(row(&doc, "spec", "duration").contains("| duration |"));
        assert!(row(&doc, "spec", "fleet").contains("1 to 64 items; unique `name`"));
        assert!(row(&doc, "spec", "queue").contains("pattern `^[a-z0-9]([-a-z0-9]*[a-z0-9])?$`"));
        assert!(row(&doc, "spec.zones[]", "polygon").contains("3 to 256 items"));
        assert!(row(&doc, "spec.world.city", "builtFraction").contains("| `0.5` | 0 to 1 |"));
        assert!(row(&doc, "spec.environment.wind", "turbulence").contains("one of `none`, `light`"));
        assert!(row(&doc, "spec.fleet[].homes", "randomInArea").contains("| one of |"));
        assert!(row(&doc, "spec.fleet[].mission.items[]", "returnToLaunch").contains("| `{}` |"));
        assert!(row(&doc, "spec.archive", "url").contains(r"pattern `^(file\|s3\|gs\|az)://`"));
        assert!(row(&doc, "spec.criteria[]", "minSeparation").contains("(#spec-criteria-minseparation)"));
        assert!(doc.contains("- clock.factor is required with mode scaled and only allowed with it"));
        for p in AIRFRAME_PRESETS {
            assert!(doc.contains(&format!("| `{}` |", p.name)), "{}", p.name);
        }
    }

    #[test]
    fn every_link_has_an_anchor_and_anchors_are_unique() {
        let doc = scenario_reference_markdown();
        let mut anchors: Vec<&str> =
            doc.lines().filter_map(|l| l.strip_prefix("<a id=\"").and_then(|l| l.strip_suffix("\"></a>"))).collect();
        anchors.extend(RESERVED_ANCHORS);
        let unique: BTreeSet<&str> = anchors.iter().copied().collect();
        assert_eq!(unique.len(), anchors.len(), "duplicate anchors");
        for link in doc.split("](#").skip(1) {
            let target = &link[..link.find(')').expect("closed link")];
            assert!(unique.contains(target), "link to missing anchor #{target}");
        }
    }

    fn unconstrained_strings(schema: &Value, path: &str, out: &mut BTreeSet<String>) {
        let constrained = ["enum", "pattern", "minLength", "maxLength", "format"];
        if type_of(schema) == "string" && !constrained.iter().any(|k| schema.get(k).is_some()) {
            out.insert(path.to_string());
        }
        if let Some(items) = schema.get("items") {
            unconstrained_strings(items, &format!("{path}[]"), out);
        }
        for (name, child) in fields(schema) {
            unconstrained_strings(child, &format!("{path}.{name}"), out);
        }
    }

    #[test]
    fn duration_fields_match_the_schema() {
        let crd = serde_json::to_value(sadesim_crds::crd::crd()).unwrap();
        let spec = crd.pointer("/spec/versions/0/schema/openAPIV3Schema/properties/spec").unwrap();
        let mut found = BTreeSet::new();
        unconstrained_strings(spec, "spec", &mut found);
        let listed: BTreeSet<String> = DURATION_FIELDS.iter().map(|s| s.to_string()).collect();
        assert_eq!(
            found, listed,
            "every string without limits should be a Duration listed in DURATION_FIELDS; give other strings a maxLength"
        );
    }

    #[test]
    fn example_scenario_is_valid() {
        let doc = scenario_reference_markdown();
        assert!(doc.contains(EXAMPLE));
        let run = sadesim_crds::parse_run(EXAMPLE).expect("the example parses");
        sadesim_crds::validate(&run).expect("the example validates");
    }

    #[test]
    fn output_is_deterministic() {
        assert_eq!(scenario_reference_markdown(), scenario_reference_markdown());
    }
}
