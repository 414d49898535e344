//! Value encoding: every `sdf::Value` openusd 0.8 holds, as usd-core's crate
//! writer lays it out (`crateFile.cpp`, `crateValueInliners.h`).
//!
//! A value is described by an 8-byte rep: a type code, three flags (array,
//! inlined, compressed) and a 48-bit payload that is either the value itself
//! (small scalars, table indexes) or the file offset of its bytes. Values are
//! encoded into a buffer whose first byte lands at a known file offset, so a
//! composite value (a dictionary, a list op, time samples) is built whole and
//! written in one go, with no seeking back in the file.
//!
//! Where usd-core and openusd's reader disagree, the choice here is one both
//! read identically: negative `int64` scalars are never inlined (openusd
//! zero-extends inline payloads), and empty `string[]`/`asset[]` arrays are
//! stored as a zero count rather than as payload 0 (openusd reads payload 0
//! as an offset). Float arrays are compressed only when the encoding is
//! bit-exact: usd-core's own float compression folds `-0.0` into `0.0`.

use std::collections::HashMap;

use bytemuck::Pod;
use openusd::gf;
use openusd::sdf::{self, ListOp, Value};

use super::compress::{encode_ints, put_compressed_coded, put_compressed_ints, CodedInt};
use super::dedup::Dedup;
use super::paths::Paths;
use super::tables::{Strings, Tokens};

/// Crate type codes (`crateDataTypes.h`).
pub mod ty {
    pub const BOOL: u8 = 1;
    pub const UCHAR: u8 = 2;
    pub const INT: u8 = 3;
    pub const UINT: u8 = 4;
    pub const INT64: u8 = 5;
    pub const UINT64: u8 = 6;
    pub const HALF: u8 = 7;
    pub const FLOAT: u8 = 8;
    pub const DOUBLE: u8 = 9;
    pub const STRING: u8 = 10;
    pub const TOKEN: u8 = 11;
    pub const ASSET_PATH: u8 = 12;
    pub const MATRIX2D: u8 = 13;
    pub const MATRIX3D: u8 = 14;
    pub const MATRIX4D: u8 = 15;
    pub const QUATD: u8 = 16;
    pub const QUATF: u8 = 17;
    pub const QUATH: u8 = 18;
    pub const VEC2D: u8 = 19;
    pub const VEC2F: u8 = 20;
    pub const VEC2H: u8 = 21;
    pub const VEC2I: u8 = 22;
    pub const VEC3D: u8 = 23;
    pub const VEC3F: u8 = 24;
    pub const VEC3H: u8 = 25;
    pub const VEC3I: u8 = 26;
    pub const VEC4D: u8 = 27;
    pub const VEC4F: u8 = 28;
    pub const VEC4H: u8 = 29;
    pub const VEC4I: u8 = 30;
    pub const DICTIONARY: u8 = 31;
    pub const TOKEN_LIST_OP: u8 = 32;
    pub const STRING_LIST_OP: u8 = 33;
    pub const PATH_LIST_OP: u8 = 34;
    pub const REFERENCE_LIST_OP: u8 = 35;
    pub const INT_LIST_OP: u8 = 36;
    pub const INT64_LIST_OP: u8 = 37;
    pub const UINT_LIST_OP: u8 = 38;
    pub const UINT64_LIST_OP: u8 = 39;
    pub const PATH_VECTOR: u8 = 40;
    pub const TOKEN_VECTOR: u8 = 41;
    pub const SPECIFIER: u8 = 42;
    pub const PERMISSION: u8 = 43;
    pub const VARIABILITY: u8 = 44;
    pub const VARIANT_SELECTION_MAP: u8 = 45;
    pub const TIME_SAMPLES: u8 = 46;
    pub const PAYLOAD: u8 = 47;
    pub const DOUBLE_VECTOR: u8 = 48;
    pub const LAYER_OFFSET_VECTOR: u8 = 49;
    pub const STRING_VECTOR: u8 = 50;
    pub const VALUE_BLOCK: u8 = 51;
    pub const VALUE: u8 = 52;
    pub const UNREGISTERED_VALUE: u8 = 53;
    pub const UNREGISTERED_VALUE_LIST_OP: u8 = 54;
    pub const PAYLOAD_LIST_OP: u8 = 55;
    pub const TIME_CODE: u8 = 56;
    pub const PATH_EXPRESSION: u8 = 57;
    pub const RELOCATES: u8 = 58;
}

const ARRAY: u64 = 1 << 63;
const INLINED: u64 = 1 << 62;
const COMPRESSED: u64 = 1 << 61;
const PAYLOAD_MASK: u64 = (1 << 48) - 1;

