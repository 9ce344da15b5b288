//! The compliance monitor: checks every drone's ground truth against the zones, the leases
//! and the group altitude limits at every coordinator window (>= 50 Hz; 100 Hz with the
//! default 10 ms windows), and between windows along the straight segment a drone flew,
//! so a fast drone clipping a zone's corner is still caught.
//!
//! It emits `zoneEntered`/`zoneExited` and `violationStarted`/`violationEnded` events and
//! keeps the records the criteria are judged on.
//!
//! # Rules
//! - **Inside a zone**: an airborne drone (neither `on_ground` nor crashed) whose position
//!   is inside the zone's volume while the zone is active. A drone standing on the ground
//!   or a roof is not flying in the airspace, so landing inside a zone ends the stay.
//! - **Entries between samples**: a drone outside at one window and anywhere at the next is
//!   checked along the straight segment between the two positions
//!   ([`ZoneVolume::first_inside`], the ground under the segment taken as linear between
//!   the two samples' ground heights); the entry time is interpolated on the segment. An
//!   exit is placed at the last point of the segment inside the volume the same way, so a
//!   corner clipped within one window is a stay (and, without a lease, a violation) that
//!   starts and ends between two windows.
//! - **Zone rules** are judged at the entry point and at every window sample inside:
//!   no valid lease -> `unauthorizedEntry`; a lease whose constraints give a minimum
//!   (maximum) AGL altitude and a drone strictly below (above) it -> `belowZoneMinimum`
//!   (`aboveZoneMaximum`). Inside the volume the constraints apply, with no allowance for
//!   climbing through the zone's lower part. A lease that expires inside starts an
//!   `unauthorizedEntry`; a lease granted inside ends it.
//! - **Zone activity**: a zone that becomes active while a drone is inside starts a stay
//!   at the activation time; a zone that stops being active ends every stay at its end time.
//! - **Altitude limit**: an airborne drone strictly above its group's `altitude.maxAglM`
//!   (no tolerance), anywhere, at the window samples.
//! - **Altitude minimum**: a *cruising* drone strictly below its group's `altitude.minAglM`
//!   at the window samples (cruising: from its first climb to `minAglM` until the ground or
//!   `land`/`returnToLaunch` mode; the `altitude` module defines it precisely).
//! - **Closest zone**: per drone, the closest horizontal approach to a zone it held no
//!   lease for, while airborne and within the zone's altitude band (`zone_distance`).
//! - **Separation** (only when the scenario has a `minSeparation` criterion): two airborne
//!   drones closer than the smallest such distance in 3-D at a window sample.
//!
//! # Cost
//! Per drone and zone and window, the common path is a time-window test and a bounding-box
//! test on the segment flown; the polygon and segment queries run only for drones near a
//! zone. Separation hashes the airborne drones into a horizontal grid of cells one
//! separation distance wide and compares only neighbouring cells (O(n log n) per window,
//! not O(n^2)). Buffers are reused: no allocation per drone per window unless something
//! happens (an event) or a drone moves within a zone's bounding box.

use std::collections::BTreeMap;

use sadesim_crds::criteria::Criterion;
use sadesim_crds::geo::{Enu, LocalFrame};
use sadesim_crds::plan::RunPlan;

use super::authority::LeaseConstraints;
use super::volume::{Ground, ZoneVolume};
use crate::events::{Event, EventKind, Place};
use crate::protocol::DroneSnapshot;
pub use sadesim_crds::outcome::compliance::{ComplianceReport, Presence, Touchdown, ViolationKind, ViolationRecord};

/// The monitor's state for one run.
#[derive(Debug)]
pub struct Monitor {
    zones: Vec<WatchedZone>,
    drones: Vec<DroneState>,
    /// Per drone and zone, drone-major: `stays[drone * zones.len() + zone]`.
    stays: Vec<ZoneStay>,
    separation: Option<Separation>,
    /// The window's `crashed` events, (drone, time); reused.
    crash_events: Vec<(u32, f64)>,
    /// The window's `landed` events not followed by a take-off, (drone, time), when
    /// touchdowns are tracked; reused.
    landings: Vec<(u32, f64)>,
    log: Log,
}

