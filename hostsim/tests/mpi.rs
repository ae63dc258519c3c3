//! The MPI fabric, under `mpirun` on loopback (`cargo test -p voxcube --features mpi --test mpi`;
//! needs Open MPI). The image equals the simulator's bit for bit, balanced or not, and a
//! balanced run's nodes shift the same planes as the simulator's; a rank that hangs or dies
//! mid-render ends the run within seconds with an error, never a hang.
#![cfg(feature = "mpi")]

use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

fn sha_of(report: &Path) -> Vec<String> {
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(report).expect("report")).expect("json");
    json["views"]
        .as_array()
        .expect("views")
        .iter()
        .map(|v| v["pixels_sha256"].as_str().unwrap_or("").to_string())
        .collect()
}

/// One job at a time: jobs of 9 ranks side by side on a small machine starve each other's
/// heartbeats, and a node silent for `--lost-after` is declared lost.
static ONE_JOB: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// `mpirun` with `flags` of its own, `ranks` ranks of voxcube with `args`, under `timeout`: a
/// job that fails to end fails its test instead of hanging it.
fn mpirun(ranks: u32, flags: &[&str], args: &[&str]) -> std::process::Output {
    let _one = ONE_JOB
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    Command::new("timeout")
        .args(["-s", "KILL", "120", "mpirun"])
        .args(flags)
        .args([
            "--allow-run-as-root",
            "--oversubscribe",
            "-np",
            &ranks.to_string(),
        ])
        .arg(env!("CARGO_BIN_EXE_voxcube"))
        .args(args)
        .output()
        .expect("mpirun runs (install Open MPI)")
}

/// Render `common` (a render command line) on MPI with `flags` for `mpirun`, each of `faults`
/// as a `--stop-node` and `--lost-after 1`, then on the simulator without faults: `mpirun`'s
/// output, the MPI run's report, and whether the two runs' images are the same.
fn faulty_and_fault_free(
    dir: &Path,
    common: &[&str],
    flags: &[&str],
    faults: &[&str],
) -> (std::process::Output, serde_json::Value, bool) {
    let report = dir.join("mpi.json");
    let report_arg = report.display().to_string();
    let out_dir = dir.join("mpi").display().to_string();
    let mut args = common.to_vec();
    args.extend(["--fabric", "mpi", "--lost-after", "1", "-o", &out_dir]);
    args.extend(["--report", &report_arg]);
    for fault in faults {
        args.extend(["--stop-node", fault]);
    }
    let out = mpirun(9, flags, &args);
    if !out.status.success() {
        return (out, serde_json::Value::Null, false);
    }
    let sim_report = dir.join("sim.json");
    let sim = Command::new(env!("CARGO_BIN_EXE_voxcube"))
        .args(common)
        .args(["--fabric", "sim", "-o"])
        .arg(dir.join("sim"))
        .arg("--report")
        .arg(&sim_report)
        .output()
        .expect("sim runs");
    assert!(sim.status.success());
    let same = sha_of(&report) == sha_of(&sim_report);
    (out, read_report(&report), same)
}

fn scenes() -> Vec<String> {
    let mut s = vec![String::new()];
    let sod = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/sod.toml");
    if Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/data/sod-97x97x116.u8.binary")
        .is_file()
    {
        s.push(sod.display().to_string());
    } else {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI is set but the shared data is missing"
        );
    }
    s
}

