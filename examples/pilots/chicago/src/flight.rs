//! Flying one drone through its task, on its own thread: take off, fly to the zone, ask
//! the authority, act on the verdict, come home and land.
//!
//! Every duration is measured on the drone's clock (`time_boot_ms` of its telemetry, sim
//! seconds since the run started), never the wall clock: the simulator may run 4x or 20x
//! faster than real time. Only socket waits are wall-clock (see `link`).
//!
//! Each decision is one line on stdout: sim time, drone, what it decided and why (the
//! verdicts included). Whatever happens during the task (a denial, a low battery, an API
//! error), the drone leaves the zone, releases its lease and lands at home.

use std::fmt::Display;
use std::time::{Duration, Instant};

use mavlink::dialects::common::{MavCmd, MavFrame, MavResult, MavSeverity};
use sadesim_crds::geo::{Enu, LocalFrame};
use sadesim_crds::polygon::Point;

use crate::airspace::{AltitudeBand, Client, EntryRequest, Lease, Verdict};
use crate::geometry;
use crate::link::{Link, LinkError};
use crate::plan::{self, Disc, Task};
use crate::rng::Rng;
use crate::zones::Zone;

/// A go-to is reached within this horizontal distance of its target, metres...
const ARRIVAL_RADIUS_M: f64 = 3.0;
/// ...and this close to its altitude, metres.
const ARRIVAL_ALTITUDE_M: f64 = 2.0;
/// Remaining charge below which a drone heads home at once (the brief's 25 %).
const LOW_BATTERY: f64 = 0.25;
/// Charge a drone plans to land with: watching and loitering end when what is left after
/// the way home would fall below this (PX4's own low-battery failsafe is at 15 %).
const BATTERY_RESERVE: f64 = 0.15;
/// Descent speed assumed for the way home (PX4's MPC_Z_V_AUTO_DN), m/s.
const DESCENT_MPS: f64 = 1.5;
/// Climb speed for takeoffs (MPC_TKO_SPEED; the x500's limit is 3 m/s), m/s.
const TAKEOFF_MPS: f64 = 3.0;
/// Horizontal speed of go-tos (MPC_XY_CRUISE): x500s and sub-250 g drones, m/s.
const CRUISE_X500_MPS: f64 = 12.0;
const CRUISE_SMALL_MPS: f64 = 8.0;
/// Routes of a drone without a lease keep this far from zones, metres.
const ZONE_CLEARANCE_M: f64 = 20.0;
/// Hobbyists' waypoints and legs keep this far from zones, metres.
const WAYPOINT_ZONE_MARGIN_M: f64 = 15.0;
/// A hobbyist denied entry asks again only after this long, sim seconds.
const REREQUEST_AFTER_S: f64 = 60.0;
/// Altitude margin to a lease's limits and to the group's ceiling, metres.
const ALTITUDE_MARGIN_M: f64 = 3.0;
/// A lease is renewed when it would expire within this, sim seconds.
const RENEW_BEFORE_S: f64 = 60.0;
/// Wall time without a MAVLink message after which the drone counts as lost.
const CONTACT_TIMEOUT: Duration = Duration::from_secs(10);
/// Wall time for a drone to become ready (heartbeat, 3D fix) and to accept arming.
const READY_TIMEOUT: Duration = Duration::from_secs(60);

/// What every drone thread shares.
#[derive(Debug)]
pub struct Context {
    pub client: Client,
    /// The run's local frame (fleet file `origin`).
    pub frame: LocalFrame,
    /// Every zone, from the authority's `GET /zones`.
    pub zones: Vec<Zone>,
    /// Index in `zones` of the zone of the case study (the museum).
    pub target: usize,
    /// The non-compliant variant: journalists enter after a denial.
    pub journalists_ignore_denials: bool,
    /// Each journalist ignores its denial with this probability (a worse pilot version).
    pub ignore_denials_share: f64,
    /// The run's `spec.seed` (0 without the scenario): draws `ignore_denials_share`.
    pub run_seed: u64,
    /// Seed of the hobbyists' random waypoints.
    pub seed: u64,
    /// The forecast wind (the scenario's), for the cost of the way home; `None`: unknown.
    pub wind: Option<plan::Wind>,
}

