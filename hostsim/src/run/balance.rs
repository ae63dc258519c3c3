//! Static load balancing, as in the paper: one cluster traces a probe grid of primary rays,
//! the host takes each worker's time `t_i` and sets new slab sizes by the paper's formula,
//! `size'[i] = size[i] + (mean(t) − t_i) / t_plane` with `t_plane = Σ t / nx`.
//!
//! Invariants: the new cuts cover every plane once, every slab keeps at least one plane and
//! at most `max_planes` (what a node's memory holds) also in every round of shifts between
//! neighbours that reaches them (see `voxcube_kernel::node::shift`), and the new cuts are kept
//! only if the probe runs faster with them (the formula is one-shot and can overshoot). Times are
//! simulated: each worker's work and message handling priced by a machine profile, so the
//! same scene balances the same way on every fabric and every run. The image does not depend
//! on the cuts (bit-identical for any partition), only the time does.

use crate::fabric::sim;
use crate::fabric::RunConfig;
use crate::fabric::{Category, VirtualTime};
use crate::input::dataset::Volume;
use crate::memory::storage::SkipMode;
use crate::profile::MachineProfile;
use std::fmt;
use voxcube_kernel::node::partition::Partition;
use voxcube_kernel::trace::view::{View, ViewSpec};

/// Primary rays the probe traces, about: the paper's 32 × 32 grid, in the image's aspect.
pub const PROBE_RAYS: u32 = 32 * 32;

/// Why a view could not be balanced.
#[derive(Debug)]
pub enum BalanceError {
    /// The probe view or machine could not be built.
    Setup(String),
    /// A probe run failed.
    Probe(crate::fabric::RunError),
}

impl fmt::Display for BalanceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BalanceError::Setup(what) => write!(f, "load balancing: {what}"),
            BalanceError::Probe(e) => write!(f, "load balancing probe: {e}"),
        }
    }
}

impl std::error::Error for BalanceError {}

/// What balancing did: the partitions and the probe's worker times before and after.
#[derive(Clone, Debug, PartialEq)]
pub struct Balance {
    /// Cuts before (uniform).
    pub before: Vec<u32>,
    /// Cuts chosen: the formula's, or `before` when those did not trace the probe faster.
    pub after: Vec<u32>,
    /// The formula's cuts, whether kept or not.
    pub proposed: Vec<u32>,
    /// Seconds each worker (by ring position) spent on the probe with `before`.
    pub times_before: Vec<f64>,
    /// The same with the proposed cuts.
    pub times_proposed: Vec<f64>,
    /// The probe's frame time with `before`, then with the proposed cuts.
    pub frames: (f64, f64),
}

impl Balance {
    /// Whether the new cuts were kept.
    pub fn kept(&self) -> bool {
        self.after != self.before
    }

    /// The most planes any boundary moves: the planes neighbours exchange, in parallel.
    pub fn moved_planes(&self) -> u32 {
        self.after
            .iter()
            .zip(&self.before)
            .map(|(a, b)| a.abs_diff(*b))
            .max()
            .unwrap_or(0)
    }
}