#[test]
fn mpi_images_equal_the_simulator_s() {
    let dir = tempfile::tempdir().expect("tempdir");
    for scene in scenes() {
        for (nodes, clusters) in [(4u32, 1u32), (4, 2), (8, 1), (8, 2)] {
            let (n, m) = (nodes.to_string(), clusters.to_string());
            let mut common = vec!["render", "--nodes", &n, "--clusters", &m, "-q"];
            if !scene.is_empty() {
                common.insert(1, &scene);
            }
            let mpi_report = dir.path().join("mpi.json");
            let mut args = common.clone();
            args.extend(["--fabric", "mpi", "-o"]);
            let out_dir = dir.path().join("mpi").display().to_string();
            let report = mpi_report.display().to_string();
            args.extend([out_dir.as_str(), "--report", report.as_str()]);
            let out = mpirun(nodes + 1, &[], &args);
            assert!(
                out.status.success(),
                "{scene} {nodes}/{clusters}: {}",
                String::from_utf8_lossy(&out.stderr)
            );
            let sim_report = dir.path().join("sim.json");
            let sim = Command::new(env!("CARGO_BIN_EXE_voxcube"))
                .args(&common)
                .args(["--fabric", "sim", "-o"])
                .arg(dir.path().join("sim"))
                .arg("--report")
                .arg(&sim_report)
                .output()
                .expect("runs");
            assert!(
                sim.status.success(),
                "{}",
                String::from_utf8_lossy(&sim.stderr)
            );
            assert_eq!(
                sha_of(&mpi_report),
                sha_of(&sim_report),
                "{scene} on {nodes} nodes in {clusters} clusters"
            );
        }
    }
}

fn read_report(path: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).expect("report")).expect("json")
}

#[test]
fn balanced_mpi_nodes_shift_the_simulator_s_planes() {
    let dir = tempfile::tempdir().expect("tempdir");
    for scene in scenes() {
        let mut common = vec![
            "render",
            "--nodes",
            "8",
            "--clusters",
            "2",
            "--balance",
            "-q",
        ];
        if !scene.is_empty() {
            common.insert(1, &scene);
        }
        let run = |fabric: &str| {
            let path = dir.path().join(format!("{fabric}.json"));
            let mut args = common.clone();
            let out_dir = dir.path().join(fabric).display().to_string();
            let report = path.display().to_string();
            args.extend(["--fabric", fabric, "-o", &out_dir, "--report", &report]);
            let out = if fabric == "mpi" {
                mpirun(9, &[], &args)
            } else {
                Command::new(env!("CARGO_BIN_EXE_voxcube"))
                    .args(&args)
                    .output()
                    .expect("runs")
            };
            assert!(
                out.status.success(),
                "{scene} {fabric}: {}",
                String::from_utf8_lossy(&out.stderr)
            );
            read_report(&path)
        };
        let (mpi, sim) = (run("mpi"), run("sim"));
        for v in 0..sim["views"].as_array().map_or(0, Vec::len) {
            let (m, s) = (&mpi["views"][v], &sim["views"][v]);
            assert_eq!(m["pixels_sha256"], s["pixels_sha256"], "{scene} view {v}");
            assert_eq!(m["balance"]["cuts_used"], s["balance"]["cuts_used"]);
            let shift = &s["traffic"]["shift"];
            if s["balance"]["cuts_used"] != s["balance"]["cuts_before"] {
                assert!(shift["messages"].as_u64() > Some(0), "{scene}: {shift}");
            }
            for key in ["messages", "bytes", "rounds"] {
                assert_eq!(
                    m["traffic"]["shift"][key], shift[key],
                    "{scene} view {v}: {key}"
                );
            }
        }
    }
}

