//! One attribute's time samples read one sample at a time, straight from the
//! crate (`.usdc`) file that authors them.
//!
//! openusd 0.8 decodes every sample of an attribute on its first timed read
//! (and again to list its sample times), then copies the whole map into its
//! query cache. For a point cache of 240 × 50,000 points that is 144 MB
//! decoded and copied twice before the first frame, though a frame needs at
//! most two samples. Here the sample times and each sample's value
//! representation are read once from the file's time-sample table, and a
//! frame decodes only the samples that bracket it, with openusd's own crate
//! decoder ([`CrateFile::value`]).
//!
//! Used only where it gives exactly what openusd's value resolution gives:
//! the strongest opinion is `timeSamples` (not a default, not value clips) in
//! a crate file on disk, sorted with distinct times, of `point3f[]`-like
//! arrays; the stage time goes through the same layer offset and the same
//! linear interpolation with the same arithmetic as openusd's
//! `AttributeQuery` (tests compare the two bit for bit). Everything else
//! returns `None` and the caller reads through openusd as before.

use std::path::Path;

use openusd::gf;
use openusd::sdf::{self, LayerOffset, Value};
use openusd::usd::{self, InterpolationType};
use openusd::usdc::CrateFile;

/// The crate type code of a time-sample map (USD's `TypeEnum::TimeSamples`).
const TYPE_TIME_SAMPLES: u64 = 46;
/// Bits of a crate value representation (USD's `ValueRep`).
const INLINED_BIT: u64 = 1 << 62;
const COMPRESSED_BIT: u64 = 1 << 61;
const PAYLOAD_MASK: u64 = (1 << 48) - 1;

/// Time samples of one attribute, decoded per read.
pub struct CrateSamples {
    file: CrateFile,
    /// Sample times in the authoring layer's time, strictly ascending.
    times: Vec<f64>,
    /// Each sample's value representation in `file`.
    reps: Vec<u64>,
    /// Authoring layer → stage time.
    offset: LayerOffset,
}

impl CrateSamples {
    /// The samples of `prim.name` when they can be read lazily (see the module
    /// documentation); `None` otherwise, including on any doubt about the
    /// file, in which case openusd reads (and reports) as usual.
    pub fn open(stage: &usd::Stage, prim: &usd::Prim, name: &str) -> Option<Self> {
        let site = winning_time_samples(stage, prim, name)?;
        let path = Path::new(&site.layer);
        if !path.is_file() {
            return None;
        }
        let file = map_crate(path)?;
        let (times, reps) = time_sample_table(&file, &site.path)?;
        // openusd orders and de-duplicates unsorted maps; such a file is left to it.
        if times.is_empty() || !times.windows(2).all(|w| sdf::compare_sample_times(w[0], w[1]).is_lt()) {
            return None;
        }
        // painterly's stages interpolate linearly (openusd's default); a held
        // stage would be openusd's to read.
        if stage.interpolation_type() != InterpolationType::Linear {
            return None;
        }
        let samples = CrateSamples {
            file,
            times,
            reps,
            offset: site.offset,
        };
        // Only arrays of float 3-vectors are interpolated here.
        match samples.decode(0)? {
            Value::Vec3fVec(_) => Some(samples),
            _ => None,
        }
    }

    /// The authored sample times, in stage time.
    pub fn stage_times(&self) -> Vec<f64> {
        self.times.iter().map(|&t| self.offset.apply(t)).collect()
    }

