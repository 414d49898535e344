//! Scratch folders for unit tests (test builds only).

use std::ops::Deref;
use std::path::{Path, PathBuf};

/// An empty folder under the system temp folder, named after a tag and this
/// process, removed when dropped, so a failing test leaves nothing behind.
pub(crate) struct ScratchDir(PathBuf);

impl ScratchDir {
    /// A fresh folder `painterly-<tag>-<pid>`; whatever was there is removed.
    pub(crate) fn new(tag: &str) -> ScratchDir {
        let dir = std::env::temp_dir().join(format!("painterly-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        ScratchDir(dir)
    }
}

impl Deref for ScratchDir {
    type Target = Path;

    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for ScratchDir {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scratch_dir_starts_empty_and_goes_when_dropped() {
        let stale = ScratchDir::new("scratch-self-test");
        std::fs::write(stale.join("old"), b"x").unwrap();
        let path = stale.to_path_buf();
        std::mem::forget(stale);
        let d = ScratchDir::new("scratch-self-test");
        assert_eq!(&*d, path.as_path());
        assert_eq!(std::fs::read_dir(&*d).unwrap().count(), 0);
        std::fs::write(d.join("f"), b"x").unwrap();
        drop(d);
        assert!(!path.exists());
    }
}
