//! Stages whose root layer is handed over in memory.
//!
//! A pipeline script holds a layer usd-core has open (`Sdf.Layer`), perhaps
//! edited and unsaved; C++ objects cannot cross into Rust, but its text
//! (`ExportToString()`) can. openusd reads layer bytes through its asset
//! resolver, so a resolver that serves those bytes for one path, and the
//! filesystem for everything else, opens them as if they were that file:
//! relative sublayers, references and clips anchor where the layer lives.

use std::borrow::Cow;
use std::io;
use std::path::{Path, PathBuf};
use std::time::SystemTime;

use openusd::ar::{Asset, AssetBuffer, AssetInfo, ResolvedPath, Resolver};

use super::regular::RegularResolver;

use super::stage::StageReader;
use crate::error::{Error, Result};

/// Serves one layer from memory at `identifier`; every other asset from the filesystem.
struct MemoryResolver {
    inner: RegularResolver,
    identifier: String,
    bytes: Vec<u8>,
}

impl MemoryResolver {
    fn is_ours(&self, path: &str) -> bool {
        path == self.identifier
    }
}

impl Resolver for MemoryResolver {
    fn create_identifier(&self, asset_path: &str, anchor: Option<&ResolvedPath>) -> String {
        self.inner.create_identifier(asset_path, anchor)
    }

    fn resolve(&self, asset_path: &str) -> Option<ResolvedPath> {
        if self.is_ours(asset_path) {
            return Some(ResolvedPath::new(&self.identifier));
        }
        self.inner.resolve(asset_path)
    }

    fn resolve_for_new_asset(&self, asset_path: &str) -> Option<ResolvedPath> {
        self.inner.resolve_for_new_asset(asset_path)
    }

    fn open_asset(&self, resolved_path: &ResolvedPath) -> io::Result<Box<dyn Asset>> {
        if self.is_ours(&resolved_path.to_string_lossy()) {
            return Ok(Box::new(io::Cursor::new(AssetBuffer::Owned(self.bytes.clone()))));
        }
        self.inner.open_asset(resolved_path)
    }

    fn get_extension<'a>(&self, asset_path: &'a str) -> &'a str {
        self.inner.get_extension(asset_path)
    }

    fn is_context_dependent_path(&self, asset_path: &str) -> bool {
        self.inner.is_context_dependent_path(asset_path)
    }

    fn in_memory_identifier<'a>(&self, asset_path: &'a str) -> Cow<'a, str> {
        self.inner.in_memory_identifier(asset_path)
    }

    fn get_asset_info(&self, asset_path: &str, resolved_path: &ResolvedPath) -> AssetInfo {
        self.inner.get_asset_info(asset_path, resolved_path)
    }

    fn get_modification_timestamp(&self, asset_path: &str, resolved_path: &ResolvedPath) -> Option<SystemTime> {
        if self.is_ours(&resolved_path.to_string_lossy()) {
            return None;
        }
        self.inner.get_modification_timestamp(asset_path, resolved_path)
    }

    fn identity(&self) -> String {
        format!("painterly-memory:{}", self.identifier)
    }
}

