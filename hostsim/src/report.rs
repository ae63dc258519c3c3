//! What a render reports: a per-view summary table for people and the same as JSON for tools.

use crate::render::Rendered;
use serde::Serialize;
use voxcube_kernel::counters::Counters;
use voxcube_kernel::view::View;

/// Rays by type.
#[derive(Clone, Copy, Debug, Serialize, PartialEq, Eq)]
pub struct Rays {
    /// Primary rays that entered the volume.
    pub primary: u64,
    /// Transparency rays.
    pub transparency: u64,
    /// Shadow rays.
    pub shadow: u64,
}

/// Operations by kind.
#[derive(Clone, Copy, Debug, Serialize, PartialEq, Eq)]
pub struct Operations {
    /// Lattice samples.
    pub samples: u64,
    /// Trilinear interpolations.
    pub interpolations: u64,
    /// Nearest-node lookups.
    pub lookups: u64,
    /// Field evaluations refining crossings.
    pub refinements: u64,
    /// Gradient evaluations.
    pub gradients: u64,
    /// Shading evaluations.
    pub shadings: u64,
    /// Surface crossings.
    pub crossings: u64,
    /// Rays stopped early.
    pub early_terminations: u64,
    /// Fallback normals used.
    pub normal_fallbacks: u64,
    /// Reads outside a slab (must be 0).
    pub slab_misses: u64,
}

/// The effects the view called for.
#[derive(Clone, Copy, Debug, Serialize, PartialEq, Eq)]
pub struct EffectsReport {
    /// "surfaces" or "composite".
    pub mode: &'static str,
    /// Shading on.
    pub shading: bool,
    /// Shadow-casting lights.
    pub shadow_lights: u8,
    /// Semi-transparent surfaces present.
    pub transparency: bool,
}

/// One view's report.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ViewReport {
    /// Dataset name.
    pub dataset: String,
    /// View name.
    pub view: String,
    /// The PNG written.
    pub image: String,
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Nodes requested by the scene.
    pub nodes: u32,
    /// Clusters requested by the scene.
    pub clusters: u32,
    /// What the view called for.
    pub effects: EffectsReport,
    /// Rays by type.
    pub rays: Rays,
    /// Work done.
    pub operations: Operations,
    /// Pixels whose colour was not finite before quantisation (always 0).
    pub nan_pixels: u64,
    /// Wall time of the trace, milliseconds.
    pub wall_ms: f64,
    /// SHA-256 of the RGBA8 pixel buffer.
    pub pixels_sha256: String,
}

impl ViewReport {
    /// The report of `rendered`, a render of `view`.
    pub fn new(
        dataset: &str,
        name: &str,
        image: String,
        view: &View,
        nodes: u32,
        clusters: u32,
        rendered: &Rendered,
    ) -> ViewReport {
        let c: Counters = rendered.counters;
        let e = view.effects();
        ViewReport {
            dataset: dataset.to_string(),
            view: name.to_string(),
            image,
            width: rendered.width,
            height: rendered.height,
            nodes,
            clusters,
            effects: EffectsReport {
                mode: if e.surfaces { "surfaces" } else { "composite" },
                shading: e.shading,
                shadow_lights: e.shadow_lights,
                transparency: e.transparency,
            },
            rays: Rays {
                primary: c.primary_rays,
                transparency: c.transparency_rays,
                shadow: c.shadow_rays,
            },
            operations: Operations {
                samples: c.samples,
                interpolations: c.interpolations,
                lookups: c.lookups,
                refinements: c.refinements,
                gradients: c.gradients,
                shadings: c.shadings,
                crossings: c.crossings,
                early_terminations: c.early_terminations,
                normal_fallbacks: c.normal_fallbacks,
                slab_misses: c.slab_misses,
            },
            nan_pixels: rendered.nan_pixels,
            wall_ms: rendered.wall.as_secs_f64() * 1e3,
            pixels_sha256: crate::output::pixels_sha256(&rendered.bytes()),
        }
    }
}

/// The whole run's report.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Report {
    /// The scene file.
    pub scene: String,
    /// One entry per view, in scene order.
    pub views: Vec<ViewReport>,
}

fn count(n: u64) -> String {
    match n {
        0..=9_999 => n.to_string(),
        10_000..=9_999_999 => format!("{:.1}k", n as f64 / 1e3),
        _ => format!("{:.1}M", n as f64 / 1e6),
    }
}

/// The summary table, one line per view.
pub fn summary(views: &[ViewReport]) -> String {
    let mut out = format!(
        "{:<24} {:>9} {:<9} {:>8} {:>8} {:>8} {:>9} {:>9} {:>9} {:>9}\n",
        "dataset/view",
        "size",
        "mode",
        "primary",
        "transp",
        "shadow",
        "samples",
        "interp",
        "shadings",
        "wall"
    );
    for v in views {
        let o = &v.operations;
        out += &format!(
            "{:<24} {:>9} {:<9} {:>8} {:>8} {:>8} {:>9} {:>9} {:>9} {:>6.0} ms\n",
            format!("{}/{}", v.dataset, v.view),
            format!("{}x{}", v.width, v.height),
            v.effects.mode,
            count(v.rays.primary),
            count(v.rays.transparency),
            count(v.rays.shadow),
            count(o.samples),
            count(o.interpolations + o.lookups),
            count(o.shadings),
            v.wall_ms
        );
    }
    out
}
