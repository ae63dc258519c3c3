//! Every bad input gets an error that names the file, the key or field, and what was expected.

use std::path::Path;
use voxcube::input::scene::{Scene, SceneError};

/// Check and load scene text in `dir`; the error message.
fn error_of(dir: &Path, text: &str) -> String {
    let file = dir.join("scene.toml");
    std::fs::write(&file, text).expect("write scene");
    match Scene::from_file(&file).and_then(Scene::load) {
        Ok(_) => panic!("scene was accepted:\n{text}"),
        Err(e) => e.to_string(),
    }
}

fn assert_names(msg: &str, parts: &[&str]) {
    for p in parts {
        assert!(msg.contains(p), "error {msg:?} does not mention {p:?}");
    }
}

fn raw_scene(file: &str, extra: &str) -> String {
    format!("[[datasets]]\nname = \"d\"\npath = \"{file}\"\nformat = \"raw\"\n{extra}\n[[datasets.views]]\n[[datasets.views.surfaces]]\niso = 1.0\n")
}

// ------------------------------------------------------------------ views

#[test]
fn an_unknown_accuracy_tier_names_the_key_and_the_tiers() {
    let dir = tempfile::tempdir().expect("tempdir");
    let m = error_of(
        dir.path(),
        "[[datasets]]\nname = \"m\"\nbuiltin = \"molecule\"\n[[datasets.views]]\naccuracy = \"fastest\"\n",
    );
    assert_names(
        &m,
        &["scene.toml", "accuracy", "fastest", "`exact` or `fast`"],
    );
}

// ------------------------------------------------------------------ datasets

#[test]
fn truncated_and_trailing_raw_files() {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("v.raw"), [0u8; 12 + 7]).expect("write");
    let m = error_of(
        dir.path(),
        &raw_scene(
            "v.raw",
            "dims = [2, 2, 2]\ntype = \"u8\"\nheader_bytes = 12",
        ),
    );
    assert_names(
        &m,
        &[
            "v.raw",
            "truncated",
            "expected 20 bytes, found 19",
            "datasets[0]",
        ],
    );
    std::fs::write(dir.path().join("v.raw"), [0u8; 12 + 9]).expect("write");
    let m = error_of(
        dir.path(),
        &raw_scene(
            "v.raw",
            "dims = [2, 2, 2]\ntype = \"u8\"\nheader_bytes = 12",
        ),
    );
    assert_names(&m, &["v.raw", "1 trailing bytes"]);
}

#[test]
fn zero_and_overflowing_dimensions() {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("v.raw"), [0u8; 8]).expect("write");
    let m = error_of(
        dir.path(),
        &raw_scene("v.raw", "dims = [2, 0, 2]\ntype = \"u8\""),
    );
    assert_names(&m, &["datasets[0].dims", "dims[1] is 0"]);
    let m = error_of(
        dir.path(),
        &raw_scene(
            "v.raw",
            "dims = [4294967295, 4294967295, 4294967295]\ntype = \"u16\"\nendian = \"little\"",
        ),
    );
    assert_names(&m, &["v.raw", "declare more than 2^64 samples"]);
    let m = error_of(
        dir.path(),
        &raw_scene("v.raw", "dims = [2, -1, 2]\ntype = \"u8\""),
    );
    assert_names(&m, &["scene.toml", "dims", "-1"]);
}

#[test]
fn unknown_sample_types() {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("v.raw"), [0u8; 8]).expect("write");
    let m = error_of(
        dir.path(),
        &raw_scene("v.raw", "dims = [2, 2, 2]\ntype = \"f64\""),
    );
    assert_names(&m, &["scene.toml", "unknown variant `f64`", "u8"]);
    let nhdr = "NRRD0004\ntype: double\ndimension: 3\nsizes: 2 2 2\nencoding: raw\nendian: little\ndata file: v.raw\n";
    std::fs::write(dir.path().join("v.nhdr"), nhdr).expect("write");
    let m = error_of(dir.path(), "[[datasets]]\nname = \"d\"\npath = \"v.nhdr\"\n[[datasets.views]]\n[[datasets.views.surfaces]]\niso = 1.0\n");
    assert_names(&m, &["v.nhdr", "type \"double\" is not supported"]);
}