#[test]
fn a_rank_that_hangs_or_dies_ends_the_run_within_seconds() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out_dir = dir.path().join("out").display().to_string();
    let report = dir.path().join("failed.json");
    let report_arg = report.display().to_string();
    for (hook, expect) in [("1@60", "stopped answering"), ("2@60:exit", "")] {
        let start = Instant::now();
        let out = mpirun(
            5,
            &[],
            &[
                "render",
                "--fabric",
                "mpi",
                "--nodes",
                "4",
                "-o",
                &out_dir,
                "--report",
                &report_arg,
                "--stop-node",
                hook,
            ],
        );
        let took = start.elapsed();
        assert!(!out.status.success(), "{hook}: the run must fail");
        assert!(took < Duration::from_secs(30), "{hook}: took {took:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(expect), "{hook}: {err}");
        if !expect.is_empty() {
            assert!(err.contains("pixels are lost"), "{err}");
            // A hung rank leaves the host alive to report what was lost.
            let json = read_report(&report);
            assert_eq!(json["failed"]["lost"]["node"], 1, "{json}");
            assert!(
                json["failed"]["lost"]["pixels"].as_u64() > Some(0),
                "{json}"
            );
        } else {
            // A dead rank: `mpirun` ended every process at once. The report written before
            // the view says which views finished (none) and which was cut short.
            let json = read_report(&report);
            assert_eq!(json["views"], serde_json::json!([]), "{json}");
            assert_eq!(json["failed"]["view"], "paper", "{json}");
            assert_eq!(
                json["failed"]["error"], "the run ended before this view was finished",
                "{json}"
            );
        }
        std::fs::remove_file(&report).expect("a report");
        assert!(
            !Path::new(&out_dir).join("molecule-paper.png").exists(),
            "{hook}: no image from a failed run"
        );
    }
}

/// A rank that hangs mid-render in a machine of two clusters, and one that hangs or dies
/// under `mpirun --enable-recovery` (without it `mpirun` ends the whole job at once when a rank
/// dies): the host declares its node lost, the other cluster re-traces its cluster's
/// unfinished rows and renders every later view alone, every image equals the simulator's
/// fault-free one, and the job exits 0. Without recovery the host ends the job by
/// `MPI_Abort(0)` (a hung rank never finalises); with it the host kills the lost rank and every
/// rank exits.
#[test]
fn a_hung_or_dead_rank_s_rows_are_re_traced_by_the_other_cluster() {
    let dir = tempfile::tempdir().expect("tempdir");
    let none: &[&str] = &[];
    let recovery: &[&str] = &["--enable-recovery"];
    // (scene, fault, mpirun's flags, the render's own). Balanced, node 5 stops at its first
    // poll, in the plane shift: its neighbours' plane sends to it never complete.
    let cases = scenes()
        .into_iter()
        .map(|scene| (scene, "5@60", none, none))
        .chain([
            (String::new(), "5@60:exit", recovery, none),
            (String::new(), "5@60", recovery, none),
            (String::new(), "5@1", none, &["--balance"][..]),
            (String::new(), "5@1", recovery, &["--balance"][..]),
        ]);
    for (scene, hook, flags, extra) in cases {
        let mut common = vec!["render", "--nodes", "8", "--clusters", "2", "-q"];
        if !scene.is_empty() {
            common.insert(1, &scene);
        }
        common.extend(extra);
        let (out, json, same) = faulty_and_fault_free(dir.path(), &common, flags, &[hook]);
        let err = String::from_utf8_lossy(&out.stderr);
        // Without recovery the host aborts the job (the hung rank never finalises); with it,
        // the host fences the lost rank and every rank exits.
        assert_eq!(
            err.contains(voxcube::fabric::mpi::ENDING),
            flags.is_empty(),
            "{scene} {hook} {flags:?}: {err}"
        );
        assert!(
            out.status.success(),
            "{scene} {hook} {flags:?}: {:?} {err}",
            out.status
        );
        assert!(same, "{scene}: the images differ from the simulator's");
        for v in json["views"].as_array().expect("views") {
            assert_eq!(v["recovery"]["node"], 5, "{scene}: {v}");
            assert_eq!(v["recovery"]["by"], serde_json::json!([0]), "{scene}");
        }
        let first = &json["views"][0]["recovery"];
        assert!(
            first["declared_after_ms"].as_f64() >= Some(1000.0),
            "{first}"
        );
        assert!(first["retraced"].as_u64() > Some(0), "{first}");
    }
}

