//! The nCUBE 2 model's two fitted constants, fitted on the paper's Table 1 alone: `scale` (the
//! tracer's compute, the paper's "lack of optimization of the sequential raytracer") and
//! `message_scale` (the software of the message primitives). Everything else in the profile
//! is the machine's documented characteristics; Tables 2–4 are then predictions.
//!
//! Invariants: the fit only reads Table 1 (its times, and the best cluster size the model
//! finds for each node count); it minimises the sum of squared log-time errors, so a row
//! 10% slow weighs what a row 10% fast does, whatever its size.

use super::error::ExperimentError;
use super::runs::{sequential, timed};
use crate::input::scene::DatasetJob;
use crate::profile::MachineProfile;
use std::collections::BTreeMap;
use voxcube_kernel::trace::view::View;

/// The cluster sizes the paper tried (Table 2).
pub const SIZES: [u32; 5] = [1, 2, 4, 8, 16];

/// One shape's frame seconds, or why it has none.
type Timed = Result<((u32, u32), f64), ExperimentError>;

/// Frame seconds of every shape `(nodes, cluster size)` with `nodes` in `node_counts` and a
/// size of [`SIZES`] dividing it, each run as [`timed`] runs the paper's, but one node, the
/// paper's sequential tracer ([`sequential`]); the runs shared over this machine's cores.
pub fn shapes(
    job: &DatasetJob,
    view: &View,
    profile: &MachineProfile,
    node_counts: &[u32],
) -> Result<BTreeMap<(u32, u32), f64>, ExperimentError> {
    let todo: Vec<(u32, u32)> = node_counts
        .iter()
        .flat_map(|&p| {
            SIZES
                .iter()
                .filter(move |&&s| s <= p && p.is_multiple_of(s))
                .map(move |&s| (p, s))
        })
        .collect();
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let results: Vec<Timed> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..threads)
            .map(|t| {
                let todo = &todo;
                scope.spawn(move || {
                    todo.iter()
                        .skip(t)
                        .step_by(threads)
                        .map(|&(p, s)| {
                            let seconds = match p {
                                1 => sequential(job, view, profile)?,
                                _ => timed(job, view, profile, p / s, s, None)?.frame,
                            };
                            Ok(((p, s), seconds))
                        })
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| {
                h.join().unwrap_or_else(|_| {
                    vec![Err(ExperimentError::Missing("a timed run panicked".into()))]
                })
            })
            .collect()
    });
    results.into_iter().collect()
}

/// For `nodes`, the best cluster size and its time among the shapes timed.
pub fn best(times: &BTreeMap<(u32, u32), f64>, nodes: u32) -> Option<(u32, f64)> {
    times
        .iter()
        .filter(|((p, _), _)| *p == nodes)
        .map(|((_, s), t)| (*s, *t))
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

/// One row of the fit: the model's best shape for a node count against the paper's time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Row {
    /// Nodes.
    pub nodes: u32,
    /// The model's best cluster size.
    pub size: u32,
    /// The model's seconds.
    pub model: f64,
    /// The paper's seconds.
    pub paper: f64,
}

impl Row {
    /// The model's time relative to the paper's, less one (0.05: 5% slow).
    pub fn error(&self) -> f64 {
        self.model / self.paper - 1.0
    }
}

/// The fitted constants and how well they fit.
#[derive(Clone, Debug, PartialEq)]
pub struct Fit {
    /// The fitted profile: the base profile with the two constants set.
    pub profile: MachineProfile,
    /// Table 1 under the fitted profile.
    pub rows: Vec<Row>,
    /// Every shape's frame seconds under the fitted profile (what `rows` were picked from).
    pub times: BTreeMap<(u32, u32), f64>,
    /// Root mean square of the rows' log-time errors.
    pub rms: f64,
    /// Table 1 evaluations the fit took.
    pub evaluations: usize,
    /// The fitted `message_scale` is at an end of [`MESSAGE_RANGE`]: the table asks for
    /// message software the machine's documentation rules out.
    pub at_bound: bool,
}

/// The factors on the profile's message software costs the fit may choose: from a quarter to
/// four times its estimates (a message start-up of 25 to 400 µs; the nCUBE 2's is of the
/// order of 100 µs).
pub const MESSAGE_RANGE: (f64, f64) = (0.25, 4.0);

/// Table 1 under `profile`: each node count's best shape against `table`.
pub fn table1(
    job: &DatasetJob,
    view: &View,
    profile: &MachineProfile,
    table: &[(u32, f64)],
) -> Result<Vec<Row>, ExperimentError> {
    let nodes: Vec<u32> = table.iter().map(|r| r.0).collect();
    rows_of(&shapes(job, view, profile, &nodes)?, table)
}

/// Each node count's best shape among `times` against `table`.
fn rows_of(
    times: &BTreeMap<(u32, u32), f64>,
    table: &[(u32, f64)],
) -> Result<Vec<Row>, ExperimentError> {
    table
        .iter()
        .map(|&(p, paper)| {
            let (size, model) = best(times, p)
                .ok_or_else(|| ExperimentError::Missing(format!("no shape of {p}")))?;
            Ok(Row {
                nodes: p,
                size,
                model,
                paper,
            })
        })
        .collect()
}

/// Root mean square of the rows' log-time errors.
pub fn rms(rows: &[Row]) -> f64 {
    let n = rows.len().max(1) as f64;
    (rows
        .iter()
        .map(|r| (r.model / r.paper).ln().powi(2))
        .sum::<f64>()
        / n)
        .sqrt()
}

