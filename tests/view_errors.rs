//! The messages of `painterly::view::ViewError`, as a bake shows them for
//! a view-dependent mesh whose keys cannot be interpolated: each names the
//! offending key by its index, so the user can find the authored prim.

use painterly::view::{NaturalCubicSpline, ViewError};

#[test]
fn spline_errors_name_the_key_time() {
    let e = NaturalCubicSpline::new(&[]).expect_err("no key times is an error");
    assert_eq!(e.to_string(), "at least one key time is needed");
    let e = NaturalCubicSpline::new(&[0.0, f64::NAN]).expect_err("a NaN time is an error");
    assert_eq!(e.to_string(), "key time 1 is not finite");
    let e = NaturalCubicSpline::new(&[0.0, 2.0, 2.0]).expect_err("a repeated time is an error");
    assert_eq!(e.to_string(), "key time 2 is not greater than key time 1");
}

#[test]
fn direction_and_hull_errors_name_the_key_viewpoint() {
    let cases = [
        (
            ViewError::NonFiniteDirection { index: 3 },
            "key viewpoint 3: direction is not finite",
        ),
        (
            ViewError::ZeroDirection { index: 0 },
            "key viewpoint 0: direction has zero length",
        ),
        (
            ViewError::InvalidSharpness(-1.0),
            "sharpness must be finite and > 0, got -1",
        ),
        (ViewError::Hull("coplanar".into()), "key viewpoint hull: coplanar"),
    ];
    for (e, want) in cases {
        assert_eq!(e.to_string(), want);
    }
    let dup = ViewError::DuplicateDirection { first: 1, second: 4 }.to_string();
    assert!(
        dup.starts_with("key viewpoints 1 and 4 have the same direction"),
        "{dup}"
    );
}
