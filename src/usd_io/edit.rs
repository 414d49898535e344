//! Edit sessions for the authoring commands (`bind`, `key`, `smudge`,
//! `expand`): where edits go and how they are written.
//!
//! By default edits go into an edit layer the user names, which sublayers the
//! input (created if missing), so opening the edit layer shows the edited
//! character and the input is untouched. `--in-place` edits the input's root
//! layer instead. Every write is atomic (temporary file, then rename).
//!
//! A `.usda` target is never re-serialised: the specs the session authored
//! are spliced into the file's own text ([`super::usda_splice`]), so every
//! other spec, field, comment and byte stays as it was. The result is parsed
//! again and compared, spec by spec and field by field, with the edited layer;
//! if anything else would change, the edit is refused and the file is left
//! untouched.

use std::cell::RefCell;
use std::io::Write;
use std::path::{Path, PathBuf};

use openusd::sdf::{self, AbstractData, Value};

use super::atomic::{write_atomic_as, Publish, ScratchFile};
use super::layer::Format;
use super::stage::{StageMetadata, StageReader};
use super::usda_splice;
use crate::error::{Error, Result};

/// A value the authoring commands write, in painterly's own types: the USD
/// value and its type name are made here, so `author` never touches
/// `openusd`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Authored<'a> {
    /// `point3f[]`
    Points(&'a [glam::Vec3]),
    /// `float[]`
    Floats(&'a [f32]),
    /// `float`
    Float(f32),
    /// `double`
    Double(f64),
    /// `bool`
    Bool(bool),
}

impl Authored<'_> {
    fn type_name(&self) -> &'static str {
        match self {
            Authored::Points(_) => "point3f[]",
            Authored::Floats(_) => "float[]",
            Authored::Float(_) => "float",
            Authored::Double(_) => "double",
            Authored::Bool(_) => "bool",
        }
    }

    fn into_value(self) -> Value {
        match self {
            Authored::Points(p) => Value::Vec3fVec(p.iter().map(|p| openusd::gf::vec3f(p.x, p.y, p.z)).collect()),
            Authored::Floats(f) => Value::FloatVec(f.to_vec()),
            Authored::Float(x) => Value::Float(x),
            Authored::Double(x) => Value::Double(x),
            Authored::Bool(b) => Value::Bool(b),
        }
    }
}

/// Where an edit session writes.
#[derive(Debug, Clone, PartialEq)]
pub enum EditTarget {
    /// A separate layer that sublayers the input (created when missing).
    Layer(PathBuf),
    /// The input file itself.
    InPlace,
}

/// An open stage whose root layer receives edits.
pub struct EditSession {
    /// The composed stage (the edit layer over the input, or the input).
    pub reader: StageReader,
    /// The input's stage metadata (time range, rates): an edit layer's own
    /// metadata may be missing, and the input's range is what `--time` means.
    pub input_meta: StageMetadata,
    target: PathBuf,
    /// The target's text before editing (the new header for a new layer),
    /// when the target is usda text; None for crate files.
    original_text: Option<String>,
    /// An existing crate target as read: the values openusd cannot read, or
    /// reads wrong, are written back from it.
    crate_source: Option<super::usdc::CrateSource>,
    /// The header a new edit layer is opened from; removed on drop.
    _scratch: Option<ScratchFile>,
    /// The existing file the edit replaces, locked and as it was read.
    guard: Option<TargetGuard>,
    /// Prim specs defined, and attribute specs set, in order.
    prims: RefCell<Vec<String>>,
    attrs: RefCell<Vec<(String, String)>>,
}

/// What tells one version of a file from another: device, inode (a save
/// through a rename makes a new one), size and modification time. The edit
/// lock and the crate reader's check of a file replaced while read both use it.
type FileId = (u64, u64, u64, std::time::SystemTime);

fn file_id(path: &Path) -> Option<FileId> {
    use std::os::unix::fs::MetadataExt;
    let m = std::fs::metadata(path).ok()?;
    Some((m.dev(), m.ino(), m.len(), m.modified().ok()?))
}

/// An existing file an edit replaces: locked (`flock`) against other
/// painterly edits of it while the edit runs, and its [`FileId`] taken
/// before it is read and checked again just before the write, so that an
/// edit never replaces a version of the file it did not read (two edits at
/// once each kept only its own change).
struct TargetGuard {
    _lock: std::fs::File,
    read: FileId,
}

