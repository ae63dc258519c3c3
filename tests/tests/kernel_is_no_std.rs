//! The kernel is `no_std` and allocation-free: no dependency of it enables a `std` feature, and
//! its sources never bring in `alloc`.

use std::path::Path;
use std::process::Command;

#[test]
fn no_std_feature_in_the_kernel_dependency_tree() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let out = Command::new(env!("CARGO"))
        .args([
            "tree",
            "-p",
            "voxcube-kernel",
            "-e",
            "features",
            "--prefix",
            "none",
            "--offline",
        ])
        .current_dir(&root)
        .output()
        .expect("cargo runs");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "cargo tree failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains("voxcube-kernel"), "{text}");
    let std_features: Vec<&str> = text
        .lines()
        .filter(|l| l.contains("feature \"std\""))
        .collect();
    assert!(
        std_features.is_empty(),
        "std enabled in the kernel's tree: {std_features:?}"
    );
}

/// Every `.rs` file below `dir`, in every subfolder.
fn sources(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("a kernel source folder") {
        let path = entry.expect("entry").path();
        if path.is_dir() {
            sources(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// What of the allocator or std a source names.
fn forbidden(text: &str) -> Vec<&'static str> {
    ["extern crate alloc", "alloc::", "extern crate std", "std::"]
        .into_iter()
        .filter(|needle| text.contains(needle))
        .collect()
}

#[test]
fn kernel_sources_use_no_allocator() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("../kernel/src");
    let lib = std::fs::read_to_string(src.join("lib.rs")).expect("lib.rs");
    assert!(lib.contains("#![no_std]"));
    let mut files = Vec::new();
    sources(&src, &mut files);
    // The walk reaches the modules in the role folders, not just the top level.
    for inner in [
        "node/worker.rs",
        "trace/march.rs",
        "volume/field.rs",
        "skip/blocks.rs",
    ] {
        assert!(files.contains(&src.join(inner)), "the walk missed {inner}");
    }
    for path in &files {
        let text = std::fs::read_to_string(path).expect("source");
        let found = forbidden(&text);
        assert!(found.is_empty(), "{} uses {found:?}", path.display());
    }
}

#[test]
fn the_check_catches_an_allocator_or_std() {
    assert_eq!(forbidden("use alloc::vec::Vec;"), ["alloc::"]);
    assert_eq!(forbidden("let t = std::time::Instant::now();"), ["std::"]);
    assert!(forbidden("use core::fmt;").is_empty());
}
