//! `remove_all_temporaries` (run before the composition watchdog's exit)
//! removes every live temporary. A file of its own: it removes the
//! temporaries of every thread, so no other test may run in this process.

use painterly::usd_io::atomic::{
    remove_all_temporaries, remove_all_temporaries_unless_held, ScratchFile, TempDir, TempFile,
};

#[test]
fn remove_all_temporaries_removes_files_and_folders() {
    let dir = std::env::temp_dir().join(format!("painterly-remove-all-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let (tmp, file) = TempFile::create(&dir.join("out.usdc"), "").unwrap();
    drop(file);
    let scratch = ScratchFile::create(&dir.join("e.usda"), b"#usda 1.0\n").unwrap();
    let render = TempDir::new().unwrap();
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 2);
    assert!(render.path().is_dir());
    remove_all_temporaries();
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
    assert!(!render.path().exists());
    drop((tmp, scratch, render));
    // The panic hook's version does the same when nothing holds the list.
    let (tmp, file) = TempFile::create(&dir.join("out.usdc"), "").unwrap();
    drop(file);
    let render = TempDir::new().unwrap();
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
    remove_all_temporaries_unless_held();
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
    assert!(!render.path().exists());
    drop((tmp, render));
    std::fs::remove_dir_all(&dir).unwrap();
}
