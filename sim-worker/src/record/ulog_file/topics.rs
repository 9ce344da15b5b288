//! PX4 uORB messages as ULog formats: one Rust struct per message, fields in the order and
//! with the types of PX4-Autopilot's `msg/*.msg` (the commit each was copied from is noted;
//! all are the 2024-2025 definitions of PX4 v1.15/v1.16: `sensor_gps` carries float64
//! `latitude_deg`/`longitude_deg`, not the int32 1e-7 degrees of v1.14 and older).
//!
//! PX4's logger reorders fields by size and inserts `_padding` fields; readers go by the
//! format text, so we keep the declared order and pack fields without padding.
//!
//! Units and frames are PX4's: NED world frame (x north, y east, z down), FRD body frame,
//! metres, m/s, radians, degrees for latitude/longitude, AMSL metres for altitudes.

/// A ULog field type: its name in the format text and its little-endian encoding.
pub trait FieldType {
    /// `uint64_t`, `float`, `float[4]`, ...
    fn ulog_type() -> String;
    fn put(&self, out: &mut Vec<u8>);
}

macro_rules! scalar_field {
    ($($t:ty => $name:literal),* $(,)?) => {$(
        impl FieldType for $t {
            fn ulog_type() -> String {
                $name.to_string()
            }
            fn put(&self, out: &mut Vec<u8>) {
                out.extend_from_slice(&self.to_le_bytes());
            }
        }
    )*};
}

scalar_field!(
    u8 => "uint8_t", i8 => "int8_t", u16 => "uint16_t", i16 => "int16_t", u32 => "uint32_t",
    i32 => "int32_t", u64 => "uint64_t", i64 => "int64_t", f32 => "float", f64 => "double",
);

impl FieldType for bool {
    fn ulog_type() -> String {
        "bool".to_string()
    }
    fn put(&self, out: &mut Vec<u8>) {
        out.push(u8::from(*self));
    }
}

impl<T: FieldType, const N: usize> FieldType for [T; N] {
    fn ulog_type() -> String {
        format!("{}[{N}]", T::ulog_type())
    }
    fn put(&self, out: &mut Vec<u8>) {
        for x in self {
            x.put(out);
        }
    }
}

