//! The `voxcube` command: the default render works with no files; a bad scene exits non-zero,
//! says what is wrong on stderr and writes no image.

use std::process::Command;

fn voxcube() -> Command {
    Command::new(env!("CARGO_BIN_EXE_voxcube"))
}

/// Run `voxcube render ARGS -o DIR --report DIR/REPORT`, which must succeed; the report and stdout.
fn render_ok(dir: &std::path::Path, args: &[&str], report: &str) -> (serde_json::Value, String) {
    let out = voxcube()
        .arg("render")
        .args(args)
        .arg("-o")
        .arg(dir)
        .arg("--report")
        .arg(dir.join(report))
        .output()
        .expect("runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json =
        serde_json::from_slice(&std::fs::read(dir.join(report)).expect("report")).expect("json");
    (json, String::from_utf8_lossy(&out.stdout).to_string())
}

#[test]
fn default_render_writes_a_png_and_a_report() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (json, stdout) = render_ok(dir.path(), &[], "r.json");
    let png = std::fs::read(dir.path().join("molecule-paper.png")).expect("image written");
    assert_eq!(&png[1..4], b"PNG");
    let view = &json["views"][0];
    assert_eq!(view["pixels_sha256"].as_str().map(str::len), Some(64));
    assert_eq!(view["rays"]["shadow"], 0);
    assert_eq!(view["nan_pixels"], 0);
    assert!(
        stdout.contains("molecule/paper") && stdout.contains("shadow"),
        "{stdout}"
    );
}

#[test]
fn the_skipping_switches_change_no_pixel_and_no_count() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (on, _) = render_ok(dir.path(), &[], "on.json");
    let (no_leap, _) = render_ok(dir.path(), &["--no-leap"], "no-leap.json");
    let (no_cells, _) = render_ok(dir.path(), &["--no-cells"], "no-cells.json");
    let (off, _) = render_ok(dir.path(), &["--no-skip"], "off.json");
    let view = |j: &serde_json::Value| j["views"][0].clone();
    for other in [&no_leap, &no_cells, &off] {
        assert_eq!(view(&on)["pixels_sha256"], view(other)["pixels_sha256"]);
    }
    // Leaping skips the same samples as one block per jump; cell masks skip more; without
    // skipping none are.
    assert_eq!(view(&on)["operations"], view(&no_leap)["operations"]);
    let skipped = |j: &serde_json::Value| view(j)["operations"]["skipped"].as_u64().unwrap_or(0);
    assert!(skipped(&on) > skipped(&no_cells), "{}", view(&no_cells));
    assert!(
        view(&on)["operations"]["skipped"].as_u64().unwrap_or(0) > 0,
        "{}",
        view(&on)
    );
    assert_eq!(view(&off)["operations"]["skipped"], 0, "{}", view(&off));
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

#[test]
fn sim_fabric_reports_traffic_and_matches_the_direct_image() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (direct, _) = render_ok(dir.path(), &[], "direct.json");
    let (sim, stdout) = render_ok(
        dir.path(),
        &[
            "--nodes",
            "4",
            "--clusters",
            "1",
            "--fabric",
            "sim",
            "--seed",
            "3",
        ],
        "sim.json",
    );
    assert_eq!(
        direct["views"][0]["pixels_sha256"],
        sim["views"][0]["pixels_sha256"]
    );
    assert_eq!(direct["views"][0]["traffic"], serde_json::Value::Null);
    let traffic = &sim["views"][0]["traffic"];
    assert!(
        traffic["rays_forwarded"].as_u64().unwrap_or(0) > 0,
        "{traffic}"
    );
    assert!(traffic["descriptors_returned"].as_u64().unwrap_or(0) > 0);
    assert!(traffic["messages"]["ray"].as_u64().unwrap_or(0) > 0);
    assert_eq!(traffic["nodes"].as_array().map(Vec::len), Some(4));
    assert_eq!(
        traffic["boundary_crossings"][0].as_array().map(Vec::len),
        Some(3)
    );
    assert_eq!(sim["views"][0]["seed"], 3);
    assert!(stdout.contains("rays across slab boundaries"), "{stdout}");
}

