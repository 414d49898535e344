//! The evaluation API behind bake, Python and the preview: configuration
//! reads and what-if overrides on the committed blowfish.

use std::path::Path;

use painterly::character::{key_weights, Character, Configuration};

fn fish() -> Character {
    Character::open(Path::new("fixtures/blowfish.usda"), None).expect("blowfish opens")
}

#[test]
fn configuration_lists_every_axis_in_axis_units() {
    let ch = fish();
    let c = ch.configuration(30.0).unwrap();
    let names: Vec<&str> = c.keys().map(String::as_str).collect();
    assert_eq!(
        names,
        [
            "/Blowfish/Paint/blink",
            "/Blowfish/Paint/eyeX",
            "/Blowfish/Paint/eyeY",
            "/Blowfish/Paint/inflate"
        ]
    );
    // fixtures/README.md: inflate is held at 1 from frame 22 to 32; the
    // blink is 1 at frames 29-30.
    assert_eq!(c["/Blowfish/Paint/inflate"], 1.0);
    assert_eq!(c["/Blowfish/Paint/blink"], 1.0);
}

#[test]
fn overriding_with_the_stage_value_changes_nothing() {
    let ch = fish();
    let c = ch.configuration(17.0).unwrap();
    let plain = ch.model.evaluate(ch.read_frame(17.0).unwrap(), false).unwrap();
    let same = ch.model.evaluate(ch.read_frame_with(17.0, &c).unwrap(), false).unwrap();
    for (a, b) in plain.layers.iter().zip(&same.layers) {
        assert_eq!(a.points, b.points);
        assert_eq!(a.opacity, b.opacity);
    }
}

#[test]
fn an_override_moves_the_blend_onto_the_key() {
    let ch = fish();
    let (ri, li) = ch
        .model
        .rigs
        .iter()
        .enumerate()
        .find_map(|(ri, r)| {
            r.layers
                .iter()
                .position(|l| l.path == "/Blowfish/Paint/Spikes")
                .map(|li| (ri, li))
        })
        .unwrap();
    let inflate = ch.model.rigs[ri]
        .axes
        .iter()
        .position(|a| a == "/Blowfish/Paint/inflate")
        .unwrap();
    for (value, key) in [(0.0, "flat"), (0.5, "half"), (1.0, "out")] {
        let overrides = Configuration::from([("/Blowfish/Paint/inflate".to_string(), value)]);
        // Frame 5: before the shock's sentinels, so only pose keys blend.
        let input = ch.read_frame_with(5.0, &overrides).unwrap();
        assert_eq!(input.rigs[ri].axis_values[inflate], value);
        let w = key_weights(&ch.model.rigs[ri].layers[li].keys, &input.rigs[ri].axis_values, 5.0);
        let on_key: Vec<_> = w.position.iter().filter(|(_, w)| *w > 1e-12).collect();
        assert_eq!(on_key.len(), 1, "{value}: {:?}", w.position);
        assert_eq!(
            on_key[0].0.as_deref(),
            Some(format!("/Blowfish/Paint/Spikes/{key}").as_str())
        );
        assert!((on_key[0].1 - 1.0).abs() < 1e-12);
    }
}

#[test]
fn overriding_an_unknown_axis_is_an_error() {
    let ch = fish();
    let overrides = Configuration::from([("/Blowfish/Paint/nope".to_string(), 1.0)]);
    let e = ch.read_frame_with(5.0, &overrides).err().unwrap();
    assert_eq!(e.prim.as_deref(), Some("/Blowfish/Paint/nope"));
    let nan = Configuration::from([("/Blowfish/Paint/inflate".to_string(), f64::NAN)]);
    assert!(ch.read_frame_with(5.0, &nan).is_err());
}

/// A library caller (no clap to check the flags) asking for one chunk or
/// the assembly without `chunk` is refused before anything is read or written.
#[test]
fn chunk_index_or_assemble_without_chunk_is_refused() {
    use painterly::bake::{open_for_bake, BakeOptions};
    let out = std::env::temp_dir().join(format!("painterly-chunkless-{}.usda", std::process::id()));
    for opts in [
        BakeOptions {
            chunk_index: Some(0),
            ..Default::default()
        },
        BakeOptions {
            assemble: true,
            ..Default::default()
        },
    ] {
        let e = open_for_bake(Path::new("fixtures/blowfish.usda"), &out, &opts)
            .err()
            .expect("refused");
        assert_eq!(e.message, "--chunk-index and --assemble need --chunk N");
        assert!(!out.exists());
    }
}