impl TargetGuard {
    fn take(path: &Path) -> Result<TargetGuard> {
        use std::os::fd::AsRawFd;
        let read = file_id(path);
        let lock =
            super::regular::open_regular(path).map_err(|e| Error::msg(format!("cannot open: {e}")).in_file(path))?;
        // SAFETY: flock on a file descriptor this function owns.
        if unsafe { libc::flock(lock.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) } != 0 {
            return Err(Error::msg(
                "another painterly edit of this file is running: run this one when it has finished",
            )
            .in_file(path));
        }
        match read {
            Some(read) if file_id(path) == Some(read) => Ok(TargetGuard { _lock: lock, read }),
            _ => Err(Error::msg("the file changed while it was read; run the edit again").in_file(path)),
        }
    }

    /// Fails, naming `path`, unless the file at `at` (`path` itself, or
    /// where the publish moved the file it replaced) is the version read.
    fn check_unchanged(&self, path: &Path, at: &Path) -> Result<()> {
        if file_id(at) == Some(self.read) {
            return Ok(());
        }
        Err(Error::msg(
            "the file changed since this edit read it (saved by another program?); nothing was written: run the edit again",
        )
        .in_file(path))
    }
}

/// The path to write in `subLayers` for `input`, seen from `edit_dir`:
/// `./name` when they share a folder, else the absolute path.
fn sublayer_path(input: &Path, edit_dir: &Path) -> Result<String> {
    let abs = input
        .canonicalize()
        .map_err(|e| Error::msg(format!("cannot open input: {e}")).in_file(input))?;
    let dir = edit_dir.canonicalize().ok();
    Ok(match (abs.parent(), dir, abs.file_name()) {
        (Some(p), Some(d), Some(name)) if p == d => format!("./{}", name.to_string_lossy()),
        _ => abs.to_string_lossy().into_owned(),
    })
}

/// The file's text when it is usda (by content, whatever the extension),
/// None for crate files.
fn read_text(path: &Path) -> Result<Option<String>> {
    // A FIFO or device would block the read, or never end it: refused,
    // also when one replaced the file since it was checked.
    super::stage::require_file(path, "the layer")?;
    let bytes =
        super::regular::read_regular(path).map_err(|e| Error::msg(format!("cannot read: {e}")).in_file(path))?;
    if !bytes.starts_with(b"#usda") {
        return Ok(None);
    }
    String::from_utf8(bytes)
        .map(Some)
        .map_err(|_| Error::msg("the usda text is not valid UTF-8; cannot edit it").in_file(path))
}

/// The crate file at `path` (None for usda text), mapped, for the values
/// openusd cannot read; `before` is its [`file_id`] from before the stage
/// read it, so a file replaced in between is refused rather than mixed in.
fn crate_source(
    path: &Path,
    text: &Option<String>,
    before: Option<FileId>,
) -> Result<Option<super::usdc::CrateSource>> {
    use openusd::ar::{Asset, Resolver};
    if text.is_some() {
        return Ok(None);
    }
    let cannot = |e: String| Error::msg(format!("cannot read the crate file: {e}")).in_file(path);
    let buffer = super::stage::mapped_resolver()
        .open_asset(&openusd::ar::ResolvedPath::new(path))
        .and_then(|a: Box<dyn Asset>| a.into_buffer())
        .map_err(|e| cannot(e.to_string()))?;
    if before.is_none() || file_id(path) != before {
        return Err(Error::msg("the file changed while it was read; run the edit again").in_file(path));
    }
    super::usdc::CrateSource::open(buffer).map(Some).map_err(cannot)
}

/// An existing edit layer must have `input` in its layer stack: otherwise
/// the edits would be computed from the character it was made over, and
/// `input` silently ignored.
fn require_over(reader: &StageReader, input: &Path, edit: &Path) -> Result<()> {
    let Ok(want) = input.canonicalize() else {
        return Ok(()); // the input was just opened; nothing better to compare
    };
    let stack = reader.stage.layer_stack();
    let found = stack.iter().any(|id| {
        // A package's inner layer is named `a.usdz[inner.usdc]`.
        let file = super::stage::package_file(id);
        Path::new(file).canonicalize().is_ok_and(|p| p == want)
    });
    if found {
        return Ok(());
    }
    Err(Error::msg(format!(
        "this edit layer does not sublayer {} (it was made over another input): name a new --edit-layer, or give its input",
        input.display()
    ))
    .in_file(edit))
}

