//! Names of the airframe presets a fleet group may use.
//!
//! The physical parameters (mass, inertia, arm length, motor constants) live with the
//! vehicle model in `sim-worker`; this list is the contract the validator checks
//! `spec.fleet[].airframe` against. A `sim-worker` test fails when a name here has no
//! parameters there.

/// A preset's name and a one-line description for docs and error messages.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AirframePreset {
    pub name: &'static str,
    pub description: &'static str,
}

/// Every preset the simulator knows.
pub const AIRFRAME_PRESETS: &[AirframePreset] = &[
    AirframePreset {
        name: "x500",
        description: "Holybro X500 V2 class quadrotor, 2.0 kg, 0.5 m diagonal (PX4's default SITL airframe)",
    },
    AirframePreset {
        name: "mini250",
        description: "sub-250 g folding quadrotor (DJI Mini 2 class), 0.249 kg, 0.213 m motor diagonal",
    },
];

/// Looks up a preset by name.
pub fn preset(name: &str) -> Option<&'static AirframePreset> {
    AIRFRAME_PRESETS.iter().find(|p| p.name == name)
}

/// The names, comma separated, for "expected one of ..." messages.
pub fn preset_names() -> String {
    AIRFRAME_PRESETS.iter().map(|p| p.name).collect::<Vec<_>>().join(", ")
}
