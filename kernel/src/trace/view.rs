//! One view: everything a node needs to trace an image of a dataset, checked once, and the
//! effects it calls for. It also makes the rays every node must agree on (primary, shadow,
//! transparency continuations), so their lattices come from one piece of arithmetic.
//!
//! Invariants (checked by [`View::new`]): image at least 1×1; Δt in `[1/64, 2]` cell edges;
//! gradient distance in `[1/4, 3]` cells; surfaces mode has 1 to [`MAX_SURFACES`] surfaces
//! with finite iso values, colours in `[0, 1]` and transparency in `[0, 1]`; cutoff in
//! `[0, 1)`; depth at most [`MAX_DEPTH`]; refinement at most [`MAX_REFINE_STEPS`] steps.

use crate::optics::classify::Classified;
use crate::optics::segments::Layout;
use crate::optics::shade::{Highlights, Light, Shading, MAX_LIGHTS};
use crate::optics::shading_table::ShadingTable;
use crate::optics::surface::{IsoSurface, MAX_SURFACES};
use crate::optics::transfer::TransferFunction;
use crate::trace::camera::{Camera, Projection};
use crate::trace::lattice::Lattice;
use crate::trace::ray::{clip, Ray};
use crate::trace::starts::RowLeaps;
use crate::trace::state::{RayKind, RayState};
use crate::volume::grid::{Grid, Model};
use crate::volume::sample::Range;
use core::fmt;
use glam::Vec3;
use heapless::Vec;

/// Deepest chain of transparency rays behind one primary ray.
pub const MAX_DEPTH: u8 = 15;
/// Most field evaluations spent refining one crossing.
pub const MAX_REFINE_STEPS: u8 = 16;
/// The default cutoff: stop when what is behind could change the pixel by less than half an
/// 8-bit level.
pub const DEFAULT_CUTOFF: f32 = 1.0 / 512.0;

/// How exactly a view's samples are evaluated. Each tier is bit-identical for every node
/// count, cluster size, partition and schedule; they differ from each other.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Accuracy {
    /// The image definition every test pins: every sample exact.
    #[default]
    Exact,
    /// The approximations production ray casters make, each named by
    /// [`View::approximations`].
    Fast,
}

impl Accuracy {
    /// Every tier, in the order the CLI and the docs list them.
    pub const ALL: [Accuracy; 2] = [Accuracy::Exact, Accuracy::Fast];

    /// The tier's name in scene files, on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Accuracy::Exact => "exact",
            Accuracy::Fast => "fast",
        }
    }

    /// The tier of that name, if any: [`Accuracy::name`]'s inverse, the one reading of a
    /// tier's name for the scene and the command line alike.
    pub fn from_name(name: &str) -> Option<Accuracy> {
        Accuracy::ALL.into_iter().find(|a| a.name() == name)
    }
}

/// How a composited view integrates between its samples.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Compositing {
    /// Each sample stands for the segment that follows it, at its own value (the
    /// definition, and the fast tier's pre-classified table).
    #[default]
    Sampled,
    /// Each segment between two samples is read from a table of the transfer function
    /// integrated over a value running linearly from the one to the other
    /// ([`crate::optics::segments`]): a fast-tier approximation.
    PreIntegrated,
}

impl Compositing {
    /// Every way, in the order the docs list them.
    pub const ALL: [Compositing; 2] = [Compositing::Sampled, Compositing::PreIntegrated];

    /// Its name in scene files, on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Compositing::Sampled => "sampled",
            Compositing::PreIntegrated => "pre-integrated",
        }
    }

    /// The way of that name, if any: [`Compositing::name`]'s inverse.
    pub fn from_name(name: &str) -> Option<Compositing> {
        Compositing::ALL.into_iter().find(|c| c.name() == name)
    }
}

/// An approximation the fast tier makes, where a view calls for it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Approximation {
    /// Compositing reads a pre-classified table of the transfer function and its opacity
    /// for a whole Δt segment ([`crate::optics::classify`]) at the nearest of its entries.
    PreClassified,
    /// Phong's highlight is read from a table of cosines by linear interpolation
    /// ([`crate::optics::shade::Highlights`]) instead of `powf`.
    HighlightTable,
    /// The shading gradient is the trilinear interpolation of the nodes' central
    /// differences ([`crate::volume::nodes`]) instead of central differences of the
    /// trilinear field: equal in exact arithmetic inside the grid, rounded differently, and
    /// one-sided at the grid's faces on the nodes rather than at the point.
    NodeGradients,
    /// A composited view with parallel rays and directional lights shades by a table over
    /// normal directions ([`crate::optics::shading_table`]), read at its gradient's cell.
    ShadingTable,
    /// Compositing reads each segment between two samples from a pre-integrated table
    /// ([`crate::optics::segments`]) at its two values' nearest entries.
    PreIntegrated,
}

