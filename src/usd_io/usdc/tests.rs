//! The writer against openusd's reader: every value variant, path trees,
//! empty and large layers, the streaming API and its errors. usd-core's side
//! (in-place saves, versions, sizes) is `python_tests/test_usdc_fidelity.py`.

use std::collections::HashMap;
use std::io::Cursor;

use openusd::gf::{self, f16};
use openusd::sdf::{self, AbstractData, LayerOffset, ListOp, SpecType, Value};
use openusd::usdc::{CrateData, CrateFile};

use super::*;

fn path(s: &str) -> sdf::Path {
    sdf::Path::new(s).unwrap()
}

fn write(data: &dyn AbstractData) -> Vec<u8> {
    write_layer(data, Cursor::new(Vec::new())).unwrap().into_inner()
}

/// Read back with openusd, with its consistency checks on.
fn read(bytes: &[u8]) -> CrateData {
    CrateData::open(bytes.to_vec(), true).expect("openusd reads the file")
}

fn version(bytes: &[u8]) -> [u8; 3] {
    [bytes[8], bytes[9], bytes[10]]
}

/// Every spec, spec type, field name (in order) and value of `a` is in `b`
/// and nothing else is.
fn assert_same(a: &dyn AbstractData, b: &dyn AbstractData) {
    let (pa, pb) = (a.spec_paths(), b.spec_paths());
    assert_eq!(pa, pb, "spec paths");
    for p in &pa {
        assert_eq!(a.spec_type(p), b.spec_type(p), "{p}");
        let fa = a.list_fields(p).unwrap_or_default();
        assert_eq!(fa, b.list_fields(p).unwrap_or_default(), "fields of {p}");
        for f in &fa {
            let va = a.get_field(p, f).unwrap().into_owned();
            let vb = b.get_field(p, f).unwrap().into_owned();
            assert_eq!(va, vb, "{p} {f}");
        }
    }
}

fn f16s(v: &[f32]) -> Vec<f16> {
    v.iter().map(|&x| f16::from_f32(x)).collect()
}

fn list_op<T: Default + Clone + PartialEq>(explicit: bool, lists: [Vec<T>; 6]) -> ListOp<T> {
    let [e, a, p, ap, d, o] = lists;
    ListOp {
        explicit,
        explicit_items: e,
        added_items: a,
        prepended_items: p,
        appended_items: ap,
        deleted_items: d,
        ordered_items: o,
    }
}

