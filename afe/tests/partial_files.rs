//! Issue 44, item 11, in a process of its own (removing this process's temporary files
//! would race with other tests' writes in a shared test binary).

use std::path::{Path, PathBuf};

use afe::output::{commit_all, remove_partial_files, OutputFile};

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("afe-output-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("temp dir");
    d
}

fn entries(d: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(d)
        .expect("dir")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// A process quitting at once removes the temporary files it is writing; staged outputs
/// dropped uncommitted leave nothing; committed ones are in place.
#[test]
fn staged_outputs_commit_together_or_leave_nothing() {
    let d = dir("staged");
    let a = OutputFile::check(&d.join("a.npz")).expect("a");
    let b = OutputFile::check(&d.join("b.json")).expect("b");
    let staged = vec![
        a.stage(|f| f.write_all(b"aa")).expect("staged"),
        b.stage(|f| f.write_all(b"bb")).expect("staged"),
    ];
    assert_eq!(entries(&d).len(), 2);
    assert!(entries(&d).iter().all(|n| n.ends_with(".partial")));
    drop(staged);
    assert!(entries(&d).is_empty(), "{:?}", entries(&d));

    let staged = a.stage(|f| f.write_all(b"aa")).expect("staged");
    assert_eq!(entries(&d).len(), 1);
    remove_partial_files();
    assert!(entries(&d).is_empty(), "{:?}", entries(&d));
    drop(staged);

    let staged = vec![
        a.stage(|f| f.write_all(b"aa")).expect("staged"),
        b.stage(|f| f.write_all(b"bb")).expect("staged"),
    ];
    commit_all(staged).expect("committed");
    assert_eq!(entries(&d), ["a.npz", "b.json"]);
    assert_eq!(std::fs::read(d.join("b.json")).expect("b"), b"bb");
}
