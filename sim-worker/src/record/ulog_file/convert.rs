//! Our snapshots (world ENU, body FLU, SI units) as PX4 messages (NED from the drone's
//! local origin, body FRD, float32 where PX4 uses it).

use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use sadesim_crds::geo::{Enu, GeoPoint, LocalFrame};

use super::topics::{
    ActuatorOutputs, BatteryStatus, MAV_TYPE_QUADROTOR, SensorGps, VEHICLE_TYPE_ROTARY_WING, VehicleAttitude,
    VehicleGlobalPosition, VehicleLocalPosition, VehicleStatus, arming_state, nav_state,
};
use sadesim_engine::autopilot::navigator::{BAT_CRIT_THR, BAT_EMERGEN_THR, BAT_LOW_THR};
use sadesim_engine::events::FlightMode;
use sadesim_engine::mavlink::telemetry::{attitude_ned_frd, enu_to_ned, unlocked_yaw};
use sadesim_engine::protocol::{DroneSnapshot, GnssDetail};
use sadesim_engine::vehicle::BatterySpec;

/// Microseconds of simulated time, at least 1 (ULog readers treat 0 as "no time").
pub fn micros(time_s: f64) -> u64 {
    ((time_s * 1e6).round() as u64).max(1)
}

/// ENU vector -> NED components (`mavlink::telemetry::enu_to_ned`, on arrays).
fn ned(v: [f64; 3]) -> [f64; 3] {
    let n = enu_to_ned(&Vector3::from(v));
    [n.x, n.y, n.z]
}

/// Body FLU -> ENU (w, x, y, z) as body FRD -> NED (w, x, y, z), w >= 0.
pub fn q_ned_frd(q_enu_flu_wxyz: [f64; 4]) -> [f64; 4] {
    let [w, x, y, z] = q_enu_flu_wxyz;
    let q = attitude_ned_frd(&UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z)));
    let s = if q.w < 0.0 { -1.0 } else { 1.0 };
    [s * q.w, s * q.i, s * q.j, s * q.k]
}

/// Yaw of an FRD -> NED attitude (w, x, y, z): from north, clockwise, -pi..pi, rad.
fn heading_rad(q: [f64; 4]) -> f64 {
    let [w, x, y, z] = q;
    unlocked_yaw(&UnitQuaternion::new_unchecked(Quaternion::new(w, x, y, z)))
}

/// One drone's geometry for the conversions: the run's ENU frame and the drone's local
/// origin (PX4's EKF origin: where it booted).
#[derive(Clone, Copy, Debug)]
pub struct DroneFrame {
    pub frame: LocalFrame,
    pub origin_enu_m: [f64; 3],
    pub origin: GeoPoint,
    /// When the origin was taken (the drone's first snapshot), microseconds.
    pub origin_time_us: u64,
}

impl DroneFrame {
    pub fn new(frame: LocalFrame, origin_enu_m: [f64; 3], origin_time_us: u64) -> Self {
        let [e, n, u] = origin_enu_m;
        Self { frame, origin_enu_m, origin: frame.to_geodetic(Enu::new(e, n, u)), origin_time_us }
    }

    fn geodetic(&self, p: [f64; 3]) -> GeoPoint {
        self.frame.to_geodetic(Enu::new(p[0], p[1], p[2]))
    }
}

/// A position solution to log: the estimator's or the ground truth.
#[derive(Clone, Copy, Debug)]
pub struct Solution {
    pub position_enu_m: [f64; 3],
    pub velocity_enu_mps: [f64; 3],
    /// Body FLU -> ENU, (w, x, y, z).
    pub attitude_wxyz: [f64; 4],
    /// 1-sigma horizontal / vertical position errors, m (0 for the truth).
    pub eph_m: f64,
    pub epv_m: f64,
}

impl Solution {
    pub fn truth(d: &DroneSnapshot) -> Self {
        Self {
            position_enu_m: d.position_enu_m,
            velocity_enu_mps: d.velocity_enu_mps,
            attitude_wxyz: d.attitude_wxyz,
            eph_m: 0.0,
            epv_m: 0.0,
        }
    }

    /// The estimator's output, `None` before its first GNSS fix.
    pub fn estimate(d: &DroneSnapshot) -> Option<Self> {
        d.detail.estimate.as_ref().map(|e| Self {
            position_enu_m: e.position_enu_m,
            velocity_enu_mps: e.velocity_enu_mps,
            attitude_wxyz: e.attitude_wxyz,
            eph_m: e.eph_m,
            epv_m: e.epv_m,
        })
    }
}

