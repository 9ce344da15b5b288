//! The procedural city: a street grid, blocks split into lots, one box per built lot (a
//! [`Building`] prism over an axis-aligned rectangle).
//!
//! Layout (world ENU metres, `P = blockSizeM + streetWidthM`, `s = streetWidthM`):
//! - Streets are corridors of width `s` centred on the lines `east = k P` and `north = k P`,
//!   so the origin sits on a street intersection (open ground for the run's reference point).
//! - Block `(i, j)` is the square `[i P + s/2, (i + 1) P - s/2] x [j P + s/2, (j + 1) P - s/2]`,
//!   clipped to the world square `[-extentM, extentM]^2`; slivers under [`MIN_BLOCK_SIDE_M`]
//!   are dropped. Blocks are visited row by row (south to north, west to east) so the
//!   random stream is consumed in a fixed order.
//! - [`PARK_FRACTION`] of blocks are parks or plazas without buildings.
//! - Each other block is cut into a grid of lots ~30-50 m wide (wider downtown, where towers
//!   take bigger parcels), cut lines jittered so lots differ. A lot is built with a
//!   probability and a footprint fill chosen so that buildings cover `builtFraction` of the
//!   block area on average; footprints keep at least [`MIN_SETBACK_M`] from the lot edges.
//! - Heights are log-normal: `h = median exp(g(r) - g_med + sigma_b z_block + sigma_l z_lot)`,
//!   where `g(r) = ln(DOWNTOWN_BOOST) exp(-(r / R_core)^2)` raises buildings near the origin
//!   (the downtown core) and `g_med`, the median of `g` over the built lots, keeps the
//!   city-wide median at `medianBuildingHeightM`. Heights are capped at
//!   `maxBuildingHeightM` and floored at one storey ([`MIN_HEIGHT_M`]).
//! - Buildings whose footprint touches an open area are dropped (after all draws).

use sadesim_crds::random::Rng;
use sadesim_crds::run::City;

use super::building::Building;
use super::footprint::{AxisRect, Footprint};
use super::index::{GridIndex, Rect};
use super::inputs::OpenArea;
use super::terrain::Terrain;

/// Share of blocks left as parks or plazas. Dense North American downtowns give roughly
/// 5-8 % of their block area to parks and plazas.
pub const PARK_FRACTION: f64 = 0.065;
/// Blocks clipped by the world edge narrower than this are dropped, metres.
pub const MIN_BLOCK_SIDE_M: f64 = 10.0;
/// Lots narrower than this stay empty, metres: too small for a building with setbacks.
pub const MIN_LOT_SIDE_M: f64 = 8.0;
/// Least distance between a footprint and its lot's edges, metres (walls, alleys, yards).
pub const MIN_SETBACK_M: f64 = 1.0;
/// One storey: the lowest building, metres (unless `maxBuildingHeightM` is lower).
pub const MIN_HEIGHT_M: f64 = 3.0;
/// Typical lot width range, metres (US downtown parcels are ~25-60 m wide).
const LOT_WIDTH_M: (f64, f64) = (30.0, 50.0);
/// Typical share of a built lot its footprint covers; the rest is setbacks and yards.
const TYPICAL_FILL: f64 = 0.65;
/// Largest share of a lot a footprint may cover.
const MAX_FILL: f64 = 0.92;
/// How much taller the downtown core's median is than the outskirts' (a factor). Real
/// downtowns are several times taller than their city's median building.
const DOWNTOWN_BOOST: f64 = 3.0;
/// Log-normal spread of heights: a per-block term (neighbours look alike) and a per-lot
/// term; together sigma ~ 0.57, in the 0.5-0.7 range of city building-height samples.
const SIGMA_BLOCK: f64 = 0.35;
const SIGMA_LOT: f64 = 0.45;

/// The generated buildings and the counts [`super::WorldStats`] reports.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CityLayout {
    pub buildings: Vec<Building>,
    /// Blocks inside the world (parks included).
    pub block_count: usize,
    pub park_count: usize,
    /// Total block area (land between streets, parks included), square metres.
    pub block_area_m2: f64,
    /// Buildings dropped because their footprint touched an open area.
    pub dropped_for_open_areas: usize,
}

/// Street-grid geometry derived from the city parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StreetGrid {
    /// Distance between street centrelines, metres: block + street.
    pub pitch_m: f64,
    pub street_width_m: f64,
    pub extent_m: f64,
}

impl StreetGrid {
    pub fn new(city: &City, extent_m: f64) -> Self {
        let street_width_m = city.street_width_m.max(0.0);
        Self { pitch_m: city.block_size_m.max(1.0) + street_width_m, street_width_m, extent_m: extent_m.max(0.0) }
    }