impl Approximation {
    /// What reports call it.
    pub fn name(self) -> &'static str {
        match self {
            Approximation::PreClassified => "pre-classified transfer function",
            Approximation::HighlightTable => "highlight by table",
            Approximation::NodeGradients => "gradient from node differences",
            Approximation::ShadingTable => "shading by table over normal directions",
            Approximation::PreIntegrated => "pre-integrated segments",
        }
    }
}

/// What a view's verdict on a range of values depends on ([`View::emptiness`]).
#[allow(
    clippy::large_enum_variant,
    reason = "made once a frame and kept by a host beside masks of megabytes; the kernel has no heap to box the larger"
)]
#[derive(Clone, Debug, PartialEq)]
pub enum Emptiness {
    /// Surfaces: a range is empty below the least iso value (its bits).
    Below(u32),
    /// Composited in the fast tier: by the pre-classified table's entries that show.
    Table(crate::optics::classify::Shown),
    /// Composited by the transfer function's opacities (colours too, compared whole).
    Function(TransferFunction),
    /// Pre-integrated: below the table's first entry that shows
    /// ([`crate::optics::segments::Layout::key`]).
    Segments((u32, u32, u32)),
}

/// What a view renders.
#[derive(Clone, Debug, PartialEq)]
pub enum Mode {
    /// Surface searching for these iso-surfaces.
    Surfaces(Vec<IsoSurface, MAX_SURFACES>),
    /// Compositing through this transfer function.
    Composite(TransferFunction),
}

/// The parameters of a view, as a scene states them.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewSpec {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// The camera (world space).
    pub camera: Camera,
    /// Interpolation model.
    pub model: Model,
    /// Sample distance in cell edges (the smallest spacing).
    pub dt: f32,
    /// Central-difference distance for gradients, in cells.
    pub gradient_distance: f32,
    /// Surfaces or compositing.
    pub mode: Mode,
    /// Illumination, or `None` for unlit colour (no gradients, no lights, no shadow rays).
    pub shading: Option<Shading>,
    /// Lights, in order.
    pub lights: Vec<Light, MAX_LIGHTS>,
    /// Background colour, each channel in `[0, 1]`.
    pub background: Vec3,
    /// Transmittance below which a ray stops: compositing terminates, a transparency ray is
    /// not spawned, a shadow ray counts as blocked at its accumulated value.
    pub cutoff: f32,
    /// Deepest chain of transparency rays.
    pub max_depth: u8,
    /// Field evaluations to refine each surface crossing.
    pub refine_steps: u8,
    /// The accuracy tier.
    pub accuracy: Accuracy,
    /// How a composited view integrates between samples.
    pub compositing: Compositing,
}

/// Why a view is unusable; each names the scene key at fault.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ViewError {
    /// `width` or `height` is zero.
    ImageSize,
    /// `dt` out of range.
    Step(f32),
    /// `gradient_distance` out of range.
    GradientDistance(f32),
    /// Surfaces mode without surfaces.
    NoSurfaces,
    /// `surfaces[index]` is malformed.
    Surface {
        /// Which surface.
        index: usize,
    },
    /// A shadow light in compositing mode.
    ShadowsInComposite {
        /// Which light.
        index: usize,
    },
    /// Background colour out of range.
    Background,
    /// `cutoff` out of range.
    Cutoff(f32),
    /// `max_depth` out of range.
    Depth(u8),
    /// `refine_steps` out of range.
    Refine(u8),
    /// A shading coefficient is negative or not finite.
    Shading,
    /// Pre-integrated compositing asked of a view that is not composited in the fast tier.
    PreIntegration,
}