/// Ground height (ENU up) below the drone, from the ground truth.
fn ground_up_m(d: &DroneSnapshot) -> f64 {
    d.position_enu_m[2] - d.height_agl_m
}

pub fn local_position(t_us: u64, f: &DroneFrame, s: &Solution, d: &DroneSnapshot) -> VehicleLocalPosition {
    let rel = [
        s.position_enu_m[0] - f.origin_enu_m[0],
        s.position_enu_m[1] - f.origin_enu_m[1],
        s.position_enu_m[2] - f.origin_enu_m[2],
    ];
    let [x, y, z] = ned(rel);
    let [vx, vy, vz] = ned(s.velocity_enu_mps);
    let heading = heading_rad(q_ned_frd(s.attitude_wxyz)) as f32;
    VehicleLocalPosition {
        timestamp: t_us,
        timestamp_sample: t_us,
        xy_valid: true,
        z_valid: true,
        v_xy_valid: true,
        v_z_valid: true,
        x: x as f32,
        y: y as f32,
        z: z as f32,
        vx: vx as f32,
        vy: vy as f32,
        vz: vz as f32,
        z_deriv: vz as f32,
        heading,
        unaided_heading: heading,
        heading_good_for_control: true,
        xy_global: true,
        z_global: true,
        ref_timestamp: f.origin_time_us,
        ref_lat: f.origin.latitude_deg,
        ref_lon: f.origin.longitude_deg,
        ref_alt: f.origin.altitude_msl_m as f32,
        dist_bottom: (s.position_enu_m[2] - ground_up_m(d)) as f32,
        dist_bottom_valid: true,
        eph: s.eph_m as f32,
        epv: s.epv_m as f32,
        ..Default::default()
    }
}

pub fn global_position(t_us: u64, f: &DroneFrame, s: &Solution, d: &DroneSnapshot) -> VehicleGlobalPosition {
    let p = f.geodetic(s.position_enu_m);
    let ground = f.geodetic([d.position_enu_m[0], d.position_enu_m[1], ground_up_m(d)]);
    VehicleGlobalPosition {
        timestamp: t_us,
        timestamp_sample: t_us,
        lat: p.latitude_deg,
        lon: p.longitude_deg,
        alt: p.altitude_msl_m as f32,
        // `sadesim_crds::geo` treats ellipsoid heights as MSL (constant geoid offset).
        alt_ellipsoid: p.altitude_msl_m as f32,
        lat_lon_valid: true,
        alt_valid: true,
        alt_ellipsoid_valid: true,
        eph: s.eph_m as f32,
        epv: s.epv_m as f32,
        terrain_alt: ground.altitude_msl_m as f32,
        terrain_alt_valid: true,
        ..Default::default()
    }
}

pub fn attitude(t_us: u64, s: &Solution) -> VehicleAttitude {
    let q = q_ned_frd(s.attitude_wxyz);
    VehicleAttitude { timestamp: t_us, timestamp_sample: t_us, q: q.map(|c| c as f32), ..Default::default() }
}

/// A GNSS receiver output; `t_us` is when it is logged, `timestamp_sample` when measured.
pub fn sensor_gps(t_us: u64, f: &DroneFrame, g: &GnssDetail) -> SensorGps {
    let p = f.geodetic(g.position_enu_m);
    let [vn, ve, vd] = ned(g.velocity_enu_mps);
    let unknown = |x: Option<f64>| x.map_or(f32::NAN, |x| x as f32);
    // PX4 marks velocity valid with a 2D fix too.
    let fix = g.fix_type >= 2;
    SensorGps {
        timestamp: t_us,
        timestamp_sample: micros(g.time_s).min(t_us),
        latitude_deg: p.latitude_deg,
        longitude_deg: p.longitude_deg,
        altitude_msl_m: p.altitude_msl_m,
        altitude_ellipsoid_m: p.altitude_msl_m,
        fix_type: g.fix_type,
        eph: unknown(g.eph_m),
        epv: unknown(g.epv_m),
        hdop: unknown(g.hdop),
        vdop: unknown(g.vdop),
        vel_m_s: vn.hypot(ve) as f32,
        vel_n_m_s: vn as f32,
        vel_e_m_s: ve as f32,
        vel_d_m_s: vd as f32,
        cog_rad: ve.atan2(vn) as f32,
        vel_ned_valid: fix,
        satellites_used: g.satellites,
        // No dual-antenna heading.
        heading: f32::NAN,
        heading_offset: f32::NAN,
        ..Default::default()
    }
}

