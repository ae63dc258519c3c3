//! `voxcube info`: what a volume is (grid, type, spacing, values and their histogram), what
//! it needs of a node on each machine profile, and where to start looking at it: iso values
//! and a transfer function from its histogram, and a ready scene file.
//!
//! The suggestions are Otsu thresholds of the value histogram: the first splits the
//! background from the material, the second the material from its densest part. They are
//! starting points for a scene, not a segmentation.

use crate::input::dataset::{Volume, VolumeData};
use crate::input::formats::{self, Format};
use crate::input::scene::Scene;
use crate::memory::budget::{largest_node, Profile, ViewNeeds};
use std::fmt::Write;
use std::path::Path;
use voxcube_kernel::node::flow;

/// Bins of the histogram the suggestions come from.
const BINS: usize = 256;
/// Rows of the histogram printed.
const ROWS: usize = 16;

/// Why `info` could not describe a path.
#[derive(Debug, thiserror::Error)]
pub enum InfoError {
    /// A raw file has no header to describe it.
    #[error("{0}: a raw file has no header to read dims and type from; describe it in a scene file (dims, type, endian) and run `voxcube info SCENE`")]
    Raw(String),
    /// The file or scene did not load.
    #[error("{0}")]
    Load(String),
}

/// A counted histogram of a volume's values over `[min, max]`.
#[derive(Clone, Debug)]
pub struct Histogram {
    /// Least value.
    pub min: f64,
    /// Greatest value.
    pub max: f64,
    /// Samples per bin, bins of equal width.
    pub counts: Vec<u64>,
}

impl Histogram {
    /// The histogram of `volume` in `bins` bins.
    pub fn of(volume: &Volume, bins: usize) -> Histogram {
        let stats = volume.stats();
        let (min, max) = (stats.min, stats.max);
        let mut counts = vec![0u64; bins.max(1)];
        let width = (max - min).max(f64::MIN_POSITIVE);
        let mut add = |v: f64| {
            let b = (((v - min) / width) * bins as f64) as usize;
            counts[b.min(bins - 1)] += 1;
        };
        match &volume.data {
            VolumeData::U8(v) => v.iter().for_each(|&x| add(x.into())),
            VolumeData::U16(v) => v.iter().for_each(|&x| add(x.into())),
            VolumeData::I16(v) => v.iter().for_each(|&x| add(x.into())),
            VolumeData::F32(v) => v.iter().for_each(|&x| add(x.into())),
        }
        Histogram { min, max, counts }
    }

    /// The value at the low edge of bin `b`.
    pub fn edge(&self, b: usize) -> f64 {
        self.min + (self.max - self.min) * b as f64 / self.counts.len() as f64
    }

    /// Otsu's threshold over bins `from..`: the bin that best splits them into two classes
    /// (greatest between-class variance), or `None` when they hold one value.
    pub fn otsu(&self, from: usize) -> Option<usize> {
        let bins = &self.counts[from.min(self.counts.len())..];
        let total: f64 = bins.iter().map(|&c| c as f64).sum();
        let sum: f64 = bins
            .iter()
            .enumerate()
            .map(|(i, &c)| i as f64 * c as f64)
            .sum();
        let (mut w0, mut s0, mut best) = (0.0, 0.0, None::<(f64, usize)>);
        for (i, &c) in bins.iter().enumerate().take(bins.len().saturating_sub(1)) {
            w0 += c as f64;
            s0 += i as f64 * c as f64;
            let w1 = total - w0;
            if w0 == 0.0 || w1 == 0.0 {
                continue;
            }
            let between = w0 * w1 * (s0 / w0 - (sum - s0) / w1).powi(2);
            if best.is_none_or(|(b, _)| between > b) {
                best = Some((between, from + i + 1));
            }
        }
        best.map(|(_, b)| b)
    }
}