/// One value of every variant openusd 0.8 can hold in a layer, in the
/// encodings that matter (inlined and not, compressed and not, empty).
fn every_value() -> Vec<(&'static str, Value)> {
    let long_ints: Vec<i32> = (0..100).map(|i| i * i - 50 * (i % 3)).collect();
    let mut dict = HashMap::new();
    dict.insert("int".to_string(), Value::Int(3));
    dict.insert(
        "points".to_string(),
        Value::Vec3fVec(vec![gf::vec3f(1.0, 2.0, 3.5); 20]),
    );
    dict.insert("empty".to_string(), Value::Dictionary(HashMap::new()));
    dict.insert(
        "nested".to_string(),
        Value::Dictionary(HashMap::from([("s".to_string(), Value::String("deep".into()))])),
    );
    dict.insert("tokens".to_string(), Value::TokenVec(vec!["a".into(), "b".into()]));
    let reference = sdf::Reference {
        asset_path: "./other.usda".into(),
        prim_path: path("/Other/Prim"),
        layer_offset: LayerOffset {
            offset: 10.0,
            scale: 2.0,
        },
        custom_data: HashMap::from([("note".to_string(), Value::String("hi".into()))]),
    };
    let no_prim = sdf::Reference {
        asset_path: "./default.usda".into(),
        prim_path: sdf::Path::default(),
        layer_offset: LayerOffset::default(),
        custom_data: HashMap::new(),
    };
    let payload = sdf::Payload {
        asset_path: "./payload.usdc".into(),
        prim_path: path("/P"),
        layer_offset: LayerOffset {
            offset: -3.0,
            scale: 0.5,
        },
    };
    vec![
        ("bool", Value::Bool(true)),
        ("boolArray", Value::BoolVec(vec![true, false, true])),
        ("uchar", Value::Uchar(200)),
        ("ucharArray", Value::UcharVec((0..40).collect())),
        ("int", Value::Int(-7)),
        ("intShort", Value::IntVec(vec![3, -1, 4])),
        ("intLong", Value::IntVec(long_ints.clone())),
        ("intEmpty", Value::IntVec(vec![])),
        ("uint", Value::Uint(u32::MAX)),
        ("uintLong", Value::UintVec((0..50).map(|i| u32::MAX - i * 7).collect())),
        ("int64Neg", Value::Int64(-5)),
        ("int64Small", Value::Int64(5)),
        ("int64Min", Value::Int64(i64::MIN)),
        (
            "int64Long",
            Value::Int64Vec((0..40).map(|i| i * 1_000_000_007 - 3).collect()),
        ),
        (
            "int64Wild",
            Value::Int64Vec(
                (0..40)
                    .map(|i| if i % 2 == 0 { i64::MIN + i } else { i64::MAX - i })
                    .collect(),
            ),
        ),
        ("uint64", Value::Uint64(u64::MAX)),
        ("uint64Small", Value::Uint64(9)),
        ("uint64Array", Value::Uint64Vec(vec![1, u64::MAX, 0])),
        ("half", Value::Half(f16::from_f32(1.5))),
        ("halfInts", Value::HalfVec(f16s(&[1.0, -2.0, 3.0, 100.0].repeat(5)))),
        ("halfLut", Value::HalfVec(f16s(&[0.5, 0.25].repeat(10)))),
        (
            "halfRaw",
            Value::HalfVec(f16s(&(0..20).map(|i| i as f32 + 0.5).collect::<Vec<_>>())),
        ),
        ("float", Value::Float(-1.25)),
        (
            "floatInts",
            Value::FloatVec((0..64).map(|i| (i * 3) as f32 - 10.0).collect()),
        ),
        ("floatLut", Value::FloatVec([0.5f32, 0.75, -0.0, 0.0].repeat(8))),
        ("floatRaw", Value::FloatVec((0..64).map(|i| i as f32 * 0.1).collect())),
        ("floatShort", Value::FloatVec(vec![1.0, 2.0])),
        ("doubleInline", Value::Double(2.5)),
        ("doubleWide", Value::Double(0.1)),
        ("doubleNegZero", Value::Double(-0.0)),
        ("doubleInts", Value::DoubleVec((0..30).map(|i| i as f64).collect())),
        ("doubleRaw", Value::DoubleVec((0..30).map(|i| i as f64 / 7.0).collect())),
        ("string", Value::String("h\u{e9} \"quoted\"\nline".into())),
        ("stringArray", Value::StringVec(vec!["a".into(), "".into(), "b".into()])),
        ("stringEmpty", Value::StringVec(vec![])),
        ("token", Value::Token("Mesh".into())),
        ("tokenArray", Value::TokenVec(vec!["x".into(), "y".into()])),
        ("tokenEmpty", Value::TokenVec(vec![])),
        ("asset", Value::AssetPath("./tex/@diffuse@.png".into())),
        ("assetArray", Value::AssetPathVec(vec!["a.usd".into(), "b.usd".into()])),
        ("assetEmpty", Value::AssetPathVec(vec![])),
        (
            "quath",
            Value::quath(f16::from_f32(1.0), f16::from_f32(0.5), f16::ZERO, f16::from_f32(-0.5)),
        ),
        ("quatf", Value::quatf(0.9, 0.1, 0.2, 0.3)),
        ("quatd", Value::quatd(0.5, -0.5, 0.5, -0.5)),
        (
            "quathArray",
            Value::QuathVec(vec![gf::quath(f16::ONE, f16::ZERO, f16::ONE, f16::ZERO); 3]),
        ),
        (
            "quatfArray",
            Value::QuatfVec(vec![gf::quatf(1.0, 2.0, 3.0, 4.0), gf::quatf(5.0, 6.0, 7.0, 8.0)]),
        ),
        ("quatdArray", Value::QuatdVec(vec![gf::quatd(1.0, 2.0, 3.0, 4.0)])),
        ("vec2h", Value::Vec2h(gf::vec2h(f16::from_f32(0.5), f16::ONE))),
        (
            "vec3hInline",
            Value::Vec3h(gf::vec3h(f16::ONE, f16::ZERO, f16::from_f32(-3.0))),
        ),
        (
            "vec3hRaw",
            Value::Vec3h(gf::vec3h(f16::from_f32(0.5), f16::ZERO, f16::ONE)),
        ),
        (
            "vec4h",
            Value::Vec4h(gf::vec4h(f16::ONE, f16::ONE, f16::ONE, f16::from_f32(200.0))),
        ),
        ("vec2f", Value::Vec2f(gf::vec2f(1.0, -1.0))),
        ("vec3fInline", Value::Vec3f(gf::vec3f(0.0, 1.0, -128.0))),
        ("vec3fRaw", Value::Vec3f(gf::vec3f(0.0, 1.0, 128.0))),
        ("vec3fNegZero", Value::Vec3f(gf::vec3f(-0.0, 1.0, 2.0))),
        ("vec4f", Value::Vec4f(gf::vec4f(0.25, 1.0, 2.0, 3.0))),
        ("vec2d", Value::Vec2d(gf::vec2d(1e10, 2.0))),
        ("vec3d", Value::Vec3d(gf::vec3d(1.0, 2.0, 3.0))),
        ("vec4d", Value::Vec4d(gf::vec4d(0.1, 0.2, 0.3, 0.4))),
        ("vec2i", Value::Vec2i(gf::vec2i(1, 2))),
        ("vec3i", Value::Vec3i(gf::vec3i(1000, -2, 3))),
        ("vec4i", Value::Vec4i(gf::vec4i(-1, -2, -3, -4))),
        ("vec2hArray", Value::Vec2hVec(vec![gf::vec2h(f16::ONE, f16::ZERO); 5])),
        (
            "vec3hArray",
            Value::Vec3hVec(vec![gf::vec3h(f16::ONE, f16::ZERO, f16::ONE); 5]),
        ),
        (
            "vec4hArray",
            Value::Vec4hVec(vec![gf::vec4h(f16::ONE, f16::ZERO, f16::ONE, f16::ONE); 5]),
        ),
        ("vec2fArray", Value::Vec2fVec(vec![gf::vec2f(0.5, 1.5); 5])),
        (
            "vec3fArray",
            Value::Vec3fVec((0..33).map(|i| gf::vec3f(i as f32, 0.5, -1.0)).collect()),
        ),
        ("vec3fEmpty", Value::Vec3fVec(vec![])),
        ("vec4fArray", Value::Vec4fVec(vec![gf::vec4f(0.5, 1.5, 2.5, 3.5); 5])),
        ("vec2dArray", Value::Vec2dVec(vec![gf::vec2d(0.5, 1.5); 5])),
        ("vec3dArray", Value::Vec3dVec(vec![gf::vec3d(0.5, 1.5, 9.0); 5])),
        ("vec4dArray", Value::Vec4dVec(vec![gf::vec4d(0.5, 1.5, 2.5, 3.5); 5])),
        ("vec2iArray", Value::Vec2iVec(vec![gf::vec2i(1, 2); 5])),
        ("vec3iArray", Value::Vec3iVec(vec![gf::vec3i(1, 2, 3); 5])),
        ("vec4iArray", Value::Vec4iVec(vec![gf::vec4i(1, 2, 3, 4); 5])),
        ("matrix2dIdentity", Value::Matrix2d(gf::Mat2d([1.0, 0.0, 0.0, 1.0]))),
        (
            "matrix3dDiag",
            Value::Matrix3d(gf::Mat3d([2.0, 0.0, 0.0, 0.0, -3.0, 0.0, 0.0, 0.0, 1.0])),
        ),
        (
            "matrix4d",
            Value::Matrix4d(gf::Matrix4d([
                1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 5.0, 6.5, 7.0, 1.0,
            ])),
        ),
        (
            "matrix4dNegZero",
            Value::Matrix4d(gf::Matrix4d([
                1.0, -0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
            ])),
        ),
        (
            "matrix2dArray",
            Value::Matrix2dVec(vec![gf::Mat2d([1.0, 2.0, 3.0, 4.0]); 2]),
        ),
        ("matrix3dArray", Value::Matrix3dVec(vec![gf::Mat3d([0.5; 9]); 2])),
        ("matrix4dArray", Value::Matrix4dVec(vec![gf::Matrix4d([0.25; 16]); 3])),
        ("specifier", Value::Specifier(sdf::Specifier::Class)),
        ("permission", Value::Permission(sdf::Permission::Private)),
        ("variability", Value::Variability(sdf::Variability::Uniform)),
        ("dictionary", Value::Dictionary(dict.clone())),
        ("emptyDictionary", Value::Dictionary(HashMap::new())),
        (
            "tokenListOp",
            Value::TokenListOp(list_op(
                false,
                [
                    vec![],
                    vec!["add".into()],
                    vec!["pre".into()],
                    vec!["app".into()],
                    vec!["del".into()],
                    vec!["o1".into(), "o2".into()],
                ],
            )),
        ),
        (
            "stringListOp",
            Value::StringListOp(list_op(
                true,
                [vec!["e".into()], vec![], vec![], vec![], vec![], vec![]],
            )),
        ),
        (
            "explicitEmptyListOp",
            Value::StringListOp(list_op(true, Default::default())),
        ),
        (
            "pathListOp",
            Value::PathListOp(list_op(
                false,
                [
                    vec![],
                    vec![],
                    vec![path("/Targets/T1")],
                    vec![path("/Targets/T2.attr")],
                    vec![path("/Gone")],
                    vec![],
                ],
            )),
        ),
        (
            "referenceListOp",
            Value::ReferenceListOp(list_op(
                false,
                [vec![], vec![], vec![reference, no_prim], vec![], vec![], vec![]],
            )),
        ),
        (
            "payloadListOp",
            Value::PayloadListOp(list_op(
                false,
                [vec![], vec![], vec![], vec![payload.clone()], vec![], vec![]],
            )),
        ),
        (
            "intListOp",
            Value::IntListOp(list_op(false, [vec![], vec![1, -2], vec![], vec![], vec![3], vec![]])),
        ),
        (
            "int64ListOp",
            Value::Int64ListOp(list_op(true, [vec![i64::MIN], vec![], vec![], vec![], vec![], vec![]])),
        ),
        (
            "uintListOp",
            Value::UIntListOp(list_op(false, [vec![], vec![], vec![7], vec![], vec![], vec![]])),
        ),
        (
            "uint64ListOp",
            Value::UInt64ListOp(list_op(false, [vec![], vec![], vec![], vec![u64::MAX], vec![], vec![]])),
        ),
        ("payload", Value::Payload(payload)),
        ("pathVector", Value::PathVec(vec![path("/Targets/T1"), path("/A.b")])),
        (
            "relocates",
            Value::Relocates(vec![(path("/A/B"), path("/A/C")), (path("/X"), path("/Y"))]),
        ),
        (
            "variantSelection",
            Value::VariantSelectionMap(HashMap::from([
                ("shape".to_string(), "round".to_string()),
                ("lod".to_string(), "".to_string()),
            ])),
        ),
        (
            "layerOffsets",
            Value::LayerOffsetVec(vec![LayerOffset {
                offset: 1.0,
                scale: 2.0,
            }]),
        ),
        ("valueBlock", Value::ValueBlock),
        ("unregistered", Value::UnregisteredValue("mystery".into())),
        ("unregisteredDict", Value::UnregisteredDictionary(dict)),
        (
            "unregisteredListOp",
            Value::UnregisteredValueListOp(list_op(
                false,
                [vec![], vec![], vec!["a".into()], vec![], vec![], vec![]],
            )),
        ),
        ("timeCode", Value::TimeCode(sdf::TimeCode(12.5))),
        (
            "timeCodeArray",
            Value::TimeCodeVec(vec![sdf::TimeCode(1.0), sdf::TimeCode(-2.5)]),
        ),
        (
            "pathExpression",
            Value::PathExpression(sdf::PathExpression::parse("/World//Mesh* - /World/Hidden")),
        ),
        (
            "pathExpressionArray",
            Value::PathExpressionVec(vec![
                sdf::PathExpression::parse("/A"),
                sdf::PathExpression::parse("//B"),
            ]),
        ),
        (
            "timeSamples",
            Value::TimeSamples(vec![
                (1.0, Value::FloatVec(vec![1.0, 2.0])),
                (2.0, Value::ValueBlock),
                (2.5, Value::FloatVec(vec![1.0, 2.0])),
                (4.0, Value::FloatVec(vec![0.5; 40])),
            ]),
        ),
    ]
}

