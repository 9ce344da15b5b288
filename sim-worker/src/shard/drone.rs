//! One simulated drone: rigid body, motors, battery, sensors and its FMU, stepped at the
//! physics rate. Ground contact is handled here (landing gear on the terrain); building
//! contact comes from the shard's rapier world.

use nalgebra::{UnitQuaternion, Vector3};
use sadesim_crds::plan::PlannedDrone;

use crate::autopilot::control::yaw_of;
use crate::autopilot::fmu::{Fmu, SensorFrame};
use crate::autopilot::mission::MissionPlan;
use crate::autopilot::navigator::{Command, NavigatorConfig};
use crate::env::{EnvSample, SampleContext};
use crate::events::EventKind;
use crate::protocol::DroneSnapshot;
use crate::sensors::SensorSuite;
use crate::vehicle::{Airframe, Battery, Motor, RigidState, wrench};
use crate::world::World;

/// Touchdown faster than this (m/s, downward) is a crash, not a landing.
pub const CRASH_VERTICAL_MPS: f64 = 3.0;
/// Touching the ground faster than this horizontally (m/s) is a crash.
pub const CRASH_HORIZONTAL_MPS: f64 = 4.0;
/// Landing-gear height: body origin (centre of mass) above the ground at rest, m.
const GEAR_HEIGHT_M: f64 = 0.1;
/// Barometer readings every this many physics steps (50 Hz at 1 kHz, like PX4's baro).
const BARO_DIVIDER: u64 = 20;

/// A scripted pilot: loads its mission, arms (retrying each second while arming checks
/// fail, as a pilot script would) and starts the mission when pilots are released.
#[derive(Clone, Debug)]
struct ScriptedPilot {
    mission: MissionPlan,
    started: bool,
    next_try_s: f64,
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
    on_ground: bool,
    crashed: bool,
    wind_enu_mps: Vector3<f64>,
    height_agl_m: f64,
    origin_alt_msl_m: f64,
    events: Vec<EventKind>,
}

impl DroneSim {
    /// A drone resting on the ground at its home.
    pub fn new(
        plan: PlannedDrone,
        airframe: Airframe,
        sensors: SensorSuite,
        world: &World,
        navigator: NavigatorConfig,
        origin_alt_msl_m: f64,
        mission: Option<MissionPlan>,
    ) -> Result<Self, crate::autopilot::control::ControlError> {
        let (e, n) = (plan.home.local.east_m, plan.home.local.north_m);
        let home = Vector3::new(e, n, world.ground_up_m(e, n) + GEAR_HEIGHT_M);
        let fmu = Fmu::new(&airframe, home, navigator, origin_alt_msl_m)?;
        let radius_m = airframe.rotors.iter().map(|r| r.position_body_m.xy().norm()).fold(0.0, f64::max) + 0.12;
        Ok(Self {
            plan,
            motors: Motor::for_airframe(&airframe),
            battery: Battery::new(airframe.battery),
            state: RigidState::at_rest(home),
            airframe,
            sensors,
            fmu,
            pilot: mission.map(|mission| ScriptedPilot { mission, started: false, next_try_s: 0.0 }),
            radius_m,
            on_ground: true,
            crashed: false,
            wind_enu_mps: Vector3::zeros(),
            height_agl_m: GEAR_HEIGHT_M,
            origin_alt_msl_m,
            events: Vec::new(),
        })
    }

    pub fn position_enu_m(&self) -> Vector3<f64> {
        self.state.position_enu_m
    }
    pub fn is_crashed(&self) -> bool {
        self.crashed
    }
    /// The FMU has a position estimate.
    pub fn is_ready(&self) -> bool {
        self.fmu.estimate().is_some()
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
        self.ground_contact(world);
        if self.crashed {
            return;
        }
        let accel_enu = (self.state.velocity_enu_mps - v_before) / dt_s;

        // Sensors.
        let imu = self.sensors.imu.measure(accel_enu, self.state.rate_body_rps, &self.state.attitude, dt_s);
        let gnss = self.sensors.gnss.update(t_end, self.state.position_enu_m, self.state.velocity_enu_mps, &env.gnss);
        let baro = step.is_multiple_of(BARO_DIVIDER).then(|| {
            let alt_msl = self.origin_alt_msl_m + self.state.position_enu_m.z;
            self.sensors.barometer.measure(alt_msl, dt_s * BARO_DIVIDER as f64)
        });

        // Flight controller and actuators.
        let frame = SensorFrame { imu: &imu, gnss: gnss.as_ref(), baro: baro.as_ref() };
        let out =
            self.fmu.step(t_end, dt_s, frame, self.state.attitude, self.on_ground, self.battery.remaining_fraction());
        let mut power_w = 0.0;
        for (motor, u) in self.motors.iter_mut().zip(&out.motor_commands) {
            motor.step(*u, dt_s);
            power_w += motor.mechanical_power_w();
        }
        self.battery.update(power_w, dt_s);
        self.events.extend(self.fmu.take_events());
    }

    fn fly_scripted_pilot(&mut self, t_s: f64, released: bool) {
        let Some(pilot) = &mut self.pilot else { return };
        if !released || pilot.started || t_s < pilot.next_try_s {
            return;
        }
        let battery = self.battery.remaining_fraction();
        let plan = pilot.mission.clone();
        let result = self
            .fmu
            .command(Command::LoadMission(plan), self.on_ground, battery)
            .and_then(|()| self.fmu.command(Command::Arm, self.on_ground, battery))
            .and_then(|()| self.fmu.command(Command::StartMission, self.on_ground, battery));
        match result {
            Ok(()) => pilot.started = true,
            Err(e) => {
                pilot.next_try_s = t_s + 1.0;
                self.events.push(EventKind::CommandRejected { command: "startMission".into(), reason: e.to_string() });
            }
        }
    }

    /// Landing gear on the terrain: touchdown below the crash speeds rests the drone level
    /// on its gear; faster is a crash.
    fn ground_contact(&mut self, world: &World) {
        let p = self.state.position_enu_m;
        let floor = world.ground_up_m(p.x, p.y) + GEAR_HEIGHT_M;
        self.height_agl_m = p.z - floor + GEAR_HEIGHT_M;
        if p.z > floor {
            if p.z > floor + 0.02 {
                self.on_ground = false;
            }
            return;
        }
        let v = self.state.velocity_enu_mps;
        let horizontal = v.xy().norm();
        if !self.on_ground && (-v.z > CRASH_VERTICAL_MPS || horizontal > CRASH_HORIZONTAL_MPS) {
            self.crash("ground", v.norm());
            return;
        }
        self.on_ground = true;
        self.state.position_enu_m.z = floor;
        self.state.velocity_enu_mps = Vector3::zeros();
        self.state.rate_body_rps = Vector3::zeros();
        self.state.attitude = UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_of(&self.state.attitude));
        self.height_agl_m = GEAR_HEIGHT_M;
    }

    /// Stops the drone where it is: motors off, nothing simulated any more.
    pub fn crash(&mut self, with: &str, speed_mps: f64) {
        if self.crashed {
            return;
        }
        self.crashed = true;
        for m in &mut self.motors {
            m.set_omega(0.0);
        }
        self.events.push(EventKind::Crashed { with: with.into(), speed_mps });
    }

    pub fn speed_mps(&self) -> f64 {
        self.state.velocity_enu_mps.norm()
    }

    pub fn take_events(&mut self) -> Vec<EventKind> {
        std::mem::take(&mut self.events)
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
        }
    }
}
