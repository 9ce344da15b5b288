//! Every preset's parameters read the way a ground station reads them (encoded frames in,
//! PARAM_VALUE frames out of the session), compared with the controller a drone of that
//! preset flies with.

use std::collections::HashMap;

use sadesim_crds::fixtures::RunBuilder;
use sadesim_crds::plan::RunPlan;

use super::*;
use crate::autopilot::control::Controller;
use crate::autopilot::fmu::Fmu;
use crate::fixtures::plan_of;
use crate::mavlink::params::ParamValue;
use crate::mavlink::params::plan::{drone_table, navigator_config};
use crate::preset::Preset;

fn plan_for(preset: &Preset) -> RunPlan {
    let name = preset.name().to_owned();
    plan_of(RunBuilder::test().with_drones(1).with(|r| r.spec.fleet[0].airframe = name).build())
}

/// The session a shard opens for the plan's only drone (`Shard::open_mavlink`).
fn session_for(plan: &RunPlan) -> Session {
    let d = &plan.drones[0];
    let id = VehicleIdentity { system_id: d.system_id, frame: frame_origin(), unix_epoch_at_start_us: 0, uid: 1 };
    Session::new(id, drone_table(plan, d).expect("known preset"))
}

/// The controller the shard builds for the plan's only drone (`DroneSim::new`: the preset's
/// airframe and gains, the group's navigator tunables).
fn controller_for(plan: &RunPlan) -> Controller {
    let d = &plan.drones[0];
    let Preset { airframe, gains, .. } = Preset::named(&d.airframe).expect("known preset");
    let nav = navigator_config(&plan.spec.fleet[d.group_index as usize]);
    Fmu::new(&airframe, &gains, Vector3::zeros(), nav, 0.0).expect("mixer").controller().clone()
}

/// Sends `request` as an encoded frame, returns the PARAM_VALUEs of the session's answer
/// after encoding and parsing them back (what a client receives), by name.
fn exchange(s: &mut Session, request: MavMessage) -> HashMap<String, (ParamValue, PARAM_VALUE_DATA)> {
    let mut vehicle = FakeVehicle::default();
    s.handle(&from_gcs(request), &view(0.0), &mut vehicle);
    let mut parser = FrameParser::new();
    let mut values = HashMap::new();
    for out in s.poll(&view(0.0)) {
        let bytes = out.encode(MavHeader { system_id: 1, component_id: 1, sequence: 0 });
        for frame in parser.push(&bytes) {
            if let crate::mavlink::frame::Decoded::Message(MavMessage::PARAM_VALUE(v)) = frame.message {
                let value = ParamValue::from_wire(v.param_value, v.param_type).expect("PX4 type");
                values.insert(v.param_id.to_str().expect("ASCII").to_owned(), (value, v));
            }
        }
    }
    values
}

fn read(s: &mut Session, system_id: u8, name: &str) -> ParamValue {
    let request = MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
        param_index: -1,
        target_system: system_id,
        target_component: 1,
        param_id: name.into(),
    });
    let reply = exchange(s, request);
    assert_eq!(reply.len(), 1, "{name}: {reply:?}");
    reply[name].0
}

fn real(v: f64) -> ParamValue {
    ParamValue::Real32(v as f32)
}