/// How deep values may nest (a dictionary in a dictionary...): openusd's
/// reader refuses deeper files (`openusd::usdc::MAX_NESTING`).
const MAX_NESTING: usize = 32;

/// Arrays shorter than this are never compressed (usd-core's
/// `MinCompressedArraySize`; both readers treat them as raw).
const MIN_COMPRESSED: usize = 16;

/// Crate minor versions (major 0, patch 0). 0.8.0 is what usd-core 26.11
/// writes for content that needs nothing newer; see the module docs of
/// [`super`] for what needs which.
pub const BASE_MINOR: u8 = 8;
const TIMECODE_MINOR: u8 = 9;
const PATH_EXPRESSION_MINOR: u8 = 10;
const RELOCATES_MINOR: u8 = 11;

fn rep(ty: u8, flags: u64, payload: u64) -> u64 {
    flags | ((ty as u64) << 48) | (payload & PAYLOAD_MASK)
}

fn inline(ty: u8, bits: u32) -> u64 {
    rep(ty, INLINED, bits as u64)
}

/// Bytes being encoded, the first of which goes to file offset `base`.
pub struct Buf {
    pub base: u64,
    pub bytes: Vec<u8>,
}

impl Buf {
    fn pos(&self) -> u64 {
        self.base + self.bytes.len() as u64
    }
    fn put<T: Pod>(&mut self, v: &T) {
        self.bytes.extend_from_slice(bytemuck::bytes_of(v));
    }
    fn put_slice<T: Pod>(&mut self, v: &[T]) {
        self.bytes.extend_from_slice(bytemuck::cast_slice(v));
    }
    fn count(&mut self, n: usize) {
        self.put(&(n as u64));
    }
    fn align8(&mut self) {
        while !self.pos().is_multiple_of(8) {
            self.bytes.push(0);
        }
    }
}

/// The tables values refer to, the dedup table and the version the content
/// needs so far.
pub struct Encoder {
    pub tokens: Tokens,
    pub strings: Strings,
    pub paths: Paths,
    pub minor: u8,
    dedup: Dedup,
    depth: usize,
}

type Res<T> = Result<T, String>;

impl Encoder {
    pub fn new() -> Encoder {
        let mut tokens = Tokens::new();
        let paths = Paths::new(&mut tokens);
        Encoder {
            tokens,
            strings: Strings::default(),
            paths,
            minor: BASE_MINOR,
            dedup: Dedup::default(),
            depth: 0,
        }
    }

    fn need(&mut self, minor: u8) {
        self.minor = self.minor.max(minor);
    }

    fn string(&mut self, s: &str) -> u32 {
        self.strings.intern(s, &mut self.tokens)
    }

    fn token(&mut self, s: &str) -> u32 {
        self.tokens.intern(s)
    }

    fn path(&mut self, p: &sdf::Path) -> Res<u32> {
        self.paths.intern(p.as_str(), &mut self.tokens)
    }

    /// The rep of a field's value. The field decides between usd-core's
    /// `TfTokenVector`/`std::vector<std::string>` and `token[]`/`string[]`,
    /// which openusd reads into one variant each.
    pub fn field(&mut self, buf: &mut Buf, name: &str, v: &Value) -> Res<u64> {
        if sdf::is_vector_field(name) {
            match v {
                Value::TokenVec(items) => {
                    return self.stored(buf, ty::TOKEN_VECTOR, 0, false, |e, b| {
                        e.token_list(b, items);
                        Ok(0)
                    })
                }
                Value::StringVec(items) => {
                    return self.stored(buf, ty::STRING_VECTOR, 0, false, |e, b| {
                        e.string_list(b, items);
                        Ok(0)
                    })
                }
                _ => {}
            }
        }
        self.value(buf, v)
    }

    /// Writes `body` (unless an identical value is already stored) and
    /// returns the rep addressing it. `body` returns extra flags (the
    /// compressed bit).
    fn stored(
        &mut self,
        buf: &mut Buf,
        ty: u8,
        flags: u64,
        align: bool,
        body: impl FnOnce(&mut Self, &mut Buf) -> Res<u64>,
    ) -> Res<u64> {
        let before = buf.bytes.len();
        if align {
            buf.align8();
        }
        let start = buf.bytes.len();
        let extra = body(self, buf)?;
        let flags = flags | extra;
        let kind = ((flags >> 61) as u16) << 8 | ty as u16;
        let (found, fingerprint) = self.dedup.find(kind, &buf.bytes[start..]);
        if let Some(r) = found {
            buf.bytes.truncate(before);
            return Ok(r);
        }
        let r = rep(ty, flags, buf.base + start as u64);
        self.dedup.insert(kind, buf.bytes.len() - start, fingerprint, r);
        Ok(r)
    }