impl Monitor {
    /// Drones, groups (altitude limits) and separation distance (the smallest
    /// `minSeparation` criterion, if any) from the plan.
    pub fn new(plan: &RunPlan, zones: Vec<ZoneVolume>) -> Self {
        let drones: Vec<DroneState> = plan
            .drones
            .iter()
            .map(|d| {
                let limits = plan.spec.fleet.get(d.group_index as usize).map(|g| &g.altitude);
                DroneState {
                    name: d.name.clone(),
                    max_agl_m: limits.map_or(f64::INFINITY, |a| a.max_agl_m),
                    min_agl_m: limits.and_then(|a| a.min_agl_m),
                    last: None,
                    crashed: false,
                    above_limit: None,
                    cruising: false,
                    below_minimum: None,
                    closest_zone_m: None,
                }
            })
            .collect();
        let distances = plan.spec.criteria.iter().filter_map(|c| match c {
            Criterion::MinSeparation { distance_m } if distance_m.is_finite() && *distance_m > 0.0 => Some(*distance_m),
            _ => None,
        });
        let position_errors = plan.spec.criteria.iter().any(|c| matches!(c, Criterion::EstimatedPositionError { .. }));
        let touchdowns = plan.spec.criteria.iter().any(|c| matches!(c, Criterion::LandedNear { .. }));
        let separation = distances
            .fold(None, |acc: Option<(f64, f64)>, d| Some(acc.map_or((d, d), |(lo, hi)| (lo.min(d), hi.max(d)))));
        Self {
            stays: vec![ZoneStay::default(); drones.len() * zones.len()],
            zones: zones.into_iter().map(WatchedZone::new).collect(),
            drones,
            separation: separation.map(|(smallest, largest)| Separation {
                distance_m: smallest,
                cell_m: largest,
                grid: Vec::new(),
                open: BTreeMap::new(),
                window: 0,
            }),
            crash_events: Vec::new(),
            landings: Vec::new(),
            log: Log {
                frame: LocalFrame::new(plan.spec.origin.geo()),
                report: ComplianceReport {
                    worst_position_errors: if position_errors { vec![None; plan.drones.len()] } else { Vec::new() },
                    touchdowns: if touchdowns { vec![None; plan.drones.len()] } else { Vec::new() },
                    ..ComplianceReport::default()
                },
                events: Vec::new(),
            },
        }
    }

    /// One window ending at `time_s`: `drones` is every drone's ground truth, `events` the
    /// window's events (crashes are taken from them), `lease(drone, zone, time_s)` the
    /// drone's valid lease constraints. Returns the events the monitor raised, in time
    /// order.
    ///
    /// Snapshots whose `index` is not a drone of the plan are ignored. `lease` is only
    /// asked about drones inside a zone.
    pub fn observe(
        &mut self,
        time_s: f64,
        drones: &[DroneSnapshot],
        events: &[Event],
        lease: &dyn Fn(u32, &str, f64) -> Option<LeaseConstraints>,
    ) -> Vec<Event> {
        self.crash_events.clear();
        self.landings.clear();
        for e in events {
            match (&e.kind, e.drone) {
                (EventKind::Crashed { .. }, Some(d)) => self.crash_events.push((d, e.time_s)),
                // The window's last take-off or landing of a drone decides.
                (EventKind::Takeoff, Some(d)) => {
                    self.landings.retain(|l| l.0 != d);
                    if let Some(t) = self.log.report.touchdowns.get_mut(d as usize) {
                        *t = None;
                    }
                }
                (EventKind::Landed, Some(d)) if !self.log.report.touchdowns.is_empty() => {
                    self.landings.retain(|l| l.0 != d);
                    self.landings.push((d, e.time_s));
                }
                _ => {}
            }
        }
        for snap in drones {
            let i = snap.index as usize;
            if i >= self.drones.len() {
                continue;
            }
            let now = Sample::of(time_s, snap);
            // Crash time from the event when there is one, else the window's.
            let crash_s = self.crash_events.iter().find(|c| c.0 == snap.index).map(|c| c.1);
            if snap.crashed || crash_s.is_some() {
                self.record_crash(i, crash_s.unwrap_or(time_s), &now);
            }
            if let Some(&(_, landed_s)) = self.landings.iter().find(|l| l.0 == snap.index)
                && !snap.crashed
            {
                let at = self.log.place(&now);
                self.log.report.touchdowns[i] = Some(Touchdown { time_s: landed_s, at });
            }
            // The first sample of a drone has no segment behind it.
            let prev = self.drones[i].last.unwrap_or(now);
            let airborne = !snap.on_ground && !snap.crashed && !self.drones[i].crashed;
            for z in 0..self.zones.len() {
                self.watch_zone(i, z, &prev, &now, airborne, lease);
            }
            if airborne {
                self.watch_zone_distance(i, &now, lease);
            }
            self.watch_altitude(i, &now, airborne, snap.mode);
            self.watch_position_error(i, &now, snap, airborne);
            self.drones[i].last = Some(now);
        }
        // Crashes of drones without a snapshot this window: where they were last seen.
        for k in 0..self.crash_events.len() {
            let (d, t) = self.crash_events[k];
            if let Some(last) = self.drones.get(d as usize).and_then(|s| s.last) {
                self.record_crash(d as usize, t, &last);
            }
        }
        self.watch_separation(time_s, drones);
        self.log.take_events()
    }