    /// The value at stage time `time`, as [`StageReader::value`] resolves it
    /// (`None` where a blocked sample withholds it); an error names what
    /// could not be decoded.
    pub fn value_at(&self, time: f64) -> Result<Option<Value>, String> {
        let lt = self.offset.inverse().apply(time);
        let decode = |i: usize| self.decode(i).ok_or_else(|| format!("cannot decode time sample {i}"));
        let last = self.times.len() - 1;
        let clean = |v: Value| (!matches!(v, Value::ValueBlock | Value::None)).then_some(v);
        if sdf::compare_sample_times(lt, self.times[0]).is_le() {
            return Ok(clean(decode(0)?));
        }
        if sdf::compare_sample_times(lt, self.times[last]).is_ge() {
            return Ok(clean(decode(last)?));
        }
        let (lo, hi) = match self.times.binary_search_by(|t| sdf::compare_sample_times(*t, lt)) {
            Ok(i) => return Ok(clean(decode(i)?)),
            Err(i) => (i - 1, i),
        };
        let (v_lo, v_hi) = (decode(lo)?, decode(hi)?);
        let u = (lt - self.times[lo]) / (self.times[hi] - self.times[lo]);
        Ok(match (v_lo, v_hi) {
            // A block withholds values from its time to the next sample; the
            // sample before a block holds up to it (usd-core; openusd 0.8
            // withholds it, and `StageReader::value` corrects that).
            (Value::ValueBlock | Value::None, _) => None,
            (a, Value::ValueBlock | Value::None) => Some(a),
            (Value::Vec3fVec(a), Value::Vec3fVec(b)) if a.len() == b.len() => {
                let u = u as f32;
                Some(Value::Vec3fVec(
                    a.iter().zip(&b).map(|(x, y)| gf::Vec3f::lerp(*x, *y, u)).collect(),
                ))
            }
            // Mismatched lengths or kinds hold the lower sample, as openusd does.
            (a, _) => Some(a),
        })
    }

    fn decode(&self, i: usize) -> Option<Value> {
        // openusd's `ValueRep` cannot be named here (its module is private):
        // copy one out of the file's fields and set its bits.
        let mut rep = self.file.fields.first()?.value_rep;
        rep.0 = self.reps[i];
        self.file.value(rep).ok()
    }
}

/// The spec whose `timeSamples` answer for `prim.name` at every time, found
/// as USD's value resolution finds it (strongest first, the first spec with
/// `timeSamples` or a `default` wins) but without reading either field:
/// openusd's own resolve info decodes every sample. `None` when a default
/// wins, nothing is authored, or value clips may apply (`clips` on the prim
/// or an ancestor), which openusd resolves per time.
fn winning_time_samples(stage: &usd::Stage, prim: &usd::Prim, name: &str) -> Option<usd::SpecSite> {
    let mut p = Some(prim.clone());
    while let Some(q) = p {
        if q.get_metadata::<Value>("clips").ok()?.is_some() || q.get_metadata::<Value>("clipSets").ok()?.is_some() {
            return None;
        }
        p = q.parent();
    }
    strongest_samples_site(stage, prim, name, |data, path| data.has_field(path, "timeSamples"))
}

/// The strongest spec of `prim.name` for which `has_samples` holds, walking
/// its property stack as USD's value resolution does: a spec with a
/// `default` (and none of its own samples) ends the walk, and so does a
/// layer the stage does not hold. `has_samples` decides how much of the
/// field to read: its presence alone ([`winning_time_samples`], which must
/// not decode a point cache) or a non-empty map.
pub(crate) fn strongest_samples_site(
    stage: &usd::Stage,
    prim: &usd::Prim,
    name: &str,
    has_samples: impl Fn(&dyn sdf::AbstractData, &sdf::Path) -> bool,
) -> Option<usd::SpecSite> {
    for site in prim.attribute(name).property_stack().ok()? {
        let layer = stage.layer(&site.layer)?;
        if has_samples(layer.data(), &site.path) {
            return Some(site);
        }
        if layer.data().has_field(&site.path, "default") {
            return None;
        }
    }
    None
}

/// The crate file at `path` over a read-only memory mapping.
fn map_crate(path: &Path) -> Option<CrateFile> {
    use openusd::ar::Resolver;
    let p = path.to_str()?;
    let resolver = super::stage::mapped_resolver();
    let resolved = resolver.resolve(p)?;
    let bytes = resolver.open_asset(&resolved).ok()?.into_buffer().ok()?;
    let file = CrateFile::open(bytes).ok()?;
    file.validate().ok()?;
    Some(file)
}

/// The time-sample table of the attribute spec at `path` in `file`: its times
/// and each sample's value representation, read as openusd's decoder reads a
/// `TimeSamples` value (a jump to the times' representation, a jump to the
/// count and the sample representations), with every offset bounds-checked.
fn time_sample_table(file: &CrateFile, path: &sdf::Path) -> Option<(Vec<f64>, Vec<u64>)> {
    let (times, count_at) = locate_time_samples(file, path)?;
    let bytes: &[u8] = file.bytes();
    let count = usize::try_from(read_u64(bytes, count_at)?).ok()?;
    // The times were decoded from the file, so a count equal to theirs is
    // bounded by the file's size.
    if count != times.len() {
        return None;
    }
    let reps = (0..count)
        .map(|i| read_u64(bytes, count_at + 8 + 8 * i))
        .collect::<Option<Vec<u64>>>()?;
    Some((times, reps))
}

