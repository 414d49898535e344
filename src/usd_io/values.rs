//! Conversions from composed USD values to plain arrays.
//!
//! USD lets a file store `point3f[]` as float, double or half; painterly's math
//! wants one representation, so readers accept every precision and convert.

use glam::{DMat4, Vec3};
use openusd::gf;
use openusd::sdf::Value;

use crate::bind::Binding;

/// `point3f[]`, `float3[]`, `vector3f[]`, ... in any precision, as f32 vectors.
pub fn vec3_array(v: &Value) -> Option<Vec<Vec3>> {
    Some(match v {
        Value::Vec3fVec(a) => a.iter().map(|p| Vec3::new(p.x, p.y, p.z)).collect(),
        Value::Vec3dVec(a) => a
            .iter()
            .map(|p| Vec3::new(p.x as f32, p.y as f32, p.z as f32))
            .collect(),
        Value::Vec3hVec(a) => a
            .iter()
            .map(|p| Vec3::new(p.x.to_f32(), p.y.to_f32(), p.z.to_f32()))
            .collect(),
        _ => return None,
    })
}

/// Like [`vec3_array`], taking the value: float arrays are reinterpreted in
/// place (no copy), which matters for per-frame reads of big meshes. The
/// error is the value's kind name.
pub fn into_vec3_array(v: Value) -> Result<Vec<Vec3>, String> {
    match v {
        Value::Vec3fVec(a) => Ok(bytemuck::allocation::cast_vec(a)),
        other => vec3_array(&other).ok_or_else(|| kind_name(&other)),
    }
}

/// A single 3-vector in any precision.
pub fn vec3(v: &Value) -> Option<[f64; 3]> {
    Some(match v {
        Value::Vec3f(p) => [p.x as f64, p.y as f64, p.z as f64],
        Value::Vec3d(p) => [p.x, p.y, p.z],
        Value::Vec3h(p) => [p.x.to_f64(), p.y.to_f64(), p.z.to_f64()],
        _ => return None,
    })
}

/// `float[]`, `double[]`, `half[]` as f32.
pub fn f32_array(v: &Value) -> Option<Vec<f32>> {
    Some(match v {
        Value::FloatVec(a) => a.clone(),
        Value::DoubleVec(a) => a.iter().map(|&x| x as f32).collect(),
        Value::HalfVec(a) => a.iter().map(|x| x.to_f32()).collect(),
        _ => return None,
    })
}

/// `int[]` (and other integer arrays) as i64.
pub fn int_array(v: &Value) -> Option<Vec<i64>> {
    Some(match v {
        Value::IntVec(a) => a.iter().map(|&x| x as i64).collect(),
        Value::UintVec(a) => a.iter().map(|&x| x as i64).collect(),
        Value::Int64Vec(a) => a.clone(),
        Value::UcharVec(a) => a.iter().map(|&x| x as i64).collect(),
        _ => return None,
    })
}

/// `int3[]` as i64 triples.
pub fn int3_array(v: &Value) -> Option<Vec<[i64; 3]>> {
    match v {
        Value::Vec3iVec(a) => Some(a.iter().map(|p| [p.x as i64, p.y as i64, p.z as i64]).collect()),
        _ => None,
    }
}

/// Any numeric scalar (bool, int, float, double, half) as f64.
pub fn scalar(v: &Value) -> Option<f64> {
    Some(match v {
        Value::Bool(b) => *b as i32 as f64,
        Value::Int(x) => *x as f64,
        Value::Uint(x) => *x as f64,
        Value::Int64(x) => *x as f64,
        Value::Uint64(x) => *x as f64,
        Value::Uchar(x) => *x as f64,
        Value::Float(x) => *x as f64,
        Value::Double(x) => *x,
        Value::Half(x) => x.to_f64(),
        _ => return None,
    })
}

/// A token or string value.
pub fn token(v: &Value) -> Option<String> {
    match v {
        Value::Token(t) => Some(t.as_str().to_string()),
        Value::String(s) => Some(s.clone()),
        _ => None,
    }
}

