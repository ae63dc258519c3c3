//! VTK, the yardstick, run in the same process tree as voxcube's own renders: its CPU ray
//! caster (`vtkFixedPointVolumeRayCastMapper`, two threads) on SOD with voxcube's framing,
//! through the repository's peer script (`peers/vtk_peer.py`, built into the binary) and the
//! virtualenv `peers/setup.sh` installs. Ratios between the two are only meaningful from one
//! run: the machine's speed drifts with its other tenants.
//!
//! Invariant: a [`Peer`] holds one volume's samples (SOD's without their header, or any byte
//! volume X fastest, with its dimensions) and the script in a scratch folder of its own,
//! removed with it.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

/// Where `peers/setup.sh` installs VTK.
pub const VENV_PYTHON: &str = "/tmp/peers/venv/bin/python";

/// The peer script, as `peers/vtk_peer.py` holds it.
const SCRIPT: &str = include_str!("../../../peers/vtk_peer.py");

/// SOD's nodes along X, Y and Z.
const SOD_DIMS: [u32; 3] = [97, 97, 116];

/// SOD's samples after its 12-byte header.
const SOD_SAMPLES: usize = 97 * 97 * 116;

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

/// A frame for VTK to render: its size, step and the world units across it.
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

impl Frame {
    /// The paper's: 350×250, Δt = ½, 175 grid units across.
    pub const PAPER: Frame = Frame {
        width: 350,
        height: 250,
        dt: 0.5,
        span: 175.0,
    };
}

/// What VTK renders: the script's mode, as voxcube's experiments define their views of SOD
/// (`peers/vtk_peer.py` spells out the transfer function and the surface's step and colour).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PeerMode {
    /// The iso-surface at SOD's iso value, as a step in opacity.
    Surface,
    /// Composited with SOD's transfer function.
    Composite,
}

impl PeerMode {
    fn name(self) -> &'static str {
        match self {
            PeerMode::Surface => "surface",
            PeerMode::Composite => "composite",
        }
    }
}

/// One render asked of VTK.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Request {
    /// Surface or composited.
    pub mode: PeerMode,
    /// Size, step and framing.
    pub frame: Frame,
    /// Timed renders after a first one (the median is kept).
    pub runs: usize,
}

/// What VTK gave: its median time and, when asked, its last image.
#[derive(Clone, Debug, PartialEq)]
pub struct PeerRender {
    /// The median of the timed renders.
    pub median: Duration,
    /// The last image as RGBA8 rows, top row first, where it was asked for.
    pub pixels: Option<Vec<[u8; 4]>>,
}

/// VTK ready to render a volume: the script and the volume's samples in a scratch folder.
#[derive(Debug)]
pub struct Peer {
    folder: tempfile::TempDir,
    /// The volume's nodes along X, Y and Z.
    dims: [u32; 3],
    /// The samples' type, as the script's `--type` names it.
    kind: &'static str,
    /// The composited views' transfer function in the script's `--transfer` form, where it
    /// is not the script's default (SOD's).
    transfer: Option<String>,
}

impl Peer {
    /// VTK for `sod` (the raw file with its 12-byte header); `Ok(None)` when the virtualenv
    /// is not installed.
    pub fn open(sod: &Path) -> Result<Option<Peer>, String> {
        if !Path::new(VENV_PYTHON).is_file() {
            return Ok(None);
        }
        let bytes = std::fs::read(sod).map_err(|e| format!("{}: {e}", sod.display()))?;
        let body = bytes
            .get(bytes.len().saturating_sub(SOD_SAMPLES)..)
            .filter(|b| b.len() == SOD_SAMPLES)
            .ok_or_else(|| format!("{}: not SOD's {SOD_SAMPLES} samples", sod.display()))?;
        Peer::of_samples(body, SOD_DIMS)
    }

    /// VTK for a byte volume of `dims` nodes whose `samples` run X fastest, then Y, then Z;
    /// `Ok(None)` when the virtualenv is not installed.
    pub fn of_samples(samples: &[u8], dims: [u32; 3]) -> Result<Option<Peer>, String> {
        Peer::of_bytes(samples, samples.len(), "u8", dims)
    }

    /// [`Peer::of_samples`] for signed 16-bit samples (a CT's Hounsfield units).
    pub fn of_i16(samples: &[i16], dims: [u32; 3]) -> Result<Option<Peer>, String> {
        let bytes: Vec<u8> = samples.iter().flat_map(|v| v.to_le_bytes()).collect();
        Peer::of_bytes(&bytes, samples.len(), "i16", dims)
    }

    /// The same VTK, compositing with `points` (value, colour, opacity per unit length)
    /// instead of SOD's transfer function.
    pub fn with_transfer(self, points: &[(f32, [f32; 3], f32)]) -> Peer {
        Peer {
            transfer: Some(transfer_arg(points)),
            ..self
        }
    }