    /// The rep of a value copied from another crate file as it was stored
    /// there ([`super::recover`]); the file needs that file's version.
    pub fn raw(&mut self, buf: &mut Buf, v: &super::recover::RawValue) -> Res<u64> {
        self.need(v.minor);
        if v.bytes.is_empty() {
            return Ok(v.rep);
        }
        buf.align8();
        let at = buf.pos();
        buf.bytes.extend_from_slice(&v.bytes);
        Ok((v.rep & !PAYLOAD_MASK) | at)
    }

    /// The rep of `v`, writing its bytes into `buf` when it is not inlined.
    pub fn value(&mut self, buf: &mut Buf, v: &Value) -> Res<u64> {
        Ok(match v {
            Value::None => return Err("an empty value (none) has no file representation".into()),
            Value::Opaque => return Err("an opaque value is never written".into()),
            Value::ValueVec(_) => {
                return Err("a heterogeneous value array (spline knots) has no crate representation".into())
            }
            Value::ValueBlock => inline(ty::VALUE_BLOCK, 0),
            Value::Value => inline(ty::VALUE, 0),

            Value::Bool(b) => inline(ty::BOOL, *b as u32),
            Value::Uchar(x) => inline(ty::UCHAR, *x as u32),
            Value::Int(x) => inline(ty::INT, *x as u32),
            Value::Uint(x) => inline(ty::UINT, *x),
            Value::Half(x) => inline(ty::HALF, x.to_bits() as u32),
            Value::Float(x) => inline(ty::FLOAT, x.to_bits()),
            Value::Int64(x) => match u32::try_from(*x) {
                // Only non-negative values: openusd zero-extends the payload.
                Ok(small) if *x <= i32::MAX as i64 => inline(ty::INT64, small),
                _ => self.scalar(buf, ty::INT64, x)?,
            },
            Value::Uint64(x) => match u32::try_from(*x) {
                Ok(small) => inline(ty::UINT64, small),
                Err(_) => self.scalar(buf, ty::UINT64, x)?,
            },
            Value::Double(x) => match exact_f32(*x) {
                Some(f) => inline(ty::DOUBLE, f.to_bits()),
                None => self.scalar(buf, ty::DOUBLE, x)?,
            },
            Value::TimeCode(t) => {
                self.need(TIMECODE_MINOR);
                self.scalar(buf, ty::TIME_CODE, &t.0)?
            }

            Value::String(s) => {
                let i = self.string(s);
                inline(ty::STRING, i)
            }
            Value::Token(t) => {
                let i = self.token(t.as_str());
                inline(ty::TOKEN, i)
            }
            Value::AssetPath(a) => {
                let i = self.token(&a.authored_path);
                inline(ty::ASSET_PATH, i)
            }
            Value::PathExpression(e) => {
                self.need(PATH_EXPRESSION_MINOR);
                let i = self.string(&e.to_string());
                self.scalar(buf, ty::PATH_EXPRESSION, &i)?
            }

            Value::Vec2h(x) => inline(ty::VEC2H, u32::from_le_bytes(bytemuck::cast(*x))),
            Value::Vec3h(x) => self.small_vec(buf, ty::VEC3H, &[x.x, x.y, x.z].map(|c| c.to_f64()), x)?,
            Value::Vec4h(x) => self.small_vec(buf, ty::VEC4H, &[x.x, x.y, x.z, x.w].map(|c| c.to_f64()), x)?,
            Value::Vec2f(x) => self.small_vec(buf, ty::VEC2F, &[x.x, x.y].map(f64::from), x)?,
            Value::Vec3f(x) => self.small_vec(buf, ty::VEC3F, &[x.x, x.y, x.z].map(f64::from), x)?,
            Value::Vec4f(x) => self.small_vec(buf, ty::VEC4F, &[x.x, x.y, x.z, x.w].map(f64::from), x)?,
            Value::Vec2d(x) => self.small_vec(buf, ty::VEC2D, &[x.x, x.y], x)?,
            Value::Vec3d(x) => self.small_vec(buf, ty::VEC3D, &[x.x, x.y, x.z], x)?,
            Value::Vec4d(x) => self.small_vec(buf, ty::VEC4D, &[x.x, x.y, x.z, x.w], x)?,
            Value::Vec2i(x) => self.small_vec(buf, ty::VEC2I, &[x.x, x.y].map(f64::from), x)?,
            Value::Vec3i(x) => self.small_vec(buf, ty::VEC3I, &[x.x, x.y, x.z].map(f64::from), x)?,
            Value::Vec4i(x) => self.small_vec(buf, ty::VEC4I, &[x.x, x.y, x.z, x.w].map(f64::from), x)?,
            Value::Matrix2d(m) => self.matrix(buf, ty::MATRIX2D, 2, &m.0)?,
            Value::Matrix3d(m) => self.matrix(buf, ty::MATRIX3D, 3, &m.0)?,
            Value::Matrix4d(m) => self.matrix(buf, ty::MATRIX4D, 4, &m.0)?,
            Value::Quath(q) => self.scalar(buf, ty::QUATH, &quat_xyzw_h(q))?,
            Value::Quatf(q) => self.scalar(buf, ty::QUATF, &[q.x, q.y, q.z, q.w])?,
            Value::Quatd(q) => self.scalar(buf, ty::QUATD, &[q.x, q.y, q.z, q.w])?,

            Value::Specifier(s) => inline(ty::SPECIFIER, *s as i32 as u32),
            Value::Permission(p) => inline(ty::PERMISSION, *p as i32 as u32),
            Value::Variability(x) => inline(ty::VARIABILITY, *x as i32 as u32),

            // Arrays.
            Value::BoolVec(v) => {
                let bytes: Vec<u8> = v.iter().map(|&b| b as u8).collect();
                self.raw_array(buf, ty::BOOL, &bytes)?
            }
            Value::UcharVec(v) => self.raw_array(buf, ty::UCHAR, v)?,
            Value::IntVec(v) => self.int_array(buf, ty::INT, v)?,
            Value::UintVec(v) => self.int_array(buf, ty::UINT, v)?,
            Value::Int64Vec(v) => self.int_array(buf, ty::INT64, v)?,
            Value::Uint64Vec(v) => self.int_array(buf, ty::UINT64, v)?,
            Value::HalfVec(v) => self.float_array(buf, ty::HALF, v)?,
            Value::FloatVec(v) => self.float_array(buf, ty::FLOAT, v)?,
            Value::DoubleVec(v) => self.float_array(buf, ty::DOUBLE, v)?,
            Value::TimeCodeVec(v) => {
                self.need(TIMECODE_MINOR);
                let raw: Vec<f64> = v.iter().map(|t| t.0).collect();
                self.raw_array(buf, ty::TIME_CODE, &raw)?
            }
            Value::StringVec(v) => self.indexed_array(buf, ty::STRING, v, |e, s| e.string(s))?,
            Value::TokenVec(v) => self.indexed_array(buf, ty::TOKEN, v, |e, t| e.token(t.as_str()))?,
            Value::AssetPathVec(v) => self.indexed_array(buf, ty::ASSET_PATH, v, |e, a| e.string(&a.authored_path))?,
            Value::PathExpressionVec(v) => {
                self.need(PATH_EXPRESSION_MINOR);
                self.indexed_array(buf, ty::PATH_EXPRESSION, v, |e, x| e.string(&x.to_string()))?
            }
            Value::Vec2hVec(v) => self.raw_array(buf, ty::VEC2H, v)?,
            Value::Vec3hVec(v) => self.raw_array(buf, ty::VEC3H, v)?,
            Value::Vec4hVec(v) => self.raw_array(buf, ty::VEC4H, v)?,
            Value::Vec2fVec(v) => self.raw_array(buf, ty::VEC2F, v)?,
            Value::Vec3fVec(v) => self.raw_array(buf, ty::VEC3F, v)?,
            Value::Vec4fVec(v) => self.raw_array(buf, ty::VEC4F, v)?,
            Value::Vec2dVec(v) => self.raw_array(buf, ty::VEC2D, v)?,
            Value::Vec3dVec(v) => self.raw_array(buf, ty::VEC3D, v)?,
            Value::Vec4dVec(v) => self.raw_array(buf, ty::VEC4D, v)?,
            Value::Vec2iVec(v) => self.raw_array(buf, ty::VEC2I, v)?,
            Value::Vec3iVec(v) => self.raw_array(buf, ty::VEC3I, v)?,
            Value::Vec4iVec(v) => self.raw_array(buf, ty::VEC4I, v)?,
            Value::Matrix2dVec(v) => self.raw_array(buf, ty::MATRIX2D, v)?,
            Value::Matrix3dVec(v) => self.raw_array(buf, ty::MATRIX3D, v)?,
            Value::Matrix4dVec(v) => self.raw_array(buf, ty::MATRIX4D, v)?,
            // openusd holds quaternions as (w, x, y, z); GfQuat stores (x, y, z, w).
            Value::QuathVec(v) => {
                let raw: Vec<[gf::f16; 4]> = v.iter().map(quat_xyzw_h).collect();
                self.raw_array(buf, ty::QUATH, &raw)?
            }
            Value::QuatfVec(v) => {
                let raw: Vec<[f32; 4]> = v.iter().map(|q| [q.x, q.y, q.z, q.w]).collect();
                self.raw_array(buf, ty::QUATF, &raw)?
            }
            Value::QuatdVec(v) => {
                let raw: Vec<[f64; 4]> = v.iter().map(|q| [q.x, q.y, q.z, q.w]).collect();
                self.raw_array(buf, ty::QUATD, &raw)?
            }

            // Composite values.
            Value::Dictionary(d) if d.is_empty() => inline(ty::DICTIONARY, 0),
            Value::Dictionary(d) => self.stored(buf, ty::DICTIONARY, 0, false, |e, b| {
                e.dictionary(b, d)?;
                Ok(0)
            })?,
            Value::UnregisteredValue(s) => self.stored(buf, ty::UNREGISTERED_VALUE, 0, false, |e, b| {
                e.nested(b, &Value::String(s.clone()))?;
                Ok(0)
            })?,
            Value::UnregisteredDictionary(d) => self.stored(buf, ty::UNREGISTERED_VALUE, 0, false, |e, b| {
                e.nested_with(b, |e, b| {
                    if d.is_empty() {
                        Ok(inline(ty::DICTIONARY, 0))
                    } else {
                        e.stored(b, ty::DICTIONARY, 0, false, |e, b| {
                            e.dictionary(b, d)?;
                            Ok(0)
                        })
                    }
                })?;
                Ok(0)
            })?,
            Value::UnregisteredValueListOp(op) => self.stored(buf, ty::UNREGISTERED_VALUE, 0, false, |e, b| {
                e.nested_with(b, |e, b| {
                    e.list_op(b, ty::UNREGISTERED_VALUE_LIST_OP, op, |e, b, s| {
                        e.nested(b, &Value::String(s.clone()))
                    })
                })?;
                Ok(0)
            })?,
            Value::TokenListOp(op) => self.list_op(buf, ty::TOKEN_LIST_OP, op, |e, b, t| {
                let i = e.token(t.as_str());
                b.put(&i);
                Ok(())
            })?,
            Value::StringListOp(op) => self.list_op(buf, ty::STRING_LIST_OP, op, |e, b, s| {
                let i = e.string(s);
                b.put(&i);
                Ok(())
            })?,
            Value::PathListOp(op) => self.list_op(buf, ty::PATH_LIST_OP, op, |e, b, p| {
                let i = e.path(p)?;
                b.put(&i);
                Ok(())
            })?,
            Value::ReferenceListOp(op) => self.list_op(buf, ty::REFERENCE_LIST_OP, op, |e, b, r| {
                let asset = e.string(&r.asset_path);
                let prim = e.path(&r.prim_path)?;
                b.put(&asset);
                b.put(&prim);
                b.put(&[r.layer_offset.offset, r.layer_offset.scale]);
                e.dictionary(b, &r.custom_data)
            })?,
            Value::PayloadListOp(op) => self.list_op(buf, ty::PAYLOAD_LIST_OP, op, |e, b, p| e.payload(b, p))?,
            Value::IntListOp(op) => self.list_op(buf, ty::INT_LIST_OP, op, |_, b, x| {
                b.put(x);
                Ok(())
            })?,
            Value::UIntListOp(op) => self.list_op(buf, ty::UINT_LIST_OP, op, |_, b, x| {
                b.put(x);
                Ok(())
            })?,
            Value::Int64ListOp(op) => self.list_op(buf, ty::INT64_LIST_OP, op, |_, b, x| {
                b.put(x);
                Ok(())
            })?,
            Value::UInt64ListOp(op) => self.list_op(buf, ty::UINT64_LIST_OP, op, |_, b, x| {
                b.put(x);
                Ok(())
            })?,
            Value::Payload(p) => self.stored(buf, ty::PAYLOAD, 0, false, |e, b| {
                e.payload(b, p)?;
                Ok(0)
            })?,
            Value::PathVec(v) => self.stored(buf, ty::PATH_VECTOR, 0, false, |e, b| {
                b.count(v.len());
                for p in v {
                    let i = e.path(p)?;
                    b.put(&i);
                }
                Ok(0)
            })?,
            Value::LayerOffsetVec(v) => self.stored(buf, ty::LAYER_OFFSET_VECTOR, 0, false, |_, b| {
                b.count(v.len());
                for o in v {
                    b.put(&[o.offset, o.scale]);
                }
                Ok(0)
            })?,
            Value::VariantSelectionMap(m) => self.stored(buf, ty::VARIANT_SELECTION_MAP, 0, false, |e, b| {
                let mut keys: Vec<&String> = m.keys().collect();
                keys.sort();
                b.count(keys.len());
                for k in keys {
                    let (ki, vi) = (e.string(k), e.string(&m[k]));
                    b.put(&ki);
                    b.put(&vi);
                }
                Ok(0)
            })?,
            Value::Relocates(v) => {
                self.need(RELOCATES_MINOR);
                self.stored(buf, ty::RELOCATES, 0, false, |e, b| {
                    b.count(v.len());
                    for (src, dst) in v {
                        let (s, d) = (e.path(src)?, e.path(dst)?);
                        b.put(&s);
                        b.put(&d);
                    }
                    Ok(0)
                })?
            }
            Value::TimeSamples(samples) => {
                let mut times = Vec::with_capacity(samples.len());
                let mut reps = Vec::with_capacity(samples.len());
                for (t, v) in samples {
                    times.push(*t);
                    reps.push(self.nested_value(buf, v)?);
                }
                self.time_samples(buf, &times, &reps)?
            }
        })
    }

