//! What the plots and tables share: a colour per fleet group, the zones projected into the
//! run's local frame, and number formats (metres with feet, since airspace rules are in
//! feet; `m:ss` sim times).

use sadesim_crds::fleet::Role;
use sadesim_crds::geo::LocalFrame;
use sadesim_crds::plan::RunPlan;
use sadesim_crds::zones::{AltitudeReference, ZoneAltitude};

/// Metres per foot (exact, international foot).
pub const M_PER_FT: f64 = 0.3048;

/// Colours of the paper's Fig. 4A for its three roles (public safety red, journalists
/// blue, recreational green), then distinct colours for the other roles and for a second
/// group of a role already coloured.
const ROLE_COLOURS: [(Role, &str); 5] = [
    (Role::PublicSafety, "#d62728"),
    (Role::Journalist, "#1f77b4"),
    (Role::Recreational, "#2ca02c"),
    (Role::Commercial, "#9467bd"),
    (Role::Delivery, "#ff7f0e"),
];
const SPARE_COLOURS: [&str; 8] =
    ["#8c564b", "#e377c2", "#17becf", "#bcbd22", "#7f7f7f", "#393b79", "#843c39", "#637939"];

/// One fleet group as the report draws it.
#[derive(Clone, Debug, PartialEq)]
pub struct GroupStyle {
    pub name: String,
    /// `#rrggbb`.
    pub colour: &'static str,
    /// The role as written in the scenario (`publicSafety`, ...).
    pub role: String,
    pub operator: String,
    pub count: u32,
    /// The group's `altitude.maxAglM`.
    pub max_agl_m: f64,
    /// The group's `altitude.minAglM`, when set.
    pub min_agl_m: Option<f64>,
}

/// The groups of `plan`, in fleet order, each with its colour.
pub fn group_styles(plan: &RunPlan) -> Vec<GroupStyle> {
    let mut used: Vec<&'static str> = Vec::new();
    let mut spare = SPARE_COLOURS.iter().cycle();
    plan.spec
        .fleet
        .iter()
        .map(|g| {
            let by_role = ROLE_COLOURS.iter().find(|(r, _)| *r == g.role).map(|(_, c)| *c);
            let colour = match by_role {
                Some(c) if !used.contains(&c) => c,
                _ => *spare.find(|c| !used.contains(c)).unwrap_or(&SPARE_COLOURS[0]),
            };
            used.push(colour);
            let role = serde_json::to_value(g.role).ok().and_then(|v| v.as_str().map(String::from)).unwrap_or_default();
            GroupStyle {
                name: g.name.clone(),
                colour,
                role,
                operator: g.operator.clone(),
                count: g.count,
                max_agl_m: g.altitude.max_agl_m,
                min_agl_m: g.altitude.min_agl_m,
            }
        })
        .collect()
}

/// The style of group `name` (a grey default for a group the plan does not know).
pub fn style_of<'a>(styles: &'a [GroupStyle], name: &str) -> Option<&'a GroupStyle> {
    styles.iter().find(|s| s.name == name)
}

/// A zone in the local frame.
#[derive(Clone, Debug, PartialEq)]
pub struct ZoneShape {
    pub name: String,
    /// Outline, metres east/north of the origin, not closed.
    pub ring_en_m: Vec<[f64; 2]>,
    pub floor: ZoneAltitude,
    pub ceiling: ZoneAltitude,
    /// The policy's altitude constraints for lease holders, metres AGL.
    pub min_altitude_agl_m: Option<f64>,
    pub max_altitude_agl_m: Option<f64>,
}

impl ZoneShape {
    /// Axis-aligned bounds `[east_min, north_min, east_max, north_max]`.
    pub fn bounds(&self) -> [f64; 4] {
        let mut b = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
        for [e, n] in &self.ring_en_m {
            b = [b[0].min(*e), b[1].min(*n), b[2].max(*e), b[3].max(*n)];
        }
        b
    }