#[test]
fn impossible_machines_are_refused_before_anything_is_written() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out_dir = dir.path().join("out");
    for (args, expect) in [
        (
            vec!["--nodes", "4", "--fabric", "direct"],
            "direct fabric renders on one node",
        ),
        (vec!["--nodes", "6"], "power of two"),
        (
            vec!["--nodes", "4", "--clusters", "8"],
            "at most the 4 nodes",
        ),
    ] {
        let out = voxcube()
            .arg("render")
            .args(&args)
            .arg("-o")
            .arg(&out_dir)
            .output()
            .expect("runs");
        assert!(!out.status.success(), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(expect), "{args:?}: {err}");
        assert!(!out_dir.join("molecule-paper.png").exists());
    }
}

#[test]
fn bad_machines_are_clear_errors() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = dir.path().join("s.toml");
    std::fs::write(&scene, "[[datasets]]\nname = \"s\"\nbuiltin = \"sphere\"\n[[datasets.views]]\nwidth = 8\nheight = 8\n[[datasets.views.surfaces]]\niso = 0.0\n").expect("write");
    for (args, expect) in [
        (vec!["--nodes", "0"], "power of two"),
        (vec!["--nodes", "12"], "power of two"),
        (vec!["--nodes", "2048"], "1 to 1024"),
        (vec!["--nodes", "4", "--clusters", "3"], "a power of two"),
        (vec!["--nodes", "128"], "need at least 128 X planes"),
        (
            vec!["--nodes", "4", "--buffer", "100"],
            "give each node at least",
        ),
    ] {
        let out = voxcube()
            .arg("render")
            .arg(&scene)
            .args(&args)
            .arg("-o")
            .arg(dir.path().join("o"))
            .output()
            .expect("runs");
        assert!(!out.status.success(), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(expect), "{args:?}: {err}");
        assert!(
            !dir.path().join("o").join("s-view0.png").exists(),
            "{args:?} wrote an image"
        );
    }
}

/// `--machine host` gives each node this machine's memory shared by the nodes: the default
/// scene's two nodes then hold what an nCUBE 2 node (4 MiB) has no room for (the node field,
/// the cells' value ranges), and draw the same pixels.
#[test]
fn host_nodes_hold_what_small_nodes_cannot_and_draw_the_same_pixels() {
    let dir = tempfile::tempdir().expect("tempdir");
    let run = |machine: &str| {
        let args = ["--fabric", "threads", "--nodes", "2", "--clusters", "2"];
        let args = [&args[..], &["--machine", machine]].concat();
        let (json, _) = render_ok(dir.path(), &args, &format!("{machine}.json"));
        let view = &json["views"][0];
        (
            view["pixels_sha256"]
                .as_str()
                .unwrap_or_default()
                .to_string(),
            view["traffic"]["memory_max"].as_u64().unwrap_or(0),
        )
    };
    let (small, small_bytes) = run("ncube2");
    let (host, host_bytes) = run("host");
    assert_eq!(small.len(), 64);
    assert_eq!(small, host);
    assert!(small_bytes <= 4 << 20, "{small_bytes}");
    assert!(host_bytes > 4 << 20, "{host_bytes}");
}

#[test]
fn balancing_moves_the_cuts_and_not_a_pixel() {
    for fabric in ["sim", "threads"] {
        balancing_on(fabric);
    }
}