/// Iso values to start from: the background/material split and, when there is one, the
/// material/dense split, each strictly inside the data's range.
pub fn suggested_isos(h: &Histogram) -> Vec<f64> {
    let mut out = Vec::new();
    if let Some(first) = h.otsu(0) {
        out.push(round(h.edge(first)));
        if let Some(second) = h.otsu(first) {
            let v = round(h.edge(second));
            if v > out[0] && v < h.max {
                out.push(v);
            }
        }
    }
    out.retain(|&v| v > h.min && v <= h.max);
    out
}

/// Three significant digits, enough for an iso value and short to read.
fn round(v: f64) -> f64 {
    if v == 0.0 {
        return 0.0;
    }
    let scale = 10f64.powf(2.0 - v.abs().log10().floor());
    (v * scale).round() / scale
}

fn type_name(data: &VolumeData) -> &'static str {
    match data {
        VolumeData::U8(_) => "u8",
        VolumeData::U16(_) => "u16",
        VolumeData::I16(_) => "i16",
        VolumeData::F32(_) => "f32",
    }
}

fn mib(bytes: usize) -> String {
    format!("{:.2} MiB", bytes as f64 / (1024.0 * 1024.0))
}

/// The volumes `path` names: a scene's datasets, or one volume file or DICOM folder.
pub fn volumes(path: &Path) -> Result<Vec<(String, Volume)>, InfoError> {
    if path.extension().is_some_and(|e| e == "toml") {
        let jobs = Scene::from_file(path)
            .and_then(Scene::load)
            .map_err(|e| InfoError::Load(e.to_string()))?;
        return Ok(jobs
            .into_iter()
            .map(|j| (format!("{} ({})", j.name, j.source), j.volume))
            .collect());
    }
    let format = Format::from_extension(path)
        .or_else(|| Format::sniff(path))
        .filter(|&f| f != Format::Raw)
        .ok_or_else(|| InfoError::Raw(path.display().to_string()))?;
    let volume = formats::load(path, format, None).map_err(|e| InfoError::Load(e.to_string()))?;
    Ok(vec![(format!("{} ({format:?})", path.display()), volume)])
}

