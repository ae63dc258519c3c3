//! Where a frame's time goes after its set-up: a sampling profile of the threads that trace
//! rays (`voxcube_sampler`: the fabrics mark their ray loops, so the view's set-up, which
//! the frame's report times on its own, is not in it), each sample put in one phase by the
//! functions at its instruction: the rays' set-up, skipping, sampling, compositing, or the
//! rest (the host, messages between nodes, waiting).
//!
//! Invariant: every sample lands in exactly one phase, decided by the functions at its
//! address alone ([`phase_of`]): the innermost in a kernel source file that names a phase
//! decides (inlined ones count: a read the compiler merged into the sample loop is the
//! sample's; the kernel's shared parts, counters or the topology, take the phase they are
//! inlined into), else a call into `libm` is compositing (the sample loop's only calls into
//! it are the exact tier's opacity correction and highlight), else the rest.

use std::time::{Duration, Instant};
use voxcube_sampler::{Profiler, StartError};

/// What a sample of a frame's time was spent on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    /// Primary rays: each pixel's ray made, clipped to the volume and started on the lattice,
    /// and its colour written.
    Rays,
    /// Deciding what a ray may pass over: depth bounds, leaps, cell masks, runs.
    Skipping,
    /// Finding and reading a sample: its lattice position, its cell, the interpolation of
    /// the slab's values or the node field's lanes.
    Sampling,
    /// What a sample becomes: classification, shading, compositing (a surface view's search
    /// counts here too).
    Compositing,
    /// The rest: the host and its fabric, messages between nodes, waiting.
    Other,
}

impl Phase {
    /// Every phase, in the order the tables print them.
    pub const ALL: [Phase; 5] = [
        Phase::Rays,
        Phase::Skipping,
        Phase::Sampling,
        Phase::Compositing,
        Phase::Other,
    ];

    /// The phase's column name.
    pub fn name(self) -> &'static str {
        match self {
            Phase::Rays => "rays",
            Phase::Skipping => "skipping",
            Phase::Sampling => "sampling",
            Phase::Compositing => "compositing",
            Phase::Other => "other",
        }
    }
}

/// The phase of a sample at whose address are `frames`, innermost first, each a function's
/// name and its source file where the binary's line tables name one.
pub fn phase_of<'a>(frames: impl IntoIterator<Item = (&'a str, Option<&'a str>)>) -> Phase {
    let mut libm = false;
    for (name, file) in frames {
        if let Some(phase) = file.and_then(|f| kernel_phase(f, name)) {
            return phase;
        }
        // Built with link-time optimisation, libm's functions keep their C names.
        libm |= name.starts_with("libm::") || file.is_some_and(|f| f.contains("/libm-"));
    }
    if libm {
        Phase::Compositing
    } else {
        Phase::Other
    }
}

/// The phase of function `name` in the kernel's (or its SIMD helpers') source file `file`,
/// or `None` where that file names none: a file of neither, or the kernel's parts that serve
/// every phase (counters, the node's messages, topology, a ray's record), whose code inlined
/// into a phase's is that phase's. The worker's generation of primary rays (`generate`, on
/// the fabrics; the one-node tracer's pixels are in `trace/`) is the rays'.
fn kernel_phase(file: &str, name: &str) -> Option<Phase> {
    if file.contains("/simd/src/") {
        return Some(Phase::Sampling);
    }
    let (_, inside) = file.split_once("/kernel/src/")?;
    let (folder, leaf) = inside.split_once('/').unwrap_or(("", inside));
    match (folder, leaf) {
        ("skip", _) => Some(Phase::Skipping),
        ("trace", "skipping.rs" | "runway.rs" | "interior.rs") => Some(Phase::Skipping),
        ("volume", _) | ("trace", "lattice.rs") => Some(Phase::Sampling),
        ("optics", _) => Some(Phase::Compositing),
        ("trace", "composite.rs" | "deferred.rs" | "lighting.rs" | "march.rs") => {
            Some(Phase::Compositing)
        }
        ("trace", _) => Some(Phase::Rays),
        ("node", "worker.rs") if name.starts_with("generate") => Some(Phase::Rays),
        _ => None,
    }
}

/// Samples counted per phase.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Phases {
    counts: [u64; 5],
}

impl Phases {
    /// Count `n` samples in `phase`.
    pub fn add(&mut self, phase: Phase, n: u64) {
        self.counts[phase as usize] += n;
    }

    /// Samples in `phase`.
    pub fn count(&self, phase: Phase) -> u64 {
        self.counts[phase as usize]
    }