/// A layer holding `values`, each as the `default` of its own attribute
/// (field names are arbitrary in a crate, so each value sits where its kind
/// is read back in isolation).
fn layer_of(values: &[(&str, Value)]) -> sdf::Data {
    let mut data = sdf::Data::new();
    data.create_spec(sdf::Path::abs_root(), SpecType::PseudoRoot)
        .add("primChildren", Value::TokenVec(vec!["Values".into()]));
    let names: Vec<openusd::tf::Token> = values.iter().map(|(n, _)| (*n).into()).collect();
    let prim = data.create_spec(path("/Values"), SpecType::Prim);
    prim.add("specifier", Value::Specifier(sdf::Specifier::Def));
    prim.add("propertyChildren", Value::TokenVec(names));
    for (name, v) in values {
        let spec = data.create_spec(path(&format!("/Values.{name}")), SpecType::Attribute);
        spec.add("default", v.clone());
    }
    data
}

#[test]
fn every_value_variant_reads_back_equal() {
    let data = layer_of(&every_value());
    let bytes = write(&data);
    let back = read(&bytes);
    assert_same(&data, &back);
    // Bit-level checks PartialEq cannot make (it calls -0.0 equal to 0.0).
    let get = |n: &str| {
        back.get_field(&path(&format!("/Values.{n}")), "default")
            .unwrap()
            .into_owned()
    };
    assert_eq!(
        get("doubleNegZero").try_as_double().unwrap().to_bits(),
        (-0.0f64).to_bits()
    );
    let lut = get("floatLut").try_as_float_vec().unwrap();
    assert_eq!(lut[2].to_bits(), (-0.0f32).to_bits());
    assert_eq!(lut[3].to_bits(), 0);
    let v = get("vec3fNegZero").try_as_vec_3f().unwrap();
    assert_eq!(v.x.to_bits(), (-0.0f32).to_bits());
    let m = get("matrix4dNegZero").try_as_matrix_4d().unwrap();
    assert_eq!(m.0[1].to_bits(), (-0.0f64).to_bits());
}