impl fmt::Display for ViewError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            ViewError::ImageSize => write!(f, "width and height must be at least 1 pixel"),
            ViewError::Step(v) => write!(f, "dt is {v}; it must lie in [1/64, 2] cell edges"),
            ViewError::GradientDistance(v) => {
                write!(f, "gradient_distance is {v}; it must lie in [0.25, 3] cells")
            }
            ViewError::NoSurfaces => write!(f, "mode \"surfaces\" needs at least one [[...surfaces]] entry"),
            ViewError::Surface { index } => write!(
                f,
                "surfaces[{index}]: iso must be finite, color channels and transparency in [0, 1]"
            ),
            ViewError::ShadowsInComposite { index } => write!(
                f,
                "lights[{index}].shadows: shadow rays are traced from surfaces; mode \"composite\" has none"
            ),
            ViewError::Background => write!(f, "background channels must lie in [0, 1]"),
            ViewError::Cutoff(v) => write!(f, "cutoff is {v}; it must lie in [0, 1)"),
            ViewError::Depth(v) => write!(f, "max_depth is {v}; it must be at most {MAX_DEPTH}"),
            ViewError::Refine(v) => write!(f, "refine_steps is {v}; it must be at most {MAX_REFINE_STEPS}"),
            ViewError::Shading => write!(f, "shading coefficients must be finite and >= 0"),
            ViewError::PreIntegration => write!(
                f,
                "compositing = \"pre-integrated\" is a fast-tier approximation of mode \"composite\": it needs accuracy = \"fast\" and mode = \"composite\""
            ),
        }
    }
}

impl core::error::Error for ViewError {}

/// The effects a view calls for: nothing is traced, computed or reserved for the others.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Effects {
    /// Surface searching (otherwise compositing).
    pub surfaces: bool,
    /// Shading from gradients and lights.
    pub shading: bool,
    /// Lights that trace shadow rays (0 without shading or in compositing).
    pub shadow_lights: u8,
    /// Whether any surface is semi-transparent (transparency rays may be traced).
    pub transparency: bool,
}

/// A checked view of a grid.
#[derive(Clone, Debug, PartialEq)]
pub struct View {
    spec: ViewSpec,
    dt_world: f32,
    cell_edge: f32,
    inv_spacing: Vec3,
    spacing: Vec3,
    box_lo: Vec3,
    box_hi: Vec3,
    effects: Effects,
    /// The least iso value (surfaces mode): a value below it is outside every surface.
    min_iso: f32,
    /// How far first samples move along an image row (parallel projections only).
    row_leaps: Option<RowLeaps>,
    /// The pre-classified transfer function (fast tier, sampled compositing).
    classified: Option<Classified>,
    /// Where values fall in the pre-integration table (fast tier, pre-integrated
    /// compositing); the table itself is large and a node holds it beside its slab.
    segments: Option<Layout>,
    /// The highlight table (fast tier, shaded views with a highlight).
    highlights: Option<Highlights>,
    /// The shading by normal direction (fast tier, compositing with parallel rays and
    /// directional lights).
    shading_table: Option<ShadingTable>,
    /// Whether shading reads gradients from the node field (fast tier, shaded, cell model,
    /// differences one cell apart).
    node_gradients: bool,
    /// Whether the exact tier's shading reads a gradient from the nodes' differences where
    /// that is its own definition re-associated ([`View::exact_node_gradients`]).
    exact_node_gradients: bool,
    /// A test-only fault: the fast tier skips by the transfer function's own emptiness
    /// instead of its table's.
    #[cfg(feature = "mutants")]
    exact_emptiness: bool,
    /// A test-only fault: pre-integrated compositing passes over a sample whatever the
    /// segment ending there holds.
    #[cfg(feature = "mutants")]
    careless_segments: bool,
}