/// One drone, from the fleet file.
#[derive(Clone, Debug)]
pub struct DroneSpec {
    pub index: u32,
    pub name: String,
    pub operator: String,
    pub airframe: String,
    pub system_id: u8,
    pub component_id: u8,
    /// `mavlink.udp` of the fleet file.
    pub udp_url: String,
    /// Home on the local plane.
    pub home: Point,
    /// The group's ceiling, metres above ground.
    pub max_altitude_agl_m: f64,
    /// The bearer token (from the variable named by `credentialEnv`).
    pub token: Option<String>,
}

/// Why a task stopped early.
#[derive(Debug)]
enum Abort {
    /// Not enough charge left for more than the way home (remaining fraction).
    Battery(f64),
    /// Something went wrong; the drone still tries to come home.
    Failed(String),
}

impl From<LinkError> for Abort {
    fn from(e: LinkError) -> Self {
        Abort::Failed(e.to_string())
    }
}

/// A lease the drone holds.
#[derive(Debug)]
struct Held {
    lease: Lease,
    zone: String,
    /// Where the drone leaves the zone to (where it was granted entry).
    exit: Point,
    /// Our clock minus the authority's, sim seconds (0 when the lease gives no grant time).
    clock_offset_s: f64,
    renew_failed: bool,
}

/// Flies `spec` through `task`; `Ok` when it landed and disarmed without trouble, else
/// what went wrong (the drone is brought home whenever it can be).
///
/// # Errors
/// The drone could not be readied or armed, lost contact, could not land, or an API call
/// failed on the way (the message lists every problem).
pub fn fly(spec: &DroneSpec, ctx: &Context, task: &Task) -> Result<(), String> {
    if *task == Task::Unassigned {
        log_line(None, &spec.name, "no task for this role in the case study: staying on the ground");
        return Ok(());
    }
    let link = Link::open(&spec.udp_url, spec.system_id, spec.component_id).map_err(|e| e.to_string())?;
    let cruise_mps = if spec.airframe == "x500" { CRUISE_X500_MPS } else { CRUISE_SMALL_MPS };
    let mut p = Pilot {
        spec,
        ctx,
        link,
        cruise_mps,
        returning: false,
        battery_origin: None,
        lease: None,
        problems: Vec::new(),
    };
    let takeoff_m = match task {
        Task::PublicSafety { .. } => plan::PUBLIC_SAFETY_CRUISE_AGL_M,
        Task::Journalist { .. } => plan::JOURNALIST_CRUISE_AGL_M,
        _ => plan::RECREATIONAL_TAKEOFF_AGL_M,
    }
    .min(spec.max_altitude_agl_m - ALTITUDE_MARGIN_M);
    if let Err(e) = p.prepare(takeoff_m) {
        let why = match e {
            Abort::Failed(m) => m,
            Abort::Battery(r) => format!("battery {:.0} % before takeoff", r * 100.0),
        };
        p.log(format!("not flying: {why}"));
        return Err(why);
    }
    let mission = match task {
        Task::PublicSafety { hold, watch } => p.public_safety(takeoff_m, *hold, *watch),
        Task::Journalist { spot, inside } => p.journalist(takeoff_m, *spot, *inside),
        Task::Recreational { area } => p.recreational(takeoff_m, *area),
        Task::Unassigned => Ok(()),
    };
    p.finish(mission)
}

/// One log line: sim time (when known), drone, text.
fn log_line(time_s: Option<f64>, drone: &str, what: impl Display) {
    let t = time_s.map_or_else(|| "      -".to_owned(), |t| format!("{t:7.1}"));
    println!("t={t}s {drone:<16} {what}");
}

/// One drone's pilot.
#[derive(Debug)]
struct Pilot<'a> {
    spec: &'a DroneSpec,
    ctx: &'a Context,
    link: Link,
    cruise_mps: f64,
    /// Set once the drone heads home: a low battery no longer cuts anything short.
    returning: bool,
    /// (sim time, remaining charge) at takeoff: the origin of the consumption rate.
    battery_origin: Option<(f64, f64)>,
    lease: Option<Held>,
    /// Problems to report even though the drone came home.
    problems: Vec<String>,
}