    /// A value nested in another (a time sample): one level deeper.
    fn nested_value(&mut self, buf: &mut Buf, v: &Value) -> Res<u64> {
        if self.depth >= MAX_NESTING {
            return Err(format!("values nested more than {MAX_NESTING} deep"));
        }
        self.depth += 1;
        let r = self.value(buf, v);
        self.depth -= 1;
        r
    }

    /// Time samples whose values are already stored: the times (a
    /// `std::vector<double>`, shared by every attribute sampled at the same
    /// times), then a jump to the times' rep, a jump to the values, the
    /// count and the value reps.
    pub fn time_samples(&mut self, buf: &mut Buf, times: &[f64], reps: &[u64]) -> Res<u64> {
        let times_rep = self.stored(buf, ty::DOUBLE_VECTOR, 0, false, |_, b| {
            b.count(times.len());
            b.put_slice(times);
            Ok(0)
        })?;
        self.stored(buf, ty::TIME_SAMPLES, 0, false, |_, b| {
            b.put(&8i64);
            b.put(&times_rep);
            b.put(&8i64);
            b.count(reps.len());
            b.put_slice(reps);
            Ok(0)
        })
    }

    /// A scalar stored out of line as its raw bytes.
    fn scalar<T: Pod>(&mut self, buf: &mut Buf, ty: u8, v: &T) -> Res<u64> {
        self.stored(buf, ty, 0, false, |_, b| {
            b.put(v);
            Ok(0)
        })
    }

