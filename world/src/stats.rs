//! Summary numbers of a generated world, for logs and reports.

use serde::{Deserialize, Serialize};
use std::fmt;

use super::building::Building;
use super::city::CityLayout;

/// What a world contains. Heights in metres, areas in square metres.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct WorldStats {
    /// Generator seed (a hash of the inputs), so logs tell two worlds apart.
    pub seed: u64,
    /// Half-width of the world square, metres.
    pub extent_m: f64,
    pub building_count: usize,
    /// City blocks inside the world, parks included.
    pub block_count: usize,
    /// Blocks left as parks or plazas.
    pub park_count: usize,
    /// Open areas given to the generator.
    pub open_area_count: usize,
    /// Buildings removed because they touched an open area.
    pub dropped_for_open_areas: usize,
    /// Median building height, metres (0 without buildings).
    pub median_height_m: f64,
    /// Mean building height, metres (0 without buildings).
    pub mean_height_m: f64,
    /// Tallest building, metres (0 without buildings).
    pub max_height_m: f64,
    /// Building footprint area over block area (land between streets, parks included):
    /// comparable with `city.builtFraction`.
    pub built_area_fraction: f64,
    /// Lowest and highest ground inside the world, sampled on a lattice (see
    /// `World::generate`), ENU up metres.
    pub ground_min_up_m: f64,
    pub ground_max_up_m: f64,
    /// For `world.source: osm`: what the import kept, skipped and how many heights it had
    /// to default. `null` for the procedural city (written, not skipped: the world bundle's
    /// binary encoding is not self-describing, so every field is always there).
    #[serde(default)]
    pub osm: Option<crate::osm::OsmStats>,
}

impl WorldStats {
    pub(super) fn new(
        seed: u64,
        extent_m: f64,
        layout: &CityLayout,
        open_area_count: usize,
        ground_range_up_m: (f64, f64),
    ) -> Self {
        let buildings: &[Building] = &layout.buildings;
        let mut heights: Vec<f64> = buildings.iter().map(Building::height_m).collect();
        let (median_height_m, mean_height_m, max_height_m) = if heights.is_empty() {
            (0.0, 0.0, 0.0)
        } else {
            let n = heights.len();
            let mean = heights.iter().sum::<f64>() / n as f64;
            let max = heights.iter().copied().fold(f64::MIN, f64::max);
            let (_, &mut median, _) = heights.select_nth_unstable_by(n / 2, f64::total_cmp);
            (median, mean, max)
        };
        let footprint_m2: f64 = buildings.iter().map(Building::footprint_area_m2).sum();
        Self {
            seed,
            extent_m,
            building_count: buildings.len(),
            block_count: layout.block_count,
            park_count: layout.park_count,
            open_area_count,
            dropped_for_open_areas: layout.dropped_for_open_areas,
            median_height_m,
            mean_height_m,
            max_height_m,
            built_area_fraction: if layout.block_area_m2 > 0.0 { footprint_m2 / layout.block_area_m2 } else { 0.0 },
            ground_min_up_m: ground_range_up_m.0,
            ground_max_up_m: ground_range_up_m.1,
            osm: None,
        }
    }
}

impl fmt::Display for WorldStats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "world {:016x}: extent {:.0} m, {} buildings on {} blocks ({} parks), height median {:.1} m \
             mean {:.1} m max {:.1} m, built {:.1} %, ground {:+.2}..{:+.2} m, {} open areas ({} buildings dropped)",
            self.seed,
            self.extent_m,
            self.building_count,
            self.block_count,
            self.park_count,
            self.median_height_m,
            self.mean_height_m,
            self.max_height_m,
            100.0 * self.built_area_fraction,
            self.ground_min_up_m,
            self.ground_max_up_m,
            self.open_area_count,
            self.dropped_for_open_areas,
        )
    }
}