#[test]
fn nan_and_infinities_keep_their_bits() {
    let nan = f64::from_bits(0x7ff8_0000_dead_beef);
    let data = layer_of(&[
        ("nan", Value::Double(nan)),
        ("inf", Value::Double(f64::NEG_INFINITY)),
        ("floats", Value::FloatVec([f32::NAN, f32::INFINITY, 1.0, 2.0].repeat(4))),
    ]);
    let back = read(&write(&data));
    let get = |n: &str| {
        back.get_field(&path(&format!("/Values.{n}")), "default")
            .unwrap()
            .into_owned()
    };
    assert_eq!(get("nan").try_as_double().unwrap().to_bits(), nan.to_bits());
    assert_eq!(get("inf").try_as_double().unwrap(), f64::NEG_INFINITY);
    let f = get("floats").try_as_float_vec().unwrap();
    assert!(f[0].is_nan() && f[1] == f32::INFINITY && f[15] == 2.0);
}

#[test]
fn versions_are_the_lowest_the_content_needs() {
    let v = |values: &[(&str, Value)]| version(&write(&layer_of(values)));
    assert_eq!(v(&[("a", Value::Vec3fVec(vec![gf::vec3f(1.0, 2.0, 3.0)]))]), [0, 8, 0]);
    let payloads = every_value()
        .into_iter()
        .filter(|(n, _)| n.starts_with("payload"))
        .collect::<Vec<_>>();
    assert_eq!(v(&payloads), [0, 8, 0]);
    assert_eq!(v(&[("t", Value::TimeCode(sdf::TimeCode(1.0)))]), [0, 9, 0]);
    assert_eq!(v(&[("t", Value::TimeCodeVec(vec![sdf::TimeCode(1.0)]))]), [0, 9, 0]);
    let in_dict = Value::Dictionary(HashMap::from([("t".to_string(), Value::TimeCode(sdf::TimeCode(1.0)))]));
    assert_eq!(v(&[("d", in_dict)]), [0, 9, 0]);
    assert_eq!(
        v(&[("e", Value::PathExpression(sdf::PathExpression::parse("/A")))]),
        [0, 10, 0]
    );
    assert_eq!(
        v(&[("r", Value::Relocates(vec![(path("/A"), path("/B"))]))]),
        [0, 11, 0]
    );
    assert_eq!(version(&write(&layer_of(&every_value()))), [0, 11, 0]);
}

#[test]
fn path_trees_with_siblings_children_properties_and_variants() {
    let mut data = sdf::Data::new();
    data.create_spec(sdf::Path::abs_root(), SpecType::PseudoRoot)
        .add("primChildren", Value::TokenVec(vec!["A".into(), "B".into()]));
    for (p, ty) in [
        ("/A", SpecType::Prim),
        ("/A/C", SpecType::Prim),
        ("/A/D", SpecType::Prim),
        ("/A/D/E", SpecType::Prim),
        ("/A.x", SpecType::Attribute),
        ("/A.y:ns", SpecType::Attribute),
        ("/A/D/E.z", SpecType::Attribute),
        ("/A{shape=}", SpecType::VariantSet),
        ("/A{shape=round}", SpecType::Variant),
        ("/A{shape=round}Inner", SpecType::Prim),
        ("/A{shape=round}Inner.w", SpecType::Attribute),
        ("/A{shape=round}.v", SpecType::Attribute),
        ("/A{shape=square}", SpecType::Variant),
        ("/B", SpecType::Prim),
        ("/B.rel", SpecType::Relationship),
        ("/B.rel2", SpecType::Relationship),
    ] {
        data.create_spec(path(p), ty).add("custom", Value::Bool(false));
    }
    data.create_spec(path("/B.rel2"), SpecType::Relationship).add(
        "targetPaths",
        Value::PathListOp(ListOp::explicit(vec![
            path("/A/D/E"),
            path("/Elsewhere/Deep/Prim.attr"),
        ])),
    );
    let bytes = write(&data);
    assert_same(&data, &read(&bytes));

    let file = CrateFile::open(bytes).unwrap();
    // usd-core reserves token 0 (a prim property stored at -0 would read back
    // as a prim child) and re-derives the pseudo-root's empty element token
    // on an in-place save.
    assert_eq!(file.tokens[0], ";-)");
    for t in [
        "",
        "A",
        "C",
        "x",
        "y:ns",
        "{shape=}",
        "{shape=round}",
        "Inner",
        "w",
        "v",
        "rel",
        "Elsewhere",
        "Deep",
        "attr",
    ] {
        assert!(file.tokens.iter().any(|k| k == t), "token {t:?} missing");
    }
    // Paths named only by values come with their ancestors.
    for p in [
        "/Elsewhere",
        "/Elsewhere/Deep",
        "/Elsewhere/Deep/Prim",
        "/Elsewhere/Deep/Prim.attr",
    ] {
        assert!(file.paths.iter().any(|k| k.as_str() == p), "path {p} missing");
    }
}

