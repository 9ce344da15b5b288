//! `spec.criteria`, and references from any section to groups and zones by name.

use std::collections::{BTreeSet, HashSet};

use crate::criteria::Criterion;
use crate::run::SimulationRunSpec;

use super::MAX_DURATION_S;
use super::problems::Problems;

pub(super) fn non_empty(p: &mut Problems, path: String, list: &[String]) {
    if list.is_empty() {
        p.add(path, "must name at least one group");
    }
}

/// Names in a stable order for messages.
pub(super) fn sorted(names: &HashSet<String>) -> String {
    let names: BTreeSet<&str> = names.iter().map(String::as_str).collect();
    if names.is_empty() { "(none defined)".into() } else { names.into_iter().collect::<Vec<_>>().join(", ") }
}

pub(super) fn check_group_refs(refs: &[String], groups: &HashSet<String>, path: &str, p: &mut Problems) {
    p.max_items(path, refs.len(), 64);
    for (k, g) in refs.iter().enumerate() {
        if !groups.contains(g) {
            p.add(format!("{path}[{k}]"), format!("unknown group {g:?}, expected one of: {}", sorted(groups)));
        }
    }
}

pub(super) fn check_criteria(
    spec: &SimulationRunSpec,
    groups: &HashSet<String>,
    zones: &HashSet<String>,
    p: &mut Problems,
) {
    let zone_ref = |p: &mut Problems, path: String, z: &str| {
        if !zones.contains(z) {
            p.add(path, format!("unknown zone {z:?}, expected one of: {}", sorted(zones)));
        }
    };
    p.max_items("spec.criteria", spec.criteria.len(), 64);
    for (i, c) in spec.criteria.iter().enumerate() {
        let path = format!("spec.criteria[{i}]");
        match c {
            Criterion::MinSeparation { distance_m } => {
                p.range(format!("{path}.minSeparation.distanceM"), *distance_m, 0.1, 10_000.0);
            }
            Criterion::ReachZone { groups: gs, zone, within } => {
                non_empty(p, format!("{path}.reachZone.groups"), gs);
                check_group_refs(gs, groups, &format!("{path}.reachZone.groups"), p);
                zone_ref(p, format!("{path}.reachZone.zone"), zone);
                if let Some(w) = p.duration(format!("{path}.reachZone.within"), within, MAX_DURATION_S)
                    && w > spec.duration_s()
                {
                    p.add(
                        format!("{path}.reachZone.within"),
                        format!("is longer than the run ({} s): it could never be checked", spec.duration_s()),
                    );
                }
            }
            Criterion::ZoneVerdicts { groups: gs, zone, .. } => {
                non_empty(p, format!("{path}.zoneVerdicts.groups"), gs);
                check_group_refs(gs, groups, &format!("{path}.zoneVerdicts.groups"), p);
                zone_ref(p, format!("{path}.zoneVerdicts.zone"), zone);
            }
            Criterion::EstimatedPositionError { groups: gs, max_horizontal_m } => {
                let path = format!("{path}.estimatedPositionError");
                check_group_refs(gs, groups, &format!("{path}.groups"), p);
                p.range(format!("{path}.maxHorizontalM"), *max_horizontal_m, 0.1, 1000.0);
            }
            Criterion::LandedNear { groups: gs, marker, within_m } => {
                let path = format!("{path}.landedNear");
                check_group_refs(gs, groups, &format!("{path}.groups"), p);
                let markers: HashSet<String> = spec.world().markers.iter().map(|m| m.name.clone()).collect();
                if !markers.contains(marker) {
                    p.add(
                        format!("{path}.marker"),
                        format!("unknown marker {marker:?}, expected one of spec.world.markers: {}", sorted(&markers)),
                    );
                }
                p.range(format!("{path}.withinM"), *within_m, 0.01, 1000.0);
            }
            Criterion::NoUnauthorizedEntries {}
            | Criterion::ZoneConstraintsRespected {}
            | Criterion::AltitudeLimitsRespected {}
            | Criterion::NoCrashes {} => {}
        }
    }
}