/// The report `voxcube info` prints for one volume.
pub fn describe(name: &str, volume: &Volume) -> Result<String, InfoError> {
    let mut out = String::new();
    let [nx, ny, nz] = volume.grid.dims();
    let s = volume.grid.spacing();
    let stats = volume.stats();
    let h = Histogram::of(volume, BINS);
    let _ = writeln!(out, "volume      {name}");
    let _ = writeln!(
        out,
        "grid        {nx} x {ny} x {nz} samples, spacing {} x {} x {}",
        s.x, s.y, s.z
    );
    let _ = writeln!(
        out,
        "samples     {}, {} ({})",
        type_name(&volume.data),
        volume.data.len(),
        mib(volume.data.len() * volume.data.kind().bytes())
    );
    let rms = volume.rms(stats.mean);
    let _ = writeln!(out, "values      {stats} rms {rms:.2}");
    // Density maps are contoured at the mean plus whole and half multiples of σ.
    let contours: Vec<String> = [1.0, 1.5, 2.0, 3.0]
        .iter()
        .map(|k| format!("{k}σ {:.4}", stats.mean + k * rms))
        .collect();
    let _ = writeln!(
        out,
        "mean + k·σ  {} (density-map contour levels)",
        contours.join(", ")
    );
    let _ = writeln!(out, "histogram   (bar length: log of the count)");
    let row = Histogram::of(volume, ROWS);
    let peak = row.counts.iter().copied().max().unwrap_or(1).max(1);
    for (i, &c) in row.counts.iter().enumerate() {
        let bar = if c == 0 {
            0
        } else {
            1 + ((c as f64).ln() / (peak as f64).ln().max(1e-9) * 39.0) as usize
        };
        let _ = writeln!(
            out,
            "  {:>12.6} | {:<40} {c}",
            row.edge(i),
            "#".repeat(bar.min(40))
        );
    }
    let isos = suggested_isos(&h);
    let _ = writeln!(
        out,
        "iso values  {} (Otsu thresholds of the histogram)",
        isos.iter()
            .map(|v| v.to_string())
            .collect::<Vec<_>>()
            .join(", ")
    );
    let _ = writeln!(
        out,
        "transfer    {} (value: opacity per cell edge)",
        transfer(volume, &isos)
            .iter()
            .map(|(v, _, o)| format!("{}: {o}", round(*v)))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let profiles: Vec<Profile> = ["ncube2", "modern"]
        .iter()
        .filter_map(|n| Profile::builtin(n))
        .collect();
    // This machine as the cluster's nodes (`--machine host`): its memory shared by them.
    let physical = crate::memory::resident::physical();
    let _ = writeln!(
        out,
        "node memory (the largest node of a cluster; surfaces view, default receive buffer):"
    );
    let _ = write!(out, "  {:>8} {:>12}", "cluster", "per node");
    for p in &profiles {
        let _ = write!(
            out,
            " {:>16}",
            format!("{} ({})", p.name, mib(p.node_memory))
        );
    }
    if let Some(bytes) = physical {
        let whole = Profile::sharing(bytes, 1).node_memory;
        let _ = write!(out, " {:>24}", format!("host ({} / nodes)", mib(whole)));
    }
    let _ = writeln!(out);
    let needs = first_view_needs(volume, &isos)?;
    let mut size = 1u32;
    while size <= nx.min(1024) {
        let buffer = flow::buffer_bytes(size as usize, crate::fabric::DEFAULT_I_MAX);
        let m = largest_node(
            &volume.grid,
            volume.data.kind().bytes(),
            size,
            needs,
            buffer,
        );
        let Some(m) = m else { break };
        let _ = write!(out, "  {size:>8} {:>12}", mib(m.total()));
        let fits = |p: &Profile| match m.total() <= p.node_memory {
            true => "fits",
            false => "too big",
        };
        for p in &profiles {
            let _ = write!(out, " {:>16}", fits(p));
        }
        if let Some(bytes) = physical {
            let _ = write!(out, " {:>24}", fits(&Profile::sharing(bytes, size)));
        }
        let _ = writeln!(out);
        size *= 2;
    }
    out += &structures(volume, &isos)?;
    Ok(out)
}

/// The structures one node holding the whole volume builds beside its samples: its value
/// ranges, built once per volume; for each view of the suggested scene, each one's bytes and
/// how long building them all took here (they are built together, on this machine's threads,
/// for each new view; a byte volume keeps the masks and cell leap maps for the next frame
/// of the same transfer function); and the fast tier's node field, built once per volume.
fn structures(volume: &Volume, isos: &[f64]) -> Result<String, InfoError> {
    match &volume.data {
        VolumeData::U8(d) => structures_of(volume, d, isos),
        VolumeData::U16(d) => structures_of(volume, d, isos),
        VolumeData::I16(d) => structures_of(volume, d, isos),
        VolumeData::F32(d) => structures_of(volume, d, isos),
    }
}

fn structures_of<T: voxcube_kernel::volume::sample::Sample + Sync>(
    volume: &Volume,
    data: &[T],
    isos: &[f64],
) -> Result<String, InfoError> {
    use crate::memory::storage::{SkipMode, Skipping};
    use std::time::Instant;
    let bad = |e: String| InfoError::Load(format!("the suggested scene does not build: {e}"));
    let slab = voxcube_kernel::volume::slab::Slab::whole(volume.grid, data)
        .map_err(|e| bad(e.to_string()))?;
    let threads = std::thread::available_parallelism().map_or(1, usize::from);
    let mut out = format!(
        "structures (one node holding the whole volume; built on {threads} threads here):\n"
    );
    let start = Instant::now();
    let ranges = crate::memory::ranges::SlabRanges::build(&slab, true, threads);
    let took = start.elapsed();
    let _ = writeln!(
        out,
        "  value ranges: min/max blocks {}, cells' ranges {}; built in {:.1} ms once per volume",
        kib(size_of_val(ranges.blocks.as_slice())),
        mib(ranges.cell_bytes()),
        took.as_secs_f64() * 1e3
    );
    for (name, view) in suggested_views(volume, isos)? {
        let start = Instant::now();
        let skipping = Skipping::build_on(&slab, &ranges, &view, SkipMode::ALL, threads);
        let took = start.elapsed();
        let parts: Vec<String> = skipping
            .bytes()
            .iter()
            .filter(|(_, b)| *b > 0)
            .map(|(what, b)| format!("{what} {}", kib(*b)))
            .collect();
        let _ = writeln!(
            out,
            "  {name:<10} {}; built in {:.1} ms for each new view",
            parts.join(", "),
            took.as_secs_f64() * 1e3
        );
    }
    let start = Instant::now();
    let field = crate::memory::nodes::NodeField::build(&slab, threads);
    let took = start.elapsed();
    let _ = writeln!(
        out,
        "  node field {} (the fast tier's value and differences per node); built in {:.1} ms once per volume",
        mib(field.bytes()),
        took.as_secs_f64() * 1e3
    );
    Ok(out)
}

fn kib(bytes: usize) -> String {
    format!("{:.1} KiB", bytes as f64 / 1024.0)
}

/// The smallest power-of-two cluster whose largest node fits `profile`, if any.
fn smallest_fit(volume: &Volume, profile: &Profile, needs: ViewNeeds) -> Option<u32> {
    (0..=10)
        .map(|k| 1u32 << k)
        .take_while(|&s| s <= volume.grid.dims()[0])
        .find(|&s| {
            let buffer = flow::buffer_bytes(s as usize, crate::fabric::DEFAULT_I_MAX);
            largest_node(&volume.grid, volume.data.kind().bytes(), s, needs, buffer)
                .is_some_and(|m| m.total() <= profile.node_memory)
        })
}

/// The suggested scene's views, by name, built on the volume's grid.
fn suggested_views(
    volume: &Volume,
    isos: &[f64],
) -> Result<Vec<(String, voxcube_kernel::trace::view::View)>, InfoError> {
    let text = scene_text("v", Path::new("unused"), volume, isos, 1);
    // A built-in stands in for the file while the text is parsed; the views are then rebuilt
    // on the real grid.
    let scene = text.replace("path = ", "builtin = \"sphere\"\n# path = ");
    let bad = |e: String| InfoError::Load(format!("the suggested scene does not build: {e}"));
    let jobs = Scene::parse(&scene, "suggested", Path::new("."))
        .and_then(Scene::load)
        .map_err(|e| bad(e.to_string()))?;
    jobs.into_iter()
        .flat_map(|d| d.views)
        .map(|v| {
            voxcube_kernel::trace::view::View::new(v.view.spec().clone(), &volume.grid)
                .map(|view| (v.name, view))
                .map_err(|e| bad(e.to_string()))
        })
        .collect()
}

/// What the suggested scene's first view asks of a node's memory.
fn first_view_needs(volume: &Volume, isos: &[f64]) -> Result<ViewNeeds, InfoError> {
    let (_, view) = suggested_views(volume, isos)?
        .into_iter()
        .next()
        .ok_or_else(|| InfoError::Load("the suggested scene does not build: no view".into()))?;
    Ok(ViewNeeds::of(&view))
}

/// A starting transfer function: clear below the first iso value, faint at it, denser at the
/// second, densest at the maximum (value, colour, opacity per cell edge).
pub fn transfer(volume: &Volume, isos: &[f64]) -> [(f64, [f32; 3], f32); 4] {
    let stats = volume.stats();
    let iso_a = isos
        .first()
        .copied()
        .unwrap_or((stats.min + stats.max) / 2.0);
    let iso_b = isos
        .get(1)
        .copied()
        .unwrap_or(iso_a + (stats.max - iso_a) * 0.5);
    let low = iso_a - (iso_a - stats.min) * 0.25;
    [
        (low, [0.8, 0.5, 0.3], 0.0),
        (iso_a, [0.85, 0.6, 0.4], 0.02),
        (iso_b, [1.0, 0.95, 0.85], 0.3),
        (stats.max.max(iso_b + 1e-3), [1.0, 1.0, 1.0], 0.6),
    ]
}

fn scene_text(name: &str, path: &Path, volume: &Volume, isos: &[f64], nodes: u32) -> String {
    let stats = volume.stats();
    let [nx, ny, nz] = volume.grid.dims();
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# A first scene for {}, written by `voxcube info --scene`:\n# {nx} x {ny} x {nz} {} samples, values {} to {}.",
        path.display(),
        type_name(&volume.data),
        stats.min,
        stats.max
    );
    let _ = writeln!(
        s,
        "[[datasets]]\nname = \"{name}\"\npath = {:?}\n",
        path.display().to_string()
    );
    let iso_a = isos
        .first()
        .copied()
        .unwrap_or((stats.min + stats.max) / 2.0);
    // The cell model interpolates between two samples along each axis: a volume one sample
    // thick (a single image) renders in the voxel model.
    let model = match [nx, ny, nz].contains(&1) {
        true => "# One sample thick: the voxel model (the cell model needs two along each axis).\nmodel = \"voxel\"\n",
        false => "",
    };
    let _ = writeln!(
        s,
        "[[datasets.views]]\nname = \"surfaces\"\nwidth = 400\nheight = 400\nnodes = {nodes}\n{model}"
    );
    let _ = writeln!(s, "[[datasets.views.surfaces]]\niso = {iso_a:?}");
    match isos.get(1) {
        Some(iso_b) => {
            let _ = writeln!(
                s,
                "color = [0.85, 0.75, 0.6]\ntransparency = 0.6\n[[datasets.views.surfaces]]\niso = {iso_b:?}\ncolor = [1.0, 1.0, 0.95]\n"
            );
        }
        None => {
            let _ = writeln!(s, "color = [0.85, 0.75, 0.6]\n");
        }
    }
    let _ = writeln!(
        s,
        "[[datasets.views]]\nname = \"composite\"\nmode = \"composite\"\nwidth = 400\nheight = 400\nnodes = {nodes}\n{model}"
    );
    for (value, color, opacity) in transfer(volume, isos) {
        let _ = writeln!(
            s,
            "[[datasets.views.transfer]]\nvalue = {value:?}\ncolor = {color:?}\nopacity = {opacity:?}"
        );
    }
    s
}