#[test]
fn empty_layers() {
    // A pseudo-root without fields.
    let mut data = sdf::Data::new();
    data.create_spec(sdf::Path::abs_root(), SpecType::PseudoRoot);
    let bytes = write(&data);
    assert_eq!(&bytes[..8], b"PXR-USDC");
    assert_eq!(version(&bytes), [0, 8, 0]);
    assert_same(&data, &read(&bytes));
    // No spec at all.
    let none = sdf::Data::new();
    let back = read(&write(&none));
    assert!(back.spec_paths().is_empty());
}

#[test]
fn large_arrays() {
    let n = 1_000_003usize;
    let points: Vec<gf::Vec3f> = (0..n)
        .map(|i| gf::vec3f(i as f32 * 0.001, (i % 977) as f32, -(i as f32).sqrt()))
        .collect();
    let indices: Vec<i32> = (0..n as i32).map(|i| i.wrapping_mul(7919) % 100_003).collect();
    let data = layer_of(&[
        ("points", Value::Vec3fVec(points)),
        ("indices", Value::IntVec(indices)),
        ("widths", Value::FloatVec(vec![0.5; n])),
    ]);
    let bytes = write(&data);
    assert_same(&data, &read(&bytes));
    // Points are stored raw (12 MB); the constant widths and the indices
    // compress far below their 4 MB.
    assert!(bytes.len() < 12 * n + 4 * n, "{} bytes", bytes.len());
}

/// Frames arrive in time order, attributes interleaved; only handles are
/// kept; specs are declared at the end.
#[test]
fn streaming_frames_then_specs() {
    let frames = 20;
    let mut stream = CrateStream::new(Cursor::new(Vec::new())).unwrap();
    let constant = Value::Vec3fVec(vec![gf::vec3f(0.25, 0.5, 1.0); 10_000]);
    let (mut times, mut moving, mut still) = (Vec::new(), Vec::new(), Vec::new());
    let mut expected_moving = Vec::new();
    for f in 0..frames {
        let t = 1.0 + f as f64 * 0.5;
        let pts = Value::Vec3fVec(vec![gf::vec3f(f as f32, 1.0, 2.0); 100]);
        moving.push(stream.write_value(&pts).unwrap());
        expected_moving.push((t, pts));
        still.push(stream.write_value(&constant).unwrap());
        times.push(t);
    }
    assert_eq!(std::mem::size_of::<ValueHandle>(), 8);
    let root_kids = Value::TokenVec(vec!["Mesh".into()]);
    let props = Value::TokenVec(vec!["points".into(), "extent".into()]);
    let over = Value::Specifier(sdf::Specifier::Over);
    let ty = Value::Token("point3f[]".into());
    stream
        .add_spec(
            &sdf::Path::abs_root(),
            SpecType::PseudoRoot,
            &[("primChildren", Field::Value(&root_kids))],
        )
        .unwrap();
    stream
        .add_spec(
            &path("/Mesh"),
            SpecType::Prim,
            &[
                ("specifier", Field::Value(&over)),
                ("propertyChildren", Field::Value(&props)),
            ],
        )
        .unwrap();
    stream
        .add_spec(
            &path("/Mesh.points"),
            SpecType::Attribute,
            &[
                ("typeName", Field::Value(&ty)),
                (
                    "timeSamples",
                    Field::TimeSamples {
                        times: &times,
                        values: &moving,
                    },
                ),
            ],
        )
        .unwrap();
    stream
        .add_spec(
            &path("/Mesh.extent"),
            SpecType::Attribute,
            &[(
                "timeSamples",
                Field::TimeSamples {
                    times: &times,
                    values: &still,
                },
            )],
        )
        .unwrap();
    assert_eq!(stream.version(), (0, 8, 0));
    let bytes = stream.finish().unwrap().into_inner();
    // The constant array is stored once, not 20 times.
    assert!(
        bytes.len() < 2 * 120_000 + frames * 1_200 + 4_096,
        "{} bytes",
        bytes.len()
    );

    let back = read(&bytes);
    let samples = |p: &str| match back.get_field(&path(p), "timeSamples").unwrap().into_owned() {
        Value::TimeSamples(s) => s,
        other => panic!("{other:?}"),
    };
    assert_eq!(samples("/Mesh.points"), expected_moving);
    assert!(samples("/Mesh.extent").iter().all(|(_, v)| *v == constant));
    assert_eq!(
        back.get_field(&path("/Mesh"), "propertyChildren").unwrap().into_owned(),
        props
    );
}

