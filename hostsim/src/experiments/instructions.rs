//! `voxcube bench --instructions`: what a frame costs in instructions, a figure that does not
//! move with the machine's load, its other tenants or its clock. Each SOD view of the bench
//! at 350×250, Δt = ½ is rendered on one node of the modern profile (one thread, the fast
//! tier's node field held) by this binary under callgrind, valgrind's instruction counter,
//! three times over: loading alone, then one frame, then two. The second frame's
//! instructions are what every further frame of that view costs (the bench's medians time
//! those); the first frame's extra is what it builds once per volume, and what a byte
//! volume keeps from its first view of a transfer function (cell masks, cell leap maps).
//!
//! Invariant: a count is the difference of two whole runs of the same binary with the same
//! arguments but the frame count, so what the process does around the frames (parsing,
//! loading, exiting) cancels; the frames' own counters come from the same runs.

use super::bench::{sod_scene, Size, FAST_VIEW};
use crate::input::scene::Scene;
use crate::memory::budget::Profile;
use crate::run::render::{render_on, Fabric, Machine};
use std::fmt::Write;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The most instructions a frame of SOD's composited view in the fast tier may take on one
/// node (the issue "Faster than VTK on composited volumes").
pub const FAST_TARGET: u64 = 700_000_000;

/// One view's counts.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Count {
    /// The bench's view.
    pub view: String,
    /// Instructions of the first frame, with what it builds once per volume.
    pub first: u64,
    /// Instructions of every further frame.
    pub frame: u64,
    /// Lattice samples a frame evaluated.
    pub samples: u64,
    /// Lattice samples a frame skipped as provably empty.
    pub skipped: u64,
}

impl Count {
    /// Instructions per lattice sample a frame's rays passed, evaluated or skipped.
    pub fn per_lattice_sample(&self) -> f64 {
        self.frame as f64 / ((self.samples + self.skipped).max(1)) as f64
    }

    /// Instructions per evaluated lattice sample.
    pub fn per_evaluated_sample(&self) -> f64 {
        self.frame as f64 / self.samples.max(1) as f64
    }
}

/// Why the instructions could not be counted.
#[derive(Debug, thiserror::Error)]
pub enum InstructionsError {
    /// SOD is not where it was looked for.
    #[error("{0}: SOD not found (--sod names it); the instruction counts are SOD's views")]
    NoSod(PathBuf),
    /// valgrind could not be started.
    #[error("could not run valgrind ({0}); it counts the instructions: apt-get install valgrind")]
    NoValgrind(std::io::Error),
    /// This binary's own path is unknown.
    #[error("could not find this binary to run it under valgrind: {0}")]
    OwnPath(std::io::Error),
    /// A scratch folder for callgrind's files could not be made or read.
    #[error("callgrind's output {0}: {1}")]
    Scratch(String, std::io::Error),
    /// A counted run failed or said something other than its counters.
    #[error("view {view}, {frames} frames under valgrind: {detail}")]
    Run {
        /// The view.
        view: String,
        /// How many frames the run rendered.
        frames: u32,
        /// What went wrong.
        detail: String,
    },
    /// The bench's own scene did not load.
    #[error("{0}")]
    Bench(String),
}

/// The bench's SOD views at 350×250, read from `sod`.
fn sod_views(sod: &Path) -> Result<Vec<crate::input::scene::DatasetJob>, String> {
    let text = sod_scene(Size::PAPER, sod);
    Scene::parse(&text, "<bench>", Path::new("."))
        .and_then(|s| s.load())
        .map_err(|e| e.to_string())
}

/// The machine the counts are made on: one node in process, one thread, the modern profile,
/// so that the fast tier holds its node field.
fn machine() -> Machine {
    Machine {
        threads: 1,
        profile: Profile::builtin("modern").unwrap_or_else(Profile::ncube2),
        ..Machine::new(Fabric::Direct, 1, 1, 1)
    }
}