#[test]
fn nan_and_infinity_in_float_volumes() {
    let dir = tempfile::tempdir().expect("tempdir");
    for (bad, word) in [(f32::NAN, "NaN"), (f32::NEG_INFINITY, "-inf")] {
        let bytes: Vec<u8> = [1.0f32, 2.0, bad, 3.0]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        std::fs::write(dir.path().join("f.raw"), bytes).expect("write");
        let m = error_of(
            dir.path(),
            &raw_scene(
                "f.raw",
                "dims = [2, 2, 1]\ntype = \"f32\"\nendian = \"little\"",
            ),
        );
        assert_names(&m, &["f.raw", "(x 0, y 1, z 0)", word, "must be finite"]);
    }
}

#[test]
fn missing_files_and_missing_raw_fields() {
    let dir = tempfile::tempdir().expect("tempdir");
    let m = error_of(
        dir.path(),
        &raw_scene("nowhere.raw", "dims = [2, 2, 2]\ntype = \"u8\""),
    );
    assert_names(&m, &["nowhere.raw", "cannot read"]);
    let m = error_of(dir.path(), &raw_scene("v.raw", "type = \"u8\""));
    assert_names(&m, &["datasets[0].dims", "needs dims"]);
    let m = error_of(
        dir.path(),
        &raw_scene("v.raw", "dims = [2, 2, 2]\ntype = \"u16\""),
    );
    assert_names(&m, &["datasets[0].endian", "little or big"]);
}

#[test]
fn bad_nrrd_headers() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = "[[datasets]]\nname = \"d\"\npath = \"v.nrrd\"\n[[datasets.views]]\n[[datasets.views.surfaces]]\niso = 1.0\n";
    let cases: [(&[u8], &str); 5] = [
        (
            b"NRRD0004\ntype: uchar\nsizes: 2 2 2\nencoding: raw\n\n\0\0\0\0\0\0\0\0",
            "missing field \"dimension\"",
        ),
        (
            b"NRRD0004\ntype: uchar\ndimension: 2\nsizes: 2 2\nencoding: raw\n\n\0\0\0\0",
            "dimension is 2",
        ),
        (
            b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: bzip2\n\n",
            "encoding \"bzip2\"",
        ),
        (
            b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n\0\0\0",
            "truncated: expected 8 bytes, found 3",
        ),
        (
            b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: gzip\n\nnot gzip",
            "corrupt compressed data",
        ),
    ];
    for (bytes, expected) in cases {
        std::fs::write(dir.path().join("v.nrrd"), bytes).expect("write");
        assert_names(&error_of(dir.path(), scene), &["v.nrrd", expected]);
    }
}

#[test]
fn gzip_nrrd_loads() {
    use std::io::Write;
    let dir = tempfile::tempdir().expect("tempdir");
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    gz.write_all(&[0, 10, 20, 30, 40, 50, 60, 70])
        .expect("gzip");
    let mut bytes =
        b"NRRD0005\ntype: uint8\ndimension: 3\nsizes: 2 2 2\nencoding: gzip\nspacings: 1 2 3\n\n"
            .to_vec();
    bytes.extend(gz.finish().expect("gzip"));
    std::fs::write(dir.path().join("v.nrrd"), bytes).expect("write");
    let file = dir.path().join("s.toml");
    std::fs::write(&file, "[[datasets]]\nname = \"d\"\npath = \"v.nrrd\"\n[[datasets.views]]\n[[datasets.views.surfaces]]\niso = 1.0\n").expect("write");
    let jobs = Scene::from_file(&file)
        .and_then(Scene::load)
        .expect("loads");
    assert_eq!(jobs[0].volume.grid.dims(), [2, 2, 2]);
    assert_eq!(jobs[0].volume.grid.spacing().to_array(), [1.0, 2.0, 3.0]);
    assert_eq!(jobs[0].volume.stats().max, 70.0);
}