    /// A vector inlined as 8-bit integers when every component is one
    /// (`(0, 1, 0)`), else stored raw.
    fn small_vec<T: Pod>(&mut self, buf: &mut Buf, ty: u8, comps: &[f64], raw: &T) -> Res<u64> {
        match small_ints(comps) {
            Some(bits) => Ok(inline(ty, bits)),
            None => self.scalar(buf, ty, raw),
        }
    }

    /// A matrix inlined as its 8-bit-integer diagonal when it is diagonal
    /// with such entries (identity), else stored raw (row-major).
    fn matrix(&mut self, buf: &mut Buf, ty: u8, n: usize, m: &[f64]) -> Res<u64> {
        // +0.0 only: an inlined matrix reads back with +0.0 off the diagonal.
        let off_diagonal_zero = (0..n).all(|i| (0..n).all(|j| i == j || m[i * n + j].to_bits() == 0));
        let diag: Vec<f64> = (0..n).map(|i| m[i * n + i]).collect();
        match small_ints(&diag).filter(|_| off_diagonal_zero) {
            Some(bits) => Ok(inline(ty, bits)),
            None => self.stored(buf, ty, 0, false, |_, b| {
                b.put_slice(m);
                Ok(0)
            }),
        }
    }

    /// An array of plain elements: the count and the elements, 8-byte
    /// aligned (usd-core maps such arrays straight from the file).
    fn raw_array<T: Pod>(&mut self, buf: &mut Buf, ty: u8, v: &[T]) -> Res<u64> {
        if v.is_empty() {
            return Ok(rep(ty, ARRAY, 0));
        }
        self.stored(buf, ty, ARRAY, true, |_, b| {
            b.count(v.len());
            b.put_slice(v);
            Ok(0)
        })
    }

