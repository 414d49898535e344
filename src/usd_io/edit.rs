//! Edit sessions for the authoring commands (`bind`, `key`, `smudge`,
//! `expand`): where edits go and how they are written.
//!
//! By default edits go into an edit layer the user names, which sublayers the
//! input (created if missing), so opening the edit layer shows the edited
//! character and the input is untouched. `--in-place` edits the input's root
//! layer instead. Every write is atomic (temporary file, then rename).

use std::path::{Path, PathBuf};

use openusd::sdf::{self, Value};

use super::layer::{write_atomic, Format};
use super::stage::{StageMetadata, StageReader};
use crate::error::{Error, Result};

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
    /// A temporary header written to open a new edit layer; removed on drop.
    scratch: Option<PathBuf>,
}

impl Drop for EditSession {
    fn drop(&mut self) {
        if let Some(s) = &self.scratch {
            let _ = std::fs::remove_file(s);
        }
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

impl EditSession {
    /// Opens `input` for editing into `target`.
    pub fn open(input: &Path, target: &EditTarget) -> Result<EditSession> {
        // Reading the input first gives its own errors (missing, unreadable).
        let input_meta = StageReader::open(input)?.metadata();
        match target {
            EditTarget::InPlace => {
                let ext = input.extension().and_then(|e| e.to_str()).unwrap_or("");
                if ext == "usdz" {
                    return Err(Error::msg("cannot edit a .usdz package in place; use --edit-layer").in_file(input));
                }
                Ok(EditSession {
                    reader: StageReader::open(input)?,
                    input_meta,
                    target: input.to_path_buf(),
                    scratch: None,
                })
            }
            EditTarget::Layer(edit) => {
                Format::from_path(edit)?;
                if let (Ok(a), Ok(b)) = (input.canonicalize(), edit.canonicalize()) {
                    if a == b {
                        return Err(Error::msg(
                            "the edit layer is the input itself: pass --in-place to edit the input",
                        )
                        .in_file(edit));
                    }
                }
                if edit.exists() {
                    return Ok(EditSession {
                        reader: StageReader::open(edit)?,
                        input_meta,
                        target: edit.to_path_buf(),
                        scratch: None,
                    });
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
                let sub = sublayer_path(input, &dir)?;
                let name = edit
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default();
                let scratch = dir.join(format!(".{name}.painterly-new-{}.usda", std::process::id()));
                // Stage metadata comes from the root layer: copy the input's, or
                // opening the edit layer would retime and re-orient the input.
                let mut header = format!("#usda 1.0\n(\n    doc = \"painterly edit layer over {sub}\"\n");
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
                    header.push_str(&format!("    upAxis = \"{up}\"\n"));
                }
                if let Some(dp) = StageReader::open(input)?.stage.default_prim() {
                    header.push_str(&format!("    defaultPrim = \"{}\"\n", dp.as_str()));
                }
                header.push_str(&format!("    subLayers = [@{sub}@]\n)\n"));
                std::fs::write(&scratch, header)
                    .map_err(|e| Error::msg(format!("cannot create edit layer: {e}")).in_file(edit))?;
                let session = EditSession {
                    input_meta,
                    reader: StageReader {
                        stage: StageReader::open(&scratch)?.stage,
                        file: edit.to_path_buf(),
                    },
                    target: edit.to_path_buf(),
                    scratch: Some(scratch),
                };
                Ok(session)
            }
        }
    }

    /// The file edits are written to.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Authors an attribute's default value (`uniform` when the schema says so).
    pub fn set(&self, prim: &str, name: &str, type_name: &str, uniform: bool, value: Value) -> Result<()> {
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
            .map_err(|e| Error::attr(prim, name, format!("cannot author: {e}")))
    }

    /// Defines a typed prim (or re-specifies an existing one's type).
    pub fn define(&self, path: &str, type_name: &str) -> Result<()> {
        self.reader
            .stage
            .define_prim(path)
            .and_then(|p| p.set_type_name(type_name))
            .map(|_| ())
            .map_err(|e| Error::prim(path, format!("cannot define {type_name}: {e}")))
    }

    /// Writes the root layer to the target, atomically.
    pub fn save(self) -> Result<()> {
        let format = Format::from_path(&self.target)?;
        let root = self.reader.stage.root_layer();
        match format {
            Format::Usda => {
                let bytes = openusd::usda::TextWriter::write_to_string(root.data())
                    .map(String::into_bytes)
                    .map_err(|e| Error::msg(format!("cannot serialise edit layer: {e}")))?;
                drop(root);
                write_atomic(&self.target, &bytes)
            }
            Format::Usdc => super::usdc::write_layer_file(&self.target, root.data()),
        }
    }
}