#[test]
fn mpi_fast_tier_images_equal_the_simulator_s() {
    let dir = tempfile::tempdir().expect("tempdir");
    let tests = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/tests/scenes.toml");
    // A pre-integrated view: every rank needs the view's table beside its slab.
    let shell = dir.path().join("shell.toml");
    std::fs::write(
        &shell,
        r#"[[datasets]]
name = "shell"
builtin = "molecule"
[[datasets.views]]
name = "pre-integrated"
width = 40
height = 30
dt = 1.5
mode = "composite"
accuracy = "fast"
compositing = "pre-integrated"
[[datasets.views.transfer]]
value = 118.0
color = [0.9, 0.7, 0.3]
opacity = 0.0
[[datasets.views.transfer]]
value = 120.0
color = [0.9, 0.7, 0.3]
opacity = 0.7
[[datasets.views.transfer]]
value = 122.0
color = [0.9, 0.7, 0.3]
opacity = 0.0
"#,
    )
    .expect("scene");
    let mut scenes = vec![tests.display().to_string(), shell.display().to_string()];
    scenes.extend(scenes_with_data());
    for scene in scenes {
        let render = |fabric: &str, name: &str| {
            let report = dir.path().join(format!("{name}.json"));
            let out = dir.path().join(name).display().to_string();
            let report_arg = report.display().to_string();
            let args = [
                "render",
                &scene,
                "--accuracy",
                "fast",
                "--nodes",
                "4",
                "--clusters",
                "2",
                "-q",
                "--fabric",
                fabric,
                "-o",
                &out,
                "--report",
                &report_arg,
            ];
            let status = if fabric == "mpi" {
                mpirun(5, &[], &args)
            } else {
                Command::new(env!("CARGO_BIN_EXE_voxcube"))
                    .args(args)
                    .output()
                    .expect("runs")
            };
            assert!(
                status.status.success(),
                "{scene} on {fabric}: {}",
                String::from_utf8_lossy(&status.stderr)
            );
            sha_of(&report)
        };
        let (mpi, sim) = (render("mpi", "mpi-fast"), render("sim", "sim-fast"));
        assert!(!mpi.is_empty());
        assert_eq!(mpi, sim, "{scene}: the fast tier's images differ on MPI");
    }
}

/// SOD's scene, where the shared data is there.
fn scenes_with_data() -> Vec<String> {
    scenes().into_iter().filter(|s| !s.is_empty()).collect()
}

/// A second rank lost during the re-trace the first loss causes (8 nodes in 4 clusters: node 3
/// stops in the frame, node 0 in the re-trace): its cluster leaves the re-trace too, the two
/// clusters left finish it, the image is the simulator's fault-free one, and the job exits 0.
#[test]
fn a_rank_lost_during_the_re_trace_takes_its_cluster_out_and_the_rest_finish() {
    let dir = tempfile::tempdir().expect("tempdir");
    let common = ["render", "--nodes", "8", "--clusters", "4", "-q"];
    let faults = ["3@40", "0@5"];
    let (out, json, same) = faulty_and_fault_free(dir.path(), &common, &[], &faults);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{:?} {err}", out.status);
    assert!(same, "the images differ from the simulator's");
    let recovery = &json["views"][0]["recovery"];
    assert_eq!(recovery["node"], 3, "{recovery}");
    assert_eq!(recovery["also_lost"], serde_json::json!([0]), "{recovery}");
    assert_eq!(recovery["by"], serde_json::json!([2, 3]), "{recovery}");
}

