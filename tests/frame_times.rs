//! `FrameRange::times` on ranges that `count` refuses: its documented
//! fallback still lists `start + k·step` up to the end (within 1e-9), never
//! more than MAX_FRAMES codes, and nothing for a range that runs backwards
//! or does not move.

use painterly::frames::{FrameRange, MAX_FRAMES};

fn range(start: f64, end: f64, step: f64) -> FrameRange {
    FrameRange { start, end, step }
}

#[test]
fn a_range_whose_codes_collide_still_lists_every_step() {
    // Near 2^53 the f64 spacing is 2, so start + 1 and start + 3 round
    // (half to even) onto their neighbours: count refuses the range, and
    // times lists k = 0..=4 as IEEE rounds them.
    let start = 2f64.powi(53);
    let r = range(start, start + 4.0, 1.0);
    assert!(r.count().unwrap_err().contains("too small to separate"));
    let offsets: Vec<f64> = r.times().iter().map(|t| t - start).collect();
    assert_eq!(offsets, [0.0, 0.0, 2.0, 4.0, 4.0]);
}

#[test]
fn backward_and_still_ranges_have_no_codes_and_a_long_one_is_cut() {
    let back = range(10.0, 2.0, 1.0);
    assert!(back.count().is_err());
    assert!(back.times().is_empty());
    // A step of zero never reaches the end: no codes, not MAX_FRAMES copies
    // of the start.
    let still = range(0.0, 5.0, 0.0);
    assert!(still.count().is_err());
    assert!(still.times().is_empty());
    let long = range(0.0, 2.0 * MAX_FRAMES as f64, 1.0);
    assert!(long.count().is_err());
    let t = long.times();
    assert_eq!(
        (t.len(), t[0], t[MAX_FRAMES - 1]),
        (MAX_FRAMES, 0.0, (MAX_FRAMES - 1) as f64)
    );
}

#[test]
fn the_stage_range_check_allows_rounding_and_nothing_more() {
    assert!(range(1.0 - 1e-12, 10.0 + 1e-12, 1.0).check_within(1.0, 10.0).is_ok());
    for (s, e) in [(1.0 - 1e-6, 10.0), (1.0, 10.0 + 1e-6)] {
        let err = range(s, e, 1.0).check_within(1.0, 10.0).unwrap_err().to_string();
        assert!(err.contains("outside the stage's time range 1:10"), "{err}");
    }
}