/// The counted side, run under valgrind: render the bench's SOD view `view` `frames` times on
/// `machine` and say the last frame's counters as `samples N skipped N` (zeros without a
/// frame).
pub fn count_frames(view: &str, frames: u32, sod: &Path) -> Result<String, String> {
    let jobs = sod_views(sod)?;
    let v = jobs
        .iter()
        .flat_map(|j| j.views.iter().map(move |v| (j, v)))
        .find(|(_, v)| v.name == view)
        .ok_or_else(|| format!("the bench has no SOD view named {view:?}"))?;
    let (mut samples, mut skipped) = (0, 0);
    for _ in 0..frames {
        let r = render_on(&v.0.volume, &v.1.view, &machine()).map_err(|e| e.to_string())?;
        (samples, skipped) = (r.counters.samples, r.counters.skipped);
    }
    Ok(format!("samples {samples} skipped {skipped}\n"))
}

/// Count every SOD view of the bench at 350×250, reading SOD from `sod`.
pub fn run(sod: &Path) -> Result<Vec<Count>, InstructionsError> {
    if !sod.is_file() {
        return Err(InstructionsError::NoSod(sod.to_path_buf()));
    }
    // Named without reading SOD: each counted child loads it itself.
    let names = Scene::parse(&sod_scene(Size::PAPER, sod), "<bench>", Path::new("."))
        .map_err(|e| InstructionsError::Bench(e.to_string()))?
        .view_names();
    let exe = std::env::current_exe().map_err(InstructionsError::OwnPath)?;
    let scratch = tempfile::tempdir()
        .map_err(|e| InstructionsError::Scratch("a scratch folder".into(), e))?;
    let mut counts = Vec::new();
    for view in names {
        let run = |frames| counted(&exe, &view, frames, sod, scratch.path());
        let (none, _) = run(0)?;
        let (one, counters) = run(1)?;
        let (two, _) = run(2)?;
        counts.push(Count {
            first: one.saturating_sub(none),
            frame: two.saturating_sub(one),
            samples: counters.0,
            skipped: counters.1,
            view,
        });
    }
    Ok(counts)
}

/// The instructions of `exe` rendering `view` `frames` times, under callgrind, and the last
/// frame's counters.
fn counted(
    exe: &Path,
    view: &str,
    frames: u32,
    sod: &Path,
    scratch: &Path,
) -> Result<(u64, (u64, u64)), InstructionsError> {
    let file = scratch.join(format!("{view}-{frames}.callgrind"));
    let fail = |detail: String| InstructionsError::Run {
        view: view.to_string(),
        frames,
        detail,
    };
    let output = Command::new("valgrind")
        .arg("--tool=callgrind")
        .arg(format!("--callgrind-out-file={}", file.display()))
        .arg(exe)
        .args(["bench", "--count-frame", view, "--frames"])
        .arg(frames.to_string())
        .arg("--sod")
        .arg(sod)
        .output()
        .map_err(InstructionsError::NoValgrind)?;
    if !output.status.success() {
        let stderr = String::from_utf8_lossy(&output.stderr);
        return Err(fail(format!(
            "exit {}: {}",
            output.status,
            stderr.lines().last().unwrap_or("")
        )));
    }
    let counters = parse_counters(&String::from_utf8_lossy(&output.stdout))
        .ok_or_else(|| fail("no 'samples N skipped N' line on its output".into()))?;
    let text = std::fs::read_to_string(&file)
        .map_err(|e| InstructionsError::Scratch(file.display().to_string(), e))?;
    let total =
        callgrind_total(&text).ok_or_else(|| fail(format!("no total in {}", file.display())))?;
    Ok((total, counters))
}

/// The counters [`count_frames`] says.
fn parse_counters(stdout: &str) -> Option<(u64, u64)> {
    stdout.lines().find_map(|line| {
        let mut words = line.split_whitespace();
        match (words.next()?, words.next()?, words.next()?, words.next()?) {
            ("samples", s, "skipped", k) => Some((s.parse().ok()?, k.parse().ok()?)),
            _ => None,
        }
    })
}

/// The instructions a callgrind output file counts: its `totals:` line, or its `summary:`
/// line (the same figure, in the header) where the totals are absent. With several events
/// the first is the instructions (`Ir`), the only one collected by default.
fn callgrind_total(text: &str) -> Option<u64> {
    let line = |key: &str| {
        text.lines()
            .find_map(|l| l.strip_prefix(key))
            .and_then(|rest| rest.split_whitespace().next()?.parse().ok())
    };
    line("totals:").or_else(|| line("summary:"))
}

