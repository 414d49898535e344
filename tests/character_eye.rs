//! A frame seen from a world-space eye position instead of the cameras (the
//! live preview's orbit camera), on the committed head fixture: its face is
//! static and its camera orbits, so the eye placed where the camera is at
//! frame B must give, at any frame A, exactly what frame B gives.

use std::path::Path;

use glam::DVec3;
use painterly::character::{Character, Configuration, FrameOutput};
use painterly::usd_io::stage::StageReader;

const HEAD: &str = "fixtures/head.usda";

fn camera_at(t: f64) -> DVec3 {
    let r = StageReader::open(Path::new(HEAD)).unwrap();
    let cam = r.require_prim("/Head/Camera").unwrap();
    r.local_to_world(&cam, t).unwrap().transform_point3(DVec3::ZERO)
}

fn same(a: &FrameOutput, b: &FrameOutput) {
    assert_eq!(a.views.len(), b.views.len());
    for (x, y) in a.views.iter().zip(&b.views) {
        assert_eq!(x, y);
    }
    for (x, y) in a.layers.iter().zip(&b.layers) {
        assert_eq!(x.points, y.points);
        assert_eq!(x.opacity, y.opacity);
    }
}

#[test]
fn an_eye_where_the_camera_is_gives_that_frame() {
    let ch = Character::open(Path::new(HEAD), None).unwrap();
    let none = Configuration::new();
    let (a, b) = (1.0, 30.0);
    let want = ch.evaluate(b, false).unwrap();
    let input = ch.read_frame_seen_from(a, &none, Some(camera_at(b))).unwrap();
    // Every viewDirection axis measures the eye, not the prim it names.
    let conf_b = ch.configuration(b).unwrap();
    for (rig, rf) in ch.model.rigs.iter().zip(&input.rigs) {
        for (path, v) in rig.axes.iter().zip(&rf.axis_values) {
            assert!((v - conf_b[path]).abs() < 1e-12, "{path}: {v} vs {}", conf_b[path]);
        }
    }
    let got = ch.model.evaluate(input, false).unwrap();
    same(&got, &want);
    // And the frame without an eye is frame A itself, which differs.
    let plain = ch
        .model
        .evaluate(ch.read_frame_seen_from(a, &none, None).unwrap(), false)
        .unwrap();
    same(&plain, &ch.evaluate(a, false).unwrap());
    assert_ne!(plain.views[0], got.views[0], "the head's shape follows the eye");
}

#[test]
fn overrides_win_over_the_eye_and_bad_eyes_are_refused() {
    let ch = Character::open(Path::new(HEAD), None).unwrap();
    let c = Configuration::from([("/Head/Paint/viewX".to_string(), 0.25)]);
    let input = ch.read_frame_seen_from(1.0, &c, Some(camera_at(30.0))).unwrap();
    let i = ch.model.rigs[0]
        .axes
        .iter()
        .position(|a| a == "/Head/Paint/viewX")
        .unwrap();
    assert_eq!(input.rigs[0].axis_values[i], 0.25);
    assert!(ch
        .read_frame_seen_from(1.0, &Configuration::new(), Some(DVec3::NAN))
        .is_err());
    let bad = Configuration::from([("/Head/Nope".to_string(), 0.0)]);
    assert!(ch.read_frame_seen_from(1.0, &bad, None).is_err());
}
