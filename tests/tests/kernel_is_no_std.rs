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

#[test]
fn kernel_sources_use_no_allocator() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("../kernel/src");
    let lib = std::fs::read_to_string(src.join("lib.rs")).expect("lib.rs");
    assert!(lib.contains("#![no_std]"));
    for entry in std::fs::read_dir(&src).expect("kernel/src") {
        let path = entry.expect("entry").path();
        let text = std::fs::read_to_string(&path).expect("source");
        for needle in ["extern crate alloc", "alloc::", "extern crate std", "std::"] {
            assert!(!text.contains(needle), "{} uses `{needle}`", path.display());
        }
    }
}