    /// The extent of block `k` along one axis, clipped to the world, or `None` if too thin.
    pub fn block_span(&self, k: i64) -> Option<(f64, f64)> {
        let lo = (k as f64 * self.pitch_m + self.street_width_m / 2.0).max(-self.extent_m);
        let hi = ((k + 1) as f64 * self.pitch_m - self.street_width_m / 2.0).min(self.extent_m);
        (hi - lo >= MIN_BLOCK_SIDE_M).then_some((lo, hi))
    }

    /// Block numbers along one axis that may intersect the world.
    fn block_range(&self) -> std::ops::RangeInclusive<i64> {
        let k_lo = (-self.extent_m / self.pitch_m).floor() as i64 - 1;
        let k_hi = (self.extent_m / self.pitch_m).ceil() as i64;
        k_lo..=k_hi
    }
}

/// A built lot's rectangle and base (ENU up, metres: the ground at its centre).
struct Lot {
    rect: AxisRect,
    base_up_m: f64,
}

/// A built lot before its height is known.
struct Draft {
    footprint: Lot,
    /// log-height offset from the downtown profile, `g(r)`.
    downtown_log: f64,
    /// log-height offset from the random block and lot terms.
    noise_log: f64,
}

/// Generates the city. Consumes `rng` in a fixed order; O(blocks + lots + open-area cells).
pub fn generate(city: &City, extent_m: f64, open_areas: &[OpenArea], terrain: &Terrain, rng: &mut Rng) -> CityLayout {
    let grid = StreetGrid::new(city, extent_m);
    let core_radius_m = (0.2 * grid.extent_m).clamp(150.0, 1500.0);
    let downtown = |east_m: f64, north_m: f64| {
        let r2 = (east_m * east_m + north_m * north_m) / (core_radius_m * core_radius_m);
        (-r2).exp()
    };
    // Parks take their share of block area, so the other blocks build a little denser to
    // keep the city-wide coverage at builtFraction.
    let target_cover = (city.built_fraction.clamp(0.0, 1.0) / (1.0 - PARK_FRACTION)).min(MAX_FILL);
    let p_built = (target_cover / TYPICAL_FILL).min(1.0);
    let mean_fill = if p_built > 0.0 { (target_cover / p_built).min(MAX_FILL) } else { 0.0 };

    let mut layout = CityLayout::default();
    let mut drafts = Vec::new();
    for j in grid.block_range() {
        let Some((s, n)) = grid.block_span(j) else { continue };
        for i in grid.block_range() {
            let Some((w, e)) = grid.block_span(i) else { continue };
            layout.block_count += 1;
            layout.block_area_m2 += (e - w) * (n - s);
            if rng.next_f64() < PARK_FRACTION {
                layout.park_count += 1;
                continue;
            }
            let core = downtown((w + e) / 2.0, (s + n) / 2.0);
            let lot_width_m = rng.uniform(LOT_WIDTH_M.0, LOT_WIDTH_M.1) * (1.0 + 0.6 * core);
            let cuts_east = cuts(w, e, lot_width_m, rng);
            let cuts_north = cuts(s, n, lot_width_m, rng);
            let block_log = SIGMA_BLOCK * rng.normal();
            for lot_ns in cuts_north.windows(2) {
                for lot_we in cuts_east.windows(2) {
                    // Every lot consumes the same draws, built or not.
                    let draws = [rng.next_f64(), rng.next_f64(), rng.next_f64(), rng.next_f64(), rng.next_f64()];
                    let lot_log = SIGMA_LOT * rng.normal();
                    if draws[0] >= p_built {
                        continue;
                    }
                    let Some(footprint) = footprint(lot_we, lot_ns, mean_fill, &draws[1..], terrain) else { continue };
                    drafts.push(Draft {
                        downtown_log: DOWNTOWN_BOOST.ln()
                            * downtown(footprint.rect.center_east_m, footprint.rect.center_north_m),
                        noise_log: block_log + lot_log,
                        footprint,
                    });
                }
            }
        }
    }

    let before = drafts.len();
    drop_open(&mut drafts, open_areas, &grid);
    layout.dropped_for_open_areas = before - drafts.len();
    layout.buildings = heights(drafts, city);
    layout
}

