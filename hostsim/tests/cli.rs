//! The `voxcube` command: the default render works with no files; a bad scene exits non-zero,
//! says what is wrong on stderr and writes no image.

use std::process::Command;

fn voxcube() -> Command {
    Command::new(env!("CARGO_BIN_EXE_voxcube"))
}

#[test]
fn default_render_writes_a_png_and_a_report() {
    let dir = tempfile::tempdir().expect("tempdir");
    let report = dir.path().join("r.json");
    let out = voxcube()
        .args(["render", "-o"])
        .arg(dir.path())
        .arg("--report")
        .arg(&report)
        .output()
        .expect("runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let png = std::fs::read(dir.path().join("molecule-paper.png")).expect("image written");
    assert_eq!(&png[1..4], b"PNG");
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(report).expect("report")).expect("json");
    let view = &json["views"][0];
    assert_eq!(view["pixels_sha256"].as_str().map(str::len), Some(64));
    assert_eq!(view["rays"]["shadow"], 0);
    assert_eq!(view["nan_pixels"], 0);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("molecule/paper") && stdout.contains("shadow"),
        "{stdout}"
    );
}

#[test]
fn a_bad_scene_fails_cleanly_and_writes_nothing() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = dir.path().join("bad.toml");
    // The first dataset is fine; the second is missing: nothing may be written for either.
    std::fs::write(
        &scene,
        "[[datasets]]\nname = \"ok\"\nbuiltin = \"sphere\"\n[[datasets.views]]\n[[datasets.views.surfaces]]\niso = 0.0\n\
         [[datasets]]\nname = \"gone\"\npath = \"missing.nhdr\"\n[[datasets.views]]\n[[datasets.views.surfaces]]\niso = 0.0\n",
    )
    .expect("write");
    let out_dir = dir.path().join("out");
    let out = voxcube()
        .arg("render")
        .arg(&scene)
        .arg("-o")
        .arg(&out_dir)
        .output()
        .expect("runs");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("bad.toml") && err.contains("datasets[1]") && err.contains("missing.nhdr"),
        "{err}"
    );
    assert!(!out_dir.exists(), "nothing may be written for a bad scene");
}

#[test]
fn scene_prints_the_default_scene_which_parses() {
    let out = voxcube().arg("scene").output().expect("runs");
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("[[datasets]]") && text.contains("builtin = \"molecule\""));
}