/// New slab sizes for the slabs of `old` from the workers' times (by ring position), as
/// cuts: the paper's formula, rounded to whole planes, each slab between 1 and `max_planes`
/// planes, all summing to the grid's planes. Pure: the decision alone, tested alone.
pub fn new_cuts(old: &Partition, times: &[f64], max_planes: u32) -> Vec<u32> {
    let n = old.slabs();
    let nx = old.cuts().last().copied().unwrap_or(0);
    let total: f64 = times.iter().take(n).sum();
    // A total that is zero, negative, infinite or NaN says nothing about the slabs.
    if n == 0 || times.len() < n || !total.is_finite() || total <= 0.0 {
        return old.cuts().to_vec();
    }
    let mean = total / n as f64;
    let per_plane = total / f64::from(nx);
    let cap = max_planes.max(1);
    let mut whole: Vec<u32> = (0..n)
        .map(|i| {
            let r = old.planes(i);
            let size = f64::from(r.end - r.start) + (mean - times[i]) / per_plane;
            // `as` saturates; the clamp keeps every slab non-empty and within memory.
            (size.round().max(1.0) as u32).min(cap)
        })
        .collect();
    // Whole planes summing to nx: take from the largest, give to the smallest that has room.
    while whole.iter().sum::<u32>() > nx {
        match (0..n).filter(|&i| whole[i] > 1).max_by_key(|&i| whole[i]) {
            Some(i) => whole[i] -= 1,
            None => break,
        }
    }
    while whole.iter().sum::<u32>() < nx {
        match (0..n).filter(|&i| whole[i] < cap).min_by_key(|&i| whole[i]) {
            Some(i) => whole[i] += 1,
            // No slab has room: memory cannot hold a different partition; keep the old one.
            None => return old.cuts().to_vec(),
        }
    }
    let mut cuts = Vec::with_capacity(n + 1);
    cuts.push(0);
    for w in whole {
        cuts.push(cuts.last().copied().unwrap_or(0) + w);
    }
    // The workers reach these cuts in rounds of shifts between neighbours; no slab is larger
    // between rounds than the larger of its sizes before and after (a property test in
    // tests/tests/shift.rs), so the cap holds throughout.
    cuts
}

/// The probe: the view's camera and settings at about [`PROBE_RAYS`] pixels, in the same
/// aspect, so its rays sample the image regularly.
pub fn probe_view(view: &View, volume: &Volume) -> Result<View, BalanceError> {
    let mut spec: ViewSpec = view.spec().clone();
    let pixels = f64::from(spec.width) * f64::from(spec.height);
    let step = (pixels / f64::from(PROBE_RAYS)).sqrt().max(1.0);
    spec.width = ((f64::from(spec.width) / step).round() as u32).max(1);
    spec.height = ((f64::from(spec.height) / step).round() as u32).max(1);
    View::new(spec, &volume.grid).map_err(|e| BalanceError::Setup(e.to_string()))
}

/// The probe traced by one cluster of `size` with `cuts` (`None`: uniform), timed by
/// `profile`: each worker's seconds by ring position, and the frame time.
pub fn probe(
    volume: &Volume,
    probe: &View,
    profile: &MachineProfile,
    size: u32,
    cuts: Option<Vec<u32>>,
    skipping: SkipMode,
) -> Result<(Vec<f64>, f64), BalanceError> {
    let base = RunConfig::machine(1, size, 1).map_err(|e| BalanceError::Setup(e.to_string()))?;
    let cfg = RunConfig {
        time: Some(profile.clone()),
        cuts,
        skipping,
        ..base
    };
    let run = sim::run(volume, probe, &cfg).map_err(BalanceError::Probe)?;
    let time = run
        .time
        .ok_or_else(|| BalanceError::Setup("a timed run returned no time".into()))?;
    Ok((by_position(&time, size)?, time.frame))
}

/// Each worker's busy seconds (work and message handling, not waiting), by ring position:
/// node ids are Gray-coded, slabs go by position.
fn by_position(time: &VirtualTime, size: u32) -> Result<Vec<f64>, BalanceError> {
    Ok(time
        .by_position(size)
        .map_err(BalanceError::Setup)?
        .iter()
        .map(|p| p.iter().sum::<f64>() - p[Category::Idle as usize] - p[Category::Test as usize])
        .collect())
}

