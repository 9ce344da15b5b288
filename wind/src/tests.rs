//! The classic reference: a surface-mounted cube in a boundary layer.

use nalgebra::Vector3;
use sadesim_world::{Building, Footprint, World};

use super::*;

/// Cube edge, metres, and the cell edge: ten cells per cube height.
const H: f64 = 20.0;
const CELL: f64 = 2.0;

/// A cube of edge `H` centred on the origin, in a 300 m square, and its field for a wind
/// from the west (sector 6 of 8).
fn cube_field() -> (World, UrbanWindField) {
    let half = H / 2.0;
    let footprint = Footprint::new(vec![[-half, -half], [half, -half], [half, half], [-half, half]], vec![]).unwrap();
    let world = World::of_buildings(150.0, vec![Building::new(footprint, 0.0, H).unwrap()]);
    let mut field = UrbanWindField::new(&world, GridSpec { spacing_m: CELL, top_factor: 2.0 }, 8);
    field.ensure_sector(&world, 6);
    (world, field)
}

/// East component along the cube's centreline (north = +1 m, the first cell row north of
/// it) in the lowest cells above the roughness length (where the undisturbed profile is
/// not zero: 3 m, 0.15 H), from the leeward face downstream: `(metres behind the face, u)`.
fn centreline(field: &UrbanWindField) -> Vec<(f64, f64)> {
    let g = &field.grid;
    let s = &field.sectors[0].1;
    let j = ((1.0 - g.corner_m[1]) / g.spacing_m).floor() as usize;
    let k = (0..g.dims[2]).find(|&k| field.profile.factor(g.height_agl_m(0, j, k)) > 0.0).expect("a level above z0");
    (0..g.dims[0])
        .map(|i| (g.centre(i, j, k)[0] - H / 2.0, f64::from(s.east[g.index(i, j, k)])))
        .filter(|(x, _)| *x > 0.0)
        .collect()
}

#[test]
fn behind_a_cube_the_flow_reverses_and_reattaches_within_the_published_range() {
    let (_, field) = cube_field();
    let line = centreline(&field);
    assert!(line[0].1 < 0.0, "reversed flow right behind the cube: {:?}", &line[..3]);
    // Reattachment: where u turns positive again, between the two cell centres.
    let k = line.iter().position(|(_, u)| *u >= 0.0).expect("the flow reattaches");
    let ((x0, u0), (x1, u1)) = (line[k - 1], line[k]);
    let reattach_h = (x0 + (x1 - x0) * (-u0) / (u1 - u0)) / H;
    eprintln!("built-in model: reattachment {reattach_h:.2} H behind the cube (Martinuzzi & Tropea 1993: 1.6 H)");
    assert!((1.0..=2.5).contains(&reattach_h), "reattachment {reattach_h:.2} H");
    // Further downstream the wake recovers towards the profile.
    let far = line.iter().find(|(x, _)| *x > 6.0 * H).expect("a far point").1;
    assert!(far > 0.5 * field.profile.factor(3.0), "far wake {far}");
}

#[test]
fn the_adjusted_field_conserves_mass_and_the_first_guess_does_not() {
    let (_, field) = cube_field();
    let s = &field.sectors[0].1;
    eprintln!(
        "mass-conservation residual: first guess {:.3e}, adjusted {:.3e} ({} iterations)",
        s.first_guess_residual, s.residual, s.iterations
    );
    assert!(s.first_guess_residual > 0.1, "{}", s.first_guess_residual);
    assert!(s.residual < 1e-5, "{}", s.residual);
}

#[test]
fn the_flow_goes_around_and_over_the_cube_faster_than_the_profile() {
    let (_, field) = cube_field();
    let profile = |z: f64| field.profile.factor(z);
    // Beside the cube at mid height, and over its roof above the rooftop bubble (0.22 H =
    // 4.4 m high), the air speeds up.
    let side = field.factor_at(&Vector3::new(0.0, H / 2.0 + 3.0, H / 2.0), 270.0, H / 2.0).unwrap();
    assert!(side.x > profile(H / 2.0), "side {side:?} vs {}", profile(H / 2.0));
    let over = field.factor_at(&Vector3::new(0.0, 0.0, H + 6.0), 270.0, H + 6.0).unwrap();
    assert!(over.x > profile(H + 6.0) * 0.9, "over {over:?}");
    // Inside the cube nothing moves; far upstream the profile is untouched.
    assert_eq!(field.factor_at(&Vector3::new(0.0, 0.0, 5.0), 270.0, 5.0).unwrap(), Vector3::zeros());
    let upstream = field.factor_at(&Vector3::new(-140.0, 0.0, 30.0), 270.0, 30.0).unwrap();
    assert!((upstream.x - profile(30.0)).abs() < 0.05 * profile(30.0), "{upstream:?}");
    // A direction between sectors needs its two sectors.
    assert!(field.factor_at(&Vector3::new(0.0, 60.0, 10.0), 280.0, 10.0).is_none());
}

#[test]
fn the_same_world_gives_the_same_bits() {
    let (_, a) = cube_field();
    let (_, b) = cube_field();
    assert_eq!(a, b);
}