    /// Ends the run at `time_s`: closes open stays and violations (with their events).
    /// Stays end where each drone was last seen.
    pub fn finish(&mut self, time_s: f64) -> Vec<Event> {
        let Self { zones, drones, stays, separation, log, .. } = self;
        for (i, drone) in drones.iter_mut().enumerate() {
            let Some(last) = drone.last else { continue };
            let end = Sample { time_s, ..last };
            for stay in &mut stays[i * zones.len()..(i + 1) * zones.len()] {
                if stay.presence.is_some() {
                    log.leave(stay, &end);
                }
            }
            for v in [drone.above_limit.take(), drone.below_minimum.take()].into_iter().flatten() {
                log.end(v, time_s);
            }
        }
        if let Some(sep) = separation {
            for (v, _) in std::mem::take(&mut sep.open).into_values() {
                log.end(v, time_s);
            }
        }
        log.take_events()
    }

    pub fn report(&self) -> &ComplianceReport {
        &self.log.report
    }

    /// Records a crash of drone `i` once, at `time_s` where `at` is.
    fn record_crash(&mut self, i: usize, time_s: f64, at: &Sample) {
        if !self.drones[i].crashed {
            self.drones[i].crashed = true;
            self.log.report.crashes.push((i as u32, time_s));
            let place = self.log.place(at);
            self.log.report.crash_places.push(place);
        }
    }

    /// One drone and one zone over the segment `prev -> now`.
    fn watch_zone(
        &mut self,
        i: usize,
        z: usize,
        prev: &Sample,
        now: &Sample,
        airborne: bool,
        lease: &dyn Fn(u32, &str, f64) -> Option<LeaseConstraints>,
    ) {
        let Self { zones, drones, stays, log, .. } = self;
        let zone = &zones[z];
        let stay = &mut stays[i * zones.len() + z];
        let drone = i as u32;
        let name = zone.volume.name.as_str();
        let active = zone.volume.is_active(now.time_s);
        if !active || !airborne {
            if stay.presence.is_some() {
                // The zone ended during the window (at its end time), or the drone landed
                // or crashed (seen now).
                let end_s = if active { now.time_s } else { zone.volume.active_until_s.clamp(prev.time_s, now.time_s) };
                log.leave(stay, &Sample::at_time(prev, now, end_s));
            }
            return;
        }
        let inside_now = zone.contains(now);
        if stay.presence.is_some() {
            if inside_now {
                log.judge_inside(stay, drone, &drones[i].name, name, now, lease(drone, name, now.time_s));
            } else {
                log.leave(stay, &zone.last_inside(prev, now));
            }
            return;
        }
        let entry = if prev.p == now.p {
            inside_now.then_some(0.0)
        } else if zone.segment_may_touch(prev, now) {
            zone.volume.first_inside(prev.p, now.p, &SegmentGround { from: *prev, to: *now })
        } else {
            None
        };
        let Some(f) = entry else { return };
        let mut entry = Sample::at_fraction(prev, now, f);
        if entry.time_s < zone.volume.active_from_s {
            // Inside before the zone became active during the window: the stay starts then.
            entry = Sample::at_time(prev, now, zone.volume.active_from_s);
        }
        let exit = (!inside_now).then(|| zone.last_inside(prev, now));
        if exit.is_some_and(|x| x.time_s < entry.time_s) {
            // Passed through before the zone became active.
            return;
        }
        let constraints = lease(drone, name, entry.time_s);
        if constraints.is_none() {
            // Inside without a lease, if only between two samples.
            drones[i].closest_zone_m = Some(0.0);
        }
        stay.presence = Some(log.enter(drone, name, &entry, constraints.is_some()));
        log.judge_inside(stay, drone, &drones[i].name, name, &entry, constraints);
        match exit {
            Some(exit) => log.leave(stay, &exit),
            None if now.time_s > entry.time_s => {
                log.judge_inside(stay, drone, &drones[i].name, name, now, lease(drone, name, now.time_s));
            }
            None => {}
        }
    }