#[test]
fn every_preset_reports_the_gains_and_limits_its_controller_flies_with() {
    for preset in Preset::all() {
        let name = preset.name().to_owned();
        let plan = plan_for(&preset);
        let sysid = plan.drones[0].system_id;
        let c = controller_for(&plan);
        let mut s = session_for(&plan);
        let list = exchange(
            &mut s,
            MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA { target_system: sysid, target_component: 1 }),
        );
        let expected = [
            ("MC_ROLL_P", real(c.attitude.gain_roll_pitch)),
            ("MC_PITCH_P", real(c.attitude.gain_roll_pitch)),
            ("MC_YAW_P", real(c.attitude.gain_yaw)),
            ("MC_ROLLRATE_MAX", real(c.attitude.max_rate_roll_pitch_rad_s.to_degrees())),
            ("MC_PITCHRATE_MAX", real(c.attitude.max_rate_roll_pitch_rad_s.to_degrees())),
            ("MC_YAWRATE_MAX", real(c.attitude.max_rate_yaw_rad_s.to_degrees())),
            ("MPC_XY_P", real(c.position.gain_xy)),
            ("MPC_Z_P", real(c.position.gain_z)),
            ("MPC_XY_VEL_P_ACC", real(c.velocity.x.gains.kp)),
            ("MPC_Z_VEL_P_ACC", real(c.velocity.z.gains.kp)),
            ("MPC_XY_VEL_MAX", real(c.position.max_horizontal_speed_mps)),
            ("MPC_Z_VEL_MAX_UP", real(c.position.max_climb_mps)),
            ("MPC_Z_VEL_MAX_DN", real(c.position.max_descent_mps)),
            ("MPC_TILTMAX_AIR", real(c.velocity.max_tilt_rad.to_degrees())),
            ("BAT1_N_CELLS", ParamValue::Int32(preset.airframe.battery.cells as i32)),
            ("BAT1_CAPACITY", real(preset.airframe.battery.capacity_mah)),
            ("SYS_AUTOSTART", ParamValue::Int32(preset.sys_autostart)),
            ("MAV_SYS_ID", ParamValue::Int32(i32::from(sysid))),
        ];
        for (param, value) in expected {
            assert_eq!(read(&mut s, sysid, param), value, "{name}: PARAM_REQUEST_READ {param}");
            assert_eq!(list[param].0, value, "{name}: PARAM_REQUEST_LIST {param}");
        }
        // Rate gains: PX4's normalised torque per rad/s, back to ours through the inertia and
        // the full torque of each axis (the rotors pushing that way at full thrust).
        let t_max = c.mixer.max_rotor_thrust_n;
        let rotors = &preset.airframe.rotors;
        let half_sum = |arm: &dyn Fn(&crate::vehicle::Rotor) -> f64| {
            0.5 * rotors.iter().map(|r| arm(r).abs() * t_max).sum::<f64>()
        };
        let j = c.rate.inertia_kg_m2;
        for (param, kp, inertia, full_nm) in [
            ("MC_ROLLRATE_P", c.rate.roll.gains.kp, j.x, half_sum(&|r| r.position_body_m.y)),
            ("MC_PITCHRATE_P", c.rate.pitch.gains.kp, j.y, half_sum(&|r| r.position_body_m.x)),
            ("MC_YAWRATE_P", c.rate.yaw.gains.kp, j.z, half_sum(&|_| preset.airframe.torque_coeff_m)),
        ] {
            let ParamValue::Real32(px4) = read(&mut s, sysid, param) else { panic!("{name}: {param} not REAL32") };
            let ours = f64::from(px4) * full_nm / inertia;
            assert!((ours - kp).abs() < 1e-5 * kp, "{name}: {param} {px4} is {ours} rad/s² per rad/s, flown {kp}");
        }
    }
}

/// Regression: the mini250 reported the x500's table (4 cells, 45° tilt, 12 m/s) and both
/// reported SYS_AUTOSTART 4001.
#[test]
fn presets_report_their_own_tables() {
    let tables: Vec<_> = Preset::all()
        .iter()
        .map(|p| {
            let plan = plan_for(p);
            let mut s = session_for(&plan);
            let sysid = plan.drones[0].system_id;
            ["BAT1_N_CELLS", "MPC_TILTMAX_AIR", "MPC_XY_VEL_MAX", "SYS_AUTOSTART"].map(|n| read(&mut s, sysid, n))
        })
        .collect();
    for (i, a) in tables.iter().enumerate() {
        for b in &tables[i + 1..] {
            for (x, y) in a.iter().zip(b) {
                assert_ne!(x, y, "two presets report the same value");
            }
        }
    }
}