/// A node whose set-up (value ranges, skipping structures, node field of a big slab) takes
/// longer than `--lost-after` is not declared lost: its rank heartbeats while it builds. The
/// molecule at 512³ on two nodes with `--lost-after 0.5` (a rank's set-up takes about a second
/// on a 2-core machine; before the fix this run failed, "node 0 stopped answering"). The
/// image is the threads fabric's, and the report gives each rank's set-up and peak resident
/// memory and the host's.
#[test]
fn a_node_setting_up_a_big_slab_is_not_declared_lost() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (n, c) = (511.0f64 / 2.0, 2.0 * 512.0 / std::f64::consts::SQRT_2);
    let scene = dir.path().join("big.toml");
    std::fs::write(
        &scene,
        format!(
            r#"[[datasets]]
name = "m512"
builtin = "molecule"
size = 512
[[datasets.views]]
name = "fast"
width = 120
height = 90
mode = "composite"
accuracy = "fast"
[datasets.views.camera]
eye = [{e}, {n}, {e}]
look_at = [{n}, {n}, {n}]
width = 844.8
[[datasets.views.transfer]]
value = 10.0
color = [0.2, 0.3, 0.8]
opacity = 0.0
[[datasets.views.transfer]]
value = 200.0
color = [1.0, 0.2, 0.1]
opacity = 0.8
"#,
            e = n + c
        ),
    )
    .expect("scene written");
    let scene = scene.display().to_string();
    let render = |fabric: &str| {
        let report = dir.path().join(format!("{fabric}.json"));
        let out = dir.path().join(fabric).display().to_string();
        let report_arg = report.display().to_string();
        let args = [
            "render",
            &scene,
            "--nodes",
            "2",
            "--machine",
            "modern",
            "--lost-after",
            "0.5",
            "-q",
            "--fabric",
            fabric,
            "-o",
            &out,
            "--report",
            &report_arg,
        ];
        let run = match fabric {
            "mpi" => mpirun(3, &[], &args),
            _ => Command::new(env!("CARGO_BIN_EXE_voxcube"))
                .args(args)
                .output()
                .expect("runs"),
        };
        assert!(
            run.status.success(),
            "{fabric}: {}",
            String::from_utf8_lossy(&run.stderr)
        );
        read_report(&report)
    };
    let (mpi, threads) = (render("mpi"), render("threads"));
    let view = &mpi["views"][0];
    assert_eq!(view["pixels_sha256"], threads["views"][0]["pixels_sha256"]);
    let nodes = view["traffic"]["nodes"].as_array().expect("nodes");
    assert_eq!(nodes.len(), 2);
    for node in nodes {
        // A rank holds at least its slab: a quarter of the 128 MiB volume and more.
        let resident = node["resident_peak_bytes"].as_u64().expect("a rank's peak");
        assert!(resident > 64 << 20, "{node}");
    }
    let setup = view["setup_ms"]
        .as_f64()
        .expect("the slowest rank's set-up");
    assert!(setup > 0.0 && setup < view["wall_ms"].as_f64().unwrap_or(0.0));
    assert!(view["host_resident_peak_bytes"].as_u64().is_some());
    assert!(threads["views"][0]["traffic"]["nodes"][0]["resident_peak_bytes"].is_null());
}

/// A NIfTI-1 file of `n`³ u16 samples, X fastest, stored 1024 above their values with
/// `scl_inter = -1024` as scanners store CT: a ball whose values fall from 250 at its centre.
fn ct_nifti(n: u16) -> Vec<u8> {
    let mut h = vec![0u8; 352];
    let mut put = |at: usize, bytes: &[u8]| h[at..at + bytes.len()].copy_from_slice(bytes);
    put(0, &348i32.to_le_bytes());
    for (i, d) in [3, n, n, n, 1, 1, 1, 1].into_iter().enumerate() {
        put(40 + 2 * i, &d.to_le_bytes());
    }
    put(70, &512i16.to_le_bytes());
    put(72, &16i16.to_le_bytes());
    for (i, p) in [1.0f32; 8].into_iter().enumerate() {
        put(76 + 4 * i, &p.to_le_bytes());
    }
    put(108, &352f32.to_le_bytes());
    put(112, &1f32.to_le_bytes());
    put(116, &(-1024f32).to_le_bytes());
    put(344, b"n+1\0");
    for v in ball(n) {
        h.extend_from_slice(&((v.max(0) + 1024) as u16).to_le_bytes());
    }
    h
}

/// The values of a ball on `n`³ nodes, X fastest: 250 at its centre, falling with the
/// squared distance from it.
fn ball(n: u16) -> impl Iterator<Item = i32> {
    let (n, c) = (i32::from(n), i32::from(n / 2));
    (0..n * n * n).map(move |i| {
        let (x, y, z) = (i % n, i / n % n, i / (n * n));
        250 - ((x - c).pow(2) + (y - c).pow(2) + (z - c).pow(2)) / 2
    })
}

