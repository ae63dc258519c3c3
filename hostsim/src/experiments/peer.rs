//! VTK, the yardstick, timed in the same `bench` run: its CPU ray caster
//! (`vtkFixedPointVolumeRayCastMapper`, two threads) on SOD with the paper's camera at
//! 350×250, Δt = ½ (and composited at a larger frame when asked), through the peer scripts
//! beside the data (`../shared/peers/`), when their virtualenv is installed. Ratios between
//! the two are only meaningful from one run: the machine's speed drifts with its other
//! tenants.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

/// Where the peer scripts install VTK (`../shared/peers/setup.sh`).
pub const VENV_PYTHON: &str = "/tmp/peers/venv/bin/python";

/// VTK's median frame times on SOD at 350×250, Δt = ½, and composited at the larger frame
/// if one was asked for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VtkTimes {
    /// The iso-surface (a step in opacity at 50).
    pub surface: Duration,
    /// The composited view (voxcube's transfer function).
    pub composite: Duration,
    /// The composited view at the larger frame.
    pub large_composite: Option<Duration>,
}

/// A frame other than the paper's for VTK to render: its size, step and the world units
/// across it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// Pixels across.
    pub width: u32,
    /// Pixels down.
    pub height: u32,
    /// Step, in cell edges.
    pub dt: f32,
    /// World units across the image.
    pub span: f32,
}

/// The peer script `vtk_matched.py` beside `sod`'s folder, if it and the virtualenv exist.
fn script(sod: &Path) -> Option<PathBuf> {
    let data = sod.parent()?;
    let script = data.join("../peers/vtk_matched.py");
    (script.is_file() && Path::new(VENV_PYTHON).is_file()).then_some(script)
}

/// Time VTK on `sod` (the raw file with its 12-byte header), `runs` frames per mode (the
/// median kept), composited at `large` too when given; `Ok(None)` when the peer is not
/// installed.
pub fn vtk(sod: &Path, runs: usize, large: Option<Frame>) -> Result<Option<VtkTimes>, String> {
    let Some(script) = script(sod) else {
        return Ok(None);
    };
    let bytes = std::fs::read(sod).map_err(|e| format!("{}: {e}", sod.display()))?;
    let samples = 97 * 97 * 116;
    let body = bytes
        .get(bytes.len().saturating_sub(samples)..)
        .filter(|b| b.len() == samples)
        .ok_or_else(|| format!("{}: not SOD's {samples} samples", sod.display()))?;
    let raw = std::env::temp_dir().join(format!("voxcube-peer-sod-{}.raw", std::process::id()));
    std::fs::write(&raw, body).map_err(|e| format!("{}: {e}", raw.display()))?;
    let time = |mode: &str, frame: Option<Frame>| -> Result<Duration, String> {
        let mut command = Command::new(VENV_PYTHON);
        command
            .arg(&script)
            .arg("--raw")
            .arg(&raw)
            .args(["--mode", mode, "--threads", "2", "--reps"])
            .arg(runs.max(1).to_string());
        if let Some(f) = frame {
            command
                .arg("--size")
                .arg(f.width.to_string())
                .arg(f.height.to_string())
                .arg("--dt")
                .arg(f.dt.to_string())
                .arg("--width")
                .arg(f.span.to_string());
        }
        let out = command.output().map_err(|e| format!("VTK peer: {e}"))?;
        let text = String::from_utf8_lossy(&out.stdout);
        let line = text.lines().last().unwrap_or_default();
        let json: serde_json::Value = serde_json::from_str(line).map_err(|e| {
            format!(
                "VTK peer ({mode}): {e}: {}",
                String::from_utf8_lossy(&out.stderr)
            )
        })?;
        json["median_s"]
            .as_f64()
            .filter(|s| s.is_finite() && *s > 0.0)
            .map(Duration::from_secs_f64)
            .ok_or_else(|| format!("VTK peer ({mode}): no median_s in {line}"))
    };
    let result = time("surface", None).and_then(|surface| {
        Ok(VtkTimes {
            surface,
            composite: time("composite", None)?,
            large_composite: large.map(|f| time("composite", Some(f))).transpose()?,
        })
    });
    let _ = std::fs::remove_file(&raw);
    result.map(Some)
}