    /// An array of table indexes (strings, tokens). Empty arrays are stored
    /// as a zero count: openusd reads a `string[]` rep's payload as an offset
    /// even when it is 0.
    fn indexed_array<T>(&mut self, buf: &mut Buf, ty: u8, v: &[T], index: impl Fn(&mut Self, &T) -> u32) -> Res<u64> {
        self.stored(buf, ty, ARRAY, true, |e, b| {
            b.count(v.len());
            for x in v {
                let i = index(e, x);
                b.put(&i);
            }
            Ok(0)
        })
    }

    /// An integer array: raw below 16 elements, else integer-coded and LZ4
    /// compressed.
    fn int_array<T: Pod + CodedInt>(&mut self, buf: &mut Buf, ty: u8, v: &[T]) -> Res<u64> {
        if v.is_empty() {
            return Ok(rep(ty, ARRAY, 0));
        }
        self.stored(buf, ty, ARRAY, false, |_, b| {
            b.count(v.len());
            if v.len() < MIN_COMPRESSED {
                b.put_slice(v);
                return Ok(0);
            }
            let coded = encode_ints(v);
            // openusd sizes its decoding buffer for 32-bit codes whatever the
            // width; a 64-bit coding longer than that is stored raw instead.
            let openusd_limit = 4 + (v.len() * 2).div_ceil(8) + 4 * v.len();
            if T::BYTES == 8 && coded.len() > openusd_limit {
                b.put_slice(v);
                return Ok(0);
            }
            put_compressed_coded(&coded, &mut b.bytes);
            Ok(COMPRESSED)
        })
    }

