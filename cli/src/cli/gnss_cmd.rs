//! `sadesim gnss sky FILE`: the GNSS satellites an orbit file puts in the sky over a place at
//! a time, with their look angles and the dilution of precision of those above the mask.

use std::io::Write;
use std::path::Path;

use sadesim_crds::geo::GeoPoint;
use sadesim_gnss::orbits::STALE_DAYS;
use sadesim_gnss::{Constellation, Dop, LookAngles};
use serde_json::json;

use super::{CliError, Outcome};

pub(super) fn sky(
    file: &Path,
    at: (f64, f64, f64),
    time: &str,
    mask_deg: f64,
    json: bool,
    out: &mut dyn Write,
) -> Result<Outcome, CliError> {
    let shown = file.display().to_string();
    let text = std::fs::read_to_string(file).map_err(|source| CliError::Read { path: shown.clone(), source })?;
    let constellation = Constellation::parse(&text).map_err(|e| CliError::Failed(format!("{shown}: {e}")))?;
    let unix_s = sadesim_gnss::parse_utc(time).map_err(|e| CliError::Failed(format!("--time {e}")))?;
    let receiver = GeoPoint::new(at.0, at.1, at.2);
    let mut seen: Vec<(usize, LookAngles)> = constellation
        .positions(unix_s)
        .into_iter()
        .map(|p| (p.index, LookAngles::of(receiver, p.ecef)))
        .filter(|(_, look)| look.elevation_deg >= mask_deg)
        .collect();
    seen.sort_by(|a, b| b.1.elevation_deg.total_cmp(&a.1.elevation_deg));
    let units: Vec<[f64; 3]> = seen.iter().map(|(_, l)| l.unit_enu).collect();
    let dop = Dop::of(&units);
    let age_days = constellation.age_days(unix_s);
    let warning = (age_days > STALE_DAYS).then(|| {
        format!(
            "{shown}: element sets up to {age_days:.0} days from {time}: SGP4 drifts by kilometres per day from their epoch, so this is not that day's sky; use an orbit file from within a few days"
        )
    });
    if let Some(w) = &warning {
        eprintln!("warning: {w}");
    }
    if json {
        let satellites: Vec<_> = seen
            .iter()
            .map(|(i, l)| {
                let s = &constellation.satellites[*i];
                json!({"name": s.name, "noradId": s.norad_id, "system": s.system, "azimuthDeg": l.azimuth_deg,
                       "elevationDeg": l.elevation_deg, "rangeM": l.range_m})
            })
            .collect();
        let doc =
            json!({"unixS": unix_s, "ageDays": age_days, "maskDeg": mask_deg, "satellites": satellites, "dop": dop});
        writeln!(out, "{}", serde_json::to_string_pretty(&doc).expect("JSON values always serialize"))?;
        return Ok(Outcome::Success);
    }
    writeln!(
        out,
        "{shown}: {} of {} satellites above {mask_deg}° at {:.5}, {:.5} at {time}",
        seen.len(),
        constellation.satellites.len(),
        at.0,
        at.1
    )?;
    match dop {
        Some(d) => writeln!(
            out,
            "  GDOP {:.2}  PDOP {:.2}  HDOP {:.2}  VDOP {:.2}  TDOP {:.2}",
            d.gdop, d.pdop, d.hdop, d.vdop, d.tdop
        )?,
        None => writeln!(out, "  no DOP: fewer than 4 satellites (or all in one plane)")?,
    }
    for (i, l) in &seen {
        let s = &constellation.satellites[*i];
        writeln!(
            out,
            "  {} {:<28} az {:6.1}°  el {:5.1}°  {:8.0} km",
            s.system.code(),
            s.name,
            l.azimuth_deg,
            l.elevation_deg,
            l.range_m / 1000.0
        )?;
    }
    Ok(Outcome::Success)
}