/// The table of `counts`, and the target of the fast tier's composited frame.
pub fn table(counts: &[Count]) -> String {
    let mut out = format!(
        "instructions, SOD {}x{} dt 1/{}, one node ({} profile, 1 thread), counted by callgrind:\n",
        Size::PAPER.width,
        Size::PAPER.height,
        Size::PAPER.dt_inverse,
        machine().profile.name
    );
    let _ = writeln!(
        out,
        "{:<16} {:>12} {:>12} {:>12} {:>12} {:>10} {:>10}",
        "view", "first frame", "each frame", "per lattice", "per evaluated", "evaluated", "skipped"
    );
    for c in counts {
        let _ = writeln!(
            out,
            "{:<16} {:>10.1} M {:>10.1} M {:>12.1} {:>13.1} {:>8.2} M {:>8.2} M",
            c.view,
            c.first as f64 / 1e6,
            c.frame as f64 / 1e6,
            c.per_lattice_sample(),
            c.per_evaluated_sample(),
            c.samples as f64 / 1e6,
            c.skipped as f64 / 1e6,
        );
    }
    let _ = writeln!(
        out,
        "a lattice sample is one a frame's rays passed, evaluated or skipped as provably \
         empty; 'first frame' adds what a volume's first frame builds once and keeps; {}",
        super::bench::build_line()
    );
    if let Some(fast) = counts.iter().find(|c| c.view == FAST_VIEW) {
        let _ = writeln!(
            out,
            "target: {FAST_VIEW} at most {} M instructions a frame: {:.1} M, {}",
            FAST_TARGET / 1_000_000,
            fast.frame as f64 / 1e6,
            if fast.frame <= FAST_TARGET {
                "met"
            } else {
                "NOT met"
            }
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn callgrind_s_total_is_read_from_its_totals_or_its_summary() {
        let file = "# callgrind format\nversion: 1\ncreator: callgrind-3.19.0\n\
                    events: Ir\nsummary: 1513385292\n\nfl=(1)\nfn=(1) main\n16 20\n\
                    totals: 1513385292\n";
        assert_eq!(callgrind_total(file), Some(1_513_385_292));
        assert_eq!(
            callgrind_total("events: Ir\nsummary: 42\n"),
            Some(42),
            "no totals"
        );
        // With more events than the instructions, the first is Ir.
        assert_eq!(callgrind_total("events: Ir Bc\ntotals: 7 3\n"), Some(7));
        assert_eq!(callgrind_total("events: Ir\n"), None);
        assert_eq!(callgrind_total("totals: many\n"), None);
    }

    #[test]
    fn the_counted_side_s_line_reads_back() {
        assert_eq!(
            parse_counters("samples 5632 skipped 70012\n"),
            Some((5632, 70012))
        );
        assert_eq!(parse_counters("samples 5 skipped\n"), None);
        assert_eq!(parse_counters("nothing here\n"), None);
    }

    #[test]
    fn per_sample_figures_divide_a_further_frame_and_the_table_judges_the_target() {
        let count = |view: &str, frame: u64| Count {
            view: view.into(),
            first: frame + 50_000_000,
            frame,
            samples: 1_000_000,
            skipped: 3_000_000,
        };
        let c = count(FAST_VIEW, 800_000_000);
        assert_eq!(c.per_evaluated_sample(), 800.0);
        assert_eq!(c.per_lattice_sample(), 200.0);
        let t = table(&[count("surfaces", 100_000_000), c]);
        assert!(
            t.contains(
                "target: composite-fast at most 700 M instructions a frame: 800.0 M, NOT met"
            ),
            "{t}"
        );
        assert!(t.contains("   850.0 M      800.0 M"), "{t}");
        let t = table(&[count(FAST_VIEW, 700_000_000)]);
        assert!(t.ends_with("700.0 M, met\n"), "{t}");
        assert!(!table(&[count("surfaces", 1)]).contains("target"));
    }
}