/// `--balance` on `fabric`: the nodes shift planes by message to the cuts the probe chose,
/// and the image stays the same.
fn balancing_on(fabric: &str) {
    let dir = tempfile::tempdir().expect("tempdir");
    let machine = ["--nodes", "8", "--clusters", "2", "--fabric", fabric];
    let (plain, _) = render_ok(dir.path(), &machine, "plain.json");
    let mut args = machine.to_vec();
    args.push("--balance");
    let (balanced, stdout) = render_ok(dir.path(), &args, "balanced.json");
    let (p, b) = (&plain["views"][0], &balanced["views"][0]);
    assert_eq!(p["pixels_sha256"], b["pixels_sha256"], "{fabric}");
    assert!(p["balance"].is_null());
    let report = &b["balance"];
    let cuts = |key: &str| -> Vec<u64> {
        report[key]
            .as_array()
            .expect("cuts")
            .iter()
            .filter_map(serde_json::Value::as_u64)
            .collect()
    };
    let (before, proposed, used) = (
        cuts("cuts_before"),
        cuts("cuts_proposed"),
        cuts("cuts_used"),
    );
    assert_eq!(before.len(), 5, "4 slabs per cluster: {before:?}");
    assert_ne!(proposed, before, "the molecule's slabs are unevenly loaded");
    for c in [&proposed, &used] {
        assert_eq!((c.first(), c.last()), (before.first(), before.last()));
        assert!(c.windows(2).all(|w| w[0] < w[1]), "{c:?}");
    }
    let frames = report["probe_frames"].as_array().expect("frames");
    let (uniform, new) = (
        frames[0].as_f64().expect("a time"),
        frames[1].as_f64().expect("a time"),
    );
    // Kept exactly when the probe ran faster with the proposal.
    assert_eq!(used == proposed, new < uniform, "{uniform} {new} {used:?}");
    assert_eq!(report["times_before"].as_array().map(Vec::len), Some(4));
    // The nodes really rendered with the cuts used.
    let first_node_planes = &b["traffic"]["nodes"];
    let owned: Vec<u64> = first_node_planes
        .as_array()
        .expect("nodes")
        .iter()
        .filter(|n| n["cluster"] == 0)
        .flat_map(|n| n["planes"].as_array().cloned().unwrap_or_default())
        .filter_map(|v| v.as_u64())
        .collect();
    for cut in &used {
        assert!(
            owned.contains(cut),
            "cut {cut} is a slab boundary: {owned:?}"
        );
    }
    assert!(stdout.contains("molecule/paper: balance ("), "{stdout}");
    // They got there from uniform slabs by slab-plane messages.
    let shift = &b["traffic"]["shift"];
    assert!(p["traffic"]["shift"].is_null(), "{fabric}");
    if used != before {
        assert!(shift["messages"].as_u64() > Some(0), "{fabric}: {shift}");
        assert!(shift["rounds"].as_u64() >= Some(1), "{fabric}: {shift}");
    }
}

#[test]
fn a_view_asks_for_balancing_in_the_scene() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = dir.path().join("s.toml");
    std::fs::write(
        &scene,
        "[[datasets]]\nname = \"s\"\nbuiltin = \"sphere\"\n[[datasets.views]]\nname = \"v\"\nwidth = 40\nheight = 30\nnodes = 4\nclusters = 1\nbalance = true\n[[datasets.views.surfaces]]\niso = 0.5\n",
    )
    .expect("write");
    let (json, _) = render_ok(
        dir.path(),
        &[scene.to_str().expect("utf-8"), "--fabric", "threads"],
        "r.json",
    );
    assert_eq!(
        json["views"][0]["balance"]["cuts_before"]
            .as_array()
            .map(Vec::len),
        Some(5)
    );
}

#[test]
fn paper_and_accuracy_without_sod_fail_naming_the_path_unless_told_to_substitute() {
    let dir = tempfile::tempdir().expect("tempdir");
    let missing = dir.path().join("no-such-folder");
    for command in ["paper", "accuracy"] {
        let out = voxcube()
            .args([command, "--data"])
            .arg(&missing)
            .arg("-o")
            .arg(dir.path().join(command))
            .output()
            .expect("runs");
        assert!(!out.status.success(), "{command} without SOD exited 0");
        let err = String::from_utf8_lossy(&out.stderr);
        for part in ["no-such-folder", "SOD not found", "--substitute"] {
            assert!(
                err.contains(part),
                "{command}: {err:?} does not mention {part:?}"
            );
        }
        assert!(
            !dir.path().join(command).exists(),
            "{command} wrote output before failing"
        );
    }
}