/// PX4's default battery thresholds (BAT_LOW_THR, BAT_CRIT_THR, BAT_EMERGEN_THR), as
/// fractions of the capacity left.
const BATTERY_THRESHOLDS: [f64; 3] = [BAT_LOW_THR, BAT_CRIT_THR, BAT_EMERGEN_THR];

pub fn battery_status(t_us: u64, d: &DroneSnapshot, spec: Option<&BatterySpec>) -> BatteryStatus {
    let b = &d.detail;
    let warning = BATTERY_THRESHOLDS.iter().filter(|&&t| d.battery_remaining < t).count() as u8;
    BatteryStatus {
        timestamp: t_us,
        connected: true,
        voltage_v: b.battery_voltage_v as f32,
        voltage_filtered_v: b.battery_voltage_v as f32,
        current_a: b.battery_current_a as f32,
        current_filtered_a: b.battery_current_a as f32,
        current_average_a: b.battery_current_a as f32,
        discharged_mah: b.battery_consumed_mah as f32,
        remaining: d.battery_remaining as f32,
        scale: 1.0,
        time_remaining_s: f32::NAN,
        temperature: f32::NAN,
        cell_count: spec.map_or(0, |s| s.cells.min(255) as u8),
        capacity: spec.map_or(0, |s| s.capacity_mah.round().clamp(0.0, 65_535.0) as u16),
        id: 1,
        warning,
        ..Default::default()
    }
}

/// What `vehicle_status` remembers between samples: when the drone armed, took off and
/// entered its mode, and whether a failsafe is active.
#[derive(Clone, Copy, Debug, Default)]
pub struct StatusTracker {
    last: Option<(bool, bool, FlightMode)>,
    armed_time_us: u64,
    takeoff_time_us: u64,
    nav_state_time_us: u64,
    /// Set by a failsafe event, cleared on disarming.
    pub failsafe: bool,
}

impl StatusTracker {
    /// Follows the drone at every window (so the times are exact to a window).
    pub fn observe(&mut self, t_us: u64, d: &DroneSnapshot) {
        let (was_armed, was_on_ground, mode) = self.last.unwrap_or((false, true, d.mode));
        if d.armed && !was_armed {
            self.armed_time_us = t_us;
        }
        if !d.armed {
            self.armed_time_us = 0;
            self.takeoff_time_us = 0;
            self.failsafe = false;
        }
        if d.armed && !d.on_ground && was_on_ground {
            self.takeoff_time_us = t_us;
        }
        if d.mode != mode || self.last.is_none() {
            self.nav_state_time_us = t_us;
        }
        self.last = Some((d.armed, d.on_ground, d.mode));
    }

    pub fn status(&self, t_us: u64, d: &DroneSnapshot, system_id: u8, component_id: u8) -> VehicleStatus {
        let nav = nav_state(d.mode);
        VehicleStatus {
            timestamp: t_us,
            armed_time: self.armed_time_us,
            takeoff_time: self.takeoff_time_us,
            arming_state: if d.armed { arming_state::ARMED } else { arming_state::DISARMED },
            nav_state_timestamp: self.nav_state_time_us,
            nav_state_user_intention: nav,
            nav_state: nav,
            vehicle_type: VEHICLE_TYPE_ROTARY_WING,
            failsafe: self.failsafe,
            system_type: mav_type(d.detail.motor_count),
            system_id,
            component_id,
            safety_off: true,
            power_input_valid: true,
            pre_flight_checks_pass: d.position_valid && !d.crashed,
            ..Default::default()
        }
    }
}

/// MAV_TYPE by rotor count: quadrotor, hexarotor (13), octorotor (14).
fn mav_type(motors: u8) -> u8 {
    match motors {
        6 => 13,
        8 => 14,
        _ => MAV_TYPE_QUADROTOR,
    }
}

/// Motor commands (0..1) as PWM-like outputs: 1000 stopped .. 2000 full, as PX4 logs
/// `actuator_outputs` on hardware; unused outputs are 0.
pub fn actuator_outputs(t_us: u64, d: &DroneSnapshot) -> ActuatorOutputs {
    let n = usize::from(d.detail.motor_count.min(8));
    let mut output = [0.0f32; 16];
    for (o, c) in output.iter_mut().zip(&d.detail.motor_commands[..n]) {
        *o = (1000.0 + 1000.0 * c.clamp(0.0, 1.0)) as f32;
    }
    ActuatorOutputs { timestamp: t_us, noutputs: n as u32, output }
}