impl View {
    /// Check `spec` against `grid`.
    pub fn new(spec: ViewSpec, grid: &Grid) -> Result<View, ViewError> {
        if spec.width == 0 || spec.height == 0 {
            return Err(ViewError::ImageSize);
        }
        if !(spec.dt >= 1.0 / 64.0 && spec.dt <= 2.0) {
            return Err(ViewError::Step(spec.dt));
        }
        if !(spec.gradient_distance >= 0.25 && spec.gradient_distance <= 3.0) {
            return Err(ViewError::GradientDistance(spec.gradient_distance));
        }
        let unit = |v: f32| (0.0..=1.0).contains(&v);
        if !spec.background.to_array().into_iter().all(unit) {
            return Err(ViewError::Background);
        }
        if !(spec.cutoff >= 0.0 && spec.cutoff < 1.0) {
            return Err(ViewError::Cutoff(spec.cutoff));
        }
        if spec.max_depth > MAX_DEPTH {
            return Err(ViewError::Depth(spec.max_depth));
        }
        if spec.refine_steps > MAX_REFINE_STEPS {
            return Err(ViewError::Refine(spec.refine_steps));
        }
        if let Some(s) = &spec.shading {
            let ok = |v: f32| v.is_finite() && v >= 0.0;
            if !(ok(s.ambient) && ok(s.diffuse) && ok(s.specular) && ok(s.shininess)) {
                return Err(ViewError::Shading);
            }
        }
        let mut effects = Effects {
            shading: spec.shading.is_some(),
            ..Effects::default()
        };
        match &spec.mode {
            Mode::Surfaces(surfaces) => {
                if surfaces.is_empty() {
                    return Err(ViewError::NoSurfaces);
                }
                for (index, s) in surfaces.iter().enumerate() {
                    if !(s.iso.is_finite()
                        && s.color.to_array().into_iter().all(unit)
                        && unit(s.transparency))
                    {
                        return Err(ViewError::Surface { index });
                    }
                }
                effects.surfaces = true;
                effects.transparency =
                    spec.max_depth > 0 && surfaces.iter().any(|s| s.transparency > 0.0);
                if effects.shading {
                    effects.shadow_lights = spec.lights.iter().filter(|l| l.shadows).count() as u8;
                }
            }
            Mode::Composite(_) => {
                if let Some(index) = spec.lights.iter().position(|l| l.shadows) {
                    return Err(ViewError::ShadowsInComposite { index });
                }
            }
        }
        let min_iso = match &spec.mode {
            Mode::Surfaces(surfaces) => {
                surfaces.iter().map(|s| s.iso).fold(f32::INFINITY, f32::min)
            }
            Mode::Composite(_) => f32::NEG_INFINITY,
        };
        let cell_edge = grid.cell_edge();
        let (box_lo, box_hi) = grid.index_box(spec.model);
        let row_leaps = RowLeaps::new(
            spec.camera.projection(),
            spec.camera.image_axes().0,
            spec.camera.forward(),
            spec.width,
            grid.inv_spacing(),
            (box_lo, box_hi),
        );
        let (classified, segments) = match (&spec.mode, spec.accuracy, spec.compositing) {
            (Mode::Composite(tf), Accuracy::Fast, Compositing::Sampled) => {
                (Some(Classified::new(tf, spec.dt)), None)
            }
            (_, _, Compositing::Sampled) => (None, None),
            (Mode::Composite(tf), Accuracy::Fast, Compositing::PreIntegrated) => {
                let layout = Layout::of(tf, spec.dt).map_err(|_| ViewError::Step(spec.dt))?;
                (None, Some(layout))
            }
            _ => return Err(ViewError::PreIntegration),
        };
        let shading_table = match (&spec.shading, &spec.mode, spec.camera.projection()) {
            (Some(s), Mode::Composite(_), Projection::Orthographic { .. })
                if spec.accuracy == Accuracy::Fast =>
            {
                ShadingTable::new(s, &spec.lights, spec.camera.forward())
            }
            _ => None,
        };
        // Where the table shades, the highlight is its `powf`'s.
        let highlights = match (&spec.shading, spec.accuracy) {
            (Some(s), Accuracy::Fast) if s.specular > 0.0 && shading_table.is_none() => {
                Some(Highlights::new(s))
            }
            _ => None,
        };
        let by_nodes =
            spec.shading.is_some() && spec.model == Model::Cell && spec.gradient_distance == 1.0;
        let node_gradients = by_nodes && spec.accuracy == Accuracy::Fast;
        let exact_node_gradients = by_nodes && spec.accuracy == Accuracy::Exact;
        Ok(View {
            classified,
            segments,
            highlights,
            shading_table,
            node_gradients,
            exact_node_gradients,
            dt_world: spec.dt * cell_edge,
            cell_edge,
            inv_spacing: grid.inv_spacing(),
            spacing: grid.spacing(),
            box_lo,
            box_hi,
            effects,
            min_iso,
            row_leaps,
            spec,
            #[cfg(feature = "mutants")]
            exact_emptiness: false,
            #[cfg(feature = "mutants")]
            careless_segments: false,
        })
    }

