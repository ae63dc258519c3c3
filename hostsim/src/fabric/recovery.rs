//! Completing a frame without a lost cluster: the surviving clusters re-trace its unfinished
//! rows, and the host merges what they send into what it already holds.
//!
//! Invariants: every cluster holds the whole volume in the same slabs, and a pixel's colour
//! does not depend on which cluster traces it, so the re-traced rows are the fault-free bits.
//! Every pixel reaches the image once: a re-traced pixel the host already held is dropped and
//! counted, never taken twice; a pixel still missing after the re-trace is an error.

use crate::fabric::config::RunConfig;
use crate::fabric::error::RunError;
use crate::fabric::host::{missing_rows, Host};
use crate::fabric::{Category, Recovery, Span, VirtualTime};
use std::time::Duration;
use voxcube_kernel::node::stats::NodeStats;
use voxcube_kernel::node::topology::{Layout, Rows};
use voxcube_kernel::trace::view::View;

/// A node the host declared lost, and when.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LostNode {
    /// The node.
    pub node: u16,
    /// Its cluster.
    pub cluster: u16,
    /// Events run by then (simulator, which declares a node lost once nothing else can
    /// happen: no message of its cluster can come late).
    pub events: Option<u64>,
    /// Time from the start of the run (threads and MPI, which declare a node lost when it
    /// has not been heard for the configured time).
    pub after: Option<Duration>,
}

/// What a re-trace on the surviving clusters left: its host, each of its nodes' peak buffer,
/// and the traffic its fabric counted itself (the simulator: messages by kind, bytes,
/// events; others count messages from the nodes' statistics).
#[derive(Debug)]
pub struct Retraced {
    /// The re-trace's host, holding the pixels it got.
    pub host: Host,
    /// Peak receive-buffer bytes by node of the re-trace's machine.
    pub peaks: Vec<usize>,
    /// Messages delivered by kind.
    pub messages: [u64; 9],
    /// Bytes delivered.
    pub bytes: u64,
    /// Events run.
    pub events: u64,
    /// The re-trace's virtual time, by node of its machine (a timed simulator).
    pub time: Option<VirtualTime>,
}

/// What the recovery adds to a run: the image, each node's statistics with its share of the
/// re-trace, the record, and the re-trace's own traffic.
#[derive(Debug)]
pub struct Completed {
    /// The whole image.
    pub image: Vec<[u8; 4]>,
    /// Each node's statistics, a survivor's with its share of the re-trace added.
    pub stats: Vec<NodeStats>,
    /// What was lost and re-traced.
    pub recovery: Recovery,
    /// The re-trace's messages by kind, bytes and events, as its fabric counted them.
    pub messages: [u64; 9],
    /// See `messages`.
    pub bytes: u64,
    /// See `messages`.
    pub events: u64,
    /// Peak receive-buffer bytes of each node in the re-trace, by node id of the machine.
    pub peaks: Vec<usize>,
    /// The re-trace's virtual time (a timed simulator), by node of the re-trace's machine.
    pub time: Option<VirtualTime>,
    /// The node id, in the machine, of each node of the re-trace's machine.
    pub retracers: Vec<u16>,
}

impl Completed {
    /// Raise each node's peak receive-buffer bytes in `peaks` to its peak in the re-trace.
    pub fn raise_peaks(&self, peaks: &mut [usize]) {
        for (peak, more) in peaks.iter_mut().zip(&self.peaks) {
            *peak = (*peak).max(*more);
        }
    }

    /// `time`, the timed run until the host had collected the survivors, followed by the
    /// re-trace, which the host starts then: every node is idle from the end of its own work
    /// until it re-traces or the frame ends, and a re-tracer's time and spans follow.
    pub fn append_time(&self, time: &mut VirtualTime) {
        let Some(again) = &self.time else {
            return;
        };
        let start = time.end;
        let frame = start + again.frame;
        let mut resume = vec![frame; time.parts.len()];
        for &n in &self.retracers {
            if let Some(at) = resume.get_mut(usize::from(n)) {
                *at = start;
            }
        }
        // A node's categories add up to the end of its own work.
        for (n, parts) in time.parts.iter_mut().enumerate() {
            let own: f64 = parts.iter().sum();
            parts[Category::Idle as usize] += (resume[n] - own).max(0.0);
        }
        for (spans, &resume) in time.timeline.iter_mut().zip(&resume) {
            let own = spans.last().map_or(0.0, |s| s.end);
            if resume > own {
                spans.push(Span {
                    kind: "idle",
                    start: own,
                    end: resume,
                });
            }
        }
        for (r, &n) in self.retracers.iter().enumerate() {
            if let (Some(parts), Some(more)) =
                (time.parts.get_mut(usize::from(n)), again.parts.get(r))
            {
                for (part, more) in parts.iter_mut().zip(more) {
                    *part += more;
                }
            }
            if let (Some(spans), Some(more)) =
                (time.timeline.get_mut(usize::from(n)), again.timeline.get(r))
            {
                spans.extend(more.iter().map(|s| Span {
                    start: s.start + start,
                    end: s.end + start,
                    ..*s
                }));
            }
        }
        time.frame = frame;
        time.end = start + again.end;
    }
}

