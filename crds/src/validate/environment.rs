//! `spec.environment`: wind and GNSS (noise, bias and dropouts).

use std::collections::HashSet;

use crate::run::SimulationRunSpec;

use super::MAX_DURATION_S;
use super::criteria::check_group_refs;
use super::problems::{Problems, duration_s};

/// `spec.environment.gnss.constellation`: a readable file reference when one is named, an RFC 3339 epoch, a
/// mask in range.
fn check_constellation(c: &crate::environment::GnssConstellation, base: &str, p: &mut Problems) {
    let field = format!("{base}.constellation.file");
    if let Some(file) = &c.file {
        if file.trim().is_empty() {
            p.add(
                &field,
                "must name an orbit file (TLE or OMM), or be left out for the built-in nominal constellation",
            );
        }
        super::world::check_file_url(p, &field, file);
    }
    if let Some(epoch) = &c.epoch
        && epoch.trim().parse::<k8s_openapi::jiff::Timestamp>().is_err()
    {
        p.add(
            format!("{base}.constellation.epoch"),
            format!("{epoch:?} is not an RFC 3339 UTC time: expected e.g. 2020-12-01T12:00:00Z"),
        );
    }
    if let Some(mask) = c.elevation_mask_deg {
        p.range(format!("{base}.constellation.elevationMaskDeg"), mask, 0.0, 60.0);
    }
}

pub(super) fn check_environment(spec: &SimulationRunSpec, groups: &HashSet<String>, p: &mut Problems) {
    let env = spec.environment();
    if let Some(w) = &env.wind {
        p.range("spec.environment.wind.speedMps", w.speed_mps, 0.0, 40.0);
        p.range("spec.environment.wind.directionFromDeg", w.direction_from_deg, 0.0, 360.0);
        if let Some(h) = w.reference_height_m {
            p.range("spec.environment.wind.referenceHeightM", h, 1.0, 500.0);
        }
        if let Some(u) = &w.urban {
            if let Some(case) = &u.case {
                let base = "spec.environment.wind.urban.case";
                if u.model != crate::environment::UrbanWindModel::OpenFoam {
                    p.add(base, "is only allowed with model: openfoam (an imported OpenFOAM case)");
                }
                if case.dir.trim().is_empty() {
                    p.add(format!("{base}.dir"), "must name the OpenFOAM case directory");
                }
                p.range(format!("{base}.directionFromDeg"), case.direction_from_deg, 0.0, 360.0);
                p.range(format!("{base}.referenceSpeedMps"), case.reference_speed_mps, 0.1, 100.0);
                // A case holds one inflow direction; flying another would be a silent lie.
                let apart = (case.direction_from_deg - w.direction_from_deg).rem_euclid(360.0);
                if apart.min(360.0 - apart) > 0.5 {
                    p.add(
                        format!("{base}.directionFromDeg"),
                        format!(
                            "the case's wind blows from {}° but spec.environment.wind.directionFromDeg is {}°: an imported case holds one direction; set them equal or use model: openfoam without case (OpenFOAM runs for the run's direction)",
                            case.direction_from_deg, w.direction_from_deg
                        ),
                    );
                }
            }
            if let Some(spacing) = u.spacing_m {
                p.range("spec.environment.wind.urban.spacingM", spacing, 1.0, 100.0);
            }
            if let Some(n) = u.sectors
                && !(4..=36).contains(&n)
            {
                p.add("spec.environment.wind.urban.sectors", format!("{n} is out of range: expected 4 to 36"));
            }
        }
    }
    if let Some(g) = &env.gnss {
        let base = "spec.environment.gnss";
        if let Some(r) = g.rate_hz {
            p.range(format!("{base}.rateHz"), r, 1.0, 20.0);
        }
        let limits = [
            ("horizontalSigmaM", g.horizontal_sigma_m, 100.0),
            ("verticalSigmaM", g.vertical_sigma_m, 100.0),
            ("biasWalkMPerSqrtS", g.bias_walk_m_per_sqrt_s, 10.0),
        ];
        for (field, value, hi) in limits {
            if let Some(v) = value {
                p.range(format!("{base}.{field}"), v, 0.0, hi);
            }
        }
        if let Some(b) = &g.bias {
            for (field, value) in [("eastM", b.east_m), ("northM", b.north_m), ("upM", b.up_m)] {
                p.range(format!("{base}.bias.{field}"), value, -100.0, 100.0);
            }
        }
        if let Some(c) = &g.constellation {
            check_constellation(c, base, p);
            for (field, value, _) in limits {
                if value.is_some() {
                    p.add(
                        format!("{base}.{field}"),
                        "is not allowed with constellation: the ranging receiver's errors come from the \
                         satellites' geometry and signal paths, not from a noise figure",
                    );
                }
            }
        }
        p.max_items(format!("{base}.dropouts"), g.dropouts.len(), 256);
        for (k, d) in g.dropouts.iter().enumerate() {
            let dp = format!("{base}.dropouts[{k}]");
            let start = duration_s(&d.start);
            if start < 0.0 {
                p.add(format!("{dp}.start"), "must not be negative");
            } else if start >= spec.duration_s() {
                p.add(
                    format!("{dp}.start"),
                    format!("is after the run ends ({} s): the dropout would never happen", spec.duration_s()),
                );
            }
            p.duration(format!("{dp}.duration"), &d.duration, MAX_DURATION_S);
            check_group_refs(&d.groups, groups, &format!("{dp}.groups"), p);
        }
    }
}
