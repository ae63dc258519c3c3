//! What a render reports: a per-view summary table for people and the same as JSON for tools.

use crate::run::render::{Machine, Rendered};
use serde::ser::{SerializeMap, Serializer};
use serde::Serialize;
use std::collections::BTreeMap;
use voxcube_kernel::counters::{Counters, Group};
use voxcube_kernel::node::stats::KIND_NAMES;
use voxcube_kernel::trace::view::View;

/// A trace's counters as a report lists them: one map per [`Group::LISTED`] group ("rays",
/// "operations"), each counter under the key the kernel's table gives it, in the kernel's
/// order. Flattened into its report, so the groups sit beside the report's other fields.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Counted(pub Counters);

impl Serialize for Counted {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        /// One group's counters, as a map.
        struct InGroup<'a>(&'a Counters, Group);
        impl Serialize for InGroup<'_> {
            fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                s.collect_map(self.0.in_group(self.1))
            }
        }
        let mut map = s.serialize_map(Some(Group::LISTED.len()))?;
        for group in Group::LISTED {
            map.serialize_entry(group.name(), &InGroup(&self.0, group))?;
        }
        map.end()
    }
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

/// One node of a distributed run.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct NodeEntry {
    /// Node id.
    pub node: u16,
    /// Cluster.
    pub cluster: u16,
    /// Ring position.
    pub position: u16,
    /// Owned X planes `[first, end)`.
    pub planes: [u32; 2],
    /// Stored X planes, ghosts included.
    pub stored: [u32; 2],
    /// Rays forwarded to the next, previous, and a farther ring position.
    pub forwarded: [u64; 3],
    /// Hit records and resolved descriptors sent home.
    pub returned: u64,
    /// Messages sent, by kind.
    pub sent: BTreeMap<&'static str, u64>,
    /// Rays by type (primary rays counted at their home) and the work done here.
    #[serde(flatten)]
    pub counters: Counted,
    /// Measured memory high-water mark, bytes: slab, receive buffer at its peak, worker state,
    /// code and stack.
    pub memory_high_water: usize,
    /// Most bytes the receive buffer held at once.
    pub peak_buffer: usize,
    /// Wall time spent in busy polls, milliseconds (threads fabric).
    pub busy_ms: f64,
    /// Peak resident memory of the node's own process, bytes, when it could trace (MPI: its
    /// rank's); null where nodes share the host's process.
    pub resident_peak_bytes: Option<u64>,
    /// The X planes `[first, end)` of the volume the node's own process held (MPI: a rank
    /// holds only its slab's where it can); null where nodes share the host's volume.
    pub held_planes: Option<[u32; 2]>,
}

/// What a distributed run moved.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct TrafficReport {
    /// Rays forwarded from slab to slab.
    pub rays_forwarded: u64,
    /// Hit records and resolved descriptors that returned to their pixel's home node.
    pub descriptors_returned: u64,
    /// Messages delivered, by kind.
    pub messages: BTreeMap<&'static str, u64>,
    /// Bytes delivered.
    pub bytes: u64,
    /// Scheduler events.
    pub events: u64,
    /// Per cluster, rays that crossed each slab boundary (between ring positions j and j+1).
    pub boundary_crossings: Vec<Vec<u64>>,
    /// Receive-buffer capacity per node, bytes, and the `i_max` it allows.
    pub buffer_capacity: usize,
    /// The `i_max` of that buffer.
    pub i_max: u16,
    /// Largest node memory high-water mark, bytes.
    pub memory_max: usize,
    /// Mean node memory high-water mark, bytes.
    pub memory_mean: usize,
    /// The plane shift to balanced cuts before rendering, when the nodes made one.
    pub shift: Option<ShiftEntry>,
    /// Per node.
    pub nodes: Vec<NodeEntry>,
}