#[test]
fn a_view_that_draws_nothing_says_why_and_still_renders() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = dir.path().join("blank.toml");
    let view = |name: &str, body: &str| format!("[[datasets.views]]\nname = \"{name}\"\n{body}\n");
    let surface = "[[datasets.views.surfaces]]\niso = 50.0\n";
    let text = [
        "[[datasets]]\nname = \"m\"\nbuiltin = \"molecule\"\n".to_string(),
        view("high", "[[datasets.views.surfaces]]\niso = 5000.0"),
        view(
            "away",
            &format!("[datasets.views.camera]\nprojection = \"perspective\"\neye = [48.0, 48.0, -200.0]\nlook_at = [48.0, 48.0, -400.0]\n{surface}"),
        ),
        view(
            "aside",
            &format!("[datasets.views.camera]\nlook_at = [500.0, 48.0, 57.0]\nwidth = 100.0\n{surface}"),
        ),
        view(
            "clear",
            "mode = \"composite\"\n[[datasets.views.transfer]]\nvalue = 0.0\ncolor = [1.0, 1.0, 1.0]\nopacity = 0.0\n[[datasets.views.transfer]]\nvalue = 300.0\ncolor = [1.0, 1.0, 1.0]\nopacity = 0.0",
        ),
        view("fine", surface),
    ]
    .concat();
    std::fs::write(&scene, text).expect("write");
    let out = voxcube()
        .arg("render")
        .arg(&scene)
        .arg("-o")
        .arg(dir.path())
        .arg("--report")
        .arg(dir.path().join("r.json"))
        .output()
        .expect("runs");
    assert!(out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    for (view, cause) in [
        (
            "m/high",
            "surfaces[0].iso = 5000 lies outside the data's range",
        ),
        ("m/away", "the camera faces away"),
        ("m/aside", "no primary ray meets the volume"),
        (
            "m/clear",
            "the transfer function is transparent over the data's range",
        ),
    ] {
        assert!(
            stderr.contains(&format!("warning: {view}: {cause}")),
            "{view}: {stderr}"
        );
    }
    assert!(!stderr.contains("m/fine"), "{stderr}");
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("r.json")).expect("report"))
            .expect("json");
    let warnings = |i: usize| json["views"][i]["warnings"].as_array().map(Vec::len);
    assert_eq!(
        (0..5).map(warnings).collect::<Vec<_>>(),
        [Some(1), Some(1), Some(1), Some(1), Some(0)]
    );
    assert!(dir.path().join("m-high.png").exists());
}

/// `voxcube render -q -o DIR ARGS` with stdout to `stdout`; the exit success and stderr.
fn render_to(dir: &std::path::Path, args: &[&str], stdout: std::process::Stdio) -> (bool, String) {
    let out = voxcube()
        .args(["render", "-q", "-o"])
        .arg(dir)
        .args(args)
        .stdout(stdout)
        .output()
        .expect("runs");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).to_string(),
    )
}

#[test]
fn outputs_are_checked_before_rendering_and_never_replace_a_special_file() {
    use std::os::unix::fs::FileTypeExt;
    let dir = tempfile::tempdir().expect("tempdir");
    let images = dir.path().join("images");
    let quiet = std::process::Stdio::null;
    // A report in a folder that does not exist: refused before any image is written.
    let missing = dir.path().join("nowhere/r.json");
    let (ok, err) = render_to(
        &images,
        &["--report", missing.to_str().expect("utf-8")],
        quiet(),
    );
    assert!(
        !ok && err.contains("nowhere") && err.contains("does not exist"),
        "{err}"
    );
    assert!(!images.join("molecule-paper.png").exists());
    // A folder as the report, a file as the image folder.
    let (ok, err) = render_to(
        &images,
        &["--report", dir.path().to_str().expect("utf-8")],
        quiet(),
    );
    assert!(!ok && err.contains("is a folder"), "{err}");
    std::fs::write(dir.path().join("file"), b"x").expect("write");
    let (ok, err) = render_to(&dir.path().join("file"), &[], quiet());
    assert!(!ok && err.contains("expected a folder"), "{err}");
    // A device that refuses the bytes: an error, and the device stays a device.
    let (ok, err) = render_to(&images, &["--report", "/dev/full"], quiet());
    assert!(!ok && err.contains("/dev/full"), "{err}");
    let full = std::fs::metadata("/dev/full").expect("/dev/full");
    assert!(full.file_type().is_char_device());
    // A symlink is written through, and stays a symlink.
    let link = dir.path().join("link.json");
    std::os::unix::fs::symlink(dir.path().join("real.json"), &link).expect("symlink");
    let (ok, err) = render_to(
        &images,
        &["--report", link.to_str().expect("utf-8")],
        quiet(),
    );
    assert!(ok, "{err}");
    assert!(std::fs::symlink_metadata(&link)
        .expect("link")
        .file_type()
        .is_symlink());
    let real = std::fs::read_to_string(dir.path().join("real.json")).expect("written through");
    assert!(real.contains("pixels_sha256"));
    // A FIFO is written into, and stays a FIFO.
    let fifo = dir.path().join("fifo");
    assert!(Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .expect("mkfifo")
        .success());
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::read_to_string(fifo).expect("read fifo"))
    };
    let (ok, err) = render_to(
        &images,
        &["--report", fifo.to_str().expect("utf-8")],
        quiet(),
    );
    assert!(ok, "{err}");
    assert!(reader.join().expect("reader").contains("pixels_sha256"));
    assert!(std::fs::metadata(&fifo)
        .expect("fifo")
        .file_type()
        .is_fifo());
}