impl EditSession {
    /// Opens `input` for editing into `target`.
    pub fn open(input: &Path, target: &EditTarget) -> Result<EditSession> {
        // The file to replace is locked and identified before anything reads it.
        let guard = match target {
            EditTarget::InPlace if input.is_file() => Some(TargetGuard::take(input)?),
            EditTarget::Layer(edit) if edit.is_file() && !super::stage::same_file(input, edit) => {
                Some(TargetGuard::take(edit)?)
            }
            _ => None,
        };
        let input_stamp = file_id(input);
        // Reading the input first gives its own errors (missing, unreadable).
        let input_reader = StageReader::open(input)?;
        // Edits are computed from the composed character: a missing asset
        // would change what they capture.
        input_reader.require_resolved().map_err(|e| e.in_file(input))?;
        let input_meta = input_reader.metadata();
        let session = |guard, reader, target: &Path, original_text, crate_source, scratch| EditSession {
            guard,
            reader,
            input_meta: input_meta.clone(),
            target: target.to_path_buf(),
            original_text,
            crate_source,
            _scratch: scratch,
            prims: RefCell::new(Vec::new()),
            attrs: RefCell::new(Vec::new()),
        };
        match target {
            EditTarget::InPlace => {
                // usd-core finds a format by its extension in any case.
                let ext = input.extension().and_then(|e| e.to_str()).unwrap_or("");
                if ext.eq_ignore_ascii_case("usdz") {
                    return Err(Error::msg("cannot edit a .usdz package in place; use --edit-layer").in_file(input));
                }
                let text = read_text(input)?;
                let source = crate_source(input, &text, input_stamp)?;
                Ok(session(guard, input_reader, input, text, source, None))
            }
            EditTarget::Layer(edit) => {
                Format::from_path(edit)?;
                if super::stage::same_file(input, edit) {
                    return Err(
                        Error::msg("the edit layer is the input itself: pass --in-place to edit the input")
                            .in_file(edit),
                    );
                }
                if edit.exists() {
                    // Created by another process while the input was read:
                    // locked and identified now, before it is read. Not a
                    // regular file (a FIFO, whose open would wait for a
                    // writer): refused by `read_text` below.
                    let guard = match guard {
                        None if edit.is_file() => Some(TargetGuard::take(edit)?),
                        guard => guard,
                    };
                    let edit_stamp = file_id(edit);
                    let text = read_text(edit)?;
                    let reader = StageReader::open(edit)?;
                    require_over(&reader, input, edit)?;
                    let source = crate_source(edit, &text, edit_stamp)?;
                    return Ok(session(guard, reader, edit, text, source, None));
                }
                let dir = match edit.parent() {
                    Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
                    _ => PathBuf::from("."),
                };
                if !dir.is_dir() {
                    return Err(
                        Error::msg(format!("edit layer directory {} does not exist", dir.display())).in_file(edit),
                    );
                }
                // The new layer copies the input's stage metadata: usd-core
                // cannot open a layer holding a nan or inf there.
                input_meta.validate().map_err(|e| e.in_file(input))?;
                let sub = sublayer_path(input, &dir)?;
                super::layer::check_asset_path(&sub, input)?;
                // Stage metadata comes from the root layer: copy the input's, or
                // opening the edit layer would retime and re-orient the input.
                let mut header = format!(
                    "#usda 1.0\n(\n    doc = {}\n",
                    usda_splice::format_value(&Value::String(format!("painterly edit layer over {sub}")))
                        .unwrap_or_default()
                );
                let m = &input_meta;
                for (key, v) in [
                    ("startTimeCode", m.start_time_code),
                    ("endTimeCode", m.end_time_code),
                    ("timeCodesPerSecond", m.time_codes_per_second),
                    ("framesPerSecond", m.frames_per_second),
                    ("metersPerUnit", m.meters_per_unit),
                ] {
                    if let Some(v) = v {
                        header.push_str(&format!("    {key} = {v:?}\n"));
                    }
                }
                if let Some(up) = &m.up_axis {
                    header.push_str(&format!(
                        "    upAxis = {}\n",
                        usda_splice::format_value(&Value::Token(up.as_str().into())).unwrap_or_default()
                    ));
                }
                if let Some(dp) = input_reader.stage.default_prim() {
                    header.push_str(&format!(
                        "    defaultPrim = {}\n",
                        usda_splice::format_value(&Value::Token(dp.as_str().into())).unwrap_or_default()
                    ));
                }
                header.push_str(&format!("    subLayers = [\n        @{sub}@\n    ]\n)\n\n"));
                // openusd opens only UTF-8 paths: said of the edit layer, not
                // of the scratch file beside it that would be opened.
                if edit.to_str().is_none() {
                    return Err(Error::msg(
                        "the edit layer's path is not valid UTF-8 (USD reads layers by UTF-8 paths): name it another way",
                    )
                    .in_file(edit));
                }
                let scratch = ScratchFile::create(edit, header.as_bytes())?;
                let reader = StageReader {
                    file: edit.to_path_buf(),
                    ..StageReader::open(scratch.path())?
                };
                let text = (Format::from_path(edit)? == Format::Usda).then_some(header);
                Ok(session(None, reader, edit, text, None, Some(scratch)))
            }
        }
    }