/// The plane shift before a balanced render.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ShiftEntry {
    /// Slab-plane messages.
    pub messages: u64,
    /// Their bytes.
    pub bytes: u64,
    /// Simulated seconds (timed runs).
    pub seconds: Option<f64>,
    /// Rounds of shifts between neighbours.
    pub rounds: u32,
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
    /// The fabric.
    pub fabric: &'static str,
    /// Nodes.
    pub nodes: u32,
    /// Clusters.
    pub clusters: u32,
    /// Scheduler seed (sim only).
    pub seed: Option<u64>,
    /// What the view called for.
    pub effects: EffectsReport,
    /// The accuracy tier: "exact" or "fast".
    pub accuracy: &'static str,
    /// The approximations the tier made in this view (none in the exact tier).
    pub approximations: Vec<&'static str>,
    /// Rays by type and work done.
    #[serde(flatten)]
    pub counters: Counted,
    /// Traffic of a distributed run.
    pub traffic: Option<TrafficReport>,
    /// Pixels whose colour was not finite before quantisation (always 0).
    pub nan_pixels: u64,
    /// Wall time of the render, milliseconds.
    pub wall_ms: f64,
    /// Of it, the set-up before any ray was traced (the view's skipping structures; the
    /// volume's value ranges and node field the first time), milliseconds; on MPI, whose
    /// ranks each build their own side by side, the slowest rank's (absent after a loss).
    pub setup_ms: Option<f64>,
    /// The host's process's peak resident memory so far, bytes, when the view was reported
    /// (the whole machine's on the in-process fabrics; rank 0's on MPI).
    pub host_resident_peak_bytes: Option<u64>,
    /// SHA-256 of the RGBA8 pixel buffer.
    pub pixels_sha256: String,
    /// Static load balancing, when the view asked for it.
    pub balance: Option<BalanceReport>,
    /// A node lost during the render and how its rows were re-traced (also a warning).
    pub recovery: Option<crate::fabric::Recovery>,
    /// Why the view draws nothing, or part of it nothing, and any node lost (also printed on
    /// stderr).
    pub warnings: Vec<String>,
}

/// What static load balancing did for a view: partitions and the probe's worker times.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct BalanceReport {
    /// Primary rays of the probe, across and down.
    pub probe: [u32; 2],
    /// Cuts before (uniform).
    pub cuts_before: Vec<u32>,
    /// The formula's cuts.
    pub cuts_proposed: Vec<u32>,
    /// The cuts rendered with.
    pub cuts_used: Vec<u32>,
    /// Simulated seconds each worker (by ring position) spent on the probe, uniform slabs.
    pub times_before: Vec<f64>,
    /// The same with the proposed cuts.
    pub times_proposed: Vec<f64>,
    /// The probe's simulated frame, uniform then proposed.
    pub probe_frames: [f64; 2],
    /// The machine profile that priced the probe.
    pub profile: String,
}

impl BalanceReport {
    /// The report of `b`, probed at `probe` rays with `profile`.
    pub fn new(b: &crate::run::balance::Balance, probe: [u32; 2], profile: &str) -> BalanceReport {
        BalanceReport {
            probe,
            cuts_before: b.before.clone(),
            cuts_proposed: b.proposed.clone(),
            cuts_used: b.after.clone(),
            times_before: b.times_before.clone(),
            times_proposed: b.times_proposed.clone(),
            probe_frames: [b.frames.0, b.frames.1],
            profile: profile.to_string(),
        }
    }
}

fn kinds(counts: &[u64; 9]) -> BTreeMap<&'static str, u64> {
    KIND_NAMES
        .iter()
        .zip(counts)
        .filter(|(_, &n)| n > 0)
        .map(|(&k, &n)| (k, n))
        .collect()
}