/// What a re-trace that lost its node `node` (a node of the re-trace's machine) returns:
/// [`complete`] takes that node's cluster out and re-traces again.
pub fn lost_in_retrace(node: u16) -> RunError {
    RunError::Lost {
        node,
        waiting: 0,
        missing: 0,
        rows: String::new(),
    }
}

/// A re-trace on a fabric: given the surviving clusters' configuration and which of the
/// machine's clusters they are, run it to its end.
pub type Retrace<'a> = dyn Fn(&RunConfig, &[u16]) -> Result<Retraced, RunError> + 'a;

/// The frame completed: `lost`'s cluster's rows from its first unfinished one re-traced by
/// `retrace` on the other clusters of `cfg`'s layout (given a configuration of those clusters,
/// the rows dealt among them in turn, and which of `cfg`'s clusters they are), merged into
/// `held`, what the host holds.
///
/// A node lost during the re-trace (`retrace` fails with [`RunError::Lost`], naming it in the
/// re-trace's machine) takes its cluster out too: the re-trace runs again on the clusters
/// left, until one completes or none is left. The clusters taken out had finished their own
/// rows in the first run (the host collected them), so only the re-trace is redone.
pub fn complete(
    view: &View,
    cfg: &RunConfig,
    lost: LostNode,
    held: Host,
    retrace: &Retrace<'_>,
) -> Result<Completed, RunError> {
    let layout = cfg.layout;
    let width = view.spec().width;
    let (mut image, reports) = held.into_parts();
    let rows = missing_rows(&image, width);
    let mut survivors: Vec<u16> = (0..layout.clusters())
        .filter(|&c| c != lost.cluster)
        .collect();
    let own = layout.cluster_rows(lost.cluster);
    let unfinished = (0..own.count(view.spec().height))
        .map(|i| own.row(i))
        .find(|&row| {
            let start = row as usize * width as usize;
            image[start..start + width as usize]
                .iter()
                .any(Option::is_none)
        });
    let mut done = Completed {
        image: Vec::new(),
        stats: Vec::new(),
        recovery: Recovery {
            node: lost.node,
            cluster: lost.cluster,
            declared_after_events: lost.events,
            declared_after_ms: lost.after.map(|d| d.as_secs_f64() * 1e3),
            rows,
            by: Vec::new(),
            retraced: 0,
            dropped: 0,
            late: 0,
            also_lost: Vec::new(),
        },
        messages: [0; 9],
        bytes: 0,
        events: 0,
        peaks: vec![0; layout.nodes() as usize],
        time: None,
        retracers: Vec::new(),
    };
    let mut stats: Vec<NodeStats> = reports
        .into_iter()
        .enumerate()
        .map(|(n, r)| {
            r.unwrap_or(NodeStats {
                node: n as u16,
                ..NodeStats::default()
            })
        })
        .collect();
    let mut second = cfg.schedule.retrace_stop;
    let retraced = loop {
        let Some(first) = unfinished.filter(|_| !survivors.is_empty()) else {
            break None;
        };
        let machine = Layout::new(survivors.len() as u32, u32::from(layout.size()))
            .map_err(|e| RunError::Host(format!("the surviving clusters: {e}")))?
            .with_rows(Rows::new(first, own.step()));
        let node_of = |r| retracer(layout, machine, &survivors, r);
        let stop = second.take().and_then(|(node, after)| {
            let r = (0..machine.nodes() as u16).find(|&r| node_of(r) == node)?;
            Some((r, after))
        });
        let survivors_cfg = RunConfig {
            layout: machine,
            shift: false,
            schedule: crate::fabric::Schedule {
                stop,
                retrace_stop: None,
                ..cfg.schedule
            },
            ..cfg.clone()
        };
        match retrace(&survivors_cfg, &survivors) {
            Ok(again) => break Some((again, machine)),
            Err(RunError::Lost { node: r, .. }) if r < machine.nodes() as u16 => {
                let node = node_of(r);
                let cluster = layout.place(node).0;
                done.recovery.also_lost.push(node);
                survivors.retain(|&c| c != cluster);
            }
            Err(e) => return Err(e),
        }
    };
    if let Some((again, machine)) = retraced {
        let (peaks, messages, bytes, events) =
            (again.peaks, again.messages, again.bytes, again.events);
        done.time = again.time;
        let (pixels, reports) = again.host.into_parts();
        for (slot, again) in image.iter_mut().zip(pixels) {
            match (slot.is_some(), again) {
                (true, Some(_)) => done.recovery.dropped += 1,
                (false, Some(rgba)) => {
                    *slot = Some(rgba);
                    done.recovery.retraced += 1;
                }
                (_, None) => {}
            }
        }
        for (r, report) in reports.into_iter().enumerate() {
            let node = retracer(layout, machine, &survivors, r as u16);
            done.retracers.push(node);
            let node = usize::from(node);
            if let (Some(report), Some(total)) = (report, stats.get_mut(node)) {
                absorb(total, &report);
            }
            if let Some(peak) = done.peaks.get_mut(node) {
                *peak = peaks.get(r).copied().unwrap_or(0);
            }
        }
        (done.messages, done.bytes, done.events) = (messages, bytes, events);
        done.recovery.by = survivors;
    }
    let missing = image.iter().filter(|p| p.is_none()).count() as u64;
    if missing > 0 {
        return Err(RunError::Lost {
            node: lost.node,
            waiting: 0,
            missing,
            rows: missing_rows(&image, width),
        });
    }
    done.image = image.into_iter().map(Option::unwrap_or_default).collect();
    done.stats = stats;
    Ok(done)
}