    /// The file edits are written to.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Authors a painterly attribute's default value (all of them are
    /// `uniform` in the schema).
    pub fn set(&self, prim: &str, name: &str, value: Authored) -> Result<()> {
        self.set_value(prim, name, value.type_name(), true, value.into_value())
    }

    /// Blocks a painterly attribute's default value (`= None`, usd-core's
    /// `Block()`): the attribute then has no value, whatever weaker layers
    /// hold.
    pub fn block(&self, prim: &str, name: &str, type_name: &str) -> Result<()> {
        self.set_value(prim, name, type_name, true, Value::ValueBlock)
    }

    /// Caches a stroke layer's binding (SPEC §3): its rest points, each
    /// point's triangle vertices and barycentric weights.
    pub fn set_binding(&self, layer: &str, rest: &[glam::Vec3], binding: &crate::bind::Binding) -> Result<()> {
        self.set(layer, "painterly:restPoints", Authored::Points(rest))?;
        let (verts, weights) = super::values::binding_values(binding);
        self.set_value(layer, "painterly:bindVertices", "int3[]", true, verts)?;
        self.set_value(layer, "painterly:bindWeights", "float3[]", true, weights)
    }

    fn set_value(&self, prim: &str, name: &str, type_name: &str, uniform: bool, value: Value) -> Result<()> {
        let path = format!("{prim}.{name}");
        self.reader
            .stage
            .attribute_builder(path.as_str(), type_name)
            .custom(false)
            .variability(if uniform {
                sdf::Variability::Uniform
            } else {
                sdf::Variability::Varying
            })
            .set(value)
            .build()
            .map(|_| ())
            .map_err(|e| Error::attr(prim, name, format!("cannot author: {e}")))?;
        self.attrs.borrow_mut().push((prim.to_string(), name.to_string()));
        Ok(())
    }

    /// Defines a typed prim (or re-specifies an existing one's type).
    pub fn define(&self, path: &str, type_name: &str) -> Result<()> {
        self.reader
            .stage
            .define_prim(path)
            .and_then(|p| p.set_type_name(type_name))
            .map(|_| ())
            .map_err(|e| Error::prim(path, format!("cannot define {type_name}: {e}")))?;
        self.prims.borrow_mut().push(path.to_string());
        Ok(())
    }

    /// Every prim spec the session may have created or changed: defined
    /// prims, their ancestors, and the prims of set attributes, shallowest
    /// first.
    fn touched_prims(&self) -> Vec<String> {
        let mut out: Vec<String> = Vec::new();
        let explicit = self.prims.borrow();
        let attrs = self.attrs.borrow();
        for p in explicit.iter().chain(attrs.iter().map(|(p, _)| p)) {
            let mut cur = p.as_str();
            loop {
                if !out.iter().any(|q| q == cur) {
                    out.push(cur.to_string());
                }
                match cur.rsplit_once('/') {
                    Some(("", _)) | None => break,
                    Some((parent, _)) => cur = parent,
                }
            }
        }
        out.sort_by_key(|p| p.matches('/').count());
        out
    }