#[test]
fn stream_errors_name_the_spec_and_field() {
    let mut b = CrateStream::new(Cursor::new(Vec::new())).unwrap();
    // Streams created by concurrent tests may take the tags in between.
    let mut a = CrateStream::new(Cursor::new(Vec::new())).unwrap();
    while a.tag() == b.tag() {
        a = CrateStream::new(Cursor::new(Vec::new())).unwrap();
    }
    let h = b.write_value(&Value::FloatVec(vec![1.0])).unwrap();
    let err = a
        .add_spec(
            &path("/P.a"),
            SpecType::Attribute,
            &[(
                "timeSamples",
                Field::TimeSamples {
                    times: &[1.0],
                    values: &[h],
                },
            )],
        )
        .unwrap_err();
    assert_eq!(err.prim.as_deref(), Some("/P.a"));
    assert!(
        err.message.contains("timeSamples") && err.message.contains("another crate stream"),
        "{err}"
    );

    let h1 = a.write_value(&Value::Float(1.0)).unwrap();
    let err = a
        .add_spec(
            &path("/P.b"),
            SpecType::Attribute,
            &[(
                "timeSamples",
                Field::TimeSamples {
                    times: &[2.0, 1.0],
                    values: &[h1, h1],
                },
            )],
        )
        .unwrap_err();
    assert!(err.message.contains("out of order"), "{err}");

    let knots = Value::ValueVec(vec![Value::Double(1.0)]);
    let err = a
        .add_spec(&path("/P.c"), SpecType::Attribute, &[("spline", Field::Value(&knots))])
        .unwrap_err();
    assert_eq!(err.to_string().split(':').next(), Some("/P.c"));
    assert!(
        err.message.contains("`spline`") && err.message.contains("no crate representation"),
        "{err}"
    );

    let one = Value::Int(1);
    let err = a
        .add_spec(
            &path("/P.e"),
            SpecType::Attribute,
            &[("default", Field::Value(&one)), ("default", Field::Value(&one))],
        )
        .unwrap_err();
    assert!(err.message.contains("given twice"), "{err}");

    a.add_spec(&path("/P"), SpecType::Prim, &[]).unwrap();
    assert!(a
        .add_spec(&path("/P"), SpecType::Prim, &[])
        .unwrap_err()
        .message
        .contains("two specs"));
    assert!(a.add_spec(&path("/Q"), SpecType::Unknown, &[]).is_err());

    let mut deep = Value::Int(1);
    for _ in 0..40 {
        deep = Value::Dictionary(HashMap::from([("d".to_string(), deep)]));
    }
    let err = a
        .add_spec(
            &path("/P.d"),
            SpecType::Attribute,
            &[("customData", Field::Value(&deep))],
        )
        .unwrap_err();
    assert!(err.message.contains("nested more than"), "{err}");
    // The stream still finishes into a readable file after refused specs.
    let bytes = a.finish().unwrap().into_inner();
    assert!(read(&bytes).has_spec(&path("/P")));
}

/// A writer that fails after `room` bytes (a full disk).
struct Full {
    inner: Cursor<Vec<u8>>,
    room: usize,
}

impl std::io::Write for Full {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        if self.inner.get_ref().len() + b.len() > self.room {
            return Err(std::io::Error::other("no space left"));
        }
        self.inner.write(b)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl std::io::Seek for Full {
    fn seek(&mut self, to: std::io::SeekFrom) -> std::io::Result<u64> {
        self.inner.seek(to)
    }
}

#[test]
fn a_failed_write_breaks_the_stream() {
    let mut s = CrateStream::new(Full {
        inner: Cursor::new(Vec::new()),
        room: 1000,
    })
    .unwrap();
    let big = Value::Vec3fVec((0..1000).map(|i| gf::vec3f(i as f32, 0.5, 1.0)).collect());
    let err = s.write_value(&big).unwrap_err();
    assert!(err.message.contains("no space left"), "{err}");
    // Offsets after the failure would be wrong: every later call is refused.
    assert!(s.write_value(&Value::Int(1)).is_err());
    assert!(s.add_spec(&sdf::Path::abs_root(), SpecType::PseudoRoot, &[]).is_err());
    assert!(s.finish().is_err());
}

/// `write_value` refuses a value the crate format cannot hold, naming its
/// kind (the `Value` variant).
#[test]
fn write_value_names_the_kind_it_cannot_write() {
    let mut s = CrateStream::new(Cursor::new(Vec::new())).unwrap();
    let knots = Value::ValueVec(vec![Value::Double(1.0)]);
    let err = s.write_value(&knots).unwrap_err();
    assert!(err.message.contains("cannot write a ValueVec value"), "{err}");
}

/// The table of contents lists the six structural sections back to back,
/// each `size` bytes up to the next one's `start`, the last ending where
/// the table begins: the layout usd-core writes (read from a `.usdc` it
/// exported).
#[test]
fn sections_tile_the_bytes_before_the_table_of_contents() {
    let data = layer_of(&[("a", Value::FloatVec(vec![0.5, 1.5])), ("b", Value::String("s".into()))]);
    let bytes = write(&data);
    let word = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap());
    let toc = word(16) as usize;
    let count = word(toc) as usize;
    let mut names = Vec::new();
    let mut end = None;
    for k in 0..count {
        let at = toc + 8 + 32 * k;
        let name = String::from_utf8(bytes[at..at + 16].to_vec()).unwrap();
        names.push(name.trim_end_matches('\0').to_string());
        let (start, size) = (word(at + 16), word(at + 24));
        if let Some(end) = end {
            assert_eq!(start, end, "{} starts off the previous end", names[k]);
        }
        end = Some(start + size);
    }
    assert_eq!(names, ["TOKENS", "STRINGS", "FIELDS", "FIELDSETS", "PATHS", "SPECS"]);
    assert_eq!(end, Some(toc as u64));
}

