//! Names of the airframe presets a fleet group may use.
//!
//! Only the names and descriptions: each preset's record (physics, PX4 `SYS_AUTOSTART`,
//! controller gains, parameter overrides) is `sim-worker`'s `vehicle::Preset`; this list is
//! the contract the validator checks `spec.fleet[].airframe` against. A `sim-worker` test
//! fails unless its one list of presets names exactly these, in this order.

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
