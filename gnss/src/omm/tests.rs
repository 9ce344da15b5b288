use super::*;
use crate::orbits::{Constellation, System};

/// GPS SVN 43 (PRN 13), Galileo's first satellite and the ISS, which a GNSS constellation
/// skips, as TLE.
use crate::orbits::tests::SAMPLE as TLE;

/// The keys and values of an element set, in CelesTrak's order.
fn fields(e: &sgp4::Elements) -> Vec<(&'static str, String)> {
    vec![
        ("OBJECT_NAME", e.object_name.clone().unwrap_or_default()),
        ("OBJECT_ID", e.international_designator.clone().unwrap_or_default()),
        ("EPOCH", e.datetime.format("%Y-%m-%dT%H:%M:%S%.6f").to_string()),
        ("MEAN_MOTION", e.mean_motion.to_string()),
        ("ECCENTRICITY", e.eccentricity.to_string()),
        ("INCLINATION", e.inclination.to_string()),
        ("RA_OF_ASC_NODE", e.right_ascension.to_string()),
        ("ARG_OF_PERICENTER", e.argument_of_perigee.to_string()),
        ("MEAN_ANOMALY", e.mean_anomaly.to_string()),
        ("EPHEMERIS_TYPE", "0".into()),
        ("CLASSIFICATION_TYPE", "U".into()),
        ("NORAD_CAT_ID", e.norad_id.to_string()),
        ("ELEMENT_SET_NO", e.element_set_number.to_string()),
        ("REV_AT_EPOCH", e.revolution_number.to_string()),
        ("BSTAR", e.drag_term.to_string()),
        ("MEAN_MOTION_DOT", e.mean_motion_dot.to_string()),
        ("MEAN_MOTION_DDOT", e.mean_motion_ddot.to_string()),
    ]
}

/// `sets` written in `encoding` the way CelesTrak writes it (for tests and fuzz seeds).
pub(crate) fn encode(sets: &[sgp4::Elements], encoding: Encoding) -> String {
    match encoding {
        Encoding::Kvn => sets
            .iter()
            .map(|e| {
                let mut text = "CCSDS_OMM_VERS = 2.0\nCOMMENT GENERATED FOR A TEST\nORIGINATOR = SADESIM\n".to_string();
                text += "CENTER_NAME = EARTH\nREF_FRAME = TEME\nTIME_SYSTEM = UTC\nMEAN_ELEMENT_THEORY = SGP4\n";
                for (k, v) in fields(e) {
                    let unit = if k == "MEAN_MOTION" { " [rev/day]" } else { "" };
                    text += &format!("{k} = {v}{unit}\n");
                }
                text
            })
            .collect(),
        Encoding::Xml => {
            let mut text = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<ndm>\n".to_string();
            for e in sets {
                let f = fields(e);
                let tag = |range: std::ops::Range<usize>| -> String {
                    f[range]
                        .iter()
                        .map(|(k, v)| format!("<{k}>{}</{k}>", quick_xml::escape::escape(v.as_str())))
                        .collect()
                };
                text += &format!(
                    "<omm id=\"CCSDS_OMM_VERS\" version=\"2.0\">\n<header><CREATION_DATE/><ORIGINATOR/></header>\n<body><segment>\n\
                     <metadata>{}<CENTER_NAME>EARTH</CENTER_NAME><REF_FRAME>TEME</REF_FRAME><TIME_SYSTEM>UTC</TIME_SYSTEM>\
                     <MEAN_ELEMENT_THEORY>SGP4</MEAN_ELEMENT_THEORY></metadata>\n<data><meanElements>{}</meanElements>\n\
                     <tleParameters>{}</tleParameters></data>\n</segment></body></omm>\n",
                    tag(0..2),
                    tag(2..9),
                    tag(9..17)
                );
            }
            text + "</ndm>\n"
        }
        Encoding::Json => {
            let objects: Vec<serde_json::Value> = sets
                .iter()
                .map(|e| {
                    let map = fields(e)
                        .into_iter()
                        .map(|(k, v)| {
                            let text = k == "OBJECT_NAME" || k == "OBJECT_ID" || k == "EPOCH";
                            let value = match (v.parse::<u64>(), v.parse::<f64>()) {
                                (Ok(n), _) if !text => serde_json::json!(n),
                                (_, Ok(x)) if !text => serde_json::json!(x),
                                _ => serde_json::Value::String(v),
                            };
                            (k.to_string(), value)
                        })
                        .collect();
                    serde_json::Value::Object(map)
                })
                .collect();
            serde_json::to_string_pretty(&objects).expect("JSON values serialize")
        }
        Encoding::Csv => {
            let header = fields(&sets[0]).iter().map(|(k, _)| *k).collect::<Vec<_>>().join(",");
            let rows: String = sets
                .iter()
                .map(|e| {
                    let row: Vec<String> = fields(e)
                        .into_iter()
                        .map(|(_, v)| if v.contains(',') { format!("\"{}\"", v.replace('"', "\"\"")) } else { v })
                        .collect();
                    format!("{}\r\n", row.join(","))
                })
                .collect();
            format!("{header}\r\n{rows}")
        }
    }
}