    /// The peer for `count` samples of the script's type `kind`, whose little-endian bytes
    /// (X fastest) are `bytes`.
    fn of_bytes(
        bytes: &[u8],
        count: usize,
        kind: &'static str,
        dims: [u32; 3],
    ) -> Result<Option<Peer>, String> {
        if !Path::new(VENV_PYTHON).is_file() {
            return Ok(None);
        }
        let nodes = dims.iter().map(|&d| d as usize).product::<usize>();
        if count != nodes {
            return Err(format!(
                "{count} samples for VTK, {}x{}x{} = {nodes} expected",
                dims[0], dims[1], dims[2]
            ));
        }
        let folder = tempfile::Builder::new()
            .prefix("voxcube-peer-")
            .tempdir()
            .map_err(|e| format!("a scratch folder for VTK: {e}"))?;
        let peer = Peer {
            folder,
            dims,
            kind,
            transfer: None,
        };
        for (path, bytes) in [(peer.raw(), bytes), (peer.script(), SCRIPT.as_bytes())] {
            std::fs::write(&path, bytes).map_err(|e| format!("{}: {e}", path.display()))?;
        }
        Ok(Some(peer))
    }

    fn raw(&self) -> PathBuf {
        self.folder.path().join("volume.raw")
    }

    fn script(&self) -> PathBuf {
        self.folder.path().join("vtk_peer.py")
    }

    /// Render `request` with VTK, its last image kept when `image` is set.
    pub fn render(&self, request: Request, image: bool) -> Result<PeerRender, String> {
        let Request { mode, frame, runs } = request;
        let png = self.folder.path().join("vtk.png");
        let mut command = Command::new(VENV_PYTHON);
        command
            .arg(self.script())
            .arg("--raw")
            .arg(self.raw())
            .arg("--dims")
            .args(self.dims.map(|d| d.to_string()))
            .args(["--mode", mode.name(), "--threads", "2", "--reps"])
            .arg(runs.max(1).to_string())
            .arg("--size")
            .arg(frame.width.to_string())
            .arg(frame.height.to_string())
            .arg("--dt")
            .arg(frame.dt.to_string())
            .arg("--span")
            .arg(frame.span.to_string())
            .args(["--type", self.kind]);
        if let Some(transfer) = &self.transfer {
            // Joined, as a first value below zero would otherwise read as an option.
            command.arg(format!("--transfer={transfer}"));
        }
        if image {
            command.arg("--png").arg(&png);
        }
        let what = format!("VTK ({}, dt {})", mode.name(), frame.dt);
        let out = command.output().map_err(|e| format!("{what}: {e}"))?;
        let text = String::from_utf8_lossy(&out.stdout);
        let line = text.lines().last().unwrap_or_default();
        let json: serde_json::Value = serde_json::from_str(line).map_err(|e| {
            format!(
                "{what}: {e}: {}",
                String::from_utf8_lossy(&out.stderr).trim()
            )
        })?;
        let median = json["median_s"]
            .as_f64()
            .filter(|s| s.is_finite() && *s > 0.0)
            .map(Duration::from_secs_f64)
            .ok_or_else(|| format!("{what}: no median_s in {line}"))?;
        let pixels = match image {
            true => Some(read_png(&png, frame)?),
            false => None,
        };
        Ok(PeerRender { median, pixels })
    }
}

/// Control points (value, colour, opacity) as the script's `--transfer` reads them:
/// `value:r,g,b:opacity` joined by `;`.
fn transfer_arg(points: &[(f32, [f32; 3], f32)]) -> String {
    points
        .iter()
        .map(|(v, [r, g, b], o)| format!("{v}:{r},{g},{b}:{o}"))
        .collect::<Vec<_>>()
        .join(";")
}

/// The RGBA8 pixels of the PNG VTK wrote at `path`, which must be `frame`'s size.
fn read_png(path: &Path, frame: Frame) -> Result<Vec<[u8; 4]>, String> {
    let image = image::open(path)
        .map_err(|e| format!("{}: {e}", path.display()))?
        .to_rgba8();
    if image.dimensions() != (frame.width, frame.height) {
        return Err(format!(
            "{}: {}x{} pixels, {}x{} expected",
            path.display(),
            image.width(),
            image.height(),
            frame.width,
            frame.height
        ));
    }
    Ok(image.pixels().map(|p| p.0).collect())
}