/// Lot boundaries along `[lo, hi]`: `n = round(len / lot_width)` lots (at least one), inner
/// cuts jittered by up to 20 % of a lot so they stay ordered. Returns `n + 1` positions.
fn cuts(lo: f64, hi: f64, lot_width_m: f64, rng: &mut Rng) -> Vec<f64> {
    let n = ((hi - lo) / lot_width_m).round().max(1.0) as usize;
    let step = (hi - lo) / n as f64;
    let mut out = Vec::with_capacity(n + 1);
    out.push(lo);
    for k in 1..n {
        out.push(lo + step * (k as f64 + rng.uniform(-0.2, 0.2)));
    }
    out.push(hi);
    out
}

/// The footprint inside one lot from four uniform draws (fill, aspect, shift east, shift
/// north), or `None` if the lot is too small. The base is the ground at the centre.
fn footprint(we: &[f64], sn: &[f64], mean_fill: f64, u: &[f64], terrain: &Terrain) -> Option<Lot> {
    let (lot_e, lot_n) = (we[1] - we[0], sn[1] - sn[0]);
    if lot_e.min(lot_n) < MIN_LOT_SIDE_M {
        return None;
    }
    // Fill varies +-20 % around the mean; the aspect ratio stretches one side by up to ~1.3x.
    let fill = (mean_fill * (0.8 + 0.4 * u[0])).clamp(0.1, MAX_FILL);
    let aspect = (0.5 * u[1] - 0.25).exp();
    let half_east_m = (0.5 * lot_e * (fill.sqrt() * aspect).min(1.0)).min(0.5 * lot_e - MIN_SETBACK_M);
    let half_north_m = (0.5 * lot_n * (fill.sqrt() / aspect).min(1.0)).min(0.5 * lot_n - MIN_SETBACK_M);
    // Slide the footprint inside the room its setbacks leave (towards the street or back).
    let slack_e = 0.5 * lot_e - MIN_SETBACK_M - half_east_m;
    let slack_n = 0.5 * lot_n - MIN_SETBACK_M - half_north_m;
    let center_east_m = 0.5 * (we[0] + we[1]) + slack_e * (2.0 * u[2] - 1.0);
    let center_north_m = 0.5 * (sn[0] + sn[1]) + slack_n * (2.0 * u[3] - 1.0);
    Some(Lot {
        rect: AxisRect { center_east_m, center_north_m, half_east_m, half_north_m },
        base_up_m: terrain.up_m(center_east_m, center_north_m),
    })
}

/// Removes drafts whose footprint touches an open disc. Discs are bucketed on the street
/// grid's cells so each footprint checks only the discs near it.
fn drop_open(drafts: &mut Vec<Draft>, open_areas: &[OpenArea], grid: &StreetGrid) {
    let discs: Vec<&OpenArea> = open_areas.iter().filter(|a| a.radius_m > 0.0).collect();
    if discs.is_empty() {
        return;
    }
    // Clip each disc's box to just beyond the world, so a 20 km park over a 1 km world does
    // not allocate cells nobody queries.
    let bound = grid.extent_m + grid.pitch_m;
    let rects: Vec<Rect> = discs
        .iter()
        .map(|a| {
            [
                (a.east_m - a.radius_m).clamp(-bound, bound),
                (a.north_m - a.radius_m).clamp(-bound, bound),
                (a.east_m + a.radius_m).clamp(-bound, bound),
                (a.north_m + a.radius_m).clamp(-bound, bound),
            ]
        })
        .collect();
    let index = GridIndex::new(grid.pitch_m, &rects);
    drafts.retain(|d| {
        let footprint = Footprint::rectangle(d.footprint.rect);
        !index.in_rect(&footprint.bounds()).any(|k| {
            let a = discs[k as usize];
            footprint.touches_disc(a.east_m, a.north_m, a.radius_m)
        })
    });
}

/// Gives every draft its height (see the module docs) and returns the buildings.
fn heights(drafts: Vec<Draft>, city: &City) -> Vec<Building> {
    if drafts.is_empty() {
        return vec![];
    }
    let mut g: Vec<f64> = drafts.iter().map(|d| d.downtown_log).collect();
    let mid = g.len() / 2;
    let g_median = *g.select_nth_unstable_by(mid, f64::total_cmp).1;
    let max_m = city.max_building_height_m.max(f64::MIN_POSITIVE);
    let min_m = MIN_HEIGHT_M.min(max_m);
    let median_m = city.median_building_height_m.max(f64::MIN_POSITIVE);
    drafts
        .into_iter()
        .map(|d| {
            let height_m = (median_m * (d.downtown_log - g_median + d.noise_log).exp()).clamp(min_m, max_m);
            Building::boxed(d.footprint.rect, d.footprint.base_up_m, height_m)
        })
        .collect()
}