    /// Whether nothing with values in `r` can show: for surfaces, `r` lies below every iso
    /// value; for compositing, nothing in it is opaque. A sample in such a block may be
    /// skipped, provably changing nothing, when [`View::may_skip`] also holds. Depends on the
    /// block alone, so a marcher may remember it while it stays in one block.
    #[inline]
    pub fn empty(&self, r: Range) -> bool {
        match &self.spec.mode {
            // Below every iso value is below the least of them (NaN is below none).
            Mode::Surfaces(_) => self.below_surfaces(r.max),
            Mode::Composite(tf) => match (&self.classified, &self.segments) {
                (Some(table), _) if !self.skips_by_the_function() => table.empty(r.min, r.max),
                (_, Some(layout)) => layout.empty(r.min, r.max),
                _ => !(tf.max_opacity(r.min, r.max) > 0.0),
            },
        }
    }

    /// What [`View::empty`] reads, apart from the view: two views with equal ones call every
    /// range alike, so what a host classified by one (cell masks, leap maps) serves the other
    /// (an orbit's next frame, a bench's next repetition). Surfaces are told by their least
    /// iso value; a composited view by its table's entries that show, or by its transfer
    /// function where it skips by that.
    pub fn emptiness(&self) -> Emptiness {
        match &self.spec.mode {
            Mode::Surfaces(_) => Emptiness::Below(self.min_iso.to_bits()),
            Mode::Composite(tf) => match (&self.classified, &self.segments) {
                (Some(table), _) if !self.skips_by_the_function() => {
                    Emptiness::Table(table.shown())
                }
                (_, Some(layout)) => Emptiness::Segments(layout.key()),
                _ => Emptiness::Function(tf.clone()),
            },
        }
    }

    /// The same view with its pre-classified table built for segments of `dt` cell edges
    /// rather than its own: a test-only fault, for the negative control that a table for
    /// another step changes the image.
    #[cfg(feature = "mutants")]
    pub fn with_stale_table(mut self, dt: f32) -> View {
        if let (Mode::Composite(tf), Some(_)) = (&self.spec.mode, &self.classified) {
            self.classified = Some(Classified::new(tf, dt));
        }
        self
    }

    /// The same view skipping by the transfer function's own emptiness in the fast tier too,
    /// where samples read its table: a test-only fault, for the negative control that
    /// skipping asks the tier's own table.
    #[cfg(feature = "mutants")]
    pub fn with_exact_emptiness(mut self) -> View {
        self.exact_emptiness = true;
        self
    }

    /// The same view passing over samples in empty cells whatever the segment ending there
    /// holds, where it composites pre-integrated: a test-only fault, for the negative control
    /// that skipping changes no pixel only by asking the segment's front.
    #[cfg(feature = "mutants")]
    pub fn with_careless_segments(mut self) -> View {
        self.careless_segments = true;
        self
    }

    /// Whether the fault of [`View::with_careless_segments`] is in: never outside tests.
    #[inline(always)]
    fn careless(&self) -> bool {
        #[cfg(feature = "mutants")]
        return self.careless_segments;
        #[cfg(not(feature = "mutants"))]
        false
    }

    /// Whether the fault of [`View::with_exact_emptiness`] is in: never outside tests.
    #[inline(always)]
    fn skips_by_the_function(&self) -> bool {
        #[cfg(feature = "mutants")]
        return self.exact_emptiness;
        #[cfg(not(feature = "mutants"))]
        false
    }

    /// The highlight table, when the view is shaded with a highlight in the fast tier.
    #[inline]
    pub fn highlights(&self) -> Option<&Highlights> {
        self.highlights.as_ref()
    }

    /// The shading by normal direction, when the view has one
    /// ([`Approximation::ShadingTable`]).
    #[inline]
    pub fn shading_table(&self) -> Option<&ShadingTable> {
        self.shading_table.as_ref()
    }

    /// Whether shading reads its gradients from the node field
    /// ([`Approximation::NodeGradients`]).
    #[inline]
    pub fn node_gradients(&self) -> bool {
        self.node_gradients
    }

    /// Whether the exact tier's shading reads the gradient of a point in the grid from the
    /// nodes' central differences, interpolated ([`crate::volume::nodes::in_grid`]): there
    /// the central difference of the trilinear field at one cell is, in exact arithmetic,
    /// the interpolation of the nodes' differences, so the definition stands and only the
    /// order of the roundings changes. A point outside the grid takes the six reads.
    pub fn exact_node_gradients(&self) -> bool {
        self.exact_node_gradients
    }