fn tle_elements() -> Vec<sgp4::Elements> {
    TLE.lines()
        .collect::<Vec<_>>()
        .chunks(3)
        .map(|set| {
            let name = set[0].trim_start_matches("0 ").to_string();
            sgp4::Elements::from_tle(Some(name), set[1].as_bytes(), set[2].as_bytes()).expect("the sample reads")
        })
        .collect()
}

const ALL: [Encoding; 4] = [Encoding::Kvn, Encoding::Xml, Encoding::Json, Encoding::Csv];

#[test]
fn every_encoding_gives_the_sky_the_same_sets_give_as_tle() {
    let tle = Constellation::parse(TLE).expect("the TLE reads");
    let t = tle.newest_epoch_unix_s() + 5_400.0;
    let expected = tle.positions(t);
    for encoding in ALL {
        let text = encode(&tle_elements(), encoding);
        assert_eq!(Encoding::of(&text), Some(encoding), "{text}");
        let omm = Constellation::parse(&text).unwrap_or_else(|e| panic!("{encoding:?}: {e}\n{text}"));
        let kept: Vec<(&str, u64, System)> =
            omm.satellites.iter().map(|s| (s.name.as_str(), s.norad_id, s.system)).collect();
        assert_eq!(
            kept,
            [("NAVSTAR 43 (USA 132)", 24876, System::Gps), ("GALILEO-PFM", 37846, System::Galileo)],
            "{encoding:?}"
        );
        for (a, b) in expected.iter().zip(omm.positions(t)) {
            let d = ((a.ecef.x_m - b.ecef.x_m).powi(2)
                + (a.ecef.y_m - b.ecef.y_m).powi(2)
                + (a.ecef.z_m - b.ecef.z_m).powi(2))
            .sqrt();
            // The OMM epoch is written to the microsecond: a satellite moves 4 mm in it.
            assert!(d < 0.01, "{encoding:?}: {d} m apart");
        }
    }
}

#[test]
fn catalogue_numbers_beyond_a_tle_s_five_digits_read() {
    let mut sets = tle_elements();
    sets.truncate(1);
    sets[0].norad_id = 123_456_789;
    for encoding in ALL {
        let c = Constellation::parse(&encode(&sets, encoding)).unwrap_or_else(|e| panic!("{encoding:?}: {e}"));
        assert_eq!(c.satellites[0].norad_id, 123_456_789, "{encoding:?}");
    }
}

#[test]
fn celestrak_s_shapes_read_units_comments_quotes_entities_strings_and_ordinal_dates() {
    // Space-Track's JSON gives every value as text; an ordinal-date epoch is CCSDS too.
    let json = r#"[{"OBJECT_NAME":"NAVSTAR 43 (USA 132)","NORAD_CAT_ID":"24876","EPOCH":"2020-334T23:14:27.067776Z",
        "MEAN_MOTION":"2.00562032","ECCENTRICITY":"0.0046391","INCLINATION":"55.4606","RA_OF_ASC_NODE":"177.6943",
        "ARG_OF_PERICENTER":"58.6753","MEAN_ANOMALY":"301.8606","BSTAR":"0","MEAN_MOTION_DOT":null}]"#;
    let c = Constellation::parse(json).expect("Space-Track's JSON reads");
    let tle = Constellation::parse(TLE).unwrap();
    assert!((c.satellites[0].epoch_unix_s - tle.satellites[0].epoch_unix_s).abs() < 1e-5);
    // A name holding a comma (quoted in CSV) and an ampersand (an entity in XML).
    let mut sets = tle_elements();
    sets.truncate(1);
    sets[0].object_name = Some("GPS BIIR-2 (PRN 13), \"A&B\"".into());
    for encoding in [Encoding::Csv, Encoding::Xml, Encoding::Kvn] {
        let text = encode(&sets, encoding);
        let c = Constellation::parse(&text).unwrap_or_else(|e| panic!("{encoding:?}: {e}\n{text}"));
        assert_eq!(c.satellites[0].name, "GPS BIIR-2 (PRN 13), \"A&B\"", "{encoding:?}");
    }
    let kvn = encode(&sets, Encoding::Kvn);
    assert!(kvn.contains("[rev/day]") && kvn.contains("COMMENT"));
}