/// The node of `layout` that node `r` of the re-trace's `machine` is: the node at its ring
/// position of surviving cluster `survivors[k]`, for `r` in `machine`'s cluster `k`.
fn retracer(layout: Layout, machine: Layout, survivors: &[u16], r: u16) -> u16 {
    let (k, position) = machine.place(r);
    layout.node(survivors[usize::from(k)], position)
}

/// `total` with `more`'s work and traffic added: one node's statistics over two runs.
fn absorb(total: &mut NodeStats, more: &NodeStats) {
    total.counters.add(&more.counters);
    total.forwarded_next += more.forwarded_next;
    total.forwarded_prev += more.forwarded_prev;
    total.forwarded_far += more.forwarded_far;
    total.returned += more.returned;
    for (t, m) in total.sent.iter_mut().zip(more.sent) {
        *t += m;
    }
    total.protocol_errors += more.protocol_errors;
    total.peak_pending = total.peak_pending.max(more.peak_pending);
    total.peak_records = total.peak_records.max(more.peak_records);
    total.peak_outbox = total.peak_outbox.max(more.peak_outbox);
    total.peak_unacked = total.peak_unacked.max(more.peak_unacked);
    total.pixels_sent += more.pixels_sent;
}

#[cfg(test)]
mod tests {
    //! The merge's rule, by a direct test of [`complete`]: a pixel the host holds is kept and
    //! its re-traced copy dropped and counted, a hole is filled, and a hole the re-trace left
    //! is an error.
    use super::*;
    use voxcube_kernel::node::msg::{Msg, PixelSet};

    fn pixels(list: &[u32], shade: u8) -> Msg {
        let mut set = PixelSet::default();
        for &p in list {
            assert!(set.push(p, [shade, p as u8, 0, 255]).is_ok());
        }
        Msg::Pixels(set)
    }

    #[test]
    fn held_pixels_are_kept_holes_filled_and_a_hole_left_is_an_error() {
        let job = crate::experiments::explore::few_rays(4, 3).expect("a tiny view");
        let view = &job.views[0].view;
        // Two clusters of one node: cluster 0 traces rows 0 and 2, cluster 1 row 1.
        let cfg = RunConfig::machine(2, 1, 0).expect("layout");
        let lost = LostNode {
            node: 1,
            cluster: 1,
            events: Some(9),
            after: None,
        };
        let held = || {
            let mut host = Host::new(12, 4, 2, 2);
            let own = [0, 1, 2, 3, 8, 9, 10, 11];
            assert_eq!(host.receive(pixels(&own, 1)), Ok(false));
            // One pixel of the lost cluster's row came before it stopped.
            assert_eq!(host.receive(pixels(&[5], 1)), Ok(false));
            host
        };
        // The survivors re-trace row 1 (shade 2, so a kept pixel shows which copy it is).
        let retrace = |row: &[u32]| {
            let row = row.to_vec();
            move |survivors: &RunConfig, _: &[u16]| {
                assert_eq!(survivors.layout.cluster_rows(0), Rows::new(1, 2));
                let mut host = Host::new(12, 4, 1, 1);
                assert_eq!(host.receive(pixels(&row, 2)), Ok(false));
                Ok(Retraced {
                    host,
                    peaks: vec![0],
                    messages: [0; 9],
                    bytes: 0,
                    events: 0,
                    time: None,
                })
            }
        };
        let done = complete(view, &cfg, lost, held(), &retrace(&[4, 5, 6, 7]))
            .unwrap_or_else(|e| panic!("{e}"));
        assert_eq!((done.recovery.retraced, done.recovery.dropped), (3, 1));
        assert_eq!(done.image[5], [1, 5, 0, 255], "the held copy is kept");
        assert_eq!(done.image[6], [2, 6, 0, 255], "a hole is filled");
        assert_eq!(done.recovery.by, vec![0]);
        // A re-trace that leaves a hole: an error naming the node and the pixels missing.
        match complete(view, &cfg, lost, held(), &retrace(&[4, 6])) {
            Err(RunError::Lost {
                node: 1,
                missing: 1,
                ..
            }) => {}
            other => panic!("a hole must be an error: {other:?}"),
        }
    }
}