    /// Separation between airborne drones at the window samples, by grid hashing.
    fn watch_separation(&mut self, time_s: f64, snaps: &[DroneSnapshot]) {
        let Self { drones, separation, log, .. } = self;
        let Some(sep) = separation else { return };
        sep.window += 1;
        sep.grid.clear();
        for (slot, d) in snaps.iter().enumerate() {
            let known = drones.get(d.index as usize).is_some_and(|s| !s.crashed);
            if known && !d.on_ground && !d.crashed {
                let [x, y, _] = d.position_enu_m;
                sep.grid.push(((x / sep.cell_m).floor() as i64, (y / sep.cell_m).floor() as i64, slot));
            }
        }
        // Sorted by (cell x, cell y): the cells (x, y-1..=y+1) are one contiguous run. As
        // `a` walks the grid its key only grows, and so do the bounds of the runs it is
        // compared with: three forward-only cursors, O(n) after the sort.
        sep.grid.sort_unstable();
        let grid = &sep.grid;
        let key = |k: usize| (grid[k].0, grid[k].1);
        let (mut same_end, mut east_start, mut east_end) = (0, 0, 0);
        for a in 0..grid.len() {
            let (cx, cy, sa) = grid[a];
            // Each pair of neighbouring cells once: this cell and the one north of it from
            // this drone on, and the three cells of the next column east.
            let north = (cx, cy.saturating_add(1));
            let (east_lo, east_hi) =
                ((cx.saturating_add(1), cy.saturating_sub(1)), (cx.saturating_add(1), cy.saturating_add(1)));
            while same_end < grid.len() && key(same_end) <= north {
                same_end += 1;
            }
            while east_start < grid.len() && key(east_start) < east_lo {
                east_start += 1;
            }
            east_end = east_end.max(east_start);
            while east_end < grid.len() && key(east_end) <= east_hi {
                east_end += 1;
            }
            for b in (a + 1..same_end).chain(east_start..east_end) {
                let sb = grid[b].2;
                let (pa, pb) = (snaps[sa].position_enu_m, snaps[sb].position_enu_m);
                let dist_m = ((pa[0] - pb[0]).powi(2) + (pa[1] - pb[1]).powi(2) + (pa[2] - pb[2]).powi(2)).sqrt();
                let (lo, hi) = if snaps[sa].index < snaps[sb].index { (sa, sb) } else { (sb, sa) };
                let (lo_i, hi_i) = (snaps[lo].index, snaps[hi].index);
                if log.report.closest_approach.is_none_or(|c| dist_m < c.0) {
                    log.report.closest_approach = Some((dist_m, time_s, lo_i, hi_i));
                }
                if dist_m >= sep.distance_m {
                    continue;
                }
                if let Some((v, seen)) = sep.open.get_mut(&(lo_i, hi_i)) {
                    log.worsen(*v, dist_m);
                    *seen = sep.window;
                } else {
                    let limit_m = sep.distance_m;
                    let other_name = &drones[hi_i as usize].name;
                    let v = log.start(
                        NewViolation {
                            kind: ViolationKind::SeparationLoss,
                            drone: lo_i,
                            drone_name: drones[lo_i as usize].name.clone(),
                            other: Some(hi_i),
                            zone: None,
                            limit_m: Some(limit_m),
                            detail: format!("{dist_m:.2} m from {other_name}, closer than {limit_m:.1} m"),
                        },
                        &Sample::of(time_s, &snaps[lo]),
                        dist_m,
                    );
                    sep.open.insert((lo_i, hi_i), (v, sep.window));
                }
            }
        }
        let window = sep.window;
        sep.open.retain(|_, (v, seen)| {
            let lasts = *seen == window;
            if !lasts {
                log.end(*v, time_s);
            }
            lasts
        });
    }
}

/// A zone with its horizontal bounding box (ENU metres), the cheap test before the
/// polygon.
#[derive(Debug)]
struct WatchedZone {
    volume: ZoneVolume,
    min: (f64, f64),
    max: (f64, f64),
}