/// The one run of `scenario`, valid; `None` when it is not (its problems are on `out`).
pub(super) fn valid_scenario(
    scenario: &Path,
    out: &mut dyn Write,
) -> Result<Option<sadesim_crds::SimulationRun>, CliError> {
    let Some(run) = super::scenario::load_one(scenario, out)? else { return Ok(None) };
    if let Err(errors) = sadesim_crds::validate::validate(&run) {
        super::scenario::report_problems(out, &scenario.display().to_string(), &errors)?;
        return Ok(None);
    }
    Ok(Some(run))
}

/// The run's GNSS sky (its constellation must be set) and its world.
pub(super) fn sky_and_world(
    run: &sadesim_crds::SimulationRun,
    scenario: &Path,
) -> Result<(sadesim_gnss::RunSky, sadesim_world::World), CliError> {
    let sky =
        sadesim_sources::gnss::load_sky(&run.spec).map_err(|e| CliError::Failed(e.to_string()))?.ok_or_else(|| {
            CliError::Failed(format!("{}: spec.environment.gnss.constellation is not set", scenario.display()))
        })?;
    let world = sadesim_sources::world::load_world(&run.spec).map_err(|e| CliError::Failed(e.to_string()))?;
    Ok((sky, world))
}

/// `sadesim gnss los SCENARIO --points FILE`: the signal path of every satellite of the
/// scenario's constellation to each antenna point in its world.
pub(super) fn los(
    scenario: &Path,
    points: &Path,
    at_s: f64,
    buildings: Option<&Path>,
    out: &mut dyn Write,
) -> Result<Outcome, CliError> {
    use sadesim_gnss::SignalPath;
    use sadesim_gnss::signal::signal_path;

    let Some(run) = valid_scenario(scenario, out)? else { return Ok(Outcome::Problems) };
    let (sky, world) = sky_and_world(&run, scenario)?;
    let text = std::fs::read_to_string(points)
        .map_err(|source| CliError::Read { path: points.display().to_string(), source })?;
    let antennas: Vec<[f64; 3]> = serde_json::from_str(&text).map_err(|e| {
        CliError::Failed(format!("{}: expected a JSON array of [east, north, up] metres: {e}", points.display()))
    })?;
    if let Some(path) = buildings {
        let prisms: Vec<_> = world
            .buildings()
            .iter()
            .map(|b| {
                json!({"outer": b.footprint().outer(), "holes": b.footprint().holes(),
                       "baseM": b.base_up_m(), "roofM": b.roof_up_m()})
            })
            .collect();
        let bytes = serde_json::to_vec(&prisms).map_err(|e| CliError::Failed(e.to_string()))?;
        std::fs::write(path, bytes).map_err(|e| CliError::Failed(format!("--buildings {}: {e}", path.display())))?;
    }
    let states = sky.at(at_s);
    let mask_sin = sky.mask_deg().to_radians().sin();
    let names: Vec<&str> = states.iter().map(|s| sky.constellation().satellites[s.index].name.as_str()).collect();
    let points_json: Vec<_> = antennas
        .iter()
        .map(|p| {
            let antenna = sadesim_gnss::nalgebra::Vector3::new(p[0], p[1], p[2]);
            let seen: Vec<_> = states
                .iter()
                .zip(&names)
                .filter_map(|(s, name)| {
                    let u = (s.position_enu_m - antenna).normalize();
                    (u.z >= mask_sin).then(|| {
                        let (path, excess) = match signal_path(&world, &antenna, &u) {
                            SignalPath::LineOfSight => ("los", None),
                            SignalPath::Reflected { excess_m, .. } => ("reflected", Some(excess_m)),
                            SignalPath::Blocked => ("blocked", None),
                        };
                        json!({"satellite": name, "unitEnu": [u.x, u.y, u.z], "path": path, "excessM": excess})
                    })
                })
                .collect();
            json!({"enu": p, "insideBuilding": world.is_inside_building(antenna), "signals": seen})
        })
        .collect();
    let doc = json!({"epochUnixS": sky.epoch_unix_s() + at_s, "maskDeg": sky.mask_deg(), "points": points_json});
    writeln!(out, "{doc}")?;
    Ok(Outcome::Success)
}
