//! One simulated drone: rigid body, motors, battery, sensors and its FMU, stepped at the
//! physics rate, with its scripted pilot (`pilot::ScriptedPilot`), its ground contact
//! (`vehicle::ground`) and its MAVLink session, which reads and writes the shard's queues
//! (`shard::mavlink_io`), never a socket. Building contact is the shard's query of the
//! world (`World::ball_touches_building`).

use nalgebra::Vector3;
use sadesim_crds::fleet::GeofenceAction;
use sadesim_crds::plan::PlannedDrone;

use crate::airspace::volume::ZoneVolume;
use crate::autopilot::fmu::{Fmu, SensorFrame};
use crate::autopilot::geofence::Geofence;
use crate::autopilot::mission::MissionPlan;
use crate::autopilot::navigator::{Command, NavigatorConfig, Rejection};
use crate::env::{EnvSample, SampleContext};
use crate::events::{CrashCause, EventKind, FlightMode};
use crate::mavlink::session::{Outgoing, Session, Vehicle};
use crate::mavlink::telemetry::{BatteryView, MissionProgress, PositionEstimate, VehicleView};
use crate::pilot::ScriptedPilot;
use crate::preset::Preset;
use crate::protocol::{DroneDetail, DroneSnapshot, EstimateDetail, GnssDetail};
use crate::sensors::{GnssFix, SensorSuite};
use crate::vehicle::ground::{GEAR_HEIGHT_M, ground_contact};
use crate::vehicle::{Airframe, Battery, Motor, RigidState, wrench};
use sadesim_world::World;

use super::mavlink_io::MavlinkQueues;
/// Barometer readings every this many physics steps (50 Hz at 1 kHz, like PX4's baro).
const BARO_DIVIDER: u64 = 20;

/// Within this height over the last looked-up ground, m, the ground under a drone is looked
/// up every step ([`DroneSim::touch_ground`]).
const GROUND_LOOKUP_NEAR_M: f64 = 5.0;
/// Higher up, the ground under a drone is looked up every this many steps.
const GROUND_LOOKUP_STEPS: u64 = 10;
/// How far a drone may move from where it last found no building near before it asks
/// again, m ([`BuildingClearance`]).
const BUILDING_CLEARANCE_M: f64 = 2.0;

/// Whether a ball touches a building, with the exact answer of
/// [`World::ball_touches_building`] at a fraction of its cost in open air.
///
/// A query with a ball [`BUILDING_CLEARANCE_M`] larger that finds nothing clears the ball
/// for as long as its centre stays within that distance of where it asked: the smaller ball
/// around any such centre lies inside the larger one. A drone in open air asks the world
/// about once every 100-400 ms of flight instead of every step.
#[derive(Clone, Copy, Debug, Default)]
struct BuildingClearance {
    /// Where the last larger query found nothing.
    clear_at: Option<Vector3<f64>>,
}

impl BuildingClearance {
    fn touches(&mut self, world: &World, center: Vector3<f64>, radius_m: f64) -> bool {
        let clearance2 = BUILDING_CLEARANCE_M * BUILDING_CLEARANCE_M;
        if self.clear_at.is_some_and(|c| (center - c).norm_squared() < clearance2) {
            return false;
        }
        if world.ball_touches_building(center, radius_m + BUILDING_CLEARANCE_M).is_none() {
            self.clear_at = Some(center);
            return false;
        }
        self.clear_at = None;
        world.ball_touches_building(center, radius_m).is_some()
    }
}

/// The autopilot as a MAVLink session sees it for one call.
struct FmuVehicle<'a> {
    fmu: &'a mut Fmu,
    on_ground: bool,
    battery: f64,
}

impl Vehicle for FmuVehicle<'_> {
    fn command(&mut self, cmd: Command) -> Result<(), Rejection> {
        self.fmu.command(cmd, self.on_ground, self.battery)
    }
    fn navigator_config(&self) -> NavigatorConfig {
        *self.fmu.navigator().config()
    }
    fn set_navigator_config(&mut self, config: NavigatorConfig) {
        self.fmu.navigator_mut().set_config(config);
    }
}