/// Fit `scale` and `message_scale` of `base` on `table` (the paper's
/// [`TABLE1`](super::paper::TABLE1), or any
/// table of node counts and seconds): for each message factor of a geometric search, the
/// compute scale that centres the log errors (time is nearly proportional to it, so two
/// corrections settle it), keeping the pair of least squared log error.
pub fn fit(
    job: &DatasetJob,
    view: &View,
    base: &MachineProfile,
    table: &[(u32, f64)],
) -> Result<Fit, ExperimentError> {
    let mut evaluations = 0;
    let mut scale = base.scale;
    let mut at = |message_scale: f64, scale: &mut f64| -> Result<Fit, ExperimentError> {
        let mut profile = MachineProfile {
            scale: *scale,
            message_scale,
            ..base.clone()
        };
        let nodes: Vec<u32> = table.iter().map(|r| r.0).collect();
        let (mut rows, mut times) = (Vec::new(), BTreeMap::new());
        for round in 0..3 {
            times = shapes(job, view, &profile, &nodes)?;
            rows = rows_of(&times, table)?;
            evaluations += 1;
            let mean = rows.iter().map(|r| (r.model / r.paper).ln()).sum::<f64>()
                / rows.len().max(1) as f64;
            // The profile returned is the one `rows` and `times` were timed with: no
            // correction after the last round.
            if mean.abs() < 1e-3 || round == 2 {
                break;
            }
            profile.scale *= (-mean).exp();
        }
        *scale = profile.scale;
        let rms = rms(&rows);
        Ok(Fit {
            profile,
            rms,
            rows,
            times,
            evaluations: 0,
            at_bound: false,
        })
    };
    // Octaves first, then halves of an octave around the best.
    let (lo, hi) = MESSAGE_RANGE;
    let mut tried: Vec<Fit> = Vec::new();
    let mut f = lo;
    while f <= hi * (1.0 + 1e-9) {
        tried.push(at(f, &mut scale)?);
        f *= 2.0;
    }
    let best_of = |tried: &[Fit]| tried.iter().min_by(|a, b| a.rms.total_cmp(&b.rms)).cloned();
    let Some(octave) = best_of(&tried) else {
        return Err(ExperimentError::Missing("nothing to fit".into()));
    };
    for f in [
        octave.profile.message_scale / std::f64::consts::SQRT_2,
        octave.profile.message_scale * std::f64::consts::SQRT_2,
    ]
    .into_iter()
    .filter(|f| (lo..=hi).contains(f))
    {
        scale = octave.profile.scale;
        tried.push(at(f, &mut scale)?);
    }
    let mut fit = best_of(&tried).unwrap_or(octave);
    fit.evaluations = evaluations;
    let m = fit.profile.message_scale;
    fit.at_bound = (m / lo - 1.0).abs() < 1e-9 || (m / hi - 1.0).abs() < 1e-9;
    Ok(fit)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::scene::Scene;

    /// The paper's view of the built-in molecule on a small image, so that every fit test
    /// runs in seconds.
    fn small() -> DatasetJob {
        use crate::experiments::sod::{sized, SURFACE_VIEW};
        let view = sized(SURFACE_VIEW, 48, 32, 1.0, 175.0)
            .replace("NAME", "small")
            .replace("ISO", "40.0");
        let text = format!("[[datasets]]\nname = \"molecule\"\nbuiltin = \"molecule\"\n{view}");
        Scene::parse(&text, "<fit test>", std::path::Path::new("."))
            .and_then(Scene::load)
            .map(|mut jobs| jobs.remove(0))
            .unwrap_or_else(|e| panic!("{e}"))
    }

    #[test]
    fn the_fit_recovers_the_constants_a_table_was_made_with() {
        let job = small();
        let view = &job.views[0].view;
        let base = MachineProfile::ncube2();
        let truth = MachineProfile {
            scale: base.scale * 0.55,
            message_scale: 2.0,
            ..base.clone()
        };
        let shapes = [(1, 0.0), (2, 0.0), (4, 0.0)];
        let made: Vec<(u32, f64)> = table1(&job, view, &truth, &shapes)
            .unwrap_or_else(|e| panic!("{e}"))
            .iter()
            .map(|r| (r.nodes, r.model))
            .collect();
        let fit = fit(&job, view, &base, &made).unwrap_or_else(|e| panic!("{e}"));
        assert!(
            (fit.profile.scale / truth.scale - 1.0).abs() < 0.01,
            "scale {} against {}",
            fit.profile.scale,
            truth.scale
        );
        assert!(fit.rms < 0.005, "rms {}", fit.rms);
        assert!(fit.evaluations >= 2);
        // Negative control: a table no pair of constants can make (its 1-node row 30% slow
        // against the others) leaves an error the fit reports.
        let mut bent = made.clone();
        bent[0].1 *= 1.3;
        let bad = super::fit(&job, view, &base, &bent).unwrap_or_else(|e| panic!("{e}"));
        assert!(bad.rms > 0.05, "rms {}", bad.rms);
    }

    #[test]
    fn the_error_measure_weighs_slow_and_fast_alike() {
        let row = |model: f64, paper: f64| Row {
            nodes: 1,
            size: 1,
            model,
            paper,
        };
        assert!((row(11.0, 10.0).error() - 0.1).abs() < 1e-12);
        let a = rms(&[row(20.0, 10.0)]);
        let b = rms(&[row(5.0, 10.0)]);
        assert!((a - b).abs() < 1e-12 && (a - 2f64.ln()).abs() < 1e-12);
        assert_eq!(rms(&[]), 0.0);
    }
}