impl ViewReport {
    /// The report of `rendered`, a render of `view` on `machine`.
    pub fn new(
        dataset: &str,
        name: &str,
        image: String,
        view: &View,
        machine: &Machine,
        rendered: &Rendered,
    ) -> ViewReport {
        let c = &rendered.counters;
        let e = view.effects();
        let traffic = rendered.distributed.as_ref().map(|d| {
            let nodes: Vec<NodeEntry> = d
                .nodes
                .iter()
                .map(|n| NodeEntry {
                    node: n.stats.node,
                    cluster: n.cluster,
                    position: n.position,
                    planes: [n.planes.start, n.planes.end],
                    stored: [n.stored.start, n.stored.end],
                    forwarded: [
                        n.stats.forwarded_next,
                        n.stats.forwarded_prev,
                        n.stats.forwarded_far,
                    ],
                    returned: n.stats.returned,
                    sent: kinds(&n.stats.sent),
                    counters: Counted(n.stats.counters),
                    memory_high_water: n.memory.total(),
                    peak_buffer: n.peak_buffer,
                    busy_ms: n.busy.as_secs_f64() * 1e3,
                    resident_peak_bytes: n.resident_peak,
                    held_planes: n.held.as_ref().map(|h| [h.start, h.end]),
                })
                .collect();
            TrafficReport {
                rays_forwarded: nodes.iter().map(|n| n.forwarded.iter().sum::<u64>()).sum(),
                descriptors_returned: nodes.iter().map(|n| n.returned).sum(),
                messages: kinds(&d.messages),
                bytes: d.bytes,
                events: d.events,
                boundary_crossings: d.boundary_crossings(),
                buffer_capacity: d.buffer_capacity,
                i_max: d.i_max,
                memory_max: nodes.iter().map(|n| n.memory_high_water).max().unwrap_or(0),
                memory_mean: nodes.iter().map(|n| n.memory_high_water).sum::<usize>()
                    / nodes.len().max(1),
                shift: d.shift.as_ref().map(|s| ShiftEntry {
                    messages: s.messages,
                    bytes: s.bytes,
                    seconds: s.seconds,
                    rounds: s.rounds,
                }),
                nodes,
            }
        });
        ViewReport {
            dataset: dataset.to_string(),
            view: name.to_string(),
            image,
            width: rendered.width,
            height: rendered.height,
            fabric: machine.fabric.name(),
            nodes: machine.nodes,
            clusters: machine.clusters,
            seed: rendered.distributed.as_ref().map(|_| machine.seed),
            effects: EffectsReport {
                mode: if e.surfaces { "surfaces" } else { "composite" },
                shading: e.shading,
                shadow_lights: e.shadow_lights,
                transparency: e.transparency,
            },
            accuracy: view.spec().accuracy.name(),
            approximations: view.approximations().iter().map(|a| a.name()).collect(),
            counters: Counted(*c),
            traffic,
            nan_pixels: c.non_finite_pixels,
            wall_ms: rendered.wall.as_secs_f64() * 1e3,
            setup_ms: rendered.setup.map(|d| d.as_secs_f64() * 1e3),
            host_resident_peak_bytes: crate::memory::resident::peak(),
            pixels_sha256: crate::output::files::pixels_sha256(&rendered.bytes()),
            balance: None,
            recovery: rendered
                .distributed
                .as_ref()
                .and_then(|d| d.recovery.clone()),
            warnings: Vec::new(),
        }
    }
}

/// The whole run's report.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Report<'a> {
    /// The scene file.
    pub scene: &'a str,
    /// One entry per view, in scene order: the views rendered, when one failed.
    pub views: &'a [ViewReport],
    /// The view that failed and ended the run, if one did; or, in the report written before
    /// each view, the view under way (if the process is ended during it, that is what the
    /// report on disk says).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub failed: Option<FailedView>,
}

impl Report<'_> {
    /// Write the report to `path`, atomically.
    pub fn write(&self, path: &std::path::Path) -> Result<(), Box<dyn std::error::Error>> {
        let json = serde_json::to_string_pretty(self)?;
        Ok(crate::output::files::write_atomic(path, json.as_bytes())?)
    }
}

/// A view that failed: the run wrote the views before it and ends with an error.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct FailedView {
    /// Dataset name.
    pub dataset: String,
    /// View name.
    pub view: String,
    /// What went wrong, as the error line says it.
    pub error: String,
    /// When a node was lost and no cluster survived to re-trace its rows: what was lost.
    pub lost: Option<LostPixels>,
}

/// The pixels of a view that a lost node took with it.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct LostPixels {
    /// The node that stopped.
    pub node: u16,
    /// Pixels the host lacks.
    pub pixels: u64,
    /// The rows they are in, summarised.
    pub rows: String,
}

impl LostPixels {
    /// What `error` lost, if it is a lost node's error.
    pub fn of(error: &crate::fabric::RunError) -> Option<Self> {
        match error {
            crate::fabric::RunError::Lost {
                node,
                missing,
                rows,
                ..
            } => Some(Self {
                node: *node,
                pixels: *missing,
                rows: rows.clone(),
            }),
            _ => None,
        }
    }
}

fn count(n: u64) -> String {
    match n {
        0..=9_999 => n.to_string(),
        10_000..=9_999_999 => format!("{:.1}k", n as f64 / 1e3),
        _ => format!("{:.1}M", n as f64 / 1e6),
    }
}

fn mib(bytes: usize) -> String {
    format!("{:.2}", bytes as f64 / (1u64 << 20) as f64)
}