#[test]
fn over_the_roof_the_flow_separates_at_the_upwind_edge() {
    let (_, field) = cube_field();
    let g = &field.grid;
    let s = &field.sectors[0].1;
    // The first cell row over the roof (20 m), on the centreline, from the upwind edge
    // (east -10 m) downstream: reversed near the edge, forward again past the bubble
    // (0.9 H = 18 m long from the edge).
    let k = ((H + 1.0 - g.corner_m[2]) / g.spacing_m).floor() as usize;
    let j = ((1.0 - g.corner_m[1]) / g.spacing_m).floor() as usize;
    let u_at = |east: f64| {
        let i = ((east - g.corner_m[0]) / g.spacing_m).floor() as usize;
        f64::from(s.east[g.index(i, j, k)])
    };
    let bubble: Vec<f64> = (0..8).map(|m| u_at(-9.0 + 2.0 * f64::from(m))).collect();
    let open = field.profile.factor(H + 1.0);
    eprintln!("over the roof at 1 m, every 2 m from the upwind edge: {bubble:.2?} (open profile {open:.2})");
    // The bubble: the flow just over the roof is a small part of the open wind's, and
    // reversed where the bubble is deepest (after the adjustment, which keeps the first
    // guess's reversal only where the bubble is thick enough).
    let mean = bubble.iter().sum::<f64>() / bubble.len() as f64;
    assert!(mean < 0.3 * open, "mean {mean:.2} against {open:.2} in the open");
    assert!(bubble.iter().any(|u| *u < 0.0), "{bubble:.2?}");
    // Higher up the flow goes over the bubble, faster than the undisturbed profile.
    let over = field.factor_at(&Vector3::new(-5.0, 0.0, H + 5.0), 270.0, H + 5.0).unwrap();
    assert!(over.x > 0.9 * field.profile.factor(H + 5.0), "over {over:?}");
}

/// A slab `H` high, 60 m wide across a wind from the west (north -30 to 30 m) and 10 m
/// deep, its west face at `west` metres east.
fn slab(west: f64) -> Building {
    let footprint =
        Footprint::new(vec![[west, -30.0], [west + 10.0, -30.0], [west + 10.0, 30.0], [west, 30.0]], vec![]).unwrap();
    Building::new(footprint, 0.0, H).unwrap()
}

/// Two slabs 20 m high, 60 m wide across a wind from the west and 10 m deep, with a street
/// 16 m wide between them (a skimming-flow canyon: the gap is well inside the upwind
/// slab's cavity, 77 m), on 2 m cells; and the adjusted field.
fn canyon_field() -> UrbanWindField {
    // The street: east 0 (the upwind slab's back wall) to east 16 (the downwind facade).
    let world = World::of_buildings(150.0, vec![slab(-10.0), slab(16.0)]);
    let mut field = UrbanWindField::new(&world, GridSpec { spacing_m: CELL, top_factor: 2.0 }, 8);
    field.ensure_sector(&world, 6);
    field
}

#[test]
fn in_a_street_canyon_the_air_turns_in_a_vortex() {
    let field = canyon_field();
    let at = |east: f64, up: f64| field.factor_at(&Vector3::new(east, 1.0, up), 270.0, up).unwrap();
    let open = field.profile.factor(H);
    // Up the upwind slab's back wall, against the wind near the street, down the downwind
    // facade, with the wind at the roofs forward: one vortex turning with the wind.
    let (rise, street, sink, roof) = (at(3.0, 11.0), at(8.0, 3.0), at(13.0, 11.0), at(8.0, H + 6.0));
    eprintln!(
        "street canyon (factors of the reference wind; open {open:.2} at {H} m): \
         back wall {rise:.2?}, street {street:.2?}, facade {sink:.2?}, over the roofs {roof:.2?}"
    );
    // (Without the vortex, the cavity's reversed flow cut off by the facade, the adjustment
    // alone gives 0.14 of the open wind up and down the walls and 0.06 against it.)
    assert!(rise.z > 0.2 * open, "rising along the back wall: {rise:?}");
    assert!(sink.z < -0.2 * open, "sinking along the downwind facade: {sink:?}");
    assert!(street.x < -0.15 * open, "against the wind near the street: {street:?}");
    assert!(roof.x > 0.5 * open, "forward over the roofs: {roof:?}");
    // Mass-consistent all the same.
    let s = &field.sectors[0].1;
    assert!(s.residual < 1e-5, "{}", s.residual);
}

#[test]
fn a_gap_wider_than_the_cavity_is_no_canyon() {
    // The vortex is the only source of vertical wind in the first guess: with the downwind
    // slab 16 m behind there is one, with it 120 m behind (beyond the upwind slab's 77 m
    // cavity) there is none: that street is the cavity and wake of an isolated building.
    let vertical_cells = |gap: f64| {
        let world = World::of_buildings(150.0, vec![slab(-10.0), slab(gap)]);
        let grid = WindGrid::over(&world, GridSpec { spacing_m: CELL, top_factor: 2.0 });
        let guess = rockle::first_guess(&world, &grid, rockle::WindAxes::from_deg(270.0), &profile::FIELD_PROFILE);
        guess.up.iter().filter(|w| **w != 0.0).count()
    };
    let (narrow, wide) = (vertical_cells(16.0), vertical_cells(120.0));
    // 16 m x 60 m x 20 m of street is 7 x 30 x 10 cells of 2 m (the cells whose centres lie
    // inside), all of them in the vortex.
    assert!(narrow >= 7 * 30 * 10, "{narrow} cells");
    assert_eq!(wide, 0);
}