    /// A `half[]`, `float[]` or `double[]`: from 16 elements, stored as
    /// integers when every element is one ('i'), or as a lookup table and
    /// indexes when there are at most `n/4` (and 1024) distinct values ('t');
    /// else raw. Only bit-exact encodings are used.
    fn float_array<T: Pod + FloatBits>(&mut self, buf: &mut Buf, ty: u8, v: &[T]) -> Res<u64> {
        if v.is_empty() {
            return Ok(rep(ty, ARRAY, 0));
        }
        if v.len() >= MIN_COMPRESSED {
            if let Some(ints) = v.iter().map(|x| x.exact_i32()).collect::<Option<Vec<i32>>>() {
                return self.stored(buf, ty, ARRAY, false, |_, b| {
                    b.count(v.len());
                    b.bytes.push(b'i');
                    put_compressed_ints(&ints, &mut b.bytes);
                    Ok(COMPRESSED)
                });
            }
            let max_lut = (v.len() / 4).min(1024);
            let mut lut: Vec<T> = Vec::new();
            let mut lut_index: HashMap<u64, u32> = HashMap::new();
            let mut indexes: Vec<u32> = Vec::with_capacity(v.len());
            for x in v {
                let next = lut.len() as u32;
                let i = *lut_index.entry(x.bits()).or_insert(next);
                if i == next {
                    if lut.len() == max_lut {
                        lut.clear();
                        break;
                    }
                    lut.push(*x);
                }
                indexes.push(i);
            }
            if !lut.is_empty() {
                return self.stored(buf, ty, ARRAY, false, |_, b| {
                    b.count(v.len());
                    b.bytes.push(b't');
                    b.put(&(lut.len() as u32));
                    b.put_slice(&lut);
                    put_compressed_ints(&indexes, &mut b.bytes);
                    Ok(COMPRESSED)
                });
            }
        }
        self.raw_array(buf, ty, v)
    }

    fn token_list(&mut self, b: &mut Buf, items: &[openusd::tf::Token]) {
        b.count(items.len());
        for t in items {
            let i = self.token(t.as_str());
            b.put(&i);
        }
    }

    fn string_list(&mut self, b: &mut Buf, items: &[String]) {
        b.count(items.len());
        for s in items {
            let i = self.string(s);
            b.put(&i);
        }
    }

    /// A dictionary's body: the count, then per key (sorted, as VtDictionary
    /// is) its string index and the value nested.
    fn dictionary(&mut self, b: &mut Buf, d: &HashMap<String, Value>) -> Res<()> {
        let mut keys: Vec<&String> = d.keys().collect();
        keys.sort();
        b.count(keys.len());
        for k in keys {
            let i = self.string(k);
            b.put(&i);
            self.nested(b, &d[k])
                .map_err(|e| format!("in dictionary entry `{k}`: {e}"))?;
        }
        Ok(())
    }