/// A scene file for the volume at `path`, ready to render: a view of its suggested
/// iso-surfaces (the outer one transparent) and a composited view, on as few nodes as the
/// nCUBE 2 profile needs.
pub fn suggested_scene(path: &Path, volume: &Volume) -> Result<String, InfoError> {
    let h = Histogram::of(volume, BINS);
    // A density map is contoured as crystallographers do, at the mean plus 1σ and 2σ (where
    // those lie inside its values); any other volume at its histogram's thresholds.
    let map = Format::from_extension(path) == Some(Format::Mrc);
    let isos = match map {
        true => {
            let stats = volume.stats();
            let rms = volume.rms(stats.mean);
            [1.0, 2.0]
                .iter()
                .map(|k| round(stats.mean + k * rms))
                .filter(|&v| v < stats.max)
                .collect()
        }
        false => suggested_isos(&h),
    };
    let needs = first_view_needs(volume, &isos)?;
    let nodes = Profile::builtin("ncube2")
        .and_then(|p| smallest_fit(volume, &p, needs))
        .unwrap_or(1);
    let name: String = path
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("volume")
        .split('.')
        .next()
        .unwrap_or("volume")
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '-'
            }
        })
        .collect();
    let name = if name.is_empty() || name.starts_with('-') {
        format!("v{name}")
    } else {
        name
    };
    let absolute = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
    Ok(scene_text(&name, &absolute, volume, &isos, nodes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn otsu_splits_two_clusters_between_them() {
        let h = Histogram {
            min: 0.0,
            max: 100.0,
            counts: [vec![50; 10], vec![0; 40], vec![20; 10], vec![0; 40]].concat(),
        };
        let t = h.otsu(0).unwrap_or(0);
        assert!((10..=50).contains(&t), "{t}");
        let flat = Histogram {
            min: 0.0,
            max: 1.0,
            counts: vec![0, 7, 0],
        };
        assert_eq!(flat.otsu(0), None);
        assert_eq!(round(123.456), 123.0);
        assert_eq!(round(0.0123456), 0.0123);
    }
}