#[test]
fn a_failed_write_to_standard_output_is_an_error() {
    let dir = tempfile::tempdir().expect("tempdir");
    let full = || {
        std::process::Stdio::from(
            std::fs::OpenOptions::new()
                .write(true)
                .open("/dev/full")
                .expect("/dev/full"),
        )
    };
    let out = voxcube()
        .args(["render", "-o"])
        .arg(dir.path())
        .stdout(full())
        .output()
        .expect("runs");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("standard output"),
        "{err}"
    );
    let out = voxcube()
        .arg("scene")
        .stdout(full())
        .output()
        .expect("runs");
    assert!(!out.status.success());
    // Control: the same commands to /dev/null succeed.
    let out = voxcube()
        .arg("scene")
        .stdout(std::process::Stdio::null())
        .output()
        .expect("runs");
    assert!(out.status.success());
}

#[test]
fn the_fabric_help_names_every_fabric() {
    let out = voxcube().args(["render", "--help"]).output().expect("runs");
    let help = String::from_utf8_lossy(&out.stdout);
    let line = help
        .split("--fabric")
        .nth(1)
        .and_then(|s| s.split("Possible values").next())
        .unwrap_or_default();
    for fabric in ["direct", "sim", "threads", "mpi"] {
        assert!(
            line.contains(fabric),
            "--fabric's help omits {fabric}: {line}"
        );
    }
}

#[test]
fn an_orbit_writes_its_frames_and_an_animation_that_turns() {
    use image::AnimationDecoder;
    let dir = tempfile::tempdir().expect("tempdir");
    let (still, _) = render_ok(dir.path(), &[], "still.json");
    let (orbit, _) = render_ok(dir.path(), &["--orbit", "4"], "orbit.json");
    let views = orbit["views"].as_array().expect("views");
    let names: Vec<&str> = views.iter().filter_map(|v| v["view"].as_str()).collect();
    assert_eq!(names, ["paper-000", "paper-001", "paper-002", "paper-003"]);
    // Frame 0 is the view itself (its camera gives a width: no reframing); the others turn.
    let hash = |v: &serde_json::Value| v["pixels_sha256"].as_str().map(str::to_string);
    assert_eq!(hash(&views[0]), hash(&still["views"][0]));
    assert_ne!(hash(&views[0]), hash(&views[2]));
    let gif = std::fs::File::open(dir.path().join("molecule-paper.gif")).expect("gif written");
    let frames = image::codecs::gif::GifDecoder::new(std::io::BufReader::new(gif))
        .expect("a gif")
        .into_frames()
        .collect_frames()
        .expect("frames");
    assert_eq!(frames.len(), 4);
    assert_eq!(frames[0].buffer().dimensions(), (350, 250));
}