/// A `token[]` or `string[]` value.
pub fn token_array(v: &Value) -> Option<Vec<String>> {
    match v {
        Value::TokenVec(a) => Some(a.iter().map(|t| t.as_str().to_string()).collect()),
        Value::StringVec(a) => Some(a.clone()),
        _ => None,
    }
}

/// USD's row-major, row-vector `matrix4d` as a glam column-vector matrix.
///
/// USD transforms points as `p * M`; glam as `M * p`. The row-major array of
/// `M` read as columns is exactly `Mᵀ`, the column-vector form.
pub fn usd_matrix(m: &openusd::gf::Matrix4d) -> DMat4 {
    DMat4::from_cols_array(&m.0)
}

/// `matrix4d` value as a glam matrix.
pub fn matrix4(v: &Value) -> Option<DMat4> {
    match v {
        Value::Matrix4d(m) => Some(usd_matrix(m)),
        _ => None,
    }
}

/// A short name for a value's kind, for error messages ("expected point3f[], found int[]").
pub fn kind_name(v: &Value) -> String {
    // The variant's name (`Vec3fVec`, `Matrix4d`, `TokenVec`) spelled as the
    // USD type users author (`float3[]`, `matrix4d`, `token[]`).
    let dbg = format!("{v:?}");
    let variant = dbg.split(['(', ' ', '{']).next().unwrap_or("value");
    let (base, array) = match variant.strip_suffix("Vec") {
        Some(b) if !b.is_empty() => (b, "[]"),
        _ => (variant, ""),
    };
    let scalar = |c: &str| match c {
        "h" => "half",
        "f" => "float",
        "d" => "double",
        _ => "int",
    };
    let name = match base {
        "AssetPath" => "asset".to_string(),
        "ValueBlock" => return "blocked (None)".to_string(),
        b if b.len() == 5 && b.starts_with("Vec") => format!("{}{}", scalar(&b[4..]), &b[3..4]),
        b => {
            let mut c = b.chars();
            c.next().map_or(String::new(), |f| f.to_lowercase().chain(c).collect())
        }
    };
    format!("{name}{array}")
}

/// A binding as the values of `painterly:bindVertices` (`int3[]`) and
/// `painterly:bindWeights` (`float3[]`).
pub fn binding_values(b: &Binding) -> (Value, Value) {
    let verts = b
        .vertices
        .iter()
        .map(|v| gf::Vec3i {
            x: v[0] as i32,
            y: v[1] as i32,
            z: v[2] as i32,
        })
        .collect();
    let weights = b.weights.iter().map(|w| gf::vec3f(w[0], w[1], w[2])).collect();
    (Value::Vec3iVec(verts), Value::Vec3fVec(weights))
}

#[cfg(test)]
mod tests {
    use super::*;
    use openusd::gf;

    #[test]
    fn usd_row_vector_matrix_becomes_glam_column_matrix() {
        // USD translate (1,2,3): translation lives in the last row.
        let mut m = [0.0; 16];
        m[0] = 1.0;
        m[5] = 1.0;
        m[10] = 1.0;
        m[15] = 1.0;
        m[12] = 1.0;
        m[13] = 2.0;
        m[14] = 3.0;
        let g = usd_matrix(&gf::Matrix4d(m));
        let p = g.transform_point3(glam::DVec3::ZERO);
        assert_eq!(p, glam::DVec3::new(1.0, 2.0, 3.0));
    }

    #[test]
    fn arrays_convert_from_every_precision() {
        let v = Value::Vec3dVec(vec![gf::Vec3d { x: 1.0, y: 2.0, z: 3.0 }]);
        assert_eq!(vec3_array(&v).unwrap(), vec![Vec3::new(1.0, 2.0, 3.0)]);
        assert_eq!(f32_array(&Value::DoubleVec(vec![0.5])).unwrap(), vec![0.5]);
        assert!(vec3_array(&Value::IntVec(vec![1])).is_none());
    }