/// A drone and its whole simulated stack.
#[derive(Debug)]
pub struct DroneSim {
    pub plan: PlannedDrone,
    airframe: Airframe,
    state: RigidState,
    motors: Vec<Motor>,
    battery: Battery,
    sensors: SensorSuite,
    fmu: Fmu,
    pilot: Option<ScriptedPilot>,
    /// Radius of the ball used for building contact, m.
    pub radius_m: f64,
    /// Building contact, asked cheaply in open air.
    buildings: BuildingClearance,
    on_ground: bool,
    crashed: bool,
    wind_enu_mps: Vector3<f64>,
    height_agl_m: f64,
    origin_alt_msl_m: f64,
    events: Vec<EventKind>,
    /// The last GNSS report (for GPS_RAW_INT).
    last_gnss: Option<GnssFix>,
    /// Where the drone started (its body origin at rest), ENU: the origin of its local NED
    /// frame, as PX4's EKF origin is where it booted.
    local_origin_enu_m: Vector3<f64>,
    /// Ground height under the drone, ENU up, m.
    ground_up_m: f64,
    /// The MAVLink session, once the shard has MAVLink (boxed: most of a drone's size).
    session: Option<Box<Session>>,
    /// The group's built-in geofence (`spec.fleet[].geofence`), when set.
    geofence: Option<Geofence>,
}

impl DroneSim {
    /// A drone resting on the ground at its home.
    pub fn new(
        plan: PlannedDrone,
        preset: Preset,
        sensors: SensorSuite,
        world: &World,
        navigator: NavigatorConfig,
        origin_alt_msl_m: f64,
        mission: Option<MissionPlan>,
    ) -> Result<Self, crate::autopilot::control::ControlError> {
        let (e, n) = (plan.home.local.east_m, plan.home.local.north_m);
        let home = Vector3::new(e, n, world.ground_up_m(e, n) + GEAR_HEIGHT_M);
        let Preset { airframe, gains, .. } = preset;
        let fmu = Fmu::new(&airframe, &gains, home, navigator, origin_alt_msl_m)?;
        let radius_m = airframe.rotors.iter().map(|r| r.position_body_m.xy().norm()).fold(0.0, f64::max) + 0.12;
        Ok(Self {
            plan,
            motors: Motor::for_airframe(&airframe),
            battery: Battery::new(airframe.battery),
            state: RigidState::at_rest(home),
            airframe,
            sensors,
            fmu,
            pilot: mission.map(ScriptedPilot::new),
            radius_m,
            buildings: BuildingClearance::default(),
            on_ground: true,
            crashed: false,
            wind_enu_mps: Vector3::zeros(),
            height_agl_m: GEAR_HEIGHT_M,
            origin_alt_msl_m,
            events: Vec::new(),
            last_gnss: None,
            local_origin_enu_m: home,
            ground_up_m: home.z - GEAR_HEIGHT_M,
            session: None,
            geofence: None,
        })
    }

    /// Turns the built-in geofence on over `zones` zones (all forbidden until leased).
    pub fn enable_geofence(&mut self, action: GeofenceAction, zones: usize) {
        self.geofence = Some(Geofence::new(action, zones));
    }

    /// The zones (indices in `spec.zones`) the drone holds a valid lease for.
    pub fn set_permitted_zones(&mut self, zones: impl IntoIterator<Item = usize>) {
        if let Some(g) = &mut self.geofence {
            g.set_permitted(zones);
        }
    }

    /// Runs the geofence on the estimated state at the end of a window (`time_s`) and
    /// takes its action: HOLD or RTL, with a `failsafe` event naming the zone.
    pub fn check_geofence(&mut self, time_s: f64, zones: &[ZoneVolume], world: &World) {
        let (Some(fence), Some(est)) = (&mut self.geofence, self.fmu.estimate()) else { return };
        if self.crashed || self.on_ground {
            return;
        }
        let Some(breach) = fence.check(time_s, est.position_enu_m, est.velocity_enu_mps, self.fmu.mode(), zones, world)
        else {
            return;
        };
        let (command, mode) = match breach.action {
            GeofenceAction::Hold => (Command::Hold, FlightMode::Hold),
            GeofenceAction::ReturnToLaunch => (Command::ReturnToLaunch, FlightMode::ReturnToLaunch),
        };
        let zone = zones.get(breach.zone).map_or("?", |z| z.name.as_str());
        match self.fmu.command(command, self.on_ground, self.battery.remaining_fraction()) {
            Ok(()) => self.events.push(EventKind::Failsafe { reason: format!("geofence:{zone}"), action: mode }),
            Err(e) => self
                .events
                .push(EventKind::CommandRejected { command: format!("geofence:{zone}"), reason: e.to_string() }),
        }
    }

    /// The navigator tunables in force.
    pub fn navigator_config(&self) -> NavigatorConfig {
        *self.fmu.navigator().config()
    }

    /// Gives the drone its MAVLink session.
    pub fn attach_session(&mut self, session: Session) {
        self.session = Some(Box::new(session));
    }

