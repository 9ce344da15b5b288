//! `sadesim dem`: a digital elevation model as the terrain reads it.

use std::io::Write;
use std::path::Path;

use sadesim_crds::geo::{Enu, GeoPoint, LocalFrame};
use sadesim_world::dem::Dem;
use serde_json::json;

use super::{CliError, Outcome};

/// Samples per side of the grid the summary is taken on.
const GRID: usize = 100;

pub(super) fn dem_file(
    file: &Path,
    (latitude_deg, longitude_deg): (f64, f64),
    extent_m: f64,
    at: &[(f64, f64)],
    as_json: bool,
    out: &mut dyn Write,
) -> Result<Outcome, CliError> {
    let path = file.display().to_string();
    let bytes = std::fs::read(file).map_err(|source| CliError::Read { path: path.clone(), source })?;
    let failed = |e: sadesim_world::dem::DemError| CliError::Failed(format!("{path}: {e}"));
    let dem = Dem::read(&bytes, &path).map_err(failed)?;
    let frame = LocalFrame::new(GeoPoint::new(latitude_deg, longitude_deg, 0.0));
    dem.check_covers(&frame, extent_m).map_err(failed)?;

    // Ground over the square on a GRID x GRID lattice; the slope between neighbours.
    let step_m = 2.0 * extent_m / GRID as f64;
    let ground = |e: f64, n: f64| {
        let p = frame.to_geodetic(Enu { east_m: e, north_m: n, up_m: 0.0 });
        dem.elevation_m(p.latitude_deg, p.longitude_deg).unwrap_or(f64::NAN)
    };
    let mut heights = vec![0.0; (GRID + 1) * (GRID + 1)];
    for j in 0..=GRID {
        for i in 0..=GRID {
            heights[j * (GRID + 1) + i] = ground(-extent_m + i as f64 * step_m, -extent_m + j as f64 * step_m);
        }
    }
    let (lowest, highest) = heights.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &h| (a.min(h), b.max(h)));
    let mut slope: f64 = 0.0;
    for j in 0..=GRID {
        for i in 0..GRID {
            slope = slope.max((heights[j * (GRID + 1) + i + 1] - heights[j * (GRID + 1) + i]).abs() / step_m);
            slope = slope.max((heights[i * (GRID + 1) + j] - heights[(i + 1) * (GRID + 1) + j]).abs() / step_m);
        }
    }
    let origin_m = ground(0.0, 0.0);
    let points: Vec<_> = at.iter().map(|&(lat, lon)| (lat, lon, dem.elevation_m(lat, lon))).collect();
    let (width, height) = dem.size();
    if as_json {
        let summary = json!({
            "file": path,
            "crs": dem.crs().to_string(),
            "pixels": [width, height],
            "extentM": extent_m,
            "originM": origin_m,
            "lowestM": lowest,
            "highestM": highest,
            "maxSlope": slope,
            "at": points.iter().map(|(lat, lon, z)| json!({"latitudeDeg": lat, "longitudeDeg": lon, "elevationM": z})).collect::<Vec<_>>(),
        });
        serde_json::to_writer_pretty(&mut *out, &summary).map_err(std::io::Error::from)?;
        writeln!(out)?;
    } else {
        writeln!(out, "{path}: {width} x {height} pixels, {}", dem.crs())?;
        writeln!(
            out,
            "  ground within {extent_m} m of {latitude_deg:.5}, {longitude_deg:.5}: {lowest:.1} to {highest:.1} m, {origin_m:.1} m at the origin, slopes up to {:.1} % (over {step_m:.0} m)",
            100.0 * slope
        )?;
        for (lat, lon, z) in points {
            match z {
                Some(z) => writeln!(out, "  {lat:.6}, {lon:.6}: {z:.3} m")?,
                None => writeln!(out, "  {lat:.6}, {lon:.6}: no elevation (outside the grid or no data)")?,
            }
        }
    }
    Ok(Outcome::Success)
}