/// A PX4 message: its ULog field list and its packed encoding (same order).
pub trait Topic {
    /// `(type, name)` per field; the first is `uint64_t timestamp`.
    fn fields() -> Vec<(String, &'static str)>;
    /// Appends the packed fields to `out`.
    fn encode(&self, out: &mut Vec<u8>);
}

/// Declares a PX4 message struct whose fields are, in order, the ULog format.
macro_rules! px4_message {
    ($(#[$meta:meta])* $name:ident { $($(#[$fmeta:meta])* $field:ident : $ty:ty),* $(,)? }) => {
        $(#[$meta])*
        #[derive(Clone, Debug, Default, PartialEq)]
        pub struct $name {
            $($(#[$fmeta])* pub $field: $ty,)*
        }

        impl Topic for $name {
            fn fields() -> Vec<(String, &'static str)> {
                vec![$((<$ty as FieldType>::ulog_type(), stringify!($field))),*]
            }
            fn encode(&self, out: &mut Vec<u8>) {
                $(self.$field.put(out);)*
            }
        }
    };
}

px4_message! {
    /// `VehicleLocalPosition.msg` (PX4-Autopilot @0290a61): topics `vehicle_local_position`
    /// (the estimator) and `vehicle_local_position_groundtruth` (the simulator's truth).
    /// Origin: where the drone booted (`ref_lat`/`ref_lon`/`ref_alt`).
    VehicleLocalPosition {
        /// Microseconds of simulated time.
        timestamp: u64,
        timestamp_sample: u64,
        xy_valid: bool,
        z_valid: bool,
        v_xy_valid: bool,
        v_z_valid: bool,
        /// NED position from the local origin, m.
        x: f32,
        y: f32,
        z: f32,
        delta_xy: [f32; 2],
        xy_reset_counter: u8,
        delta_z: f32,
        z_reset_counter: u8,
        /// NED velocity, m/s.
        vx: f32,
        vy: f32,
        vz: f32,
        z_deriv: f32,
        delta_vxy: [f32; 2],
        vxy_reset_counter: u8,
        delta_vz: f32,
        vz_reset_counter: u8,
        /// NED acceleration, m/s^2.
        ax: f32,
        ay: f32,
        az: f32,
        /// Yaw from north, clockwise, -pi..pi, rad.
        heading: f32,
        unaided_heading: f32,
        delta_heading: f32,
        heading_reset_counter: u8,
        heading_good_for_control: bool,
        xy_global: bool,
        z_global: bool,
        ref_timestamp: u64,
        /// The local origin: WGS84 degrees, AMSL metres.
        ref_lat: f64,
        ref_lon: f64,
        ref_alt: f32,
        /// Height above the ground below, m.
        dist_bottom: f32,
        dist_bottom_valid: bool,
        dist_bottom_sensor_bitfield: u8,
        /// 1-sigma position errors, m, and velocity errors, m/s.
        eph: f32,
        epv: f32,
        evh: f32,
        evv: f32,
        dead_reckoning: bool,
        vxy_max: f32,
        vz_max: f32,
        hagl_min: f32,
        hagl_max: f32,
    }
}

px4_message! {
    /// `VehicleGlobalPosition.msg` (PX4-Autopilot @26cbb2e): `vehicle_global_position` and
    /// `vehicle_global_position_groundtruth`.
    VehicleGlobalPosition {
        timestamp: u64,
        timestamp_sample: u64,
        /// WGS84 degrees.
        lat: f64,
        lon: f64,
        /// AMSL, m.
        alt: f32,
        alt_ellipsoid: f32,
        lat_lon_valid: bool,
        alt_valid: bool,
        alt_ellipsoid_valid: bool,
        delta_alt: f32,
        delta_terrain: f32,
        lat_lon_reset_counter: u8,
        alt_reset_counter: u8,
        terrain_reset_counter: u8,
        eph: f32,
        epv: f32,
        /// Ground altitude below the drone, AMSL, m.
        terrain_alt: f32,
        terrain_alt_valid: bool,
        dead_reckoning: bool,
    }
}

px4_message! {
    /// `VehicleAttitude.msg` (PX4-Autopilot @370e5b4): `vehicle_attitude` and
    /// `vehicle_attitude_groundtruth`.
    VehicleAttitude {
        timestamp: u64,
        timestamp_sample: u64,
        /// Body FRD -> NED rotation, Hamilton, (w, x, y, z).
        q: [f32; 4],
        delta_q_reset: [f32; 4],
        quat_reset_counter: u8,
    }
}

px4_message! {
    /// `SensorGps.msg` (PX4-Autopilot @0733619, float64 degrees): `sensor_gps` and its
    /// alias `vehicle_gps_position` (what Flight Review's GPS plots read).
    SensorGps {
        timestamp: u64,
        /// When the receiver measured, microseconds of simulated time.
        timestamp_sample: u64,
        device_id: u32,
        latitude_deg: f64,
        longitude_deg: f64,
        altitude_msl_m: f64,
        altitude_ellipsoid_m: f64,
        s_variance_m_s: f32,
        c_variance_rad: f32,
        /// 0-1 no fix, 2 2D, 3 3D (MAVLink GPS_FIX_TYPE numbers).
        fix_type: u8,
        eph: f32,
        epv: f32,
        hdop: f32,
        vdop: f32,
        noise_per_ms: i32,
        automatic_gain_control: u16,
        jamming_state: u8,
        jamming_indicator: i32,
        spoofing_state: u8,
        authentication_state: u8,
        vel_m_s: f32,
        vel_n_m_s: f32,
        vel_e_m_s: f32,
        vel_d_m_s: f32,
        cog_rad: f32,
        vel_ned_valid: bool,
        timestamp_time_relative: i32,
        time_utc_usec: u64,
        satellites_used: u8,
        system_error: u32,
        heading: f32,
        heading_offset: f32,
        heading_accuracy: f32,
        rtcm_injection_rate: f32,
        selected_rtcm_instance: u8,
        rtcm_crc_failed: bool,
        rtcm_msg_used: u8,
        quality_corrections: u8,
        quality_receiver: u8,
        quality_gnss_signals: u8,
        quality_post_processing: u8,
    }
}

px4_message! {
    /// `BatteryStatus.msg` (PX4-Autopilot @0a799f4): `battery_status`.
    BatteryStatus {
        timestamp: u64,
        connected: bool,
        voltage_v: f32,
        voltage_filtered_v: f32,
        current_a: f32,
        current_filtered_a: f32,
        current_average_a: f32,
        discharged_mah: f32,
        /// 1 (full) .. 0 (empty).
        remaining: f32,
        scale: f32,
        time_remaining_s: f32,
        temperature: f32,
        cell_count: u8,
        source: u8,
        priority: u8,
        capacity: u16,
        cycle_count: u16,
        average_time_to_empty: u16,
        serial_number: u16,
        manufacture_date: u16,
        state_of_health: u16,
        max_error: u16,
        id: u8,
        interface_error: u16,
        voltage_cell_v: [f32; 14],
        max_cell_voltage_delta: f32,
        is_powering_off: bool,
        is_required: bool,
        faults: u16,
        custom_faults: u32,
        /// BATTERY_WARNING_*: 0 none, 1 low, 2 critical, 3 emergency.
        warning: u8,
        mode: u8,
    }
}

px4_message! {
    /// `VehicleStatus.msg` (PX4-Autopilot @0ebca4e): `vehicle_status`.
    VehicleStatus {
        timestamp: u64,
        armed_time: u64,
        takeoff_time: u64,
        /// 1 disarmed, 2 armed.
        arming_state: u8,
        latest_arming_reason: u8,
        latest_disarming_reason: u8,
        nav_state_timestamp: u64,
        nav_state_user_intention: u8,
        /// NAVIGATION_STATE_* (see [`nav_state`]).
        nav_state: u8,
        failure_detector_status: u16,
        hil_state: u8,
        vehicle_type: u8,
        failsafe: bool,
        failsafe_and_user_took_over: bool,
        gcs_connection_lost: bool,
        gcs_connection_lost_counter: u8,
        high_latency_data_link_lost: bool,
        is_vtol: bool,
        is_vtol_tailsitter: bool,
        in_transition_mode: bool,
        in_transition_to_fw: bool,
        system_type: u8,
        system_id: u8,
        component_id: u8,
        safety_button_available: bool,
        safety_off: bool,
        power_input_valid: bool,
        usb_connected: bool,
        open_drone_id_system_present: bool,
        open_drone_id_system_healthy: bool,
        parachute_system_present: bool,
        parachute_system_healthy: bool,
        avoidance_system_required: bool,
        avoidance_system_valid: bool,
        rc_calibration_in_progress: bool,
        calibration_enabled: bool,
        pre_flight_checks_pass: bool,
    }
}

px4_message! {
    /// `ActuatorOutputs.msg` (PX4-Autopilot, unchanged since v1.10): `actuator_outputs`.
    /// We log PWM-like values, 1000 (stopped) .. 2000 (full), as on real hardware.
    ActuatorOutputs {
        timestamp: u64,
        noutputs: u32,
        output: [f32; 16],
    }
}

/// `vehicle_status.arming_state` values.
pub mod arming_state {
    pub const DISARMED: u8 = 1;
    pub const ARMED: u8 = 2;
}

/// `vehicle_status.nav_state` values (`NAVIGATION_STATE_*`) of the modes we fly.
pub use sadesim_engine::mavlink::px4_mode::nav_state;

/// `vehicle_status.vehicle_type`: multicopter.
pub const VEHICLE_TYPE_ROTARY_WING: u8 = 1;
/// `vehicle_status.system_type`: MAV_TYPE_QUADROTOR.
pub const MAV_TYPE_QUADROTOR: u8 = 2;