    /// A nested value (usd-core's `Write(VtValue)`): a jump over whatever the
    /// value stores, then its rep.
    fn nested(&mut self, b: &mut Buf, v: &Value) -> Res<()> {
        self.nested_with(b, |e, b| e.value(b, v))
    }

    fn nested_with(&mut self, b: &mut Buf, write: impl FnOnce(&mut Self, &mut Buf) -> Res<u64>) -> Res<()> {
        if self.depth >= MAX_NESTING {
            return Err(format!("values nested more than {MAX_NESTING} deep"));
        }
        let slot = b.bytes.len();
        b.put(&0i64);
        self.depth += 1;
        let r = write(self, b);
        self.depth -= 1;
        let r = r?;
        let jump = (b.bytes.len() - slot) as i64;
        b.bytes[slot..slot + 8].copy_from_slice(&jump.to_le_bytes());
        b.put(&r);
        Ok(())
    }

    fn payload(&mut self, b: &mut Buf, p: &sdf::Payload) -> Res<()> {
        let asset = self.string(&p.asset_path);
        let prim = self.path(&p.prim_path)?;
        b.put(&asset);
        b.put(&prim);
        // Crate 0.8.0 and newer always store the layer offset.
        b.put(&[p.layer_offset.offset, p.layer_offset.scale]);
        Ok(())
    }

    /// A list op: a header byte saying which lists follow, then each
    /// non-empty list (explicit, added, prepended, appended, deleted,
    /// ordered) as a count and its items.
    fn list_op<T: Default + Clone + PartialEq>(
        &mut self,
        buf: &mut Buf,
        ty: u8,
        op: &ListOp<T>,
        mut item: impl FnMut(&mut Self, &mut Buf, &T) -> Res<()>,
    ) -> Res<u64> {
        self.stored(buf, ty, 0, false, |e, b| {
            let lists = [
                (&op.explicit_items, 1u8 << 1),
                (&op.added_items, 1 << 2),
                (&op.prepended_items, 1 << 5),
                (&op.appended_items, 1 << 6),
                (&op.deleted_items, 1 << 3),
                (&op.ordered_items, 1 << 4),
            ];
            let mut header = op.explicit as u8;
            for (items, bit) in &lists {
                if !items.is_empty() {
                    header |= bit;
                }
            }
            b.put(&header);
            for (items, _) in lists {
                if !items.is_empty() {
                    b.count(items.len());
                    for x in items {
                        item(e, b, x)?;
                    }
                }
            }
            Ok(0)
        })
    }
}

/// GfQuath's layout: imaginary part, then real.
fn quat_xyzw_h(q: &gf::Quath) -> [gf::f16; 4] {
    [q.x, q.y, q.z, q.w]
}

/// `x` as an f32 when that is exact (usd-core inlines such doubles).
fn exact_f32(x: f64) -> Option<f32> {
    let f = x as f32;
    (x.is_finite() && f as f64 == x).then_some(f)
}

/// Components packed as 8-bit integers, when each one is exactly one.
fn small_ints(comps: &[f64]) -> Option<u32> {
    let mut bytes = [0u8; 4];
    for (i, &c) in comps.iter().enumerate() {
        // -0.0 is not an integer here: it would read back as +0.0.
        if c.fract() != 0.0 || !(-128.0..=127.0).contains(&c) || (c == 0.0 && c.is_sign_negative()) {
            return None;
        }
        bytes[i] = c as i8 as u8;
    }
    Some(u32::from_le_bytes(bytes))
}

/// Floating-point elements for the float-array compressions.
pub trait FloatBits: Copy {
    /// The element as an i32 when converting back gives the same bits.
    fn exact_i32(self) -> Option<i32>;
    fn bits(self) -> u64;
}

impl FloatBits for f32 {
    fn exact_i32(self) -> Option<i32> {
        let i = self as i32;
        (self.fract() == 0.0 && (i as f32).to_bits() == self.to_bits()).then_some(i)
    }
    fn bits(self) -> u64 {
        self.to_bits() as u64
    }
}

impl FloatBits for f64 {
    fn exact_i32(self) -> Option<i32> {
        let i = self as i32;
        (self.fract() == 0.0 && (i as f64).to_bits() == self.to_bits()).then_some(i)
    }
    fn bits(self) -> u64 {
        self.to_bits()
    }
}

impl FloatBits for gf::f16 {
    fn exact_i32(self) -> Option<i32> {
        let f = self.to_f32();
        let i = f as i32;
        (f.fract() == 0.0 && gf::f16::from_f32(i as f32).to_bits() == self.to_bits()).then_some(i)
    }
    fn bits(self) -> u64 {
        self.to_bits() as u64
    }
}