/// Time VTK on `sod` (the raw file with its 12-byte header), `runs` frames per mode (the
/// median kept), composited at `large` too when given; `Ok(None)` when the peer is not
/// installed.
pub fn vtk(sod: &Path, runs: usize, large: Option<Frame>) -> Result<Option<VtkTimes>, String> {
    let Some(peer) = Peer::open(sod)? else {
        return Ok(None);
    };
    let time = |mode, frame| {
        peer.render(Request { mode, frame, runs }, false)
            .map(|r| r.median)
    };
    Ok(Some(VtkTimes {
        surface: time(PeerMode::Surface, Frame::PAPER)?,
        composite: time(PeerMode::Composite, Frame::PAPER)?,
        large_composite: large.map(|f| time(PeerMode::Composite, f)).transpose()?,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::experiments::sod::{COMPOSITE_TRANSFER, SOD_ISO, SURFACE_VIEW};
    use voxcube_kernel::optics::shade::Shading;

    #[test]
    fn a_transfer_function_reaches_the_script_as_it_splits_one() {
        let points = [
            (-400.0, [0.8, 0.5, 0.4], 0.0),
            (1100.0, [1.0, 1.0, 0.95], 0.8),
        ];
        let text = transfer_arg(&points);
        assert_eq!(text, "-400:0.8,0.5,0.4:0;1100:1,1,0.95:0.8");
        // As the script reads it: points by ';', fields by ':', colours by ','.
        let back: Vec<(f32, Vec<f32>, f32)> = text
            .split(';')
            .map(|p| {
                let f: Vec<&str> = p.split(':').collect();
                let colour = f[1].split(',').map(|c| c.parse().unwrap()).collect();
                (f[0].parse().unwrap(), colour, f[2].parse().unwrap())
            })
            .collect();
        for ((v, c, o), (bv, bc, bo)) in points.iter().zip(&back) {
            assert_eq!((*v, c.to_vec(), *o), (*bv, bc.clone(), *bo));
        }
    }

    /// The default of the script's argument `name`.
    fn default_of(name: &str) -> &'static str {
        let at = SCRIPT
            .find(&format!("ap.add_argument(\"--{name}\""))
            .unwrap_or_else(|| panic!("the script has no --{name}"));
        let line = SCRIPT[at..].lines().next().unwrap_or_default();
        let from = line.find("default=").expect("a default") + "default=".len();
        line[from..].trim_end_matches(')').trim_matches('"')
    }

    /// The numbers in `text`, in order.
    fn numbers(text: &str) -> Vec<f32> {
        text.split(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-'))
            .filter_map(|t| t.parse().ok())
            .collect()
    }

    #[test]
    fn the_script_renders_the_experiments_views_of_sod() {
        // The transfer function: value, colour and opacity of each point, in order.
        let transfer: Vec<f32> = COMPOSITE_TRANSFER
            .lines()
            .filter(|l| !l.starts_with("[["))
            .flat_map(numbers)
            .collect();
        assert_eq!(numbers(default_of("transfer")), transfer);
        assert_eq!(transfer.len(), 15);
        assert_eq!(default_of("iso").parse::<f32>(), SOD_ISO.parse::<f32>());
        // The surface's colour, and the shading coefficients voxcube's views take by default.
        let color = SURFACE_VIEW
            .lines()
            .find(|l| l.starts_with("color"))
            .map(numbers)
            .unwrap_or_default();
        assert_eq!(numbers(default_of("color")), color);
        let s = Shading::default();
        assert_eq!(
            numbers(default_of("shading")),
            vec![s.ambient, s.diffuse, s.specular, s.shininess]
        );
        // And the paper's frame.
        assert_eq!(numbers(default_of("size")), vec![350.0, 250.0]);
        assert_eq!(numbers(default_of("dt")), vec![Frame::PAPER.dt]);
        assert_eq!(numbers(default_of("span")), vec![Frame::PAPER.span]);
        assert_eq!(numbers(default_of("dims")), SOD_DIMS.map(|d| d as f32));
    }

    #[test]
    fn samples_that_do_not_fill_their_dimensions_are_refused_before_vtk_runs() {
        let samples = [0u8; 2 * 3 * 4];
        if Path::new(VENV_PYTHON).is_file() {
            let e = Peer::of_samples(&samples, [2, 3, 5]).unwrap_err();
            assert!(e.contains("24 samples") && e.contains("2x3x5 = 30"), "{e}");
            assert!(Peer::of_samples(&samples, [2, 3, 4]).unwrap().is_some());
        } else {
            assert!(Peer::of_samples(&samples, [2, 3, 5]).unwrap().is_none());
        }
    }

    #[test]
    fn a_file_that_is_not_sod_is_refused_before_vtk_runs() {
        let dir = tempfile::tempdir().unwrap();
        let short = dir.path().join("short.raw");
        std::fs::write(&short, [0u8; 100]).unwrap();
        if Path::new(VENV_PYTHON).is_file() {
            let e = Peer::open(&short).unwrap_err();
            assert!(e.contains("short.raw") && e.contains("not SOD's"), "{e}");
        } else {
            // Without the virtualenv nothing is read.
            assert!(Peer::open(&short).unwrap().is_none());
        }
    }
}
