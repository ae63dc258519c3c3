//! Virtual time of a timed simulated run: every node's clock, its time by the paper's
//! categories, and the arrival time of every message, from a machine profile.
//!
//! Invariants: a node's clock only moves forward, by what its steps are charged or to the
//! arrival of a message that wakes it (idle time); events run in time order, the scheduler
//! and seed only breaking ties.

use super::network::Envelope;
use super::schedule::Choice;
use crate::fabric::{Category, Span, VirtualTime};
use crate::profile::{MachineProfile, MessageCosts};
use voxcube_kernel::counters::Counters;
use voxcube_kernel::node::msg::Msg;
use voxcube_kernel::node::port::Dest;
use voxcube_kernel::node::topology::hops;

/// Virtual time of a timed run: every node's clock and its time by category.
#[derive(Clone)]
pub(super) struct Clock {
    pub(super) profile: MachineProfile,
    /// The profile's message costs with their fitted factor applied, once.
    messages: MessageCosts,
    /// Iso-surfaces each taken sample is tested against.
    surfaces: u32,
    pub(super) now: Vec<f64>,
    pub(super) parts: Vec<[f64; Category::COUNT]>,
    pub(super) host_time: f64,
    pub(super) last_pixel: f64,
    /// Every node's spans, when a timeline was asked for.
    timeline: Option<Vec<Vec<Span>>>,
}

/// Append a span to a node's timeline, merged into the last one when it continues it.
fn push(spans: &mut Vec<Span>, kind: &'static str, start: f64, end: f64) {
    if end <= start {
        return;
    }
    match spans.last_mut() {
        Some(last) if last.kind == kind && last.end == start => last.end = end,
        _ => spans.push(Span { kind, start, end }),
    }
}

impl Clock {
    pub(super) fn new(
        profile: &MachineProfile,
        surfaces: u32,
        nodes: usize,
        timeline: bool,
    ) -> Clock {
        Clock {
            profile: profile.clone(),
            messages: profile.message_costs(),
            surfaces,
            now: vec![0.0; nodes],
            parts: vec![[0.0; Category::COUNT]; nodes],
            host_time: 0.0,
            last_pixel: 0.0,
            timeline: timeline.then(|| vec![Vec::new(); nodes]),
        }
    }

    /// Seconds for a message of `len` bytes over `hops` hops.
    pub(super) fn transfer(&self, len: usize, hops: u32) -> f64 {
        let m = &self.messages;
        m.latency + len as f64 * m.per_byte + f64::from(hops.saturating_sub(1)) * m.per_hop
    }

    /// The earliest event: a delivery, or a step of the node whose clock is earliest.
    pub(super) fn choose(&self, inflight: &[Envelope], active: &[usize]) -> Choice {
        let deliver = inflight
            .iter()
            .enumerate()
            .min_by(|(_, a), (_, b)| a.arrival.total_cmp(&b.arrival).then(a.seq.cmp(&b.seq)));
        let step = active
            .iter()
            .enumerate()
            .min_by(|(_, &a), (_, &b)| self.now[a].total_cmp(&self.now[b]).then(a.cmp(&b)));
        match (deliver, step) {
            (Some((i, e)), Some((_, &n))) if e.arrival <= self.now[n] => Choice::Deliver(i),
            (_, Some((j, _))) => Choice::Step(j),
            (Some((i, _)), None) => Choice::Deliver(i),
            (None, None) => Choice::Step(0),
        }
    }

    /// Charge node `n`'s step (counters `before` → `after`, `pending` messages waiting when it
    /// began, `received` read) and stamp the arrival of the messages it sent.
    pub(super) fn step(
        &mut self,
        n: usize,
        after: &Counters,
        before: &Counters,
        pending: usize,
        received: u64,
        sent: &mut [Envelope],
    ) {
        let (m, scale) = (self.messages, self.profile.scale);
        let [interpolate, trace, shade, generate] =
            self.profile.compute(&after.since(before), self.surfaces);
        let mut parts = [0.0; Category::COUNT];
        parts[Category::Test as usize] = m.test + m.test_per_pending * pending as f64;
        parts[Category::Interpolate as usize] = interpolate;
        parts[Category::Trace as usize] = trace;
        parts[Category::SampleShade as usize] = shade;
        parts[Category::Generate as usize] = generate;
        parts[Category::Read as usize] = received as f64 * m.read;
        parts[Category::Write as usize] = sent.len() as f64 * m.write;
        let mut spent = 0.0;
        // A step tests its buffer, reads, computes, then writes: its spans in that order.
        let mut kinds = [0.0f64; 4];
        for (category, (total, part)) in Category::ALL
            .iter()
            .zip(self.parts[n].iter_mut().zip(parts))
        {
            // `scale` fits the tracer's compute; message handling has its own factor, already
            // in `self.messages`.
            let part = if category.is_compute() {
                part * scale
            } else {
                part
            };
            *total += part;
            spent += part;
            let k = match category {
                Category::Test => 0,
                Category::Read => 1,
                Category::Write => 3,
                _ => 2,
            };
            kinds[k] += part;
        }
        if let Some(timeline) = self.timeline.as_mut() {
            let mut at = self.now[n];
            for (kind, d) in ["test", "receive", "compute", "send"]
                .into_iter()
                .zip(kinds)
            {
                push(&mut timeline[n], kind, at, at + d);
                at += d;
            }
        }
        self.now[n] += spent;
        let me = n as u16;
        for e in sent.iter_mut() {
            let h = match e.to {
                Dest::Node(to) => hops(me, to).max(1),
                Dest::Host => 1,
            };
            e.arrival = self.now[n] + self.transfer(e.len, h);
        }
    }

    /// Node `n` is woken by a message arriving at `at`: the wait is idle time.
    pub(super) fn wake(&mut self, n: usize, at: f64) {
        if at > self.now[n] {
            self.parts[n][Category::Idle as usize] += at - self.now[n];
            if let Some(timeline) = self.timeline.as_mut() {
                push(&mut timeline[n], "idle", self.now[n], at);
            }
            self.now[n] = at;
        }
    }

    pub(super) fn host_receives(&mut self, at: f64, msg: &Msg) {
        self.host_time = self.host_time.max(at);
        if let Msg::Pixels(_) = msg {
            self.last_pixel = self.last_pixel.max(at);
        }
    }

    pub(super) fn finish(self) -> VirtualTime {
        let end = self.last_pixel;
        let mut timeline = self.timeline.unwrap_or_default();
        for (spans, &now) in timeline.iter_mut().zip(&self.now) {
            push(spans, "idle", now, end);
        }
        // From a node's last work to the end of the frame it is idle too.
        let parts = self
            .parts
            .into_iter()
            .zip(&self.now)
            .map(|(mut p, &now)| {
                if end > now {
                    p[Category::Idle as usize] += end - now;
                }
                p
            })
            .collect();
        VirtualTime {
            frame: end,
            end: self.host_time,
            parts,
            timeline,
        }
    }
}