#[test]
fn stream_must_start_at_offset_zero() {
    let mut out = Cursor::new(vec![0u8; 4]);
    out.set_position(4);
    assert!(CrateStream::new(out).is_err());
}

/// A layer read from a `.usdc` (lazily decoded by openusd) and edited is
/// written whole: the in-place path of the authoring commands.
#[test]
fn rewrites_a_crate_layer_read_from_disk() {
    let data = layer_of(&every_value());
    let mut first = read(&write(&data));
    first.set_field(&path("/Values.int"), "default", Value::Int(99));
    first.create_spec(path("/Added"), SpecType::Prim);
    let second = read(&write(&first));
    assert_same(&first, &second);
    assert_eq!(
        second.get_field(&path("/Values.int"), "default").unwrap().into_owned(),
        Value::Int(99)
    );
}

/// The rep of field `field` of spec `spec` in a crate file.
fn rep_of(file: &CrateFile, spec: &str, field: &str) -> u64 {
    let s = file
        .specs
        .iter()
        .find(|s| file.paths[s.path_index].as_str() == spec)
        .unwrap_or_else(|| panic!("no spec {spec}"));
    let mut k = s.fieldset_index;
    while let Some(f) = file.fieldsets[k] {
        let f = &file.fields[f];
        if file.tokens[f.token_index] == field {
            return f.value_rep.0;
        }
        k += 1;
    }
    panic!("{spec} has no field {field}")
}

/// openusd 0.8 keeps `ValueRep` (and its flag accessors) private to its
/// crate module: the tests read the bits.
const COMPRESSED_BIT: u64 = 1 << 61;
const PAYLOAD_MASK: u64 = (1 << 48) - 1;

/// openusd sizes its buffer for decoding a compressed 64-bit int array as if
/// the codes were 32-bit: 4 + ceil(2n / 8) + 4n bytes, 72 for 16 elements.
/// The integer coding of 16 int64s is 8 (the common difference) + 4 (the
/// 2-bit codes) + 2, 4 or 8 bytes per other difference; a coding of exactly
/// 72 bytes is compressed, one of 74 is stored raw.
#[test]
fn int64_arrays_compress_only_within_openusds_decoding_buffer() {
    // Differences from the previous element (the first from 0).
    let cumulative = |deltas: &[i64]| -> Vec<i64> {
        let mut prev = 0i64;
        deltas
            .iter()
            .map(|d| {
                prev = prev.wrapping_add(*d);
                prev
            })
            .collect()
    };
    let large = |k: i64| (1i64 << 40) + k; // 8 bytes each
                                           // 8 common (0) + 7 large (56) + 1 medium (4): 8 + 4 + 60 = 72.
    let mut at_limit = vec![0i64; 8];
    at_limit.extend((1..=7).map(large));
    at_limit.push(100_000);
    // 7 common + 7 large + 1 medium + 1 small (2): 8 + 4 + 62 = 74.
    let mut over = vec![0i64; 7];
    over.extend((1..=7).map(large));
    over.extend([100_000, 5]);
    assert_eq!((at_limit.len(), over.len()), (16, 16));
    assert_eq!(compress::encode_ints(&cumulative(&at_limit)).len(), 72);
    assert_eq!(compress::encode_ints(&cumulative(&over)).len(), 74);
    let data = layer_of(&[
        ("atLimit", Value::Int64Vec(cumulative(&at_limit))),
        ("over", Value::Int64Vec(cumulative(&over))),
        ("int32", Value::IntVec((0..16).map(|i| i * 100_000).collect())),
    ]);
    let bytes = write(&data);
    assert_same(&data, &read(&bytes));
    let file = CrateFile::open(bytes).unwrap();
    let compressed = |name: &str| rep_of(&file, &format!("/Values.{name}"), "default") & COMPRESSED_BIT != 0;
    assert!(compressed("atLimit"));
    assert!(!compressed("over"));
    assert!(compressed("int32"), "32-bit arrays are not limited");
}

/// Each nested value (a time sample, a dictionary entry) goes one level
/// deeper and comes back: many of them side by side stay at depth one.
#[test]
fn many_samples_and_entries_stay_within_the_nesting_limit() {
    let samples: Vec<(f64, Value)> = (0..40).map(|i| (i as f64, Value::Double(0.1 * i as f64))).collect();
    let entries: HashMap<String, Value> = (0..40).map(|i| (format!("k{i}"), Value::Int(i))).collect();
    let data = layer_of(&[
        ("samples", Value::TimeSamples(samples)),
        ("dict", Value::Dictionary(entries)),
    ]);
    assert_same(&data, &read(&write(&data)));
}

/// A time sample equal to an earlier one of the same attribute is stored
/// once, also when it was written after other bytes of the same value.
#[test]
fn equal_time_samples_are_stored_once() {
    let a: Vec<f32> = (0..1000).map(|i| (i as f32 * 0.37).sin()).collect();
    let b: Vec<f32> = (0..1000).map(|i| (i as f32 * 0.53).cos()).collect();
    let data = layer_of(&[(
        "samples",
        Value::TimeSamples(vec![
            (1.0, Value::FloatVec(a)),
            (2.0, Value::FloatVec(b.clone())),
            (3.0, Value::FloatVec(b)),
        ]),
    )]);
    let bytes = write(&data);
    assert_same(&data, &read(&bytes));
    // Two arrays of 4,000 raw bytes (neither is integral or few-valued),
    // not three; the rest of the file is well under 4,000 bytes.
    assert!(
        bytes.len() < 3 * 4000,
        "{} bytes: the third sample was stored again",
        bytes.len()
    );
    assert!(bytes.len() > 2 * 4000);
}