    /// Builds the telemetry due at `time_s` into `outbound` (sent at the next exchange).
    pub fn mavlink_collect(&mut self, time_s: f64, outbound: &mut Vec<Outgoing>) {
        if self.session.is_none() {
            return;
        }
        let view = self.view(time_s);
        if let Some(session) = &mut self.session {
            session.poll_into(&view, outbound);
        }
    }

    /// The drone's HEARTBEAT at `time_s` into `outbound` (nothing without a session): sent
    /// while the run holds at the release for the pilot ([`crate::protocol::ToShard::Hold`]).
    pub fn mavlink_heartbeat(&self, time_s: f64, outbound: &mut Vec<Outgoing>) {
        if let Some(session) = &self.session {
            outbound.extend(session.heartbeat(&self.view(time_s)));
        }
    }

    /// An exchange: the session acts on what peers sent (`queues.inbound`, emptied) and
    /// builds its replies and the telemetry due into `queues.outbound`.
    pub fn mavlink_exchange(&mut self, time_s: f64, queues: &mut MavlinkQueues) {
        if self.session.is_none() {
            return;
        }
        if !queues.inbound.is_empty() {
            let view = self.view(time_s);
            let Some(session) = &mut self.session else { return };
            let mut vehicle = FmuVehicle {
                fmu: &mut self.fmu,
                on_ground: self.on_ground,
                battery: self.battery.remaining_fraction(),
            };
            for f in queues.inbound.drain(..) {
                session.handle(&f, &view, &mut vehicle);
            }
            // A flood's reports (`mavlink::session`).
            self.events.extend(session.take_events());
        }
        self.mavlink_collect(time_s, &mut queues.outbound);
    }

    /// What MAVLink peers see of this drone at `time_s`.
    pub fn view(&self, time_s: f64) -> VehicleView {
        let est = self.fmu.estimate();
        let nav = self.fmu.navigator();
        let count = nav.mission().map_or(0, |m| m.items.len());
        let current = nav.current_item();
        let max_thrust = self.airframe.max_thrust_n();
        let thrust: f64 = self.motors.iter().map(crate::vehicle::Motor::thrust_n).sum();
        VehicleView {
            time_s,
            armed: self.fmu.is_armed(),
            mode: self.fmu.mode(),
            on_ground: self.on_ground,
            crashed: self.crashed,
            armable: !self.crashed && self.fmu.armable(self.on_ground, self.battery.remaining_fraction()),
            estimate: est.map(|e| PositionEstimate {
                position_enu_m: e.position_enu_m,
                velocity_enu_mps: e.velocity_enu_mps,
                eph_m: e.eph_m,
                epv_m: e.epv_m,
            }),
            attitude: self.state.attitude,
            attitude_ned: crate::mavlink::telemetry::attitude_ned_frd(&self.state.attitude),
            rate_body_rps: self.state.rate_body_rps,
            gnss: self.last_gnss,
            battery: BatteryView {
                voltage_v: self.battery.voltage_v(),
                current_a: self.battery.current_a(),
                remaining: self.battery.remaining_fraction(),
                consumed_mah: self.battery.consumed_mah(),
            },
            home_enu_m: nav.home_enu_m(),
            local_origin_enu_m: self.local_origin_enu_m,
            mission: MissionProgress {
                current: current.min(count.saturating_sub(1)),
                count,
                finished: count > 0 && current >= count,
            },
            throttle: if max_thrust > 0.0 { thrust / max_thrust } else { 0.0 },
            airspeed_mps: (self.state.velocity_enu_mps - self.wind_enu_mps).norm(),
            ground_up_m: self.ground_up_m,
        }
    }

    pub fn position_enu_m(&self) -> Vector3<f64> {
        self.state.position_enu_m
    }
    pub fn is_crashed(&self) -> bool {
        self.crashed
    }
    /// The FMU has a position estimate with a settled height reference
    /// ([`Fmu::is_ready`]): pilots are released when every drone is.
    pub fn is_ready(&self) -> bool {
        self.fmu.is_ready()
    }

    /// The environment query for this step.
    pub fn sample_context(&self, local_index: usize, time_s: f64, dt_s: f64) -> SampleContext {
        SampleContext {
            drone: local_index,
            position_enu_m: self.state.position_enu_m,
            height_agl_m: self.height_agl_m,
            airspeed_mps: (self.state.velocity_enu_mps - self.wind_enu_mps).norm(),
            time_s,
            dt_s,
        }
    }