impl WatchedZone {
    fn new(volume: ZoneVolume) -> Self {
        let (mut min, mut max) = ((f64::INFINITY, f64::INFINITY), (f64::NEG_INFINITY, f64::NEG_INFINITY));
        for &(e, n) in &volume.polygon {
            min = (min.0.min(e), min.1.min(n));
            max = (max.0.max(e), max.1.max(n));
        }
        Self { volume, min, max }
    }

    /// Whether the sample is inside the volume (bounding box first).
    fn contains(&self, s: &Sample) -> bool {
        let (e, n) = (s.p.east_m, s.p.north_m);
        e >= self.min.0
            && e <= self.max.0
            && n >= self.min.1
            && n <= self.max.1
            && self.volume.contains(s.p, s.ground_up_m)
    }

    /// Whether the horizontal bounding box of the segment overlaps the zone's.
    fn segment_may_touch(&self, a: &Sample, b: &Sample) -> bool {
        a.p.east_m.max(b.p.east_m) >= self.min.0
            && a.p.east_m.min(b.p.east_m) <= self.max.0
            && a.p.north_m.max(b.p.north_m) >= self.min.1
            && a.p.north_m.min(b.p.north_m) <= self.max.1
    }

    /// The last point of `prev -> now` inside the volume (where a drone inside at `prev`
    /// left it): the first point inside when the segment is run backwards. `prev` itself
    /// when the segment query finds nothing (rounding at the surface).
    fn last_inside(&self, prev: &Sample, now: &Sample) -> Sample {
        let back = self.volume.first_inside(now.p, prev.p, &SegmentGround { from: *now, to: *prev });
        Sample::at_fraction(prev, now, 1.0 - back.unwrap_or(1.0))
    }
}

/// A drone's ground truth at one instant: a window sample, or a point interpolated
/// linearly between two.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Sample {
    /// Sim seconds.
    time_s: f64,
    /// World ENU, metres.
    p: Enu,
    /// Terrain under the drone, ENU up metres (`p.up_m - height_agl_m`).
    ground_up_m: f64,
    /// Height above that terrain, metres.
    height_agl_m: f64,
}

impl Sample {
    fn of(time_s: f64, snap: &DroneSnapshot) -> Self {
        let [e, n, u] = snap.position_enu_m;
        Self { time_s, p: Enu::new(e, n, u), ground_up_m: u - snap.height_agl_m, height_agl_m: snap.height_agl_m }
    }

    /// The point a fraction `f` (0..1) of the way from `a` to `b`, in time and space.
    fn at_fraction(a: &Sample, b: &Sample, f: f64) -> Self {
        let lerp = |x: f64, y: f64| x + f * (y - x);
        Self {
            time_s: lerp(a.time_s, b.time_s),
            p: Enu::new(lerp(a.p.east_m, b.p.east_m), lerp(a.p.north_m, b.p.north_m), lerp(a.p.up_m, b.p.up_m)),
            ground_up_m: lerp(a.ground_up_m, b.ground_up_m),
            height_agl_m: lerp(a.height_agl_m, b.height_agl_m),
        }
    }

    /// The point at `time_s` between `a` and `b` (clamped to them).
    fn at_time(a: &Sample, b: &Sample, time_s: f64) -> Self {
        let dt = b.time_s - a.time_s;
        let f = if dt > 0.0 { ((time_s - a.time_s) / dt).clamp(0.0, 1.0) } else { 1.0 };
        Self { time_s: time_s.clamp(a.time_s.min(b.time_s), a.time_s.max(b.time_s)), ..Self::at_fraction(a, b, f) }
    }
}

/// The terrain under the straight segment between two samples, linear in the fraction
/// along it (the projection of a horizontal position onto the segment). All the monitor
/// knows about the ground is the height under each sample, so no world is needed.
struct SegmentGround {
    from: Sample,
    to: Sample,
}

impl Ground for SegmentGround {
    fn ground_up_m(&self, east_m: f64, north_m: f64) -> f64 {
        let (a, b) = (self.from.p, self.to.p);
        let (dx, dy) = (b.east_m - a.east_m, b.north_m - a.north_m);
        let len2 = dx * dx + dy * dy;
        if len2 == 0.0 {
            return self.from.ground_up_m;
        }
        let f = (((east_m - a.east_m) * dx + (north_m - a.north_m) * dy) / len2).clamp(0.0, 1.0);
        self.from.ground_up_m + f * (self.to.ground_up_m - self.from.ground_up_m)
    }
}

