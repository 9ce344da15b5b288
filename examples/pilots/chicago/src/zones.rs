//! Zones as the pilot knows them: the GeoJSON of the fleet file's `zones` field and of the
//! authority's `GET /zones`, turned into outlines on the run's local plane.

use sadesim_crds::geo::LocalFrame;
use sadesim_crds::polygon::Point;
use serde_json::Value;

/// One zone: its outline on the local plane and what a lease holder must respect inside.
#[derive(Clone, Debug, PartialEq)]
pub struct Zone {
    pub name: String,
    /// Outline `(east_m, north_m)` in the run's local frame, not repeating the first vertex.
    pub outline: Vec<Point>,
    /// The policy's lowest altitude above ground inside the zone, metres (the paper's
    /// 350 ft), when it has one. A lease states the binding value.
    pub min_altitude_agl_m: Option<f64>,
}

/// A GeoJSON document that is not a FeatureCollection of zone polygons.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{field}: {problem}")]
pub struct ZonesError {
    /// JSON path of the offending value, e.g. `features[0].geometry.coordinates`.
    pub field: String,
    pub problem: String,
}

fn err(field: impl Into<String>, problem: impl Into<String>) -> ZonesError {
    ZonesError { field: field.into(), problem: problem.into() }
}

/// Parses a FeatureCollection of Polygon features (`[lon, lat]` rings, RFC 7946) with a
/// `name` property, projecting the outer ring onto `frame`'s plane.
///
/// # Errors
/// The first field that does not have the expected shape, by its JSON path.
pub fn from_geojson(collection: &Value, frame: &LocalFrame) -> Result<Vec<Zone>, ZonesError> {
    if collection.get("type").and_then(Value::as_str) != Some("FeatureCollection") {
        return Err(err("type", "expected \"FeatureCollection\""));
    }
    let features =
        collection.get("features").and_then(Value::as_array).ok_or_else(|| err("features", "expected an array"))?;
    features.iter().enumerate().map(|(i, f)| feature(f, &format!("features[{i}]"), frame)).collect()
}

fn feature(f: &Value, path: &str, frame: &LocalFrame) -> Result<Zone, ZonesError> {
    let props = f.get("properties").ok_or_else(|| err(format!("{path}.properties"), "missing"))?;
    let name = props
        .get("name")
        .and_then(Value::as_str)
        .or_else(|| f.get("id").and_then(Value::as_str))
        .ok_or_else(|| err(format!("{path}.properties.name"), "expected the zone name as a string"))?
        .to_owned();
    let geometry = f.get("geometry").ok_or_else(|| err(format!("{path}.geometry"), "missing"))?;
    if geometry.get("type").and_then(Value::as_str) != Some("Polygon") {
        return Err(err(format!("{path}.geometry.type"), "expected \"Polygon\""));
    }
    let ring = geometry
        .get("coordinates")
        .and_then(Value::as_array)
        .and_then(|rings| rings.first())
        .and_then(Value::as_array)
        .ok_or_else(|| err(format!("{path}.geometry.coordinates"), "expected an array of rings"))?;
    let mut outline = Vec::with_capacity(ring.len());
    for (k, position) in ring.iter().enumerate() {
        let pair = position.as_array().filter(|p| p.len() >= 2);
        let lon_lat = pair.and_then(|p| Some((p[0].as_f64()?, p[1].as_f64()?)));
        let Some((lon, lat)) = lon_lat else {
            return Err(err(
                format!("{path}.geometry.coordinates[0][{k}]"),
                "expected [longitude, latitude] in degrees",
            ));
        };
        outline.push(frame.to_plane(lat, lon));
    }
    if outline.len() >= 2 && outline.first() == outline.last() {
        outline.pop(); // GeoJSON rings repeat their first position at the end
    }
    if outline.len() < 3 {
        return Err(err(
            format!("{path}.geometry.coordinates[0]"),
            "a zone outline needs at least 3 distinct vertices",
        ));
    }
    let min_altitude_agl_m = props.get("policy").and_then(|p| p.get("minAltitudeAglM")).and_then(Value::as_f64);
    Ok(Zone { name, outline, min_altitude_agl_m })
}

#[cfg(test)]
mod tests {
    use super::*;
    use sadesim_crds::geo::GeoPoint;
    use serde_json::json;

    fn frame() -> LocalFrame {
        LocalFrame::new(GeoPoint::new(41.8796, -87.6237, 181.0))
    }

    #[test]
    fn the_museum_zone_projects_to_a_300_m_block_east_of_the_origin() {
        let doc = json!({"type": "FeatureCollection", "features": [{
            "type": "Feature", "id": "museum-tfr",
            "geometry": {"type": "Polygon", "coordinates": [[
                [-87.6245, 41.8807], [-87.6245, 41.8781], [-87.6208, 41.8781], [-87.6208, 41.8807], [-87.6245, 41.8807]
            ]]},
            "properties": {"name": "museum-tfr", "floor": {"heightM": 0.0, "reference": "agl"},
                           "ceiling": {"heightM": 152.4, "reference": "agl"},
                           "policy": {"authorizedOperators": ["chicago-dps"], "minAltitudeAglM": 106.68}}
        }]});
        let zones = from_geojson(&doc, &frame()).unwrap();
        assert_eq!(zones.len(), 1);
        let z = &zones[0];
        assert_eq!(z.name, "museum-tfr");
        assert_eq!(z.outline.len(), 4, "the closing position is dropped");
        assert_eq!(z.min_altitude_agl_m, Some(106.68));
        let (x0, y0, x1, y1) = crate::geometry::bounds(&z.outline);
        assert!((x1 - x0 - 307.0).abs() < 3.0, "Michigan Ave to Columbus Dr ~307 m: {}", x1 - x0);
        assert!((y1 - y0 - 289.0).abs() < 3.0, "Monroe St to Jackson Dr ~289 m: {}", y1 - y0);
        assert!(x0 < -60.0 && x0 > -80.0, "Michigan Ave is ~66 m west of the origin: {x0}");
    }

    #[test]
    fn malformed_collections_name_the_field() {
        let e = from_geojson(&json!({"type": "Feature"}), &frame()).unwrap_err();
        assert_eq!(e.field, "type");
        let bad_point = json!({"type": "FeatureCollection", "features": [{
            "properties": {"name": "z"},
            "geometry": {"type": "Polygon", "coordinates": [[[0.0, 0.0], [1.0], [1.0, 1.0]]]}
        }]});
        let e = from_geojson(&bad_point, &frame()).unwrap_err();
        assert_eq!(e.field, "features[0].geometry.coordinates[0][1]");
        assert!(e.to_string().contains("[longitude, latitude]"), "{e}");
        let no_name = json!({"type": "FeatureCollection", "features": [{"properties": {},
            "geometry": {"type": "Polygon", "coordinates": [[[0.0, 0.0], [0.001, 0.0], [0.0, 0.001]]]}}]});
        assert_eq!(from_geojson(&no_name, &frame()).unwrap_err().field, "features[0].properties.name");
        let line = json!({"type": "FeatureCollection", "features": [{"properties": {"name": "z"},
            "geometry": {"type": "Polygon", "coordinates": [[[0.0, 0.0], [0.001, 0.0], [0.0, 0.0]]]}}]});
        assert!(from_geojson(&line, &frame()).unwrap_err().problem.contains("3 distinct"));
    }
}