/// Opens a stage whose root layer is `bytes` (usda text or crate bytes), as
/// if it were the file at `path`. `path` should end in `.usda` (or `.usdc`
/// for crate bytes): openusd picks the format by extension. Nothing is
/// read from or written to `path` itself.
pub fn open_bytes(bytes: Vec<u8>, path: &Path) -> Result<StageReader> {
    let path = if path.is_absolute() {
        path.to_path_buf()
    } else {
        std::env::current_dir()
            .map_err(|e| Error::msg(format!("cannot read the working directory: {e}")))?
            .join(path)
    };
    let path_str = path
        .to_str()
        .ok_or_else(|| Error::msg("layer path is not valid UTF-8").in_file(&path))?;
    let inner = RegularResolver::new();
    let identifier = inner.create_identifier(path_str, None);
    let resolver = MemoryResolver {
        inner,
        identifier: identifier.clone(),
        bytes,
    };
    // The checks and composition of a file on disk (guard, watch, unresolved assets).
    let mut reader = StageReader::compose(&PathBuf::from(path_str), &identifier, resolver)?;
    // Served from memory: a save of the file at `path` changes nothing read.
    reader.opened.remove(Path::new(&identifier));
    reader.opened.remove(&path);
    Ok(reader)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_text_as_if_at_a_path_with_relative_sublayers_from_disk() {
        let dir = crate::test_dir::ScratchDir::new("memory");
        std::fs::write(
            dir.join("base.usda"),
            "#usda 1.0\ndef Xform \"World\" { def Sphere \"Ball\" { double radius = 2 } }\n",
        )
        .unwrap();
        let text = "#usda 1.0\n(\n    subLayers = [@./base.usda@]\n)\nover \"World\" { def Cube \"Box\" {} }\n";
        // Not on disk: only its directory is.
        let r = open_bytes(text.as_bytes().to_vec(), &dir.join("shot.usda")).unwrap();
        let paths = r.prim_paths().unwrap();
        assert_eq!(paths, ["/World", "/World/Ball", "/World/Box"]);
        assert!(!dir.join("shot.usda").exists());
        let ball = r.require_prim("/World/Ball").unwrap();
        assert_eq!(
            r.typed(&ball, "radius", None, "double", crate::usd_io::values::scalar)
                .unwrap(),
            Some(2.0)
        );

        let err = open_bytes(b"#usda 1.0\ndef Xform \"A\" {".to_vec(), &dir.join("bad.usda"))
            .err()
            .unwrap();
        assert!(err.to_string().contains("bad.usda"), "{err}");
    }

    #[test]
    fn a_save_of_the_file_at_the_served_path_is_no_change_of_what_was_read() {
        // The text served is what was read: a file saved at its path (by
        // another process) is not, and refused a Python bake of an edited
        // layer as "changed while painterly read it".
        let dir = crate::test_dir::ScratchDir::new("memory-saved");
        std::fs::write(dir.join("base.usda"), "#usda 1.0\ndef Xform \"World\" {}\n").unwrap();
        std::fs::write(dir.join("shot.usda"), "#usda 1.0\n").unwrap();
        let text = "#usda 1.0\n(\n    subLayers = [@./base.usda@]\n)\n";
        let r = open_bytes(text.as_bytes().to_vec(), &dir.join("shot.usda")).unwrap();
        assert_eq!(r.opened.keys().collect::<Vec<_>>(), [&dir.join("base.usda")]);
        std::fs::write(dir.join("shot.usda"), "#usda 1.0\n\n").unwrap();
        r.check_unchanged().unwrap();
        std::fs::write(dir.join("base.usda"), "#usda 1.0\ndef Xform \"World\" {}\n\n").unwrap();
        assert!(r.check_unchanged().is_err());
    }

    /// Every question but "what is at our path" goes to the filesystem
    /// resolver unchanged; otherwise sublayers and clips beside a handed-over
    /// layer would resolve differently from the same layer on disk.
    #[test]
    fn answers_like_the_filesystem_resolver_except_for_its_own_layer() {
        let dir = crate::test_dir::ScratchDir::new("memory-fwd");
        let on_disk = dir.join("real.usda");
        std::fs::write(&on_disk, "#usda 1.0\n").unwrap();
        let ours = dir.join("held.usdc").to_str().unwrap().to_string();
        let r = MemoryResolver {
            inner: RegularResolver::new(),
            identifier: ours.clone(),
            bytes: b"crate bytes".to_vec(),
        };
        let plain = openusd::ar::DefaultResolver::new();

        // Extensions pick the file format.
        assert_eq!(r.get_extension(&ours), "usdc");
        assert_eq!(r.get_extension("a/b.usda"), "usda");
        // A bare name is a search path (context dependent); an absolute or
        // ./-relative one is not.
        assert!(r.is_context_dependent_path("layer.usda"));
        assert!(!r.is_context_dependent_path("./layer.usda"));
        assert!(!r.is_context_dependent_path(&ours));
        // Relative spellings of one in-memory layer share one identifier.
        assert_eq!(r.in_memory_identifier("./sub//a.usda"), "sub/a.usda");
        assert_eq!(r.in_memory_identifier(&ours), ours.as_str());
        // New assets land where the filesystem resolver puts them.
        let new = dir.join("new.usda").to_str().unwrap().to_string();
        assert_eq!(r.resolve_for_new_asset(&new), plain.resolve_for_new_asset(&new));
        assert_eq!(r.resolve_for_new_asset(&new).as_deref(), Some(Path::new(&new)));
        // Our layer has no file, so no timestamp; a real file has its own.
        let real = ResolvedPath::new(on_disk.clone());
        assert_eq!(
            r.get_modification_timestamp("real.usda", &real),
            Some(std::fs::metadata(&on_disk).unwrap().modified().unwrap())
        );
        assert_eq!(r.get_modification_timestamp(&ours, &ResolvedPath::new(&ours)), None);
        // Resolving and opening: ours from memory, the rest from disk.
        assert_eq!(r.resolve(&ours), Some(ResolvedPath::new(&ours)));
        assert_eq!(r.resolve(on_disk.to_str().unwrap()), Some(real.clone()));
        let held = r.open_asset(&ResolvedPath::new(&ours)).unwrap().read_all().unwrap();
        assert_eq!(held, b"crate bytes");
        // A stack composed through this resolver is told apart from one
        // composed from the file on disk.
        assert_eq!(r.identity(), format!("painterly-memory:{ours}"));
        assert_ne!(r.identity(), plain.identity());
    }
}