impl Pilot<'_> {
    fn log(&self, what: impl Display) {
        log_line(self.link.telemetry.time_s, &self.spec.name, what);
    }

    /// The drone's clock, sim seconds.
    fn now(&self) -> f64 {
        self.link.telemetry.time_s.unwrap_or(0.0)
    }

    /// Where the drone is on the local plane (its own estimate).
    fn here(&self) -> Point {
        self.link
            .telemetry
            .position
            .map_or(self.spec.home, |f| self.ctx.frame.to_plane(f.latitude_deg, f.longitude_deg))
    }

    /// Height above home, metres.
    fn altitude(&self) -> f64 {
        self.link.telemetry.position.map_or(0.0, |f| f.relative_alt_m)
    }

    fn zone(&self) -> &Zone {
        &self.ctx.zones[self.ctx.target]
    }

    /// One turn of every wait: read the link, pass on what the drone says, keep the lease,
    /// watch the battery.
    fn step(&mut self) -> Result<(), Abort> {
        self.link.pump()?;
        while let Some((severity, text)) = self.link.status_texts.pop_front() {
            // Warnings and worse (failsafes, crashes); not "Armed" and "Disarmed".
            if (severity as u32) <= MavSeverity::MAV_SEVERITY_WARNING as u32 {
                self.log(format!("drone says: {text}"));
            }
        }
        if self.link.silent_for() > CONTACT_TIMEOUT {
            return Err(Abort::Failed(format!("lost contact: no MAVLink for {} s", CONTACT_TIMEOUT.as_secs())));
        }
        self.renew_if_due()?;
        self.check_battery()
    }

    /// Steps until `done`, or fails after `timeout_s` of the drone's clock.
    fn wait_until(&mut self, what: &str, timeout_s: f64, mut done: impl FnMut(&Self) -> bool) -> Result<(), Abort> {
        self.step()?;
        let start = self.now();
        while !done(self) {
            if self.now() - start > timeout_s {
                return Err(Abort::Failed(format!("{what}: not done after {timeout_s:.0} s")));
            }
            self.step()?;
        }
        Ok(())
    }

    /// Heartbeat, a 3D fix and a position; speeds and altitudes set; armed.
    fn prepare(&mut self, takeoff_m: f64) -> Result<(), Abort> {
        let started = Instant::now();
        loop {
            self.step()?;
            let t = &self.link.telemetry;
            if t.heartbeat && t.gps_3d_fix && t.position.is_some() && t.time_s.is_some() {
                break;
            }
            if started.elapsed() > READY_TIMEOUT {
                return Err(Abort::Failed(format!(
                    "not ready after {} s (heartbeat {}, 3D fix {}, position {})",
                    READY_TIMEOUT.as_secs(),
                    t.heartbeat,
                    t.gps_3d_fix,
                    t.position.is_some()
                )));
            }
        }
        self.link.set_param("MPC_XY_CRUISE", self.cruise_mps as f32)?;
        self.link.set_param("MPC_TKO_SPEED", TAKEOFF_MPS as f32)?;
        self.link.set_param("MIS_TAKEOFF_ALT", takeoff_m as f32)?;
        // RTL climbs to RTL_RETURN_ALT first: keep that under the group's ceiling.
        let rtl_m = 30f64.min(self.spec.max_altitude_agl_m - 10.0).max(5.0);
        self.link.set_param("RTL_RETURN_ALT", rtl_m as f32)?;
        // With no mission loaded, go-tos fly at MPC_XY_CRUISE once the mission is cleared.
        self.link.clear_mission()?;
        loop {
            match self.link.command_long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])? {
                MavResult::MAV_RESULT_ACCEPTED => return Ok(()),
                MavResult::MAV_RESULT_TEMPORARILY_REJECTED if started.elapsed() < READY_TIMEOUT => {
                    let retry = Instant::now() + Duration::from_millis(500);
                    while Instant::now() < retry {
                        self.step()?; // e.g. the position estimate is not accurate enough yet
                    }
                }
                other => return Err(Abort::Failed(format!("arming refused: {other:?}"))),
            }
        }
    }

    fn takeoff(&mut self, altitude_m: f64) -> Result<(), Abort> {
        let nan = f32::NAN; // MIS_TAKEOFF_ALT above home, here
        match self.link.command_long(MavCmd::MAV_CMD_NAV_TAKEOFF, [0.0, 0.0, 0.0, nan, nan, nan, nan])? {
            MavResult::MAV_RESULT_ACCEPTED => {}
            other => return Err(Abort::Failed(format!("takeoff refused: {other:?}"))),
        }
        if let Some(remaining) = self.link.telemetry.battery_remaining {
            self.battery_origin = Some((self.now(), remaining));
        }
        self.log(format!("armed, taking off to {altitude_m:.1} m"));
        self.wait_until("takeoff", altitude_m / TAKEOFF_MPS * 2.0 + 30.0, |p| p.altitude() >= altitude_m - 1.0)
    }

    /// DO_REPOSITION to `to` at `altitude_m` above home, then waits until there.
    fn goto(&mut self, to: Point, altitude_m: f64) -> Result<(), Abort> {
        let g = self.ctx.frame.to_geodetic(Enu { east_m: to.0, north_m: to.1, up_m: 0.0 });
        let position =
            ((g.latitude_deg * 1e7).round() as i32, (g.longitude_deg * 1e7).round() as i32, altitude_m as f32);
        // param1 -1: default speed; param2 1: switch mode (MAV_DO_REPOSITION_FLAGS_CHANGE_MODE).
        let result = self.link.command_int(
            MavCmd::MAV_CMD_DO_REPOSITION,
            MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
            [-1.0, 1.0, 0.0, f32::NAN],
            position,
        )?;
        if result != MavResult::MAV_RESULT_ACCEPTED {
            return Err(Abort::Failed(format!("go-to refused: {result:?}")));
        }
        let timeout = geometry::distance(self.here(), to) / self.cruise_mps * 2.0
            + (altitude_m - self.altitude()).abs() / 1.0
            + 60.0;
        self.wait_until(&format!("reaching ({:.0}, {:.0}) m", to.0, to.1), timeout, |p| {
            geometry::distance(p.here(), to) <= ARRIVAL_RADIUS_M
                && (p.altitude() - altitude_m).abs() <= ARRIVAL_ALTITUDE_M
        })
    }

    /// Flies to `goal` round every zone the drone holds no lease for.
    fn route_to(&mut self, goal: Point, altitude_m: f64) -> Result<(), Abort> {
        let leased = self.lease.as_ref().map(|h| h.zone.clone());
        let obstacles: Vec<Vec<Point>> =
            self.ctx.zones.iter().filter(|z| Some(&z.name) != leased.as_ref()).map(|z| z.outline.clone()).collect();
        let from = self.here();
        let path = geometry::route(from, goal, &obstacles, ZONE_CLEARANCE_M)
            .ok_or_else(|| Abort::Failed(format!("no route round the zones to ({:.0}, {:.0}) m", goal.0, goal.1)))?;
        if path.len() > 1 {
            self.log(format!(
                "routing round the zones: {} turns, {:.0} m instead of {:.0} m",
                path.len() - 1,
                geometry::path_length(from, &path),
                geometry::distance(from, goal)
            ));
        }
        for p in path {
            self.goto(p, altitude_m)?;
        }
        Ok(())
    }

    /// Stays where it is for `seconds` of the drone's clock.
    fn hold(&mut self, seconds: f64) -> Result<(), Abort> {
        let until = self.now() + seconds;
        self.wait_until("holding", seconds + 30.0, |p| p.now() >= until)
    }

    /// Stays up to `seconds` for `what` (watching, loitering): less when the charge left
    /// after the way home would fall below [`BATTERY_RESERVE`] (then logs why). `Ok(true)`
    /// when it stayed the whole time.
    fn hold_budgeted(&mut self, seconds: f64, what: &str) -> Result<bool, Abort> {
        let start = self.now();
        let until = start + seconds;
        let mut enough = true;
        self.wait_until(what, seconds + 30.0, |p| {
            p.now() >= until || {
                enough = p.can_stay();
                !enough
            }
        })?;
        if !enough {
            let left = self.link.telemetry.battery_remaining.unwrap_or(0.0);
            self.log(format!(
                "battery {:.0} %: {what} ends after {:.0} of {seconds:.0} s to keep enough for the way home",
                left * 100.0,
                self.now() - start
            ));
        }
        Ok(enough)
    }

    /// Asks the authority for the case study's zone; logs the verdict.
    fn request(&mut self, band: AltitudeBand) -> Result<Verdict, Abort> {
        let zone = self.zone().name.clone();
        let request =
            EntryRequest { drone: self.spec.name.clone(), operator: self.spec.operator.clone(), altitude: band };
        let asked = format!("request {zone} ({:.0}-{:.0} m AGL)", band.min_agl_m, band.max_agl_m);
        match self.ctx.client.request_entry(&zone, self.spec.token.as_deref(), &request) {
            Ok(v) => {
                match &v {
                    Verdict::Granted { lease, .. } => {
                        let min =
                            lease.constraints.min_altitude_agl_m.map_or("none".to_owned(), |m| format!("{m:.1} m AGL"));
                        self.log(format!(
                            "{asked}: GRANTED {} (minimum inside {min}, expires t={:.0}s)",
                            lease.id, lease.expires_at_s
                        ));
                    }
                    Verdict::Denied { reason, message, .. } => {
                        self.log(format!("{asked}: DENIED {reason} ({message})"));
                    }
                }
                Ok(v)
            }
            Err(e) => {
                self.log(format!("{asked}: no verdict: {e}"));
                Err(Abort::Failed(format!("entry request failed: {e}")))
            }
        }
    }

    fn take_lease(&mut self, lease: Lease, exit: Point) {
        let clock_offset_s = lease.granted_at_s.map_or(0.0, |g| self.now() - g);
        let zone = self.zone().name.clone();
        self.lease = Some(Held { lease, zone, exit, clock_offset_s, renew_failed: false });
    }

    /// Renews the lease when it would expire within [`RENEW_BEFORE_S`].
    fn renew_if_due(&mut self) -> Result<(), Abort> {
        let now = self.now();
        let Some(held) = &self.lease else { return Ok(()) };
        if held.renew_failed || now < held.lease.expires_at_s + held.clock_offset_s - RENEW_BEFORE_S {
            return Ok(());
        }
        let id = held.lease.id.clone();
        match self.ctx.client.renew(&id, self.spec.token.as_deref()) {
            Ok(lease) => {
                self.log(format!("renewed {id} until t={:.0}s", lease.expires_at_s));
                if let Some(h) = self.lease.as_mut() {
                    h.lease.expires_at_s = lease.expires_at_s;
                }
                Ok(())
            }
            Err(e) => {
                self.log(format!("renewing {id} failed: {e}"));
                self.problems.push(format!("lease renewal failed: {e}"));
                if let Some(h) = self.lease.as_mut() {
                    h.renew_failed = true;
                }
                if self.returning {
                    Ok(())
                } else {
                    Err(Abort::Failed("lease renewal failed: leaving the zone".into()))
                }
            }
        }
    }

    /// Releases the lease held, if any.
    fn release(&mut self) {
        let Some(held) = self.lease.take() else { return };
        match self.ctx.client.release(&held.lease.id, self.spec.token.as_deref()) {
            Ok(_) => self.log(format!("released {} ({})", held.lease.id, held.zone)),
            Err(e) => {
                self.log(format!("releasing {} failed: {e}", held.lease.id));
                self.problems.push(format!("lease release failed: {e}"));
            }
        }
    }

    /// Cuts the task short when the charge is below [`LOW_BATTERY`] (not once the drone
    /// is on its way home).
    fn check_battery(&self) -> Result<(), Abort> {
        match self.link.telemetry.battery_remaining {
            Some(remaining) if remaining < LOW_BATTERY && !self.returning => Err(Abort::Battery(remaining)),
            _ => Ok(()),
        }
    }

    /// Whether the drone can stay out longer: the charge left after the way home, at the
    /// average rate since takeoff times [`plan::return_cost_factor`] for the wind on the
    /// way home, stays above [`BATTERY_RESERVE`]. (The way home: 5 % longer than straight,
    /// at cruise speed, then the descent, plus 20 s to settle.)
    fn can_stay(&self) -> bool {
        let (Some((t0, r0)), Some(remaining)) = (self.battery_origin, self.link.telemetry.battery_remaining) else {
            return true;
        };
        let elapsed = self.now() - t0;
        if elapsed < 30.0 || r0 <= remaining {
            return true; // no rate to go by yet
        }
        let rate_per_s = (r0 - remaining) / elapsed;
        let (here, home) = (self.here(), self.spec.home);
        let factor = plan::return_cost_factor((home.0 - here.0, home.1 - here.1), self.ctx.wind);
        let horizontal_s = geometry::distance(here, home) * 1.05 / self.cruise_mps;
        let home_s = factor * horizontal_s + self.altitude() / DESCENT_MPS + 20.0;
        remaining - rate_per_s * home_s >= BATTERY_RESERVE
    }

    /// After the task (finished or cut short): out of the zone, lease released, home,
    /// landed and disarmed.
    fn finish(&mut self, mission: Result<(), Abort>) -> Result<(), String> {
        self.returning = true;
        match mission {
            Ok(()) => {}
            Err(Abort::Battery(r)) => {
                self.log(format!("battery {:.0} %: only enough for the way home, cutting the task short", r * 100.0))
            }
            Err(Abort::Failed(e)) => {
                self.log(format!("problem: {e}; returning home"));
                self.problems.push(e);
            }
        }
        if let Some(held) = &self.lease {
            let (exit, zone) = (held.exit, held.zone.clone());
            self.log(format!("leaving {zone}"));
            let altitude = self.altitude();
            if let Err(Abort::Failed(e)) = self.goto(exit, altitude) {
                self.problems.push(format!("leaving {zone}: {e}"));
            }
            self.release();
        }
        if let Err(e) = self.come_home() {
            let why = match e {
                Abort::Failed(m) => m,
                Abort::Battery(r) => format!("battery {:.0} %", r * 100.0),
            };
            self.log(format!("did not get home: {why}"));
            self.problems.push(why);
        }
        if self.problems.is_empty() { Ok(()) } else { Err(self.problems.join("; ")) }
    }

    /// Home round the zones, then RTL (which lands and disarms).
    fn come_home(&mut self) -> Result<(), Abort> {
        self.step()?;
        if !self.link.telemetry.armed {
            return Ok(());
        }
        let altitude = self.altitude().max(5.0);
        if geometry::distance(self.here(), self.spec.home) > ARRIVAL_RADIUS_M {
            self.route_to(self.spec.home, altitude)?;
        }
        self.log("over home: return to launch");
        match self.link.command_long(MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH, [0.0; 7])? {
            MavResult::MAV_RESULT_ACCEPTED => {}
            other => return Err(Abort::Failed(format!("return to launch refused: {other:?}"))),
        }
        self.wait_until("landing", altitude / 1.0 + 120.0, |p| p.link.telemetry.landed_and_disarmed())?;
        let battery = self.link.telemetry.battery_remaining.map_or("?".to_owned(), |b| format!("{:.0} %", b * 100.0));
        self.log(format!("landed and disarmed, battery {battery}"));
        Ok(())
    }

    /// Enters the zone under `lease` from `entry` to `inside`, stays `stay_s`, leaves to
    /// `entry` and releases. Refuses (and releases) a lease whose altitude constraints the
    /// drone cannot keep.
    fn visit(
        &mut self,
        lease: Lease,
        entry: Point,
        inside: Point,
        preferred_m: f64,
        band: AltitudeBand,
        stay_s: f64,
    ) -> Result<(), Abort> {
        let zone = self.zone().name.clone();
        let c = lease.constraints;
        let altitude = plan::inside_altitude(
            preferred_m,
            band,
            c.min_altitude_agl_m,
            c.max_altitude_agl_m,
            self.spec.max_altitude_agl_m,
            ALTITUDE_MARGIN_M,
        );
        self.take_lease(lease, entry);
        let Some(altitude) = altitude else {
            self.log(format!(
                "cannot keep the lease's altitude limits under my {:.1} m ceiling: not entering {zone}",
                self.spec.max_altitude_agl_m
            ));
            self.release();
            return Ok(());
        };
        if (altitude - self.altitude()).abs() > ARRIVAL_ALTITUDE_M {
            self.log(format!("changing to {altitude:.1} m AGL before entering {zone}"));
            self.goto(entry, altitude)?;
        }
        self.log(format!("entering {zone} at {altitude:.1} m AGL"));
        self.goto(inside, altitude)?;
        self.log(format!("inside {zone}: staying {stay_s:.0} s"));
        self.hold_budgeted(stay_s, &format!("the stay in {zone}"))?;
        self.log(format!("leaving {zone}"));
        self.goto(entry, altitude)?;
        self.release();
        Ok(())
    }

    /// Public safety: to the hold point, ask, watch from inside when granted.
    fn public_safety(&mut self, cruise_m: f64, hold: Point, watch: Point) -> Result<(), Abort> {
        self.takeoff(cruise_m)?;
        self.route_to(hold, cruise_m)?;
        let zone = self.zone().name.clone();
        self.log(format!("holding {:.0} m outside {zone}: asking to enter", plan::HOLD_OFFSET_M));
        match self.request(plan::PUBLIC_SAFETY_BAND)? {
            Verdict::Granted { lease, .. } => {
                self.visit(lease, hold, watch, cruise_m, plan::PUBLIC_SAFETY_BAND, plan::WATCH_S)
            }
            Verdict::Denied { .. } => {
                self.log(format!("denied: holding outside {zone} for {:.0} s, then home", plan::DENIED_HOLD_S));
                self.hold_budgeted(plan::DENIED_HOLD_S, "holding").map(|_| ())
            }
        }
    }

    /// Whether this journalist enters after a denial: always in the non-compliant variant,
    /// else with probability `ignore_denials_share` (drawn per run seed and drone).
    fn ignores_denials(&self) -> bool {
        let share = self.ctx.ignore_denials_share;
        self.ctx.journalists_ignore_denials
            || (share > 0.0
                && crate::rng::Rng::for_drone(self.ctx.run_seed ^ 0x1a7e_d0c5, self.spec.index).unit() < share)
    }

    /// News crew: to the spot north of the zone, ask, loiter when denied (or, in the
    /// non-compliant variant, go in anyway).
    fn journalist(&mut self, cruise_m: f64, spot: Point, inside: Point) -> Result<(), Abort> {
        self.takeoff(cruise_m)?;
        self.route_to(spot, cruise_m)?;
        let zone = self.zone().name.clone();
        match self.request(plan::JOURNALIST_BAND)? {
            Verdict::Granted { lease, .. } => self.visit(lease, spot, inside, cruise_m, plan::JOURNALIST_BAND, 60.0),
            Verdict::Denied { .. } if self.ignores_denials() => {
                self.log(format!("ignoring the denial: entering {zone} without a lease"));
                self.goto(inside, cruise_m)?;
                self.log(format!("inside {zone} without a lease: filming {:.0} s", plan::INTRUSION_S));
                self.hold_budgeted(plan::INTRUSION_S, "filming")?;
                self.log(format!("leaving {zone}"));
                self.goto(spot, cruise_m)
            }
            Verdict::Denied { .. } => {
                self.log(format!("denied: loitering outside {zone} for {:.0} s, then home", plan::LOITER_S));
                self.hold_budgeted(plan::LOITER_S, "loitering").map(|_| ())
            }
        }
    }

    /// Hobbyist: asks for a look at the museum first; denied, wanders between random
    /// waypoints over its park, asking again (at most once a minute) when a leg would
    /// cross the zone and diverting when denied.
    fn recreational(&mut self, takeoff_m: f64, area: Disc) -> Result<(), Abort> {
        self.takeoff(takeoff_m)?;
        let mut rng = Rng::for_drone(self.ctx.seed, self.spec.index);
        let band = plan::RECREATIONAL_BAND;
        let zone = self.zone().clone();
        let look =
            rng.point_in_polygon(&zone.outline, 20.0).unwrap_or_else(|| geometry::interior_anchor(&zone.outline));
        let look_m = rng.range(band.min_agl_m, band.max_agl_m);
        self.log(format!(
            "first waypoint: a look at {} from inside it, {:.0} m away",
            zone.name,
            geometry::distance(self.here(), look)
        ));
        let mut last_denial = None;
        match self.request(band)? {
            Verdict::Granted { lease, .. } => {
                let entry = self.here();
                self.visit(lease, entry, look, look_m, band, plan::RECREATIONAL_HOLD_S)?;
            }
            Verdict::Denied { .. } => {
                last_denial = Some(self.now());
                self.log("denied: diverting to random waypoints over my park");
            }
        }
        for k in 1..=plan::RECREATIONAL_WAYPOINTS {
            let Some((to, altitude)) = self.next_waypoint(&mut rng, area, &mut last_denial)? else {
                self.log("no waypoint clear of the zones: heading home");
                break;
            };
            self.goto(to, altitude)?;
            self.release(); // a lease taken for this leg (never, in the case study)
            self.hold(plan::RECREATIONAL_HOLD_S)?;
            self.log(format!("waypoint {k}/{} reached", plan::RECREATIONAL_WAYPOINTS));
        }
        Ok(())
    }

    /// A random waypoint in `area` (and within [`plan::WANDER_RADIUS_M`] of home) clear of
    /// every zone, whose leg from here is clear too, or for which the authority granted
    /// the crossing. `None` after 100 draws without one.
    fn next_waypoint(
        &mut self,
        rng: &mut Rng,
        area: Disc,
        last_denial: &mut Option<f64>,
    ) -> Result<Option<(Point, f64)>, Abort> {
        let band = plan::RECREATIONAL_BAND;
        let ceiling = self.spec.max_altitude_agl_m - ALTITUDE_MARGIN_M;
        for _ in 0..100 {
            let to = rng.point_in_disc(area.center, area.radius_m);
            let altitude = rng.range(band.min_agl_m, band.max_agl_m).min(ceiling);
            if geometry::distance(to, self.spec.home) > plan::WANDER_RADIUS_M {
                continue;
            }
            let margin = WAYPOINT_ZONE_MARGIN_M;
            if self.ctx.zones.iter().any(|z| geometry::distance_to_polygon(&z.outline, to) < margin) {
                continue; // not a place to fly to
            }
            let here = self.here();
            let crossed = self.ctx.zones.iter().position(|z| geometry::leg_enters(&z.outline, here, to, margin));
            let Some(crossed) = crossed else { return Ok(Some((to, altitude))) };
            let name = self.ctx.zones[crossed].name.clone();
            let recently = last_denial.is_some_and(|t| self.now() - t < REREQUEST_AFTER_S);
            if crossed != self.ctx.target || recently {
                self.log(format!("skipping a waypoint: the leg crosses {name} (denied recently)"));
                continue;
            }
            self.log(format!("the leg to the next waypoint crosses {name}: asking"));
            match self.request(band)? {
                Verdict::Denied { .. } => {
                    *last_denial = Some(self.now());
                    self.log("denied: diverting to another waypoint");
                }
                Verdict::Granted { lease, .. } => {
                    let c = lease.constraints;
                    let ok = plan::inside_altitude(
                        altitude,
                        band,
                        c.min_altitude_agl_m,
                        c.max_altitude_agl_m,
                        self.spec.max_altitude_agl_m,
                        ALTITUDE_MARGIN_M,
                    );
                    self.take_lease(lease, here);
                    match ok {
                        Some(a) => return Ok(Some((to, a))),
                        None => {
                            self.log("cannot keep the lease's altitude limits: diverting to another waypoint");
                            self.release();
                        }
                    }
                }
            }
        }
        Ok(None)
    }
}