/// The error of reading `text`, as one line.
fn error(text: &str) -> String {
    let e = Constellation::parse(text).expect_err("refused").to_string();
    assert!(!e.contains('\n'), "{e}");
    e
}

#[test]
fn a_missing_or_wrong_key_is_named_with_its_element_set() {
    let kvn = encode(&tle_elements(), Encoding::Kvn);
    let without = kvn.replacen("MEAN_MOTION = ", "MEAN_MOTION_X = ", 1);
    assert_eq!(error(&without), "line 1 (NAVSTAR 43 (USA 132)): MEAN_MOTION: missing: an SGP4 element set needs it");
    let second = kvn.match_indices("CCSDS_OMM_VERS").nth(1).unwrap().0;
    let line = kvn[..second].lines().count() + 1;
    let bad = format!("{}{}", &kvn[..second], kvn[second..].replacen("ECCENTRICITY = ", "ECCENTRICITY = 0..2 #", 1));
    assert_eq!(
        error(&bad),
        format!("line {line} (GALILEO-PFM): ECCENTRICITY: expected a number, found \"0..2 #0.0002118\"")
    );
    let hyperbolic = kvn.replacen("ECCENTRICITY = 0.0046391", "ECCENTRICITY = 1.5", 1);
    assert!(error(&hyperbolic).contains("ECCENTRICITY: 1.5 is out of range: expected 0 to 0.9999999"));
    let json =
        encode(&tle_elements(), Encoding::Json).replacen("\"EPOCH\": \"2020-11-29T", "\"EPOCH\": \"29/11/2020 ", 1);
    let e = error(&json);
    assert!(
        e.starts_with("object 1 of the JSON array (NAVSTAR 43 (USA 132)): EPOCH: expected a UTC date and time"),
        "{e}"
    );
    let csv = encode(&tle_elements(), Encoding::Csv).replacen(",24876,", ",-24876,", 1);
    assert_eq!(
        error(&csv),
        "line 2 (NAVSTAR 43 (USA 132)): NORAD_CAT_ID: expected a whole number 0 or more, found \"-24876\""
    );
}

#[test]
fn other_theories_frames_and_time_systems_are_refused_not_propagated_as_sgp4() {
    let kvn = encode(&tle_elements(), Encoding::Kvn);
    for (from, to, key) in [
        ("REF_FRAME = TEME", "REF_FRAME = GCRF", "REF_FRAME: \"GCRF\" is not supported"),
        ("TIME_SYSTEM = UTC", "TIME_SYSTEM = TAI", "TIME_SYSTEM: \"TAI\" is not supported"),
        ("CENTER_NAME = EARTH", "CENTER_NAME = MOON", "CENTER_NAME: \"MOON\" is not supported"),
        (
            "MEAN_ELEMENT_THEORY = SGP4",
            "MEAN_ELEMENT_THEORY = SGP4-XP",
            "MEAN_ELEMENT_THEORY: \"SGP4-XP\" is not supported",
        ),
        (
            "EPHEMERIS_TYPE = 0",
            "EPHEMERIS_TYPE = 4",
            "EPHEMERIS_TYPE: 4 is not supported: expected 0 (SGP4); 4 is SGP4-XP",
        ),
    ] {
        let e = error(&kvn.replacen(from, to, 1));
        assert!(e.starts_with("line 1 (NAVSTAR 43 (USA 132)): ") && e.contains(key), "{e}");
    }
    // CCSDS's own spelling of the theory is SGP4's.
    assert!(Constellation::parse(&kvn.replace("MEAN_ELEMENT_THEORY = SGP4", "MEAN_ELEMENT_THEORY = SGP/SGP4")).is_ok());
    // The same refusal for a TLE whose line 1 says SGP4-XP (column 63).
    let xp = "0 NAVSTAR 43 (USA 132)\n1 24876U 97035A   20334.96836884 +.00000096 +00000-0 +00000-0 4  9994\n\
              2 24876 055.4606 177.6943 0046391 058.6753 301.8606 02.00562032171136\n";
    let e = error(xp);
    assert!(e.starts_with("line 2 (NAVSTAR 43 (USA 132)): the elements cannot be propagated: ephemeris type 4"), "{e}");
}