#[test]
fn bad_den_files() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = "[[datasets]]\nname = \"d\"\npath = \"v.den\"\n[[datasets.views]]\n[[datasets.views.surfaces]]\niso = 1.0\n";
    std::fs::write(dir.path().join("v.den"), [7u8; 80]).expect("write");
    assert_names(&error_of(dir.path(), scene), &["v.den", "not a .den file"]);
    std::fs::write(dir.path().join("v.den"), [1u8, 0, 0]).expect("write");
    assert_names(
        &error_of(dir.path(), scene),
        &["v.den", "truncated: expected 62 bytes"],
    );
}

// ------------------------------------------------------------------ the scene file

const VOL: &str = "[[datasets]]\nname = \"m\"\nbuiltin = \"sphere\"\n";

fn view_error(view: &str) -> String {
    let dir = tempfile::tempdir().expect("tempdir");
    error_of(dir.path(), &format!("{VOL}[[datasets.views]]\n{view}"))
}

const SURF: &str = "[[datasets.views.surfaces]]\niso = 0.0\n";

#[test]
fn unknown_keys_are_named() {
    let dir = tempfile::tempdir().expect("tempdir");
    assert_names(
        &error_of(
            dir.path(),
            &format!("colour = 1\n{VOL}[[datasets.views]]\n{SURF}"),
        ),
        &["scene.toml", "unknown field `colour`"],
    );
    assert_names(
        &view_error(&format!("stepsize = 0.5\n{SURF}")),
        &["unknown field `stepsize`", "dt"],
    );
    assert_names(
        &view_error(&format!("[datasets.views.camera]\nzoom = 2.0\n{SURF}")),
        &["unknown field `zoom`"],
    );
    assert_names(
        &view_error("[[datasets.views.surfaces]]\niso = 0.0\ncolour = [1.0, 1.0, 1.0]\n"),
        &["unknown field `colour`"],
    );
    assert_names(
        &view_error(&format!("mode = \"mip\"\n{SURF}")),
        &["unknown variant `mip`", "surfaces", "composite"],
    );
}