/// The little-endian u64 at `at`, if the bytes hold one there.
fn read_u64(bytes: &[u8], at: usize) -> Option<u64> {
    Some(u64::from_le_bytes(bytes.get(at..at.checked_add(8)?)?.try_into().ok()?))
}

/// The sample times of the spec at `path` and where its sample count is.
fn locate_time_samples(file: &CrateFile, path: &sdf::Path) -> Option<(Vec<f64>, usize)> {
    let spec = file.specs.iter().find(|s| file.paths.get(s.path_index) == Some(path))?;
    let rep = file
        .fieldsets
        .get(spec.fieldset_index..)?
        .iter()
        .map_while(|slot| *slot)
        .map(|i| file.fields.get(i))
        .find(|f| f.is_some_and(|f| file.tokens.get(f.token_index).map(String::as_str) == Some("timeSamples")))??
        .value_rep;
    let bits = rep.0;
    if (bits >> 48) & 0xff != TYPE_TIME_SAMPLES || bits & (INLINED_BIT | COMPRESSED_BIT) != 0 {
        return None;
    }
    let bytes: &[u8] = file.bytes();
    let read_u64 = |at: usize| read_u64(bytes, at);
    let jump = |at: usize| -> Option<usize> {
        let off = read_u64(at)? as i64;
        usize::try_from((at as i64).checked_add(off)?).ok()
    };
    let payload = usize::try_from(bits & PAYLOAD_MASK).ok()?;
    let times_at = jump(payload)?;
    let mut times_rep = rep;
    times_rep.0 = read_u64(times_at)?;
    let times = match file.value(times_rep).ok()? {
        Value::DoubleVec(t) => t,
        _ => return None,
    };
    Some((times, jump(times_at + 8)?))
}

#[cfg(test)]
mod tests {
    use super::super::atomic::TempDir;
    use super::super::layer::{Format, OverLayer};
    use super::super::stage::{StageMetadata, StageReader};
    use super::*;

    /// A crate layer overriding `/M.points` with samples at `times` (4 points
    /// each, distinct per sample and per point).
    fn sample_layer(dir: &Path, times: &[f64]) -> std::path::PathBuf {
        let counts: Vec<(f64, Option<usize>)> = times.iter().map(|&t| (t, Some(4))).collect();
        sample_layer_of(dir, &counts)
    }

    /// As [`sample_layer`], with each sample's point count (`None`: a blocked sample).
    fn sample_layer_of(dir: &Path, samples: &[(f64, Option<usize>)]) -> std::path::PathBuf {
        let mut layer = OverLayer::new(StageMetadata::default());
        let samples = samples
            .iter()
            .enumerate()
            .map(|(k, &(t, n))| {
                let Some(n) = n else {
                    return (t, Value::ValueBlock);
                };
                let pts = (0..n)
                    .map(|i| {
                        let f = (k * 4 + i) as f32;
                        gf::Vec3f {
                            x: 0.1 * f + 0.37,
                            y: -1.3 * f.sin(),
                            z: 2.0 + (0.7 * f).cos() / 3.0,
                        }
                    })
                    .collect();
                (t, Value::Vec3fVec(pts))
            })
            .collect();
        layer.set_samples("/M", "points", "point3f[]", samples, Vec::new());
        let path = dir.join("samples.usdc");
        std::fs::write(&path, layer.into_bytes(Format::Usdc).unwrap()).unwrap();
        path
    }

    fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        path
    }

    /// Every read of `CrateSamples` equals openusd's `AttributeQuery` bit for
    /// bit: before, between, on and after the samples, through the stage's
    /// layer offsets.
    fn assert_same_as_openusd(root: &Path) {
        let r = StageReader::open_mapped(root).unwrap();
        let prim = r.require_prim("/M").unwrap();
        let lazy = r.crate_samples(&prim, "points").expect("read lazily");
        let mut times: Vec<f64> = (-40..=80).map(|i| i as f64 * 0.37).collect();
        times.extend(lazy.stage_times());
        times.extend(lazy.stage_times().iter().map(|t| t + 1e-9));
        for t in times {
            let want = r.value(&prim, "points", Some(t)).unwrap();
            let got = lazy.value_at(t).unwrap();
            let bits = |v: &Option<Value>| -> Option<Vec<u32>> {
                match v {
                    Some(Value::Vec3fVec(p)) => {
                        Some(p.iter().flat_map(|q| [q.x, q.y, q.z]).map(f32::to_bits).collect())
                    }
                    None => None,
                    other => panic!("unexpected {other:?}"),
                }
            };
            assert_eq!(bits(&got), bits(&want), "at stage time {t}");
        }
        assert_eq!(
            lazy.stage_times(),
            r.sample_times(&prim, "points").unwrap(),
            "sample times in stage time"
        );
    }

    #[test]
    fn samples_in_the_root_layer_read_as_openusd_reads_them() {
        let dir = TempDir::new().unwrap();
        let layer = sample_layer(dir.path(), &[-2.0, 0.0, 1.5, 4.0, 7.25]);
        // The crate layer is the stage; its `over` defines nothing, which a
        // value read does not mind.
        assert_same_as_openusd(&layer);
    }

    #[test]
    fn samples_through_a_sublayer_offset_read_as_openusd_reads_them() {
        let dir = TempDir::new().unwrap();
        sample_layer(dir.path(), &[0.0, 1.5, 4.0, 7.25]);
        let root = write(
            dir.path(),
            "root.usda",
            "#usda 1.0\n(\n    subLayers = [@./samples.usdc@ (offset = 10; scale = 2)]\n)\n\ndef Mesh \"M\"\n{\n}\n",
        );
        assert_same_as_openusd(&root);
        let r = StageReader::open_mapped(&root).unwrap();
        let lazy = r.crate_samples(&r.require_prim("/M").unwrap(), "points").unwrap();
        assert_eq!(lazy.stage_times(), vec![10.0, 13.0, 18.0, 24.5]);
    }

    #[test]
    fn samples_through_a_reference_offset_read_as_openusd_reads_them() {
        let dir = TempDir::new().unwrap();
        sample_layer(dir.path(), &[1.0, 2.0, 5.0]);
        let root = write(
            dir.path(),
            "root.usda",
            "#usda 1.0\n\ndef Mesh \"M\" (\n    references = @./samples.usdc@</M> (offset = -3; scale = 0.5)\n)\n{\n}\n",
        );
        assert_same_as_openusd(&root);
    }

    #[test]
    fn mismatched_counts_and_blocked_samples_read_as_usd_core_reads_them() {
        // Between samples of different lengths openusd holds the lower one;
        // a sample before a block holds up to it, and from the block on
        // there is no value (usd-core: samples 1 at t=1 and a block at t=3
        // read 1.0 at t=2 and 2.9, none at 3 and after).
        let dir = TempDir::new().unwrap();
        let layer = sample_layer_of(
            dir.path(),
            &[(1.0, Some(4)), (2.0, Some(5)), (3.0, Some(5)), (4.0, None)],
        );
        assert_same_as_openusd(&layer);
        let r = StageReader::open_mapped(&layer).unwrap();
        let lazy = r.crate_samples(&r.require_prim("/M").unwrap(), "points").unwrap();
        assert!(matches!(lazy.value_at(1.5).unwrap(), Some(Value::Vec3fVec(p)) if p.len() == 4));
        assert!(matches!(lazy.value_at(3.5).unwrap(), Some(Value::Vec3fVec(p)) if p.len() == 5));
        assert_eq!(lazy.value_at(4.0).unwrap(), None);
        assert_eq!(lazy.value_at(9.0).unwrap(), None);
    }

    #[test]
    fn a_sample_count_that_disagrees_with_the_times_is_left_to_openusd() {
        // A damaged table: openusd refuses to read it, and so does this reader
        // (rather than indexing past the table).
        let dir = TempDir::new().unwrap();
        let layer = sample_layer(dir.path(), &[1.0, 2.0, 3.0]);
        let count_at = {
            let file = map_crate(&layer).unwrap();
            let path = sdf::Path::new("/M.points").unwrap();
            let (times, at) = locate_time_samples(&file, &path).unwrap();
            assert_eq!(read_u64(file.bytes(), at), Some(times.len() as u64));
            at
        };
        let mut bytes = std::fs::read(&layer).unwrap();
        bytes[count_at..count_at + 8].copy_from_slice(&7u64.to_le_bytes());
        std::fs::write(&layer, &bytes).unwrap();
        let r = StageReader::open_mapped(&layer).unwrap();
        let prim = r.require_prim("/M").unwrap();
        assert!(r.crate_samples(&prim, "points").is_none());
        assert!(usd::AttributeQuery::new(&prim.attribute("points"))
            .get_at::<Value>(usd::TimeCode::new(1.5))
            .is_err());
    }

    #[test]
    fn a_time_sample_field_inlined_compressed_or_of_another_type_is_not_read() {
        // USD's `ValueRep`: bit 62 inlined, bit 61 compressed, bits 48..56 the
        // type (46: `TimeSamples`). openusd refuses such a table; this reader
        // must not follow its payload as if it were one. The bits are written
        // out here, not taken from the module's constants.
        let dir = TempDir::new().unwrap();
        let layer = sample_layer(dir.path(), &[1.0, 2.0, 3.0]);
        let path = sdf::Path::new("/M.points").unwrap();
        let with_rep = |edit: fn(u64) -> u64| {
            let mut file = map_crate(&layer).unwrap();
            let token = file.tokens.iter().position(|t| t == "timeSamples").unwrap();
            for f in file.fields.iter_mut().filter(|f| f.token_index == token) {
                f.value_rep.0 = edit(f.value_rep.0);
            }
            locate_time_samples(&file, &path).map(|(times, _)| times)
        };
        assert_eq!(with_rep(|b| b), Some(vec![1.0, 2.0, 3.0]), "as written");
        assert_eq!(with_rep(|b| b | (1 << 62)), None, "inlined");
        assert_eq!(with_rep(|b| b | (1 << 61)), None, "compressed");
        assert_eq!(with_rep(|b| (b & !(0xff << 48)) | (45 << 48)), None, "another type");
    }

    #[test]
    fn unsorted_or_repeated_sample_times_are_left_to_openusd() {
        // openusd sorts a crate file's samples and keeps the last of a
        // repeated time; this reader takes only strictly ascending tables.
        for times in [[2.0, 1.0, 3.0], [1.0, 2.0, 2.0]] {
            let dir = TempDir::new().unwrap();
            let layer = sample_layer(dir.path(), &times);
            let r = StageReader::open_mapped(&layer).unwrap();
            let prim = r.require_prim("/M").unwrap();
            assert!(r.crate_samples(&prim, "points").is_none(), "{times:?}");
        }
    }

    #[test]
    fn a_stronger_opinion_or_an_edited_stage_is_left_to_openusd() {
        let dir = TempDir::new().unwrap();
        sample_layer(dir.path(), &[1.0, 2.0]);
        let lazy = |text: &str| {
            let root = write(dir.path(), "root.usda", text);
            let r = StageReader::open_mapped(&root).unwrap();
            r.crate_samples(&r.require_prim("/M").unwrap(), "points").is_some()
        };
        let sub = "#usda 1.0\n(\n    subLayers = [@./samples.usdc@]\n)\n\n";
        assert!(lazy(&format!("{sub}def Mesh \"M\"\n{{\n}}\n")));
        // A default in a stronger layer wins over weaker samples.
        assert!(!lazy(&format!(
            "{sub}def Mesh \"M\"\n{{\n    point3f[] points = [(0, 0, 0)]\n}}\n"
        )));
        // Samples in a text layer are openusd's to read.
        assert!(!lazy(&format!(
            "{sub}def Mesh \"M\"\n{{\n    point3f[] points.timeSamples = {{ 1: [(0, 0, 0)] }}\n}}\n"
        )));
        // Value clips resolve per time.
        assert!(!lazy(&format!(
            "{sub}def Mesh \"M\" (\n    clips = {{ dictionary default = {{ asset[] assetPaths = [@./samples.usdc@] }} }}\n)\n{{\n}}\n"
        )));
        // A stage read into memory (the preview, the Python API, edits):
        // the files may change under it.
        let root = write(dir.path(), "root.usda", &format!("{sub}def Mesh \"M\"\n{{\n}}\n"));
        let r = StageReader::open(&root).unwrap();
        assert!(r.crate_samples(&r.require_prim("/M").unwrap(), "points").is_none());
    }
}