    /// Samples in all.
    pub fn total(&self) -> u64 {
        self.counts.iter().sum()
    }

    /// `phase`'s share of the samples, in percent (0 without samples).
    pub fn percent(&self, phase: Phase) -> f64 {
        100.0 * self.count(phase) as f64 / self.total().max(1) as f64
    }
}

/// The time of `frame` by phase, as a table's columns: the frame, the samples, its
/// `setup` as timed, and the rest apportioned by `phases`' shares, in ms.
pub fn columns(phases: &Phases, frame: Duration, setup: Duration) -> String {
    let rest = frame.saturating_sub(setup).as_secs_f64() * 1e3;
    let mut out = format!(
        "{:>8.1} {:>8} {:>8.1}",
        frame.as_secs_f64() * 1e3,
        phases.total(),
        setup.as_secs_f64() * 1e3
    );
    for phase in Phase::ALL {
        out += &format!(" {:>11.1}", rest * phases.percent(phase) / 100.0);
    }
    out
}

/// The heads of [`columns`].
pub fn column_heads() -> String {
    let mut out = format!("{:>8} {:>8} {:>8}", "ms", "samples", "set-up");
    for phase in Phase::ALL {
        out += &format!(" {:>11}", phase.name());
    }
    out
}

/// Why a profile was not taken.
#[derive(Debug, thiserror::Error)]
pub enum ProfileError {
    /// The profiler did not start.
    #[error("no profile: {0}")]
    Start(StartError),
    /// A profiled frame failed.
    #[error("{0}")]
    Frame(String),
}

/// How long the benchmarks profile each frame they split ([`profile`]): the process's
/// CPU-time timer fires at the system's tick at the finest (250 Hz on many kernels, for all
/// threads together), so two seconds are some hundreds of samples, a share to a few percent.
pub const PROFILED: Duration = Duration::from_secs(2);

/// How a table of [`columns`] was made, for its heading.
pub fn method() -> String {
    format!(
        "its set-up as timed, the rest by the shares of a sampling profile of the ray-tracing threads over {:.0} s of frames after the timed ones",
        PROFILED.as_secs_f64()
    )
}

/// How often the profiler asks for a sample, in the process's CPU time: the system's timer
/// delivers at its tick at the finest, which only makes the profile coarser.
const PERIOD: Duration = Duration::from_millis(1);

/// Profile frames rendered by `frame` until at least `wall` has passed (one frame at the
/// least), and count their samples per phase.
pub fn profile<E: std::fmt::Display>(
    wall: Duration,
    mut frame: impl FnMut() -> Result<(), E>,
) -> Result<Phases, ProfileError> {
    let profiler = Profiler::start(PERIOD).map_err(ProfileError::Start)?;
    let start = Instant::now();
    loop {
        frame().map_err(|e| ProfileError::Frame(e.to_string()))?;
        if start.elapsed() >= wall {
            break;
        }
    }
    let mut phases = Phases::default();
    for (n, frames) in profiler.stop().resolved() {
        let phase = phase_of(
            frames
                .iter()
                .map(|f| (f.function.as_str(), f.file.as_deref())),
        );
        phases.add(phase, n as u64);
    }
    Ok(phases)
}