/// Balance `view` of `volume` for clusters of `size`: probe with uniform slabs, propose cuts
/// by the formula (each slab at most `max_planes`), probe again, and keep the proposal only
/// if the probe's frame is shorter.
pub fn balance(
    volume: &Volume,
    view: &View,
    profile: &MachineProfile,
    size: u32,
    skipping: SkipMode,
    max_planes: u32,
) -> Result<Balance, BalanceError> {
    let nx = volume.grid.dims()[0];
    let old =
        Partition::uniform(nx, size as usize).map_err(|e| BalanceError::Setup(e.to_string()))?;
    let before = old.cuts().to_vec();
    let probe_view = probe_view(view, volume)?;
    let (times_before, frame_before) = probe(volume, &probe_view, profile, size, None, skipping)?;
    let proposed = new_cuts(&old, &times_before, max_planes);
    let (times_proposed, frame_proposed) = if proposed == before {
        (times_before.clone(), frame_before)
    } else {
        probe(
            volume,
            &probe_view,
            profile,
            size,
            Some(proposed.clone()),
            skipping,
        )?
    };
    let after = if frame_proposed < frame_before {
        proposed.clone()
    } else {
        before.clone()
    };
    Ok(Balance {
        before,
        after,
        proposed,
        times_before,
        times_proposed,
        frames: (frame_before, frame_proposed),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_formula_moves_planes_from_slow_workers_to_fast_ones() {
        let old = Partition::uniform(40, 4).unwrap();
        // Worker 1 took three times the others: its slab shrinks, the others grow.
        let cuts = new_cuts(&old, &[1.0, 3.0, 1.0, 1.0], 40);
        assert_eq!(cuts.first(), Some(&0));
        assert_eq!(cuts.last(), Some(&40));
        let sizes: Vec<u32> = cuts.windows(2).map(|w| w[1] - w[0]).collect();
        // t_plane = 6/40, mean 1.5: sizes 10 ± (1.5 - t)/0.15 = 13.3, 0 -> 1, 13.3, 13.3.
        assert_eq!(sizes[1], 1, "{sizes:?}");
        assert!(sizes.iter().all(|&s| s >= 1) && sizes.iter().sum::<u32>() == 40);
        assert!(sizes[0] > 10 && sizes[2] > 10 && sizes[3] > 10, "{sizes:?}");
        // Equal times change nothing.
        assert_eq!(new_cuts(&old, &[2.0; 4], 40), old.cuts().to_vec());
        // Cut 3 of eight 5-plane slabs moves from 15 to 30, past old cuts (the workers get
        // there in rounds between neighbours); a cap of 9 planes reshapes the answer.
        let eight = Partition::uniform(40, 8).unwrap();
        let slow = [0.01, 0.01, 0.01, 100.0, 100.0, 100.0, 100.0, 100.0];
        assert_eq!(
            new_cuts(&eight, &slow, 40),
            [0, 10, 20, 30, 32, 34, 36, 38, 40]
        );
        assert_eq!(
            new_cuts(&eight, &slow, 9),
            [0, 9, 18, 27, 30, 33, 36, 38, 40]
        );
    }

    #[test]
    fn memory_caps_every_slab_and_bad_times_change_nothing() {
        let old = Partition::uniform(40, 4).unwrap();
        let cuts = new_cuts(&old, &[1.0, 9.0, 1.0, 1.0], 12);
        let sizes: Vec<u32> = cuts.windows(2).map(|w| w[1] - w[0]).collect();
        assert!(sizes.iter().all(|&s| (1..=12).contains(&s)), "{sizes:?}");
        assert_eq!(sizes.iter().sum::<u32>(), 40);
        // No partition fits 4 slabs of at most 9 planes into 40: keep the old one.
        assert_eq!(
            new_cuts(&old, &[1.0, 9.0, 1.0, 1.0], 9),
            old.cuts().to_vec()
        );
        for bad in [
            [0.0; 4],
            [f64::NAN, 1.0, 1.0, 1.0],
            [f64::INFINITY, 1.0, 1.0, 1.0],
        ] {
            assert_eq!(new_cuts(&old, &bad, 40), old.cuts().to_vec(), "{bad:?}");
        }
        assert_eq!(
            new_cuts(&old, &[1.0, 2.0], 40),
            old.cuts().to_vec(),
            "too few times"
        );
    }
}