    /// Writes the root layer to the target, atomically. A usda target gets
    /// only the edited statements spliced into its text (see the module
    /// docs); an edit that cannot be written without changing anything else
    /// is refused and the file is left untouched.
    pub fn save(self) -> Result<()> {
        // Checked now, before the work, and again at the rename.
        let unchanged = |at: &Path| {
            self.guard
                .as_ref()
                .map_or(Ok(()), |g| g.check_unchanged(&self.target, at))
        };
        unchanged(&self.target)?;
        let publish = match (&self.guard, &self._scratch) {
            (Some(_), _) => Publish::ReplaceIf(&unchanged),
            // A new edit layer (opened from a scratch header): another
            // process may create it meanwhile, and keeps its file.
            (None, Some(_)) => Publish::CreateNew,
            (None, None) => Publish::Replace,
        };
        let root = self.reader.stage.root_layer();
        let Some(text) = &self.original_text else {
            // Not a usda target: a crate file, from painterly's crate writer.
            let written = match &self.crate_source {
                Some(source) => super::usdc::write_edited_layer_file(&self.target, root.data(), source, publish),
                None => super::usdc::write_layer_file_as(&self.target, root.data(), publish),
            };
            drop(root);
            return written;
        };
        let data = root.data();
        let prims: Vec<String> = self
            .touched_prims()
            .into_iter()
            .filter(|p| sdf::Path::new(p).is_ok_and(|sp| data.has_spec(&sp)))
            .collect();
        let defined = self.prims.borrow().clone();
        let attrs = self.attrs.borrow().clone();
        let refuse = |why: String| {
            Error::msg(format!(
                "cannot save the edit without changing other content ({why}); the file is unchanged"
            ))
            .in_file(&self.target)
        };
        let out = usda_splice::splice(text, data, &prims, &defined, &attrs).map_err(refuse)?;
        check_round_trip(text, &out, data).map_err(refuse)?;
        drop(root);
        write_atomic_as(&self.target, publish, |w| w.write_all(out.as_bytes()))
    }
}

/// Fields whose absence means their fallback.
fn is_fallback(field: &str, v: &Value) -> bool {
    matches!(
        (field, v),
        ("custom", Value::Bool(false)) | ("variability", Value::Variability(sdf::Variability::Varying))
    )
}

fn same_value(a: &Value, b: &Value) -> bool {
    // NaN != NaN: compare their printed form when == says no.
    a == b || format!("{a:?}") == format!("{b:?}")
}

/// Property orders as usd-core reads them from the text before and after
/// the splice (see [`usda_splice::property_orders`]).
struct TextOrders {
    before: std::collections::HashMap<String, Vec<String>>,
    after: std::collections::HashMap<String, Vec<String>>,
}

fn token_names(v: &Value) -> Option<Vec<&str>> {
    match v {
        Value::TokenVec(t) => Some(t.iter().map(|t| t.as_str()).collect()),
        _ => None,
    }
}

/// Whether prim `p`'s `propertyChildren`, which openusd read differently
/// from the spliced text (`got`) than the edited layer holds them
/// (`expected`), still name the same properties in usd-core's order: the
/// text lists the prim's original properties in their original order, then
/// the added ones, as usd-core orders them after adding properties.
fn same_properties_in_text_order(p: &str, expected: &Value, got: &Value, orders: &TextOrders) -> bool {
    let (Some(e), Some(g)) = (token_names(expected), token_names(got)) else {
        return false;
    };
    fn sorted(mut v: Vec<&str>) -> Vec<&str> {
        v.sort_unstable();
        v
    }
    let before: Vec<&str> = orders
        .before
        .get(p)
        .map_or_else(Vec::new, |v| v.iter().map(String::as_str).collect());
    let after: Vec<&str> = orders
        .after
        .get(p)
        .map_or_else(Vec::new, |v| v.iter().map(String::as_str).collect());
    let mut want = before.clone();
    want.extend(e.iter().filter(|n| !before.contains(n)));
    let e = sorted(e);
    e.windows(2).all(|w| w[0] != w[1]) && e == sorted(g) && e == sorted(after.clone()) && after == want
}