/// A binary legacy VTK file of `n`³ big-endian `short` samples, X fastest: a ball whose values
/// fall from 250 at its centre.
fn ball_vtk(n: u16) -> Vec<u8> {
    let mut file = format!(
        "# vtk DataFile Version 3.0\nball\nBINARY\nDATASET STRUCTURED_POINTS\n\
         DIMENSIONS {n} {n} {n}\nORIGIN 0 0 0\nSPACING 1 1 1\nPOINT_DATA {}\n\
         SCALARS density short\nLOOKUP_TABLE default\n",
        u32::from(n).pow(3)
    )
    .into_bytes();
    for v in ball(n) {
        file.extend_from_slice(&(v.max(-40) as i16).to_be_bytes());
    }
    file
}

/// A node's rank holds only the planes its slab stores of a built-in volume (the molecule,
/// the i16 head), a raw file, a NRRD file with raw samples, a scaled NIfTI-1 file or a binary
/// legacy VTK file (i16), whose views all place their cameras
/// themselves: generated alone or streamed, never cut from the whole. Where a view frames
/// its camera by what shows, which reads every sample, the rank holds the whole volume (the
/// control). The images are the threads fabric's, on 4 nodes in 1 and 2 clusters.
#[test]
fn a_rank_holds_only_the_planes_its_slab_stores() {
    let dir = tempfile::tempdir().expect("tempdir");
    let view = |camera: &str| {
        format!(
            r#"[[datasets.views]]
name = "v"
width = 64
height = 48
mode = "composite"
{camera}
[[datasets.views.transfer]]
value = 10.0
color = [0.2, 0.3, 0.8]
opacity = 0.0
[[datasets.views.transfer]]
value = 200.0
color = [1.0, 0.2, 0.1]
opacity = 0.8
"#
        )
    };
    let placed = "[datasets.views.camera]\neye = [200.0, 47.5, 200.0]\nlook_at = [47.5, 47.5, 47.5]\nwidth = 160.0";
    // A surface no value reaches: the host, which holds no plane of a placed dataset, warns
    // of it from the ranges its nodes reported, as the threads fabric's host does from the
    // volume.
    let beyond = format!(
        "[[datasets.views]]\nname = \"beyond\"\nwidth = 32\nheight = 24\n{placed}\n[[datasets.views.surfaces]]\niso = 300.0\ncolor = [1.0, 1.0, 1.0]\n"
    );
    let mut text = format!(
        "[[datasets]]\nname = \"placed\"\nbuiltin = \"molecule\"\nsize = 96\n{}{beyond}\n[[datasets]]\nname = \"framed\"\nbuiltin = \"molecule\"\nsize = 96\n{}",
        view(placed),
        view("")
    );
    // A raw file and a NRRD file's raw samples, streamed: SOD and neghip, where the shared
    // data is there.
    let data = scenes_with_data()
        .first()
        .map(|_| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data"));
    if let Some(data) = &data {
        text.push_str(&format!(
            "\n[[datasets]]\nname = \"sod\"\npath = \"{}\"\nformat = \"raw\"\ndims = [97, 97, 116]\ntype = \"u8\"\nheader_bytes = 12\n{}",
            data.join("sod-97x97x116.u8.binary").display(),
            view(placed)
        ));
        text.push_str(&format!(
            "\n[[datasets]]\nname = \"neghip\"\npath = \"{}\"\n{}",
            data.join("neghip-66x66x66.nhdr").display(),
            view(placed)
        ));
    }
    // A NIfTI-1 file of u16 samples scaled by its intercept, as CT is stored, streamed.
    let nii = dir.path().join("ct.nii");
    std::fs::write(&nii, ct_nifti(48)).expect("nifti written");
    text.push_str(&format!(
        "\n[[datasets]]\nname = \"ct\"\npath = \"{}\"\n{}",
        nii.display(),
        view(placed)
    ));
    // The CT-like head (i16), its planes generated alone.
    text.push_str(&format!(
        "\n[[datasets]]\nname = \"head\"\nbuiltin = \"head\"\nsize = 48\n{}",
        view(placed)
    ));
    // A binary legacy VTK file of big-endian shorts, streamed.
    let vtk = dir.path().join("ball.vtk");
    std::fs::write(&vtk, ball_vtk(48)).expect("vtk written");
    text.push_str(&format!(
        "\n[[datasets]]\nname = \"ball\"\npath = \"{}\"\n{}",
        vtk.display(),
        view(placed)
    ));
    let views: &[(&str, &str)] = match data {
        Some(_) => &[
            ("placed", "v"),
            ("placed", "beyond"),
            ("framed", "v"),
            ("sod", "v"),
            ("neghip", "v"),
            ("ct", "v"),
            ("head", "v"),
            ("ball", "v"),
        ],
        None => &[
            ("placed", "v"),
            ("placed", "beyond"),
            ("framed", "v"),
            ("ct", "v"),
            ("head", "v"),
            ("ball", "v"),
        ],
    };
    let scene = dir.path().join("two.toml");
    std::fs::write(&scene, text).expect("scene written");
    let scene = scene.display().to_string();
    for clusters in ["1", "2"] {
        let render = |fabric: &str| {
            let report = dir.path().join(format!("{fabric}.json"));
            let out = dir.path().join(fabric).display().to_string();
            let report_arg = report.display().to_string();
            let args = [
                "render",
                &scene,
                "--nodes",
                "4",
                "--clusters",
                clusters,
                "-q",
                "--fabric",
                fabric,
                "-o",
                &out,
                "--report",
                &report_arg,
            ];
            let run = match fabric {
                "mpi" => mpirun(5, &[], &args),
                _ => Command::new(env!("CARGO_BIN_EXE_voxcube"))
                    .args(args)
                    .output()
                    .expect("runs"),
            };
            assert!(
                run.status.success(),
                "{fabric}: {}",
                String::from_utf8_lossy(&run.stderr)
            );
            read_report(&report)
        };
        let (mpi, threads) = (render("mpi"), render("threads"));
        for (i, &(dataset, name)) in views.iter().enumerate() {
            let view = &mpi["views"][i];
            assert_eq!(
                (&view["dataset"], &view["view"]),
                (&dataset.into(), &name.into())
            );
            assert_eq!(
                view["pixels_sha256"], threads["views"][i]["pixels_sha256"],
                "{dataset} on {clusters} clusters"
            );
            let warnings = &view["warnings"];
            assert_eq!(
                warnings, &threads["views"][i]["warnings"],
                "{dataset}/{name}"
            );
            let outside = warnings
                .to_string()
                .contains("lies outside the data's range");
            assert_eq!(outside, name == "beyond", "{dataset}/{name}: {warnings}");
            for node in view["traffic"]["nodes"].as_array().expect("nodes") {
                let held = &node["held_planes"];
                match dataset {
                    "framed" => assert_eq!(held, &serde_json::json!([0, 96]), "{node}"),
                    _ => assert_eq!(held, &node["stored"], "{dataset}: {node}"),
                }
            }
        }
    }
}

/// `--machine host` shares this machine's memory among nodes that run in this process; a rank
/// may run on another machine, and every rank must budget alike, so MPI refuses it before any
/// rank renders, naming what to give instead.
#[test]
fn host_nodes_are_refused_on_mpi() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out_dir = dir.path().join("o").display().to_string();
    let out = mpirun(
        3,
        &[],
        &[
            "render",
            "--fabric",
            "mpi",
            "--nodes",
            "2",
            "--machine",
            "host",
            "-q",
            "-o",
            &out_dir,
        ],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(
        stderr.contains("MPI ranks are cluster nodes: give --machine modern or ncube2"),
        "{stderr}"
    );
    assert!(!dir.path().join("o/molecule-paper.png").exists());
}