/// What the monitor keeps per drone.
#[derive(Debug)]
struct DroneState {
    name: String,
    /// The group's `altitude.maxAglM`.
    max_agl_m: f64,
    /// The previous window's sample.
    last: Option<Sample>,
    crashed: bool,
    /// Open `aboveAltitudeLimit` violation (index in the report's violations).
    above_limit: Option<usize>,
    /// The group's `altitude.minAglM`, if set.
    min_agl_m: Option<f64>,
    /// Judged against `min_agl_m`: climbed to it since the last ground contact, landing
    /// or return (see the module's rules).
    cruising: bool,
    /// Open `belowAltitudeMinimum` violation.
    below_minimum: Option<usize>,
    /// Closest horizontal approach to a zone without a lease, metres (`zone_distance`).
    closest_zone_m: Option<f64>,
}

/// One drone and one zone: the open stay and zone violations, as indices in the report.
#[derive(Clone, Copy, Debug, Default)]
struct ZoneStay {
    presence: Option<usize>,
    unauthorized: Option<usize>,
    below: Option<usize>,
    above: Option<usize>,
}

/// Separation state.
#[derive(Debug)]
struct Separation {
    /// Violation threshold: the smallest `minSeparation` distance, metres.
    distance_m: f64,
    /// Grid cell width: the largest `minSeparation` distance, metres, so every pair
    /// closer than any criterion's distance lies in neighbouring cells.
    cell_m: f64,
    /// Airborne drones of the window: (cell east, cell north, slot in the snapshot slice).
    grid: Vec<(i64, i64, usize)>,
    /// Open losses by (lower drone, higher drone): (violation index, last window seen).
    /// Ordered, so losses that end together end in a deterministic order.
    open: BTreeMap<(u32, u32), (usize, u64)>,
    /// Windows observed.
    window: u64,
}

/// What a new violation is about; built only when one starts.
struct NewViolation {
    kind: ViolationKind,
    drone: u32,
    drone_name: String,
    other: Option<u32>,
    zone: Option<String>,
    limit_m: Option<f64>,
    /// Human detail for the `violationStarted` event.
    detail: String,
}

/// The report and the events raised since the last take.
#[derive(Debug)]
struct Log {
    frame: LocalFrame,
    report: ComplianceReport,
    events: Vec<Event>,
}

impl Log {
    /// The events raised since the last call, in time order (stable: what happened to a
    /// drone at one instant keeps its order, e.g. `zoneEntered` before `violationStarted`).
    fn take_events(&mut self) -> Vec<Event> {
        let mut events = std::mem::take(&mut self.events);
        events.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
        events
    }

    fn place(&self, s: &Sample) -> Place {
        let g = self.frame.to_geodetic(s.p);
        Place {
            east_m: s.p.east_m,
            north_m: s.p.north_m,
            up_m: s.p.up_m,
            latitude_deg: g.latitude_deg,
            longitude_deg: g.longitude_deg,
            altitude_msl_m: g.altitude_msl_m,
            height_agl_m: s.height_agl_m,
        }
    }

    fn emit(&mut self, time_s: f64, drone: u32, kind: EventKind) {
        self.events.push(Event { time_s, drone: Some(drone), kind });
    }

    /// Opens a stay; returns its index in the report.
    fn enter(&mut self, drone: u32, zone: &str, s: &Sample, authorized: bool) -> usize {
        self.report.presences.push(Presence {
            drone,
            zone: zone.to_string(),
            entered_s: s.time_s,
            exited_s: None,
            authorized,
            min_agl_m: s.height_agl_m,
        });
        let at = self.place(s);
        self.emit(s.time_s, drone, EventKind::ZoneEntered { zone: zone.to_string(), authorized, at });
        self.report.presences.len() - 1
    }

    /// Closes the stay and its zone violations at `s` (violations end first).
    fn leave(&mut self, stay: &mut ZoneStay, s: &Sample) {
        for v in [stay.unauthorized.take(), stay.below.take(), stay.above.take()].into_iter().flatten() {
            self.end(v, s.time_s);
        }
        let Some(k) = stay.presence.take() else { return };
        let presence = &mut self.report.presences[k];
        presence.exited_s = Some(s.time_s);
        let (drone, zone, duration_s) = (presence.drone, presence.zone.clone(), s.time_s - presence.entered_s);
        let at = self.place(s);
        self.emit(s.time_s, drone, EventKind::ZoneExited { zone, duration_s: duration_s.max(0.0), at });
    }