/// The summary table, one line per view, and for distributed runs the messages by kind and
/// the rays across each slab boundary.
pub fn summary(views: &[ViewReport]) -> String {
    let mut out = format!(
        "{:<24} {:>9} {:<9} {:<6} {:>7} {:>7} {:>7} {:>7} {:>8} {:>8} {:>8} {:>7} {:>7} {:>11} {:>9}\n",
        "dataset/view",
        "size",
        "mode",
        "fabric",
        "P/m",
        "primary",
        "transp",
        "shadow",
        "samples",
        "interp",
        "shadings",
        "fwd",
        "return",
        "MiB max/avg",
        "wall"
    );
    for v in views {
        let c = &v.counters.0;
        let (fwd, ret, mem) = match &v.traffic {
            Some(t) => (
                count(t.rays_forwarded),
                count(t.descriptors_returned),
                format!("{}/{}", mib(t.memory_max), mib(t.memory_mean)),
            ),
            None => ("-".into(), "-".into(), "-".into()),
        };
        out += &format!(
            "{:<24} {:>9} {:<9} {:<6} {:>7} {:>7} {:>7} {:>7} {:>8} {:>8} {:>8} {:>7} {:>7} {:>11} {:>6.0} ms\n",
            format!("{}/{}", v.dataset, v.view),
            format!("{}x{}", v.width, v.height),
            v.effects.mode,
            v.fabric,
            format!("{}/{}", v.nodes, v.clusters),
            count(c.primary_rays),
            count(c.transparency_rays),
            count(c.shadow_rays),
            count(c.samples),
            count(c.interpolations + c.lookups),
            count(c.shadings),
            fwd,
            ret,
            mem,
            v.wall_ms
        );
    }
    for v in views {
        if let Some(b) = &v.balance {
            let spread = |t: &[f64]| {
                let max = t.iter().copied().fold(0.0, f64::max);
                let mean = t.iter().sum::<f64>() / t.len().max(1) as f64;
                format!("max {max:.3} s, mean {mean:.3} s")
            };
            out += &format!(
                "{}/{}: balance ({}x{} probe rays, {} times): cuts {:?} -> {:?}; worker times {} -> {}; {}\n",
                v.dataset,
                v.view,
                b.probe[0],
                b.probe[1],
                b.profile,
                b.cuts_before,
                b.cuts_proposed,
                spread(&b.times_before),
                spread(&b.times_proposed),
                if b.cuts_used == b.cuts_before && b.cuts_proposed != b.cuts_before {
                    format!(
                        "not kept: the probe took {:.3} s against {:.3} s uniform",
                        b.probe_frames[1], b.probe_frames[0]
                    )
                } else if b.cuts_used == b.cuts_before {
                    "nothing to move".to_string()
                } else {
                    format!(
                        "kept: probe {:.3} s -> {:.3} s",
                        b.probe_frames[0], b.probe_frames[1]
                    )
                }
            );
        }
        if let Some(t) = &v.traffic {
            let msgs: Vec<String> = t
                .messages
                .iter()
                .map(|(k, n)| format!("{k} {}", count(*n)))
                .collect();
            let crossings: Vec<String> = t
                .boundary_crossings
                .iter()
                .map(|c| format!("{c:?}"))
                .collect();
            let shift = match &t.shift {
                Some(s) => format!(
                    "; before rendering, the nodes shifted planes to the balanced cuts: {} round{}, {} messages, {} bytes",
                    s.rounds,
                    if s.rounds == 1 { "" } else { "s" },
                    count(s.messages),
                    s.bytes
                ),
                None => String::new(),
            };
            out += &format!(
                "{}/{}: messages: {}; receive buffers {} bytes (i_max {}); rays across slab boundaries per cluster: {}{shift}\n",
                v.dataset,
                v.view,
                msgs.join(", "),
                t.buffer_capacity,
                t.i_max,
                crossings.join(" ")
            );
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counted_lists_each_group_s_counters_under_the_kernel_s_keys_in_its_order() {
        let c = Counters {
            primary_rays: 11,
            shadow_rays: 13,
            samples: 21,
            slab_misses: 29,
            rays_set_up: 99,
            non_finite_pixels: 98,
            ..Counters::default()
        };
        let json = serde_json::to_string(&Counted(c)).expect("counters serialise");
        assert_eq!(
            json,
            r#"{"rays":{"primary":11,"transparency":0,"shadow":13},"operations":{"samples":21,"#
                .to_owned()
                + r#""skipped":0,"interpolations":0,"lookups":0,"refinements":0,"gradients":0,"#
                + r#""shadings":0,"crossings":0,"early_terminations":0,"normal_fallbacks":0,"#
                + r#""slab_misses":29}}"#,
            "the counters apart (rays set up, non-finite pixels) are not in a group"
        );
    }
}