    #[test]
    fn kind_names_are_usd_type_names() {
        // As USD spells the types (Sdf.ValueTypeNames), by hand.
        let cases = [
            (Value::FloatVec(vec![]), "float[]"),
            (Value::Vec3fVec(vec![]), "float3[]"),
            (Value::Vec3hVec(vec![]), "half3[]"),
            (Value::Vec2i(gf::Vec2i { x: 0, y: 0 }), "int2"),
            (Value::Vec4dVec(vec![]), "double4[]"),
            (Value::QuatfVec(vec![]), "quatf[]"),
            (Value::Matrix4dVec(vec![]), "matrix4d[]"),
            (Value::TokenVec(vec![]), "token[]"),
            (Value::Int64(3), "int64"),
            (Value::Double(1.0), "double"),
            (Value::Bool(true), "bool"),
            (Value::String(String::new()), "string"),
            (Value::AssetPathVec(vec![]), "asset[]"),
        ];
        for (v, want) in cases {
            assert_eq!(kind_name(&v), want, "{v:?}");
        }
    }

    #[test]
    fn every_precision_and_integer_width_converts() {
        // One value of each kind a reader accepts, each with its own numbers,
        // converted by hand; any other kind is None.
        let h = |x: f32| gf::f16::from_f32(x);
        let hv = |x: f32, y: f32, z: f32| gf::Vec3h {
            x: h(x),
            y: h(y),
            z: h(z),
        };
        let v3 = |x, y, z| Vec3::new(x, y, z);
        assert_eq!(
            vec3_array(&Value::Vec3fVec(vec![gf::vec3f(1.5, -2.0, 3.25)])),
            Some(vec![v3(1.5, -2.0, 3.25)])
        );
        let d = Value::Vec3dVec(vec![gf::Vec3d {
            x: 0.1,
            y: 2.0,
            z: -3.0,
        }]);
        assert_eq!(vec3_array(&d), Some(vec![v3(0.1, 2.0, -3.0)]));
        assert_eq!(
            vec3_array(&Value::Vec3hVec(vec![hv(0.5, 4.0, -8.0)])),
            Some(vec![v3(0.5, 4.0, -8.0)])
        );
        assert_eq!(
            into_vec3_array(Value::Vec3fVec(vec![gf::vec3f(7.0, 8.0, 9.0)])),
            Ok(vec![v3(7.0, 8.0, 9.0)])
        );
        assert_eq!(
            into_vec3_array(Value::Vec3hVec(vec![hv(1.0, 2.0, 3.0)])),
            Ok(vec![v3(1.0, 2.0, 3.0)])
        );
        assert_eq!(into_vec3_array(Value::IntVec(vec![1])), Err("int[]".to_string()));

        assert_eq!(vec3(&Value::Vec3f(gf::vec3f(1.0, 2.0, 3.5))), Some([1.0, 2.0, 3.5]));
        assert_eq!(
            vec3(&Value::Vec3d(gf::Vec3d {
                x: 0.1,
                y: -0.2,
                z: 0.3
            })),
            Some([0.1, -0.2, 0.3])
        );
        assert_eq!(vec3(&Value::Vec3h(hv(0.25, 64.0, -1.0))), Some([0.25, 64.0, -1.0]));
        assert_eq!(vec3(&Value::Double(1.0)), None);

        assert_eq!(f32_array(&Value::FloatVec(vec![0.25, -4.0])), Some(vec![0.25, -4.0]));
        assert_eq!(f32_array(&Value::DoubleVec(vec![0.1])), Some(vec![0.1f32]));
        assert_eq!(f32_array(&Value::HalfVec(vec![h(0.5), h(-2.0)])), Some(vec![0.5, -2.0]));
        assert_eq!(f32_array(&Value::IntVec(vec![1])), None);

        assert_eq!(int_array(&Value::IntVec(vec![-3, 4])), Some(vec![-3, 4]));
        assert_eq!(
            int_array(&Value::UintVec(vec![4_000_000_000])),
            Some(vec![4_000_000_000])
        );
        assert_eq!(int_array(&Value::Int64Vec(vec![-(1 << 40)])), Some(vec![-(1 << 40)]));
        assert_eq!(int_array(&Value::UcharVec(vec![255, 7])), Some(vec![255, 7]));
        assert_eq!(int_array(&Value::FloatVec(vec![1.0])), None);

        let tri = Value::Vec3iVec(vec![gf::Vec3i { x: 1, y: -2, z: 3 }]);
        assert_eq!(int3_array(&tri), Some(vec![[1, -2, 3]]));
        assert_eq!(int3_array(&Value::IntVec(vec![1, 2, 3])), None);

        let scalars = [
            (Value::Bool(true), 1.0),
            (Value::Bool(false), 0.0),
            (Value::Int(-5), -5.0),
            (Value::Uint(4_000_000_000), 4e9),
            (Value::Int64(-(1 << 40)), -(2f64.powi(40))),
            (Value::Uint64(1 << 50), 2f64.powi(50)),
            (Value::Uchar(200), 200.0),
            (Value::Float(0.1), 0.1f32 as f64),
            (Value::Double(0.1), 0.1),
            (Value::Half(h(0.75)), 0.75),
        ];
        for (v, want) in scalars {
            assert_eq!(scalar(&v), Some(want), "{v:?}");
        }
        assert_eq!(scalar(&Value::FloatVec(vec![1.0])), None);

        assert_eq!(token(&Value::Token("Y".into())), Some("Y".to_string()));
        assert_eq!(token(&Value::String("a b".into())), Some("a b".to_string()));
        assert_eq!(token(&Value::Int(1)), None);
        let toks = Value::TokenVec(vec!["a".into(), "b".into()]);
        assert_eq!(token_array(&toks), Some(vec!["a".to_string(), "b".to_string()]));
        assert_eq!(
            token_array(&Value::StringVec(vec!["c".into()])),
            Some(vec!["c".to_string()])
        );
        assert_eq!(token_array(&Value::Token("a".into())), None);

        let mut m = [0.0; 16];
        m[0] = 2.0;
        m[5] = 3.0;
        m[10] = 4.0;
        m[15] = 1.0;
        m[12] = 7.0;
        let g = matrix4(&Value::Matrix4d(gf::Matrix4d(m))).unwrap();
        assert_eq!(g.transform_point3(glam::DVec3::ONE), glam::DVec3::new(9.0, 3.0, 4.0));
        assert_eq!(matrix4(&Value::Double(1.0)), None);
    }