#[test]
fn syntax_errors_name_their_line() {
    let kvn = encode(&tle_elements(), Encoding::Kvn);
    assert_eq!(
        error(&kvn.replacen("ORIGINATOR = SADESIM", "ORIGINATOR SADESIM", 1)),
        "line 3: expected KEY = value, found \"ORIGINATOR SADESIM\""
    );
    assert_eq!(
        error(&kvn.replacen("BSTAR = 0\n", "BSTAR = 0\nBSTAR = 1\n", 1)),
        "line 23: BSTAR given twice in the element set of line 1"
    );
    let csv = encode(&tle_elements(), Encoding::Csv);
    let short = csv.replacen(",U,", ",", 2);
    assert_eq!(error(&short), "line 2: 16 values for the 17 columns of the header (line 1)");
    assert_eq!(error(&csv.replacen("NAVSTAR", "\"NAVSTAR", 1)), "line 2: a quoted field is not closed on its line");
    let xml = encode(&tle_elements(), Encoding::Xml);
    let line_of = |text: &str, what: &str| text[..text.find(what).unwrap()].lines().count();
    let e = error(&xml.replacen("</INCLINATION>", "</INCLINATIO>", 1));
    assert!(e.starts_with(&format!("line {}: not well-formed XML:", line_of(&xml, "</INCLINATION>"))), "{e}");
    // Found by fuzz/fuzz_targets/orbits.rs: a file cut short was blamed on the line after its
    // last line break, past the end of the file; the element's own line is the one to name.
    assert_eq!(error(&xml[..xml.len() - 7]), "line 2: the element ndm opened here is not closed");
    // Keys that are not CCSDS-style are quoted, so that an error stays one line.
    assert_eq!(error("[{\"A\\nB\": [1]}]"), "object 1 of the JSON array: \"A\\nB\": expected a number or text");
    let json = encode(&tle_elements(), Encoding::Json);
    let e = error(&json.replacen("\"MEAN_MOTION\":", "\"MEAN_MOTION\" ", 1));
    assert!(
        e.starts_with(&format!("line {}: column ", line_of(&json, "\"MEAN_MOTION\":"))) && e.contains("not JSON"),
        "{e}"
    );
    assert_eq!(error("[1]"), "object 1 of the JSON array: expected an object of OMM keys");
    assert_eq!(error("[]"), "line 1: an OMM file (Json) without element sets");
    // Not an orbit file at all: what it is not is said, with its first line.
    let e = error("<html>\n<body>not found</body>\n</html>\n");
    assert!(e.starts_with("not an orbit file: neither TLE") && e.contains("\"<html>\""), "{e}");
}

#[test]
fn a_catalogue_s_other_objects_are_read_past_field_by_field() {
    // The ISS's set is broken, but it is not a navigation satellite: only its syntax counts.
    let kvn = encode(&tle_elements(), Encoding::Kvn);
    let iss = kvn.rfind("CCSDS_OMM_VERS").unwrap();
    let broken = format!("{}{}", &kvn[..iss], kvn[iss..].replacen("MEAN_MOTION = ", "MEAN_MOTION = fast", 1));
    assert_eq!(Constellation::parse(&broken).expect("reads").satellites.len(), 2);
    let only_iss = &kvn[iss..];
    assert_eq!(
        error(only_iss),
        "no GPS, Galileo, GLONASS or BeiDou satellite among 1 element sets: expected an orbit file of navigation satellites (e.g. CelesTrak's gnss group)"
    );
}