    /// Vertical extent for a label, e.g. "0-500 ft AGL" or "0 ft AGL - 1200 ft MSL".
    pub fn vertical_label(&self) -> String {
        let r = |a: &ZoneAltitude| match a.reference {
            AltitudeReference::Agl => "AGL",
            AltitudeReference::Msl => "MSL",
        };
        if self.floor.reference == self.ceiling.reference {
            format!("{:.0}-{:.0} ft {}", ft(self.floor.height_m), ft(self.ceiling.height_m), r(&self.ceiling))
        } else {
            format!(
                "{:.0} ft {} - {:.0} ft {}",
                ft(self.floor.height_m),
                r(&self.floor),
                ft(self.ceiling.height_m),
                r(&self.ceiling)
            )
        }
    }
}

/// The zones of `plan` projected on the local plane.
pub fn zone_shapes(plan: &RunPlan) -> Vec<ZoneShape> {
    let frame = LocalFrame::new(plan.spec.origin.geo());
    plan.spec
        .zones
        .iter()
        .map(|z| ZoneShape {
            name: z.name.clone(),
            ring_en_m: z
                .polygon
                .iter()
                .map(|p| {
                    let (e, n) = frame.to_plane(p.latitude_deg, p.longitude_deg);
                    [e, n]
                })
                .collect(),
            floor: z.floor(),
            ceiling: z.ceiling,
            min_altitude_agl_m: z.policy.min_altitude_agl_m,
            max_altitude_agl_m: z.policy.max_altitude_agl_m,
        })
        .collect()
}

/// Metres to feet.
pub fn ft(m: f64) -> f64 {
    m / M_PER_FT
}

/// A height as "106.7 m (350 ft)".
pub fn m_ft(m: f64) -> String {
    format!("{m:.1} m ({:.0} ft)", ft(m))
}

/// Sim seconds as `m:ss` (or `h:mm:ss`), for axis ticks and tables.
pub fn clock(time_s: f64) -> String {
    let t = time_s.max(0.0).round() as u64;
    let (h, m, s) = (t / 3600, t % 3600 / 60, t % 60);
    if h > 0 { format!("{h}:{m:02}:{s:02}") } else { format!("{m}:{s:02}") }
}

/// Sim seconds for tables: "312.40 s (5:12)".
pub fn time_cell(time_s: f64) -> String {
    format!("{time_s:.2} s ({})", clock(time_s))
}

/// "Nice" tick values (steps of 1, 2 or 5 times a power of ten) covering `[lo, hi]` with
/// about `target` intervals.
pub fn ticks(lo: f64, hi: f64, target: usize) -> Vec<f64> {
    if !lo.is_finite() || !hi.is_finite() || hi <= lo {
        return vec![lo];
    }
    let raw = (hi - lo) / target.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0].iter().map(|k| k * mag).find(|s| *s >= raw).unwrap_or(10.0 * mag);
    let first = (lo / step).ceil() as i64;
    let last = (hi / step).floor() as i64;
    (first..=last).map(|k| k as f64 * step).collect()
}

/// Ticks for a time axis in seconds: whole seconds, minutes or hours.
pub fn time_ticks(end_s: f64, target: usize) -> Vec<f64> {
    let raw = end_s / target.max(1) as f64;
    let steps = [1.0, 2.0, 5.0, 10.0, 15.0, 30.0, 60.0, 120.0, 300.0, 600.0, 900.0, 1800.0, 3600.0, 7200.0];
    let step = steps.iter().copied().find(|s| *s >= raw).unwrap_or(3600.0 * (raw / 3600.0).ceil());
    (0..).map(|k| k as f64 * step).take_while(|t| *t <= end_s + 1e-9).collect()
}

/// A tick label without a useless ".0".
pub fn tick_label(v: f64) -> String {
    if (v - v.round()).abs() < 1e-9 { format!("{}", v.round() as i64) } else { format!("{v}") }
}