/// Raw arrays of non-integers start 8-byte aligned (usd-core maps them
/// straight from the file), also right after a 6-byte value.
#[test]
fn raw_arrays_start_8_byte_aligned() {
    let h = |x: f32| f16::from_f32(x);
    let mut values = Vec::new();
    for k in 0..4 {
        // Named so that each 6-byte value is written just before an array.
        values.push((format!("k{k}h"), Value::Vec3h(gf::vec3h(h(0.5), h(k as f32), h(1.0)))));
        values.push((format!("k{k}v"), Value::FloatVec(vec![0.5, 0.25 + k as f32])));
    }
    let named: Vec<(&str, Value)> = values.iter().map(|(n, v)| (n.as_str(), v.clone())).collect();
    let data = layer_of(&named);
    let bytes = write(&data);
    assert_same(&data, &read(&bytes));
    let file = CrateFile::open(bytes).unwrap();
    let payload = |name: &str| rep_of(&file, &format!("/Values.{name}"), "default") & PAYLOAD_MASK;
    for k in 0..4 {
        assert_eq!(payload(&format!("k{k}v")) % 8, 0, "k{k}v");
    }
    // Not vacuous: some 6-byte value ends off an 8-byte boundary.
    assert!((0..4).any(|k| (payload(&format!("k{k}h")) + 6) % 8 != 0));
}

/// The dedup key includes the rep's flags: a raw float array whose bytes
/// spell another float array's compressed encoding (same count, same
/// length) is a different value and must get its own rep.
#[test]
fn a_raw_array_spelling_a_compressed_one_is_not_shared() {
    const N: usize = 64;
    // Integral floats (compressed as 'i' + coded ints) whose compressed
    // part is exactly 4N - 1 bytes, so that with the 'i' it is as long as
    // N raw floats. Found by trying seeds and widths; the ints stay within
    // ±2^23, where f32 holds them exactly.
    let mut state = 7u64;
    let mut next = move || {
        // splitmix64
        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let z = (state ^ (state >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        let z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    };
    let found = (0..20_000).find_map(|_| {
        let wide = (next() % (N as u64)) as usize;
        let ints: Vec<i32> = (0..N)
            .map(|k| {
                let r = next() as i32;
                if k < wide {
                    r >> 9
                } else {
                    r >> 26
                }
            })
            .collect();
        let mut body = vec![b'i'];
        compress::put_compressed_ints(&ints, &mut body);
        (body.len() == 4 * N).then_some((ints, body))
    });
    let (ints, body) = found.expect("a compressed encoding 4N bytes long");
    let compressed: Vec<f32> = ints.iter().map(|&i| i as f32).collect();
    let raw: Vec<f32> = body
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
        .collect();
    let data = layer_of(&[
        ("compressed", Value::FloatVec(compressed)),
        ("raw", Value::FloatVec(raw)),
    ]);
    let bytes = write(&data);
    let file = CrateFile::open(bytes.clone()).unwrap();
    let rep = |n: &str| rep_of(&file, &format!("/Values.{n}"), "default");
    assert_ne!(rep("compressed") & COMPRESSED_BIT, 0, "test setup: compressed");
    assert_eq!(rep("raw") & COMPRESSED_BIT, 0, "test setup: raw");
    // Same bytes after the count: only the flags tell them apart.
    let payload = |n: &str| (rep(n) & PAYLOAD_MASK) as usize;
    let at = |n: &str| &bytes[payload(n)..payload(n) + 8 + 4 * N];
    assert_ne!(payload("compressed"), payload("raw"));
    assert_eq!(
        at("compressed"),
        at("raw"),
        "test setup: the two encodings are the same bytes"
    );
    let back = read(&bytes);
    for n in ["compressed", "raw"] {
        let p = path(&format!("/Values.{n}"));
        let (a, b) = (
            data.get_field(&p, "default").unwrap(),
            back.get_field(&p, "default").unwrap(),
        );
        let bits = |v: &Value| {
            v.clone()
                .try_as_float_vec()
                .unwrap()
                .iter()
                .map(|x| x.to_bits())
                .collect::<Vec<_>>()
        };
        assert_eq!(bits(&a), bits(&b), "{n}");
    }
}

/// An integral float array holding -0.0 is not coded as integers (0 would
/// read back as +0.0): the bits come back, for f32 and f64 elements.
#[test]
fn negative_zero_keeps_integral_arrays_raw() {
    let f: Vec<f32> = (0..16).map(|k| if k == 5 { -0.0 } else { k as f32 }).collect();
    let d: Vec<f64> = (0..16).map(|k| if k == 5 { -0.0 } else { -(k as f64) }).collect();
    let h: Vec<f16> = (0..16)
        .map(|k| f16::from_f32(if k == 5 { -0.0 } else { k as f32 }))
        .collect();
    let data = layer_of(&[
        ("f", Value::FloatVec(f.clone())),
        ("d", Value::DoubleVec(d.clone())),
        ("h", Value::HalfVec(h.clone())),
    ]);
    let back = read(&write(&data));
    let get = |n: &str| {
        back.get_field(&path(&format!("/Values.{n}")), "default")
            .unwrap()
            .into_owned()
    };
    let bf = get("f").try_as_float_vec().unwrap();
    let bd = get("d").try_as_double_vec().unwrap();
    assert_eq!(
        bf.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
        f.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
    );
    assert_eq!(
        bd.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
        d.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
    );
    let bh = get("h").try_as_half_vec().unwrap();
    assert_eq!(
        bh.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
        h.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
    );
}