#[test]
fn out_of_range_values_name_their_key() {
    let cases: &[(&str, &[&str])] = &[
        (&format!("dt = 3.0\n{SURF}"), &["datasets[0].views[0]", "dt is 3", "[1/64, 2]"]),
        (&format!("dt = 0.0\n{SURF}"), &["dt is 0"]),
        (&format!("width = 0\n{SURF}"), &["datasets[0].views[0].width", "0x250"]),
        (&format!("gradient_distance = 9.0\n{SURF}"), &["gradient_distance is 9"]),
        (&format!("cutoff = 1.0\n{SURF}"), &["cutoff is 1"]),
        (&format!("max_depth = 99\n{SURF}"), &["max_depth is 99"]),
        (&format!("background = [0.0, 2.0, 0.0]\n{SURF}"), &["datasets[0].views[0].background"]),
        ("[[datasets.views.surfaces]]\niso = 0.0\ntransparency = 1.5\n", &["surfaces[0].transparency", "[0, 1]"]),
        ("[[datasets.views.surfaces]]\niso = nan\n", &["surfaces[0].iso", "finite"]),
        ("[[datasets.views.surfaces]]\niso = 0.0\ncolor = [1.0, 1.0, 7.0]\n", &["surfaces[0].color"]),
        ("", &["needs at least one", "surfaces"]),
        (&format!("nodes = 6\n{SURF}"), &["datasets[0].views[0].nodes", "power of two"]),
        (&format!("nodes = 2\nclusters = 4\n{SURF}"), &["clusters", "4 clusters cannot be made of 2 nodes"]),
        (&format!("[datasets.views.camera]\nelevation = 100.0\n{SURF}"), &["camera.elevation", "[-90, 90]"]),
        (&format!("[datasets.views.camera]\nprojection = \"perspective\"\nfov = 0.0\n{SURF}"), &["camera.fov", "(0, 180)"]),
        (&format!("[datasets.views.camera]\nfov = 30.0\n{SURF}"), &["camera.fov", "perspective"]),
        (&format!("[datasets.views.camera]\neye = [1.0, 2.0, 3.0]\nazimuth = 3.0\n{SURF}"), &["camera.eye", "not both"]),
        (&format!("[datasets.views.camera]\neye = [0.0, 5.0, 0.0]\nlook_at = [0.0, 0.0, 0.0]\n{SURF}"), &["camera", "up is zero or parallel"]),
        (&format!("[datasets.views.camera]\neye = [1.0, 1.0, 1.0]\nlook_at = [1.0, 1.0, 1.0]\n{SURF}"), &["camera", "same point"]),
        (&format!("{SURF}[[datasets.views.lights]]\ntype = \"directional\"\n"), &["lights[0].direction", "needs direction"]),
        (&format!("{SURF}[[datasets.views.lights]]\ntype = \"directional\"\ndirection = [0.0, 0.0, 0.0]\n"), &["lights[0]", "non-zero"]),
        (&format!("{SURF}[[datasets.views.lights]]\ntype = \"point\"\nposition = [0.0, 0.0, 0.0]\nintensity = -1.0\n"), &["lights[0].intensity"]),
        (
            "mode = \"composite\"\n[[datasets.views.transfer]]\nvalue = 5.0\ncolor = [1.0, 1.0, 1.0]\nopacity = 0.5\n[[datasets.views.transfer]]\nvalue = 1.0\ncolor = [1.0, 1.0, 1.0]\nopacity = 0.5\n",
            &["transfer", "point 1", "strictly increasing"],
        ),
        (
            "mode = \"composite\"\n[[datasets.views.transfer]]\nvalue = 5.0\ncolor = [1.0, 1.0, 1.0]\nopacity = 0.5\n[[datasets.views.lights]]\ntype = \"directional\"\ndirection = [1.0, 0.0, 0.0]\nshadows = true\n",
            &["lights[0].shadows", "composite"],
        ),
        ("mode = \"composite\"\n", &["transfer", "at least one point"]),
    ];
    for (view, parts) in cases {
        assert_names(&view_error(view), parts);
    }
}

