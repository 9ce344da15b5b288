//! The report's pure helpers (the whole report of a real run is tested in the `sadesim`
//! crate, which can run one).

use super::*;

#[test]
fn path_data_drops_points_closer_than_the_limit_but_keeps_both_ends() {
    let d = svg::path_data([(0.0, 0.0), (0.1, 0.1), (0.2, 0.0), (5.0, 5.0), (5.1, 5.0)].into_iter(), 1.0);
    assert_eq!(d, "M0.0 0.0L5.0 5.0L5.1 5.0");
}

#[test]
fn ticks_are_round_and_cover_the_range() {
    assert_eq!(model::ticks(-2800.0, 1900.0, 5), vec![-2000.0, -1000.0, 0.0, 1000.0]);
    assert_eq!(model::ticks(0.0, 150.0, 5), vec![0.0, 50.0, 100.0, 150.0]);
    assert_eq!(model::time_ticks(610.0, 10), vec![0.0, 120.0, 240.0, 360.0, 480.0, 600.0]);
    assert_eq!(model::clock(312.4), "5:12");
    assert_eq!(model::clock(3725.0), "1:02:05");
}