    /// The zone rules at one sample inside the zone, given the drone's valid lease
    /// constraints there (`None`: no lease).
    fn judge_inside(
        &mut self,
        stay: &mut ZoneStay,
        drone: u32,
        drone_name: &str,
        zone: &str,
        s: &Sample,
        lease: Option<LeaseConstraints>,
    ) {
        let agl_m = s.height_agl_m;
        if let Some(k) = stay.presence {
            let presence = &mut self.report.presences[k];
            presence.min_agl_m = presence.min_agl_m.min(agl_m);
        }
        let new = |kind, limit_m: Option<f64>, detail: String| NewViolation {
            kind,
            drone,
            drone_name: drone_name.to_string(),
            other: None,
            zone: Some(zone.to_string()),
            limit_m,
            detail,
        };
        self.track(&mut stay.unauthorized, lease.is_none().then_some(agl_m), s, || {
            new(ViolationKind::UnauthorizedEntry, None, format!("inside {zone} without a valid lease"))
        });
        let min_m = lease.and_then(|c| c.min_altitude_agl_m).filter(|&m| agl_m < m);
        self.track(&mut stay.below, min_m.map(|_| agl_m), s, || {
            let m = min_m.unwrap_or_default();
            new(
                ViolationKind::BelowZoneMinimum,
                min_m,
                format!("inside {zone} at {agl_m:.1} m AGL, below the lease's minimum of {m:.1} m AGL"),
            )
        });
        let max_m = lease.and_then(|c| c.max_altitude_agl_m).filter(|&m| agl_m > m);
        self.track(&mut stay.above, max_m.map(|_| agl_m), s, || {
            let m = max_m.unwrap_or_default();
            new(
                ViolationKind::AboveZoneMaximum,
                max_m,
                format!("inside {zone} at {agl_m:.1} m AGL, above the lease's maximum of {m:.1} m AGL"),
            )
        });
    }

    /// One rule at one sample: `breach` is the measured value when the rule is broken.
    /// Starts, extends or ends the episode in `open`.
    fn track(&mut self, open: &mut Option<usize>, breach: Option<f64>, s: &Sample, new: impl FnOnce() -> NewViolation) {
        match (*open, breach) {
            (None, Some(value)) => *open = Some(self.start(new(), s, value)),
            (Some(v), Some(value)) => self.worsen(v, value),
            (Some(v), None) => {
                self.end(v, s.time_s);
                *open = None;
            }
            (None, None) => {}
        }
    }

    /// Records a new episode starting at `s`; returns its index.
    fn start(&mut self, new: NewViolation, s: &Sample, value: f64) -> usize {
        let at = self.place(s);
        let rule = new.kind.as_str().to_string();
        self.emit(
            s.time_s,
            new.drone,
            EventKind::ViolationStarted {
                rule,
                zone: new.zone.clone(),
                other: new.other,
                limit_m: new.limit_m,
                at,
                detail: new.detail,
            },
        );
        self.report.violations.push(ViolationRecord {
            kind: new.kind,
            drone: new.drone,
            drone_name: new.drone_name,
            other: new.other,
            zone: new.zone,
            start_s: s.time_s,
            end_s: None,
            at,
            limit_m: new.limit_m,
            worst_m: value,
        });
        self.report.violations.len() - 1
    }

    fn worsen(&mut self, v: usize, value: f64) {
        let record = &mut self.report.violations[v];
        record.worst_m =
            if record.kind.worst_is_highest() { record.worst_m.max(value) } else { record.worst_m.min(value) };
    }

    /// Ends episode `v` at `time_s`.
    fn end(&mut self, v: usize, time_s: f64) {
        let record = &mut self.report.violations[v];
        record.end_s = Some(time_s);
        let kind = EventKind::ViolationEnded {
            rule: record.kind.as_str().to_string(),
            zone: record.zone.clone(),
            other: record.other,
            duration_s: (time_s - record.start_s).max(0.0),
            worst_m: record.worst_m,
        };
        let drone = record.drone;
        self.emit(time_s, drone, kind);
    }
}

mod altitude;
mod position_error;
#[cfg(test)]
mod tests;
mod zone_distance;