    #[test]
    fn a_binding_becomes_int3_and_float3_arrays() {
        let b = Binding {
            vertices: vec![[0, 5, 9], [2, 2, 1]],
            weights: vec![[0.5, 0.25, 0.25], [1.0, 0.0, 0.0]],
        };
        let (verts, weights) = binding_values(&b);
        assert_eq!(int3_array(&verts), Some(vec![[0, 5, 9], [2, 2, 1]]));
        assert_eq!(
            vec3_array(&weights),
            Some(vec![Vec3::new(0.5, 0.25, 0.25), Vec3::new(1.0, 0.0, 0.0)])
        );
        assert_eq!(
            (kind_name(&verts).as_str(), kind_name(&weights).as_str()),
            ("int3[]", "float3[]")
        );
    }

    #[test]
    fn kind_names_of_every_vector_precision_and_a_blocked_value() {
        let cases = [
            (Value::Vec3dVec(vec![]), "double3[]"),
            (Value::Vec3iVec(vec![]), "int3[]"),
            (Value::Vec2h(gf::Vec2h::default()), "half2"),
            (Value::Vec4f(gf::Vec4f::default()), "float4"),
            (Value::Matrix4d(gf::Matrix4d([0.0; 16])), "matrix4d"),
            (Value::ValueBlock, "blocked (None)"),
            (Value::AssetPath(Default::default()), "asset"),
            (Value::Token("t".into()), "token"),
        ];
        for (v, want) in cases {
            assert_eq!(kind_name(&v), want, "{v:?}");
        }
    }
}