/// Parses the spliced text and checks it holds exactly the edited layer:
/// the same specs, and the same fields with the same values on each.
/// `original` is the text before the splice (for property order).
fn check_round_trip(original: &str, text: &str, expected: &dyn AbstractData) -> std::result::Result<(), String> {
    let got = sdf::LayerRegistry::read_bytes(openusd::ar::AssetBuffer::Owned(text.as_bytes().to_vec()), "edit.usda")
        .map_err(|e| format!("the spliced text does not parse: {e}"))?;
    let mut orders: Option<TextOrders> = None;
    let (a, b) = (expected.spec_paths(), got.spec_paths());
    if a != b {
        let missing = a.iter().find(|p| !b.contains(p));
        let extra = b.iter().find(|p| !a.contains(p));
        return Err(match (missing, extra) {
            (Some(p), _) => format!("spec {p} would be lost"),
            (_, Some(p)) => format!("spec {p} would appear"),
            _ => "spec order differs".into(),
        });
    }
    for p in &a {
        if expected.spec_type(p) != got.spec_type(p) {
            return Err(format!("spec {p} would change type"));
        }
        let mut fields = expected.list_fields(p).unwrap_or_default();
        for f in got.list_fields(p).unwrap_or_default() {
            if !fields.contains(&f) {
                fields.push(f);
            }
        }
        for f in fields {
            let va = expected.try_field(p, &f).ok().flatten();
            let vb = got.try_field(p, &f).ok().flatten();
            let same = match (va.as_deref(), vb.as_deref()) {
                (Some(x), Some(y)) if f == "propertyChildren" && !same_value(x, y) => {
                    if orders.is_none() {
                        orders = Some(TextOrders {
                            before: usda_splice::property_orders(original)?,
                            after: usda_splice::property_orders(text)?,
                        });
                    }
                    orders
                        .as_ref()
                        .is_some_and(|o| same_properties_in_text_order(p.as_str(), x, y, o))
                }
                (Some(x), Some(y)) => same_value(x, y),
                (Some(x), None) | (None, Some(x)) => is_fallback(&f, x),
                (None, None) => true,
            };
            if !same {
                return Err(format!("field {f} of {p} would change"));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> sdf::LayerData {
        sdf::LayerRegistry::read_bytes(openusd::ar::AssetBuffer::Owned(text.as_bytes().to_vec()), "t.usda").unwrap()
    }

    const BASE: &str = "#usda 1.0\n\ndef Xform \"A\"\n{\n    float x = 1\n    double y = nan\n\n    def Xform \"B\"\n    {\n    }\n}\n";

    #[test]
    fn field_values_compare_by_value_and_nan_by_its_printed_form() {
        // NaN != NaN under ==, yet an unchanged NaN default is no change.
        assert!(same_value(&Value::Double(f64::NAN), &Value::Double(f64::NAN)));
        assert!(same_value(&Value::Float(1.0), &Value::Float(1.0)));
        assert!(!same_value(&Value::Float(1.0), &Value::Float(2.0)));
        assert!(!same_value(&Value::Double(f64::NAN), &Value::Double(0.0)));
    }

    #[test]
    fn only_custom_false_and_varying_variability_are_fallbacks() {
        // The Sdf schema's fallbacks: custom = false, variability = varying.
        assert!(is_fallback("custom", &Value::Bool(false)));
        assert!(is_fallback(
            "variability",
            &Value::Variability(sdf::Variability::Varying)
        ));
        assert!(!is_fallback("custom", &Value::Bool(true)));
        assert!(!is_fallback(
            "variability",
            &Value::Variability(sdf::Variability::Uniform)
        ));
        assert!(!is_fallback("default", &Value::Bool(false)));
        assert!(!is_fallback("documentation", &Value::String(String::new())));
    }

    #[test]
    fn crate_source_maps_a_crate_file_only_when_it_is_the_version_read() {
        let dir = crate::test_dir::ScratchDir::new("edit-crate-source");
        let path = dir.join("layer.usdc");
        super::super::usdc::write_layer_file(&path, &parse(BASE)).unwrap();
        let read = file_id(&path);
        assert!(read.is_some());
        // The version read: mapped.
        assert!(crate_source(&path, &None, read).unwrap().is_some());
        // usda text needs no crate reader.
        assert!(crate_source(&path, &Some(BASE.to_string()), read).unwrap().is_none());
        // Replaced after it was read (here: another size), or never identified.
        let (dev, ino, len, time) = read.unwrap();
        for before in [Some((dev, ino, len + 1, time)), None] {
            let Err(e) = crate_source(&path, &None, before) else {
                panic!("a changed file was mapped ({before:?})");
            };
            let e = e.to_string();
            assert!(e.contains("the file changed while it was read"), "{e}");
        }
    }

    #[test]
    fn round_trip_check_names_the_first_spec_or_field_that_would_change() {
        let base = parse(BASE);
        // The same text (with its NaN default) holds exactly the layer.
        assert_eq!(check_round_trip(BASE, BASE, &base), Ok(()));
        // /A/B dropped from the text: lost.
        let without_b = BASE.replace("\n    def Xform \"B\"\n    {\n    }\n", "");
        assert!(!without_b.contains("\"B\""));
        assert_eq!(
            check_round_trip(BASE, &without_b, &base),
            Err("spec /A/B would be lost".to_string())
        );
        // /A/B only in the text: it would appear.
        assert_eq!(
            check_round_trip(BASE, BASE, &parse(&without_b)),
            Err("spec /A/B would appear".to_string())
        );
        // A changed default.
        assert_eq!(
            check_round_trip(BASE, &BASE.replace("float x = 1", "float x = 2"), &base),
            Err("field default of /A.x would change".to_string())
        );
        // A field only the text has (prim documentation): not a fallback.
        let documented = BASE.replace("def Xform \"A\"\n", "def Xform \"A\" (\n    doc = \"d\"\n)\n");
        let e = check_round_trip(BASE, &documented, &base).unwrap_err();
        assert!(e.starts_with("field ") && e.ends_with(" of /A would change"), "{e}");
        // ... and only the layer has it.
        let e = check_round_trip(BASE, BASE, &parse(&documented)).unwrap_err();
        assert!(e.starts_with("field ") && e.ends_with(" of /A would change"), "{e}");
    }

    #[test]
    fn round_trip_check_takes_property_order_from_the_text() {
        // usd-core reads /A's properties as [c, x]; openusd lists the
        // connection-only c last, [x, c].
        let before = "#usda 1.0\n\ndef \"A\"\n{\n    float c.connect = </A.x>\n    float x = 1\n}\n";
        let after = before.replace("float x = 1\n", "float x = 1\n    float y = 2\n");
        let mut edited = parse(before);
        let a = sdf::Path::new("/A").unwrap();
        let y = sdf::Path::new("/A.y").unwrap();
        edited.create_spec(y.clone(), sdf::SpecType::Attribute);
        edited.set_field(&y, "typeName", Value::Token("float".into()));
        edited.set_field(&y, "default", Value::Float(2.0));
        let names = |v: &[&str]| Value::TokenVec(v.iter().map(|&n| n.into()).collect());
        assert_eq!(*edited.get_field(&a, "propertyChildren").unwrap(), names(&["x", "c"]));
        edited.set_field(&a, "propertyChildren", names(&["x", "c", "y"]));
        // The new property after the others: what usd-core makes of the edit.
        assert_eq!(check_round_trip(before, &after, &edited), Ok(()));
        // Before the connection, it would move c after y for usd-core.
        let moved = before.replace("    float c", "    float y = 2\n    float c");
        assert_eq!(
            check_round_trip(before, &moved, &edited),
            Err("field propertyChildren of /A would change".to_string())
        );
    }

    #[test]
    fn a_new_edit_layer_session_names_the_edit_layer_not_its_scratch_header() {
        let input = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/blowfish.usda");
        let dir = crate::usd_io::atomic::TempDir::new().unwrap();
        let edit = dir.path().join("e.usda");
        let session = EditSession::open(&input, &EditTarget::Layer(edit.clone())).unwrap();
        // StageReader::file is "the root layer's path, as given by the user".
        assert_eq!(session.reader.file, edit);
        assert_eq!(session.target(), edit.as_path());
        drop(session);
        let session = EditSession::open(&input, &EditTarget::InPlace).unwrap();
        assert_eq!(session.target(), input.as_path());
        assert_eq!(session.reader.file, input);
    }
}