#[test]
fn a_simulated_run_s_timeline_is_chrome_trace_json_covering_every_node_s_time() {
    let dir = tempfile::tempdir().expect("tempdir");
    let trace = dir.path().join("t.json");
    let args = [
        "--nodes",
        "4",
        "--clusters",
        "2",
        "--fabric",
        "sim",
        "--trace",
    ];
    let mut all: Vec<&str> = args.to_vec();
    all.push(trace.to_str().expect("utf-8"));
    render_ok(dir.path(), &all, "r.json");
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&trace).expect("trace written")).expect("json");
    let events = json["traceEvents"].as_array().expect("traceEvents");
    let names: Vec<&str> = events
        .iter()
        .filter(|e| e["ph"] == "M" && e["name"] == "thread_name")
        .filter_map(|e| e["args"]["name"].as_str())
        .collect();
    assert_eq!(names, ["node 0", "node 1", "node 2", "node 3"]);
    let frame = json["otherData"]["frame_s"].as_f64().expect("frame") * 1e6;
    for node in 0..4 {
        let spans: Vec<(f64, f64)> = events
            .iter()
            .filter(|e| e["ph"] == "X" && e["tid"] == node)
            .map(|e| {
                (
                    e["ts"].as_f64().expect("ts"),
                    e["dur"].as_f64().expect("dur"),
                )
            })
            .collect();
        assert!(spans.iter().all(|&(ts, dur)| ts >= 0.0 && dur > 0.0));
        // Spans follow each other without overlap, to the bit (a viewer nests a span that
        // starts a rounding error before its predecessor's end inside it), and cover the
        // node's whole frame.
        for w in spans.windows(2) {
            assert!(w[0].0 + w[0].1 <= w[1].0, "node {node}: {w:?}");
        }
        // From 0 to the node's end, which is the frame's end or a little after (a node may
        // still be terminating when the host holds the last pixel).
        let covered: f64 = spans.iter().map(|s| s.1).sum();
        let end = spans.last().map_or(0.0, |s| s.0 + s.1);
        assert!(spans.first().is_some_and(|s| s.0 == 0.0), "node {node}");
        assert!(
            (covered - end).abs() <= 1e-6 * end,
            "node {node}: {covered} of {end}"
        );
        assert!(
            end >= frame * (1.0 - 1e-9),
            "node {node}: ends at {end}, frame {frame}"
        );
    }
    let kinds: std::collections::BTreeSet<&str> =
        events.iter().filter_map(|e| e["cat"].as_str()).collect();
    assert!(kinds.contains("compute") && kinds.contains("send") && kinds.contains("idle"));
    // Only the simulator keeps virtual time.
    let out = voxcube()
        .args(["render", "--trace"])
        .arg(&trace)
        .arg("-o")
        .arg(dir.path())
        .output()
        .expect("runs");
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--fabric sim"));
}

/// With one cluster nobody can re-trace a lost node's rows: the run fails (exit 1), the views
/// before it are written, and the report lists them and names what the failed view lost.
#[test]
fn a_lost_node_with_no_cluster_left_fails_with_the_finished_views_written_and_the_loss_reported() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene =
        String::from_utf8(voxcube().arg("scene").output().expect("runs").stdout).expect("utf-8");
    let at = scene.find("[[datasets.views]]").expect("a view");
    let paper = &scene[at..];
    let small = paper
        .replace("name = \"paper\"", "name = \"small\"")
        .replace("width = 350", "width = 24")
        .replace("height = 250", "height = 16");
    let path = dir.path().join("two.toml");
    std::fs::write(&path, format!("{}{small}\n{paper}", &scene[..at])).expect("write");
    for fabric in ["sim", "threads"] {
        let out_dir = dir.path().join(fabric);
        let report = dir.path().join(format!("{fabric}.json"));
        // Node 1 takes fewer than 300 steps in the small view, far more in the paper's.
        let out = voxcube()
            .arg("render")
            .arg(&path)
            .args(["--nodes", "4", "--fabric", fabric, "--stop-node", "1@300"])
            .args(["--lost-after", "1", "-o"])
            .arg(&out_dir)
            .arg("--report")
            .arg(&report)
            .output()
            .expect("runs");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{fabric}: {stderr}");
        assert!(
            stderr.contains("molecule/paper") && stderr.contains("node 1 stopped answering"),
            "{fabric}: {stderr}"
        );
        assert!(out_dir.join("molecule-small.png").is_file(), "{fabric}");
        assert!(!out_dir.join("molecule-paper.png").exists(), "{fabric}");
        let json: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&report).expect("report")).expect("json");
        assert_eq!(json["views"].as_array().map(Vec::len), Some(1), "{fabric}");
        assert_eq!(json["views"][0]["view"], "small", "{fabric}");
        let failed = &json["failed"];
        assert_eq!(failed["view"], "paper", "{fabric}: {failed}");
        assert_eq!(failed["lost"]["node"], 1, "{fabric}: {failed}");
        assert!(
            failed["lost"]["pixels"].as_u64() > Some(0),
            "{fabric}: {failed}"
        );
        assert!(failed["lost"]["rows"].is_string(), "{fabric}: {failed}");
    }
}