    /// The trilinear interpolations a gradient is counted as: one in the fast tier, whose
    /// definition is the interpolation of the nodes' differences; six in the exact tier,
    /// whose definition is the difference of six interpolations, however it is evaluated
    /// (the counters, and the paper's simulated times, price what a tier defines).
    #[inline]
    pub fn interpolations_per_gradient(&self) -> u64 {
        if self.node_gradients {
            1
        } else {
            6
        }
    }

    /// Whether shading reads the node field anywhere: a node holds it when it has room.
    pub fn reads_node_field(&self) -> bool {
        self.node_gradients || self.exact_node_gradients
    }

    /// The pre-classified transfer function, when the view composites in the fast tier.
    #[inline]
    pub fn classified(&self) -> Option<&Classified> {
        self.classified.as_ref()
    }

    /// The approximations this view's tier makes here (none in the exact tier, and none
    /// where the view calls for nothing a fast-tier approximation replaces).
    pub fn approximations(&self) -> Vec<Approximation, 6> {
        let mut out = Vec::new();
        // Room for every approximation the tier knows.
        if self.classified.is_some() {
            let _ = out.push(Approximation::PreClassified);
        }
        if self.highlights.is_some() {
            let _ = out.push(Approximation::HighlightTable);
        }
        if self.node_gradients {
            let _ = out.push(Approximation::NodeGradients);
        }
        if self.shading_table.is_some() {
            let _ = out.push(Approximation::ShadingTable);
        }
        if self.segments.is_some() {
            let _ = out.push(Approximation::PreIntegrated);
        }
        out
    }

    /// Whether value `v` lies below every iso value, outside every surface (false for NaN,
    /// and for every value of a composited view).
    #[inline]
    pub fn below_surfaces(&self, v: f32) -> bool {
        v < self.min_iso
    }

    /// The ray's half of the skipping test: a surface ray may skip only where no crossing
    /// from its previous sample is pending (that sample was below every iso value, or itself
    /// skipped) and nothing on the current segment has been reported.
    #[inline]
    pub fn may_skip(&self, ray: &RayState) -> bool {
        match &self.spec.mode {
            Mode::Surfaces(_) => {
                ray.done_here == 0
                    && (!ray.primed || ray.prev_stale || self.below_surfaces(ray.prev))
            }
            // A segment ends at every sample: it may be passed over only where the one
            // ending there is transparent, between two values below the table's first
            // entry that shows.
            Mode::Composite(_) => self.may_pass(ray.prev, !ray.primed || ray.prev_stale),
        }
    }

    /// [`View::may_skip`] for a composited ray whose last value read is `prev`, or none
    /// (`stale`: samples were passed over since, or none was read): pre-integrated, only
    /// where the segment ending at the next sample may be transparent.
    #[inline(always)]
    pub fn may_pass(&self, prev: f32, stale: bool) -> bool {
        match &self.segments {
            Some(layout) => stale || layout.below(prev) || self.careless(),
            None => true,
        }
    }

    /// Whether a sample loop needs the value of the sample before the current one, so that a
    /// sample passed over leaves it stale ([`RayState::prev_stale`]): surfaces, for their
    /// crossings, and pre-integrated compositing, for its segments.
    #[inline]
    pub fn reads_predecessor(&self) -> bool {
        self.effects.surfaces || self.segments.is_some()
    }

    /// Where values fall in the pre-integration table, when the view composites
    /// pre-integrated (its table is the slab's: [`crate::volume::slab::Slab::segments`]).
    #[inline]
    pub fn segments(&self) -> Option<&Layout> {
        self.segments.as_ref()
    }

    /// The parameters.
    pub fn spec(&self) -> &ViewSpec {
        &self.spec
    }

    /// The effects this view calls for.
    pub fn effects(&self) -> Effects {
        self.effects
    }

    /// This view with every primary ray set up wherever it is asked for: no row leaps (a
    /// debug switch, to compare; it changes no pixel, only the time).
    pub fn without_row_leaps(mut self) -> View {
        self.row_leaps = None;
        self
    }

    /// The bound on how far first samples move along an image row, for ring positions to
    /// pass over pixels they do not start; `None` for a perspective projection.
    pub fn row_leaps(&self) -> Option<RowLeaps> {
        self.row_leaps
    }

