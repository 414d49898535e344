//! Relative asset paths that resolve from wherever a layer is opened.
//!
//! usd-core anchors a relative asset path to the path the layer was opened
//! by, joined and normalised as text (`TfNormPath`: a `..` removes the
//! folder before it, links are not followed), and only then asks the file
//! system. A folder reached through a link (`views -> scratch/a/b/views`)
//! has two such paths, the link's and the real one, and a relative path
//! made between real paths can name nothing from the link's. So a
//! candidate is kept only when it names the file from both.

use std::path::{Component, Path, PathBuf};

/// `file` as a relative asset path (`./x`, `../x`) from the folder `dir`,
/// one that names the same file whether `dir` is opened as given (through
/// links) or by its real path; `None` when none does, or when the two
/// share only the root (the caller writes an absolute path).
pub fn relative_asset_path(file: &Path, dir: &Path) -> Option<String> {
    let real_file = file.canonicalize().ok()?;
    let real_dir = dir.canonicalize().ok()?;
    let seen_file = lexical_absolute(file)?;
    let seen_dir = lexical_absolute(dir)?;
    [relative(&seen_file, &seen_dir), relative(&real_file, &real_dir)]
        .into_iter()
        .flatten()
        .find(|rel| names(&seen_dir, rel, &real_file) && names(&real_dir, rel, &real_file))
}

/// Whether `rel`, anchored to `dir` as usd-core anchors it, is `target`.
fn names(dir: &Path, rel: &str, target: &Path) -> bool {
    normalise(&dir.join(rel)).canonicalize().is_ok_and(|p| p == target)
}

/// `p` made absolute from the working folder and normalised as text. The
/// working folder is the shell's `$PWD` when that names it (`cd views`
/// through a link: the path the user sees, as `pwd -L` gives it), else the
/// real one.
fn lexical_absolute(p: &Path) -> Option<PathBuf> {
    if p.is_absolute() {
        return Some(normalise(p));
    }
    let real = std::env::current_dir().ok()?;
    let seen = std::env::var_os("PWD")
        .map(PathBuf::from)
        .filter(|d| d.is_absolute() && d.canonicalize().ok() == real.canonicalize().ok());
    Some(normalise(&seen.unwrap_or(real).join(p)))
}

/// `.` removed and each `..` taking away the component before it, without
/// looking at the file system.
fn normalise(p: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                if !out.pop() {
                    out.push(c);
                }
            }
            c => out.push(c),
        }
    }
    out
}

/// `file` relative to `dir` (both absolute and normalised), `./` or `../`
/// first; `None` when they share only the root.
fn relative(file: &Path, dir: &Path) -> Option<String> {
    let a: Vec<Component> = file.components().collect();
    let b: Vec<Component> = dir.components().collect();
    let common = a.iter().zip(&b).take_while(|(x, y)| x == y).count();
    if common <= 1 {
        return None;
    }
    let mut parts: Vec<String> = vec![".".into()];
    parts.extend(std::iter::repeat_n("..".to_string(), b.len() - common));
    parts.extend(a[common..].iter().map(|c| c.as_os_str().to_string_lossy().into_owned()));
    if parts.len() > 1 && parts[1] == ".." {
        parts.remove(0);
    }
    Some(parts.join("/"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_folder_reached_through_a_link_gets_a_path_that_works_from_both() {
        let scratch = crate::test_dir::ScratchDir::new("anchor");
        let root = scratch.canonicalize().unwrap();
        std::fs::create_dir_all(root.join("proj")).unwrap();
        std::fs::create_dir_all(root.join("deep/a/b/views")).unwrap();
        std::fs::write(root.join("proj/walk.usda"), "#usda 1.0\n").unwrap();
        std::os::unix::fs::symlink(root.join("deep/a/b/views"), root.join("views")).unwrap();
        let file = root.join("proj/walk.usda");
        // Between real paths it is ../../../../proj/walk.usda, which from the
        // link's folder (root/views) names a file above root; between the
        // paths as given, ../proj/walk.usda names deep/a/b/proj/walk.usda
        // from the real folder: neither, so the caller writes it absolute.
        assert_eq!(relative_asset_path(&file, &root.join("views")), None);
        // A file beside the view, both through the link: ./ from both.
        std::fs::write(root.join("deep/a/b/views/bake.usdc"), "").unwrap();
        assert_eq!(
            relative_asset_path(&root.join("views/bake.usdc"), &root.join("views")).as_deref(),
            Some("./bake.usdc")
        );
        // Plain folders: the plain relative path.
        assert_eq!(
            relative_asset_path(&file, &root.join("deep")).as_deref(),
            Some("../proj/walk.usda")
        );
        assert_eq!(
            relative_asset_path(&file, &root.join("proj")).as_deref(),
            Some("./walk.usda")
        );
        assert_eq!(normalise(Path::new("/a/./b/../c")), PathBuf::from("/a/c"));
    }
}