    /// Advances one physics step from `time_s` to `time_s + dt_s` (`step` is the index of
    /// the step being completed, for sensor dividers).
    pub fn step(&mut self, step: u64, time_s: f64, dt_s: f64, env: &EnvSample, world: &World, released: bool) {
        if self.crashed {
            return;
        }
        let t_end = time_s + dt_s;
        self.wind_enu_mps = env.wind_enu_mps;
        self.fly_scripted_pilot(t_end, released);

        // Dynamics: forces from motors, drag against the air, gravity; exact integration.
        let w = wrench(
            &self.airframe,
            &self.motors,
            &self.state.attitude,
            &self.state.velocity_enu_mps,
            &self.state.rate_body_rps,
            &env.wind_enu_mps,
        );
        let v_before = self.state.velocity_enu_mps;
        self.state.integrate(&self.airframe, &w, dt_s);
        self.touch_ground(world, step);
        if self.crashed {
            return;
        }
        let accel_enu = (self.state.velocity_enu_mps - v_before) / dt_s;

        // Sensors.
        let imu = self.sensors.imu.measure(accel_enu, self.state.rate_body_rps, &self.state.attitude, dt_s);
        let gnss = self.sensors.gnss.update(t_end, self.state.position_enu_m, self.state.velocity_enu_mps, &env.gnss);
        if gnss.is_some() {
            self.last_gnss = gnss;
        }
        let baro = step.is_multiple_of(BARO_DIVIDER).then(|| {
            let alt_msl = self.origin_alt_msl_m + self.state.position_enu_m.z;
            self.sensors.barometer.measure(alt_msl, dt_s * BARO_DIVIDER as f64)
        });

        // Flight controller and actuators.
        let frame = SensorFrame { imu: &imu, gnss: gnss.as_ref(), baro: baro.as_ref() };
        let commands = self.fmu.step(
            step,
            t_end,
            dt_s,
            frame,
            self.state.attitude,
            self.on_ground,
            self.battery.remaining_fraction(),
        );
        let mut power_w = 0.0;
        for (motor, u) in self.motors.iter_mut().zip(commands) {
            motor.step(*u, dt_s);
            power_w += motor.mechanical_power_w();
        }
        self.battery.update(power_w, dt_s);
        if self.fmu.has_events() {
            self.events.extend(self.fmu.take_events());
        }
    }

    /// The scripted pilot's turn (if the drone has one) at `t_s`.
    fn fly_scripted_pilot(&mut self, t_s: f64, released: bool) {
        let Some(pilot) = &mut self.pilot else { return };
        let (fmu, on_ground, battery) = (&mut self.fmu, self.on_ground, self.battery.remaining_fraction());
        if let Some(event) = pilot.fly(t_s, released, |command| fmu.command(command, on_ground, battery)) {
            self.events.push(event);
        }
    }

    /// Landing gear on the terrain under the drone ([`ground_contact`]), the `step`-th step.
    ///
    /// The ground height under the drone is looked up every step within
    /// [`GROUND_LOOKUP_NEAR_M`] of the ground, and every [`GROUND_LOOKUP_STEPS`] steps above
    /// it: the procedural relief costs four sines a lookup (a twelfth of a drone-step), and
    /// in 10 ms a drone moves at most a few decimetres, over which the ground changes by
    /// centimetres (slopes stay gentle), far from any contact.
    fn touch_ground(&mut self, world: &World, step: u64) {
        let p = self.state.position_enu_m;
        if step.is_multiple_of(GROUND_LOOKUP_STEPS) || p.z - self.ground_up_m < GROUND_LOOKUP_NEAR_M {
            self.ground_up_m = world.ground_up_m(p.x, p.y);
        }
        let contact = ground_contact(&mut self.state, self.ground_up_m, self.on_ground);
        self.height_agl_m = contact.height_agl_m;
        self.on_ground = contact.on_ground;
        if let Some(speed_mps) = contact.crash_speed_mps {
            self.crash(CrashCause::Ground, speed_mps);
        }
    }

    /// The rotor disc's ball touches a building ([`BuildingClearance`]).
    pub fn touches_building(&mut self, world: &World) -> bool {
        self.buildings.touches(world, self.state.position_enu_m, self.radius_m)
    }

    /// Stops the drone where it is: motors off, nothing simulated any more.
    pub fn crash(&mut self, with: CrashCause, speed_mps: f64) {
        if self.crashed {
            return;
        }
        self.crashed = true;
        for m in &mut self.motors {
            m.set_omega(0.0);
        }
        self.events.push(EventKind::Crashed { with, speed_mps });
    }

    pub fn speed_mps(&self) -> f64 {
        self.state.velocity_enu_mps.norm()
    }