/// [`profile`] for [`PROFILED`], or `None` with a line in `notes` saying why not, naming
/// `what` was to be profiled: a benchmark goes on without its split.
pub fn noted<E: std::fmt::Display>(
    notes: &mut String,
    what: &str,
    frame: impl FnMut() -> Result<(), E>,
) -> Option<Phases> {
    profile(PROFILED, frame)
        .map_err(|e| notes.push_str(&format!("no profile of {what}: {e}\n")))
        .ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A kernel source file's path as a build's line tables give it.
    macro_rules! k {
        ($file:literal) => {
            concat!("/work/voxcube/kernel/src/", $file)
        };
    }

    /// The phase of a stack of (function, file) pairs, innermost first; "" for no file.
    fn phase(frames: &[(&str, &str)]) -> Phase {
        phase_of(
            frames
                .iter()
                .map(|&(n, f)| (n, (!f.is_empty()).then_some(f))),
        )
    }

    #[test]
    fn the_innermost_kernel_file_decides_and_library_frames_inside_it_do_not() {
        let core = "/rustc/abc/library/core/src/num/f32.rs";
        let glam = "/cargo/registry/glam-0.29.3/src/f32/sse2/vec4.rs";
        // A lerp of glam's inlined into the node field's read, inlined into the loop.
        let read = [
            ("glam::Vec4::lerp", glam),
            ("voxcube_kernel::volume::lanes::read", k!("volume/lanes.rs")),
            (
                "voxcube_kernel::trace::composite::composite",
                k!("trace/composite.rs"),
            ),
            (
                "voxcube::run::render::render_direct",
                "/work/voxcube/hostsim/src/run/render.rs",
            ),
        ];
        assert_eq!(phase(&read), Phase::Sampling);
        // An address in libm's powf (a function of its own: its caller is not at the
        // address) is the shading's.
        let powf = [
            ("core::f32::abs", core),
            (
                "libm::math::powf::powf",
                "/cargo/registry/libm-0.2/src/math/powf.rs",
            ),
        ];
        assert_eq!(phase(&powf), Phase::Compositing);
        let lto = [(
            "log1pf",
            "/root/.cargo/registry/src/index.crates.io-x/libm-0.2.16/src/math/log1pf.rs",
        )];
        assert_eq!(phase(&lto), Phase::Compositing);
        // Inlined into the kernel, the kernel's file decides, not libm.
        let floor = [
            (
                "libm::math::floorf::floorf",
                "/cargo/registry/libm-0.2/src/math/floorf.rs",
            ),
            ("voxcube_kernel::skip::cells::reach", k!("skip/cells.rs")),
        ];
        assert_eq!(phase(&floor), Phase::Skipping);
        let leap = [
            (
                "voxcube_kernel::trace::skipping::Skipper::leap_inside",
                k!("trace/skipping.rs"),
            ),
            (
                "voxcube_kernel::trace::composite::composite",
                k!("trace/composite.rs"),
            ),
        ];
        assert_eq!(phase(&leap), Phase::Skipping);
        let clip = [
            ("voxcube_kernel::trace::ray::clip", k!("trace/ray.rs")),
            (
                "voxcube_kernel::trace::view::View::primary_ray",
                k!("trace/view.rs"),
            ),
        ];
        assert_eq!(phase(&clip), Phase::Rays);
        let prefetch = [("voxcube_simd::prefetch", "/work/voxcube/simd/src/lib.rs")];
        assert_eq!(phase(&prefetch), Phase::Sampling);
    }

    #[test]
    fn addresses_outside_the_kernel_s_source_are_the_rest() {
        assert_eq!(phase(&[]), Phase::Other);
        assert_eq!(
            phase(&[
                ("memcpy", ""),
                ("std::thread::park", "/rustc/x/std/src/thread.rs"),
            ]),
            Phase::Other
        );
        // The kernel's node and its messages are the rest too: not one of a frame's phases.
        let poll = [(
            "voxcube_kernel::node::worker::Worker::poll",
            k!("node/worker.rs"),
        )];
        assert_eq!(phase(&poll), Phase::Other);
    }

    #[test]
    fn the_kernel_s_shared_parts_take_the_phase_they_are_inlined_into() {
        // The topology's row index, inlined into the depth bound, inlined into a ray's
        // depth run: skipping, not the node's.
        let depth = [
            ("index", k!("node/topology.rs")),
            ("bound", k!("skip/bounds.rs")),
            ("depth_run<i16>", k!("trace/skipping.rs")),
        ];
        assert_eq!(phase(&depth), Phase::Skipping);
        let counted = [
            ("add", k!("counters.rs")),
            ("run<u8>", k!("trace/composite.rs")),
        ];
        assert_eq!(phase(&counted), Phase::Compositing);
        // The worker's primary rays are the rays', where its poll is not.
        let generate = [("generate<u8, 32, 64, 16, 1024>", k!("node/worker.rs"))];
        assert_eq!(phase(&generate), Phase::Rays);
    }

    #[test]
    fn the_frame_after_its_set_up_is_shared_out_by_the_samples() {
        let mut p = Phases::default();
        p.add(Phase::Sampling, 3);
        p.add(Phase::Compositing, 1);
        let ms = Duration::from_millis;
        let cols: Vec<String> = columns(&p, ms(50), ms(10))
            .split_whitespace()
            .map(String::from)
            .collect();
        assert_eq!(
            cols,
            ["50.0", "4", "10.0", "0.0", "0.0", "30.0", "10.0", "0.0"]
        );
        assert_eq!(column_heads().split_whitespace().count(), cols.len());
    }

    #[test]
    fn shares_are_of_every_counted_sample() {
        let mut p = Phases::default();
        assert_eq!(p.percent(Phase::Sampling), 0.0);
        p.add(Phase::Sampling, 3);
        p.add(Phase::Other, 1);
        assert_eq!(p.total(), 4);
        assert_eq!(p.percent(Phase::Sampling), 75.0);
        assert_eq!(p.count(Phase::Rays), 0);
    }
}