#[test]
fn a_stopped_node_costs_no_pixel_and_is_named_in_a_warning_and_the_report() {
    let dir = tempfile::tempdir().expect("tempdir");
    let machine = ["--nodes", "8", "--clusters", "2"];
    let (clean, _) = render_ok(
        dir.path(),
        &[&machine[..], &["--fabric", "sim"]].concat(),
        "clean.json",
    );
    for fabric in ["sim", "threads"] {
        let args = [
            &machine[..],
            &[
                "--fabric",
                fabric,
                "--stop-node",
                "5@60",
                "--lost-after",
                "1",
            ],
        ]
        .concat();
        let out = voxcube()
            .arg("render")
            .args(&args)
            .arg("-o")
            .arg(dir.path())
            .arg("--report")
            .arg(dir.path().join("lost.json"))
            .output()
            .expect("runs");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{fabric}: {stderr}");
        assert!(
            stderr.contains("warning: molecule/paper: node 5 (cluster 1) stopped answering"),
            "{fabric}: {stderr}"
        );
        let lost: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.path().join("lost.json")).expect("report"))
                .expect("json");
        let view = &lost["views"][0];
        assert_eq!(
            view["pixels_sha256"], clean["views"][0]["pixels_sha256"],
            "{fabric}"
        );
        assert_eq!(view["recovery"]["node"], 5, "{fabric}");
        assert_eq!(view["recovery"]["by"], serde_json::json!([0]), "{fabric}");
        assert!(view["recovery"]["retraced"].as_u64() > Some(0), "{fabric}");
    }
    // Bad uses name the flag and what was expected.
    for (args, expected) in [
        (
            vec!["--nodes", "8", "--clusters", "2", "--stop-node", "9@5"],
            "--stop-node 9: the machine has nodes 0 to 7",
        ),
        (
            vec!["--stop-node", "0@5"],
            "injects a fault into a machine of nodes",
        ),
        (
            vec!["--nodes", "2", "--stop-node", "1"],
            "expected NODE@STEPS",
        ),
        (
            vec!["--nodes", "2", "--lost-after", "0"],
            "expected seconds",
        ),
        (
            vec!["--nodes", "8", "--clusters", "4", "--fabric", "sim"]
                .into_iter()
                .chain(["--stop-node", "3@40", "--stop-node", "2@5"])
                .collect(),
            "--stop-node 2: a second fault stops a node in the re-trace of node 3's cluster, so it must be in another cluster",
        ),
        (
            vec!["--nodes", "8", "--clusters", "4", "--fabric", "sim"]
                .into_iter()
                .chain(["--stop-node", "3@40", "--stop-node", "0@5:exit"])
                .collect(),
            "`:exit` is for the first fault only",
        ),
        (
            vec!["--nodes", "8", "--clusters", "4", "--fabric", "sim"]
                .into_iter()
                .chain(["--stop-node", "3@40", "--stop-node", "0@5", "--stop-node", "4@5"])
                .collect(),
            "at most twice",
        ),
    ] {
        let out = voxcube()
            .arg("render")
            .args(&args)
            .arg("-o")
            .arg(dir.path().join("bad"))
            .output()
            .expect("runs");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && stderr.contains(expected),
            "{args:?}: {stderr}"
        );
    }
}

/// A built-in volume no machine here holds is refused before a sample is generated: 4096³
/// (64 GiB, allowed by `--max-samples`) on one `modern` node and on 64, named with the
/// smallest cluster that fits, exit 1, no image. Generated first, it would not fit this
/// machine's memory: the allocation would fail and the process abort.
#[test]
fn a_volume_too_big_for_the_machine_is_refused_before_it_is_generated() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = dir.path().join("huge.toml");
    std::fs::write(
        &scene,
        "[[datasets]]\nname = \"huge\"\nbuiltin = \"molecule\"\nsize = 4096\n[[datasets.views]]\nname = \"v\"\n[[datasets.views.surfaces]]\niso = 60.0\n",
    )
    .expect("scene written");
    for nodes in ["1", "64"] {
        let out = voxcube()
            .args(["--max-samples", "100000000000", "render"])
            .arg(&scene)
            .args(["--machine", "modern", "--nodes", nodes, "--fabric"])
            .arg(if nodes == "1" { "direct" } else { "threads" })
            .arg("-o")
            .arg(dir.path().join("out"))
            .output()
            .expect("runs");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{nodes}: {stderr}");
        assert!(
            stderr.contains(&format!("huge/v: a node of a cluster of {nodes} needs"))
                && stderr.contains("the smallest cluster that fits has 128 nodes"),
            "{nodes}: {stderr}"
        );
        assert!(!dir.path().join("out/huge-v.png").exists());
    }
}