    /// Whether [`DroneSim::take_events`] has anything (asked every physics step).
    pub fn has_events(&self) -> bool {
        !self.events.is_empty()
    }

    pub fn take_events(&mut self) -> Vec<EventKind> {
        let events = std::mem::take(&mut self.events);
        if !events.is_empty()
            && let Some(session) = &mut self.session
        {
            session.on_events(&events);
        }
        events
    }

    pub fn snapshot(&self) -> DroneSnapshot {
        let p = self.state.position_enu_m;
        let v = self.state.velocity_enu_mps;
        let q = self.state.attitude.quaternion();
        DroneSnapshot {
            index: self.plan.index,
            position_enu_m: [p.x, p.y, p.z],
            velocity_enu_mps: [v.x, v.y, v.z],
            attitude_wxyz: [q.w, q.i, q.j, q.k],
            height_agl_m: self.height_agl_m - GEAR_HEIGHT_M,
            mode: self.fmu.mode(),
            armed: self.fmu.is_armed(),
            on_ground: self.on_ground,
            crashed: self.crashed,
            battery_remaining: self.battery.remaining_fraction(),
            position_valid: self.fmu.estimate().is_some(),
            detail: self.detail(),
        }
    }

    fn detail(&self) -> DroneDetail {
        let v3 = |v: Vector3<f64>| [v.x, v.y, v.z];
        let finite = |x: f64| x.is_finite().then_some(x);
        let mut motor_commands = [0.0; 8];
        for (slot, motor) in motor_commands.iter_mut().zip(&self.motors) {
            *slot = motor.command();
        }
        DroneDetail {
            rate_body_rps: v3(self.state.rate_body_rps),
            estimate: self.fmu.estimate().map(|e| {
                let q = e.attitude.quaternion();
                EstimateDetail {
                    position_enu_m: v3(e.position_enu_m),
                    velocity_enu_mps: v3(e.velocity_enu_mps),
                    attitude_wxyz: [q.w, q.i, q.j, q.k],
                    eph_m: e.eph_m,
                    epv_m: e.epv_m,
                }
            }),
            gnss: self.last_gnss.map(|g| GnssDetail {
                time_s: g.time_s,
                position_enu_m: v3(g.position_enu_m),
                velocity_enu_mps: v3(g.velocity_enu_mps),
                fix_type: g.fix_type,
                satellites: g.satellites,
                eph_m: finite(g.eph_m),
                epv_m: finite(g.epv_m),
                hdop: finite(g.hdop),
                vdop: finite(g.vdop),
                sky: g.sky.map(|k| crate::protocol::SkyDetail {
                    above_mask: k.above_mask,
                    line_of_sight: k.line_of_sight,
                    reflected: k.reflected,
                }),
            }),
            motor_commands,
            motor_count: self.motors.len().min(8) as u8,
            battery_voltage_v: self.battery.voltage_v(),
            battery_current_a: self.battery.current_a(),
            battery_consumed_mah: self.battery.consumed_mah(),
            wind_enu_mps: v3(self.wind_enu_mps),
            local_origin_enu_m: v3(self.local_origin_enu_m),
        }
    }
}

#[cfg(test)]
mod building_tests {
    use nalgebra::Vector3;
    use sadesim_crds::fixtures::RunBuilder;
    use sadesim_world::{World, WorldInputs};

    use super::BuildingClearance;

    #[test]
    fn the_clearance_answers_as_the_exact_query_along_a_path_through_the_city() {
        // A procedural city around the origin; a wandering path at roof heights through it,
        // in steps of 2-20 cm as drones move between physics steps.
        let run = RunBuilder::test().build();
        let world = World::generate(&WorldInputs::from_spec(&run.spec, &[]));
        let mut rng = sadesim_crds::random::Rng::stream(3, 0, sadesim_crds::random::Purpose::Sensors);
        let mut clearance = BuildingClearance::default();
        let mut p = Vector3::new(0.0, 0.0, 12.0);
        let (mut touching, mut asked) = (0, 0);
        for _ in 0..200_000 {
            let step = Vector3::new(rng.normal(), rng.normal(), 0.3 * rng.normal()) * 0.1;
            p += step;
            p.z = p.z.clamp(2.0, 60.0);
            let exact = world.ball_touches_building(p, 0.5).is_some();
            assert_eq!(clearance.touches(&world, p, 0.5), exact, "at {p:?}");
            touching += usize::from(exact);
            asked += 1;
        }
        assert!(touching > 100 && touching < asked / 2, "a real mix: {touching} of {asked} touching");
    }
}