    /// Index units per world unit, per axis.
    pub fn inv_spacing(&self) -> Vec3 {
        self.inv_spacing
    }

    /// World distance between samples.
    pub fn dt_world(&self) -> f32 {
        self.dt_world
    }

    /// World length of one cell edge (opacity is defined per cell edge).
    pub fn cell_edge(&self) -> f32 {
        self.cell_edge
    }

    /// Index coordinates to world.
    #[inline]
    pub fn to_world(&self, p: Vec3) -> Vec3 {
        p * self.spacing
    }

    /// Ghost planes each side a slab needs so that no read leaves its storage: one step back
    /// to the previous sample (refinement), the gradient stencil around it, and the
    /// interpolation's second plane. A step moves at most `dt` planes along X.
    pub fn ghost_planes(&self) -> u32 {
        libm::ceilf(self.spec.dt + self.spec.gradient_distance) as u32 + 1
    }

    /// Pixels in the image.
    pub fn pixel_count(&self) -> u64 {
        u64::from(self.spec.width) * u64::from(self.spec.height)
    }

    /// The line of pixel `pixel`'s primary ray (row-major), whether or not it meets the
    /// dataset: the origin and direction [`View::primary_ray`] clips. Always inline, as
    /// [`crate::trace::camera::Camera::primary`] is: a ray returned through the stack stalls its
    /// caller's vector loads.
    #[inline(always)]
    pub fn primary_line(&self, pixel: u32) -> Ray {
        let (px, py) = (pixel % self.spec.width, pixel / self.spec.width);
        let (origin, dir) = self
            .spec
            .camera
            .primary(px, py, self.spec.width, self.spec.height);
        Ray::from_world(origin, dir, self.inv_spacing)
    }

    /// Given that pixel `pixel`'s primary ray misses the dataset, how many of the pixels
    /// after it in its row certainly miss too ([`RowLeaps::misses_after`]; none without a
    /// bound, for a perspective projection).
    pub fn misses_after(&self, pixel: u32) -> u32 {
        let left = self.spec.width - 1 - pixel % self.spec.width;
        self.row_leaps.map_or(0, |leaps| {
            leaps
                .misses_after(self.primary_line(pixel).origin)
                .min(left)
        })
    }

    /// The primary ray of pixel `pixel` (row-major), or `None` when it misses the dataset.
    /// Always inline: the ray returned through the stack stalled the pixel loops' loads of it.
    #[inline(always)]
    pub fn primary_ray(&self, pixel: u32) -> Option<RayState> {
        let ray = self.primary_line(pixel);
        let span = clip(&ray, self.box_lo, self.box_hi, 0.0, f32::MAX)?;
        let lattice = Lattice::new(span.t_near, span.t_far, self.dt_world)?;
        Some(RayState::new(
            RayKind::Primary,
            pixel,
            ray,
            lattice,
            span.entry,
            0,
        ))
    }

    /// The shadow ray from index-space point `from` toward a light in world direction
    /// `to_light` at world distance `distance`, or `None` when no lattice sample lies between
    /// (then nothing can shadow the point). Its samples start one step from the point: the
    /// surface being lit never shadows itself.
    pub fn shadow_ray(
        &self,
        pixel: u32,
        from: Vec3,
        to_light: Vec3,
        distance: f32,
    ) -> Option<RayState> {
        let ray = Ray {
            origin: from,
            dir: to_light * self.inv_spacing,
            dir_world: to_light,
        };
        let span = clip(&ray, self.box_lo, self.box_hi, 0.0, distance.min(f32::MAX))?;
        let lattice = Lattice::new(0.0, span.t_far, self.dt_world)?;
        (lattice.last >= 1)
            .then(|| RayState::new(RayKind::Shadow, pixel, ray, lattice, span.entry, 1))
    }

    /// The transparency ray that continues `ray` past the surface of opacity `alpha` it just
    /// hit, or `None` when the view does not trace one there: an opaque surface, the depth
    /// limit, or too little light left to show (the background is then seen instead).
    pub fn continuation(&self, ray: &RayState, alpha: f32) -> Option<RayState> {
        let weight = ray.weight * (1.0 - alpha);
        if !(alpha < 1.0) || ray.depth >= self.spec.max_depth || !(weight > self.spec.cutoff) {
            return None;
        }
        Some(RayState {
            kind: RayKind::Transparency,
            depth: ray.depth + 1,
            weight,
            ..*ray
        })
    }
}