#[test]
fn dataset_entries_are_checked() {
    let dir = tempfile::tempdir().expect("tempdir");
    let v = format!("[[datasets.views]]\n{SURF}");
    let cases: &[(String, &[&str])] = &[
        ("datasets = []\n".to_string(), &["datasets", "at least one"]),
        (format!("[[datasets]]\nname = \"a b\"\nbuiltin = \"sphere\"\n{v}"), &["datasets[0].name", "letters"]),
        (format!("{VOL}{v}{VOL}{v}"), &["datasets[1].name", "names two datasets"]),
        (format!("[[datasets]]\nname = \"x\"\nbuiltin = \"teapot\"\n{v}"), &["datasets[0].builtin", "unknown built-in \"teapot\"", "molecule"]),
        (format!("[[datasets]]\nname = \"x\"\n{v}"), &["datasets[0].path", "needs a path or a builtin"]),
        (format!("[[datasets]]\nname = \"x\"\nbuiltin = \"sphere\"\npath = \"a.raw\"\n{v}"), &["datasets[0].builtin", "not both"]),
        (format!("[[datasets]]\nname = \"x\"\nbuiltin = \"sphere\"\ndims = [1, 1, 1]\n{v}"), &["datasets[0].dims", "raw files"]),
        (format!("[[datasets]]\nname = \"x\"\nbuiltin = \"sphere\"\nsize = 1\n{v}"), &["datasets[0].size", "size is 1", "at least 2"]),
        (format!("[[datasets]]\nname = \"x\"\nbuiltin = \"molecule\"\nsize = 2000\n{v}"), &["datasets[0].size", "2000 × 2000 × 2000", "--max-samples"]),
        (format!("[[datasets]]\nname = \"x\"\npath = \"a.raw\"\nsize = 64\n{v}"), &["datasets[0].size", "built-in volumes"]),
        (format!("[[datasets]]\nname = \"x\"\npath = \"a.nhdr\"\nheader_bytes = 3\n{v}"), &["datasets[0].header_bytes", "header gives it"]),
        (format!("[[datasets]]\nname = \"x\"\npath = \"a.raw\"\nspacing = [1.0, 0.0, 1.0]\n{v}"), &["datasets[0].spacing", "> 0"]),
        (VOL.to_string(), &["views"]),
        (format!("{VOL}[[datasets.views]]\nname = \"a\"\n{SURF}[[datasets.views]]\nname = \"a\"\n{SURF}"), &["views[1].name", "names two views"]),
        ("this is not toml".to_string(), &["scene.toml", "TOML parse error"]),
    ];
    for (text, parts) in cases {
        assert_names(&error_of(dir.path(), text), parts);
    }
}

#[test]
fn unreadable_scene_names_the_file() {
    let e = Scene::from_file(Path::new("/no/such/scene.toml")).unwrap_err();
    assert!(matches!(e, SceneError::Read { .. }));
    assert_names(&e.to_string(), &["/no/such/scene.toml", "cannot read"]);
}

#[test]
fn a_detached_header_s_bad_spacing_names_the_header() {
    let dir = tempfile::tempdir().expect("tempdir");
    let nhdr = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nspacings: 1 0 1\nencoding: raw\ndata file: v.raw\n";
    std::fs::write(dir.path().join("v.nhdr"), nhdr).expect("write");
    std::fs::write(dir.path().join("v.raw"), [0u8; 8]).expect("write");
    let m = error_of(dir.path(), "[[datasets]]\nname = \"d\"\npath = \"v.nhdr\"\n[[datasets.views]]\n[[datasets.views.surfaces]]\niso = 1.0\n");
    assert_names(&m, &["v.nhdr", "spacing y is 0"]);
    assert!(!m.contains("v.raw"), "{m}");
}

#[test]
fn a_volume_of_one_sample_asks_for_the_voxel_model() {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("v.raw"), [7u8]).expect("write");
    let m = error_of(
        dir.path(),
        &raw_scene("v.raw", "dims = [1, 1, 1]\ntype = \"u8\""),
    );
    assert_names(
        &m,
        &[
            "datasets[0].views[0].model",
            "at least 2 along each axis",
            "model = \"voxel\"",
        ],
    );
    // The voxel model takes it.
    let file = dir.path().join("voxel.toml");
    let text = raw_scene("v.raw", "dims = [1, 1, 1]\ntype = \"u8\"").replace(
        "[[datasets.views]]\n",
        "[[datasets.views]]\nmodel = \"voxel\"\n",
    );
    std::fs::write(&file, text).expect("write");
    Scene::from_file(&file)
        .and_then(Scene::load)
        .unwrap_or_else(|e| panic!("{e}"));
}

#[test]
fn a_buffer_too_big_for_any_node_blames_the_buffer() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_voxcube"))
        .args([
            "render",
            "-q",
            "--nodes",
            "2",
            "--buffer",
            "1000000000000",
            "-o",
        ])
        .arg(tempfile::tempdir().expect("tempdir").path())
        .output()
        .expect("runs");
    let m = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert_names(&m, &["receive buffer alone leaves no room", "--buffer"]);
    assert!(!m.contains("fits this volume"), "{m}");
}
