//! `painterly view`: a small assembly layer that shows a bake over its input
//! in usdview (or any USD viewer) at the baked frames.
//!
//! The layer sublayers the bake (stronger) and the input, and carries what a
//! viewer needs from the root layer: the baked time range, rates, `upAxis`,
//! `metersPerUnit` and `defaultPrim` (UsdValidation checks the last three).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::bake_layer::{check_baked_from, quoted, UsdaNumber};
use super::layer::{write_atomic, Format};
use super::stage::StageReader;
use crate::error::{Error, Result};

/// What `painterly view` wrote.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ViewSummary {
    pub input: PathBuf,
    pub bake: PathBuf,
    pub output: PathBuf,
    pub start_time_code: f64,
    pub end_time_code: f64,
    pub default_prim: String,
    /// Problems that did not stop the write.
    pub warnings: Vec<String>,
}

/// Writes `output`: `bake` over `input`, ready to open in a viewer.
pub fn write_view_layer(input: &Path, bake: &Path, output: &Path) -> Result<ViewSummary> {
    if Format::from_path(output)? != Format::Usda {
        return Err(Error::usage("the view layer is text: name it .usda").in_file(output));
    }
    for (p, what) in [(input, "input"), (bake, "bake layer")] {
        super::stage::require_file(p, what)?;
    }
    let r = StageReader::open_mapped(input)?;
    super::clips::check_not_an_input_file(&r, output)?;
    if super::stage::same_file(bake, output) {
        return Err(Error::msg("output would overwrite the bake layer; the view layer is a new file").in_file(output));
    }
    let meta = r.metadata();
    let mut warnings = Vec::new();
    let range =
        check_baked_from(input, Some(&r), bake, &mut warnings)?.and_then(|p| p.frame_range().map(|(a, b, _)| (a, b)));
    let (start, end) = range
        .or(meta.start_time_code.zip(meta.end_time_code))
        .ok_or_else(|| Error::msg("neither the bake nor the input says which frames to show").in_file(bake))?;
    let default_prim = match r.stage.default_prim() {
        Some(p) => p.as_str().trim_start_matches('/').to_string(),
        None => {
            let first = r
                .stage
                .root_prims()
                .ok()
                .and_then(|c| c.into_iter().next())
                .map(|t| t.as_str().to_string())
                .ok_or_else(|| Error::msg("the input has no root prim to show").in_file(input))?;
            warnings.push(format!("the input has no defaultPrim: using /{first}"));
            first
        }
    };
    let dir = match output.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if !dir.is_dir() {
        return Err(Error::msg(format!("output directory {} does not exist", dir.display())).in_file(output));
    }
    let mut text = String::from("#usda 1.0\n(\n");
    let _ = writeln!(text, "    defaultPrim = {}", quoted(&default_prim));
    let _ = writeln!(
        text,
        "    doc = {}",
        quoted("Made by painterly view: the bake over its input, for viewers.")
    );
    let _ = writeln!(text, "    endTimeCode = {}", UsdaNumber(end));
    if let Some(v) = meta.frames_per_second {
        let _ = writeln!(text, "    framesPerSecond = {}", UsdaNumber(v));
    }
    if let Some(v) = meta.meters_per_unit {
        let _ = writeln!(text, "    metersPerUnit = {}", UsdaNumber(v));
    }
    let _ = writeln!(text, "    startTimeCode = {}", UsdaNumber(start));
    let _ = writeln!(text, "    subLayers = [");
    let _ = writeln!(text, "        @{}@,", asset_path(bake, &dir)?);
    let _ = writeln!(text, "        @{}@", asset_path(input, &dir)?);
    let _ = writeln!(text, "    ]");
    if let Some(v) = meta.time_codes_per_second {
        let _ = writeln!(text, "    timeCodesPerSecond = {}", UsdaNumber(v));
    }
    if let Some(v) = &meta.up_axis {
        let _ = writeln!(text, "    upAxis = {}", quoted(v));
    }
    text.push_str(")\n");
    write_atomic(output, text.as_bytes())?;
    Ok(ViewSummary {
        input: input.to_path_buf(),
        bake: bake.to_path_buf(),
        output: output.to_path_buf(),
        start_time_code: start,
        end_time_code: end,
        default_prim,
        warnings,
    })
}

/// `file` as an asset path from `dir`: relative (`./`, `../`) when one
/// names it whether `dir` is opened as given or by its real path (see
/// [`super::anchor`]), so a shot folder can move; absolute otherwise.
fn asset_path(file: &Path, dir: &Path) -> Result<String> {
    let abs = file
        .canonicalize()
        .map_err(|e| Error::msg(format!("cannot resolve path: {e}")).in_file(file))?;
    dir.canonicalize()
        .map_err(|e| Error::msg(format!("cannot resolve path: {e}")).in_file(dir))?;
    let s = super::anchor::relative_asset_path(file, dir).unwrap_or_else(|| abs.to_string_lossy().into_owned());
    super::layer::check_asset_path(&s, file)?;
    Ok(s)
}
