//! The worker: one node's sans-IO state machine. It generates the primary rays of its
//! cluster's rows that start in its slab, traces rays through its slab, forwards those that
//! leave to the node owning their next sample, keeps the pixel records of the primary rays it
//! generated, and sends finished pixels to the host in pixel sets. It is driven by
//! [`Worker::poll`] and talks only through a [`Port`].
//!
//! Where the paper keeps a primary-ray descriptor on the node of the first intersection,
//! voxcube keeps it on the node that generated the ray (its *home*), reserved before the ray
//! starts. Every hit's lighting and every secondary ray's result returns there, and the pixel
//! is combined there by [`crate::tree`]'s formula. So a ray never waits for memory on another
//! node, and "all pixels of my primary rays are final" (the paper's token condition) is a
//! local fact.
//!
//! Invariants: all state is in fixed-capacity containers; a step is attempted only with room
//! for everything it can produce (at most one message, one pixel-set flush, and one shadow ray
//! per light), so no item is ever dropped: a full container is back-pressure. Shadow rays,
//! which spawn nothing, are traced first, so the queues always drain. A ray's lattice, `k` and
//! state travel with it unchanged.

use crate::counters::Counters;
use crate::grid::Grid;
use crate::lighting::lighting;
use crate::march::{march, Hit, RayKind, Stop};
use crate::msg::{HitRecord, Msg, Outcome, PixelSet, Reply, Resolved, Travel, NO_HOME, NO_LIGHT};
use crate::partition::Partition;
use crate::pixel::rgba8;
use crate::port::{Class, Dest, Port};
use crate::record::PixelRecord;
use crate::sample::Sample;
use crate::shade::MAX_LIGHTS;
use crate::slab::{stored_planes, Slab};
use crate::stats::NodeStats;
use crate::topology::Layout;
use crate::view::{Mode, View};
use core::fmt;
use heapless::Deque;

/// Which node creates primary rays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Generation {
    /// Every worker generates all its cluster's primary rays and keeps those whose first
    /// sample lies in its slab (the paper's choice: no messages for primary rays).
    Distributed,
    /// Ring position 0 generates them all and sends each to the worker owning its first
    /// sample, which adopts it.
    Centralized,
}

/// Faults that tests switch on to show the bit-identity tests catch them (negative controls).
#[cfg(feature = "mutants")]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Mutants {
    /// Move a forwarded ray's lattice back by a quarter step: a shortened step at the boundary.
    pub shorten_step_at_boundary: bool,
}

/// Where a worker sits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Place {
    /// The layout of the machine.
    pub layout: Layout,
    /// Its cluster.
    pub cluster: u16,
    /// Its ring position.
    pub position: u16,
}

/// Why a worker cannot be set up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WorkerError {
    /// The place is outside the layout, or the partition has a different number of slabs.
    Place,
    /// The slab does not own the partition's planes for this position, or lacks ghost planes.
    Slab,
    /// A capacity is too small to make progress.
    Capacity,
}

impl fmt::Display for WorkerError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            WorkerError::Place => "the node's place does not fit the layout or the partition",
            WorkerError::Slab => "the slab does not hold this position's planes and ghost planes",
            WorkerError::Capacity => "a worker capacity is too small to make progress",
        })
    }
}

impl core::error::Error for WorkerError {}

/// What a poll did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Progress {
    /// Something happened; poll again.
    Busy,
    /// Nothing to do until a message arrives.
    Idle,
}

/// Room kept in each ray queue for what one traced ray can spawn.
const RESERVE: usize = MAX_LIGHTS + 1;

/// One node. `RAYS` and `SHADOWS` bound the ray queues, `RECORDS` the pixel records,
/// `OUTBOX` the messages waiting for the port.
#[derive(Debug)]
pub struct Worker<
    'a,
    T,
    const RAYS: usize,
    const SHADOWS: usize,
    const RECORDS: usize,
    const OUTBOX: usize,
> {
    view: &'a View,
    slab: Slab<'a, T>,
    partition: &'a Partition,
    place: Place,
    node: u16,
    generation: Generation,
    cursor: u64,
    cluster_pixels: u64,
    rays: Deque<Travel, RAYS>,
    shadows: Deque<Travel, SHADOWS>,
    records: [Option<PixelRecord>; RECORDS],
    in_use: usize,
    outbox: Deque<(Dest, Msg), OUTBOX>,
    batch: PixelSet,
    stats: NodeStats,
    /// Test-only faults.
    #[cfg(feature = "mutants")]
    pub mutants: Mutants,
}

impl<
        'a,
        T: Sample,
        const RAYS: usize,
        const SHADOWS: usize,
        const RECORDS: usize,
        const OUTBOX: usize,
    > Worker<'a, T, RAYS, SHADOWS, RECORDS, OUTBOX>
{
    /// A worker at `place`, tracing `slab` (which must own `partition`'s planes for its ring
    /// position, with the view's ghost planes).
    pub fn new(
        view: &'a View,
        slab: Slab<'a, T>,
        partition: &'a Partition,
        place: Place,
        generation: Generation,
    ) -> Result<Self, WorkerError> {
        let layout = place.layout;
        if place.cluster >= layout.clusters()
            || place.position >= layout.size()
            || partition.slabs() != usize::from(layout.size())
        {
            return Err(WorkerError::Place);
        }
        let planes = partition.planes(usize::from(place.position));
        let grid: &Grid = slab.grid();
        if slab.owned() != planes
            || slab.stored() != stored_planes(grid, planes, view.ghost_planes())
        {
            return Err(WorkerError::Slab);
        }
        if RAYS <= 2 * RESERVE || SHADOWS <= 2 * RESERVE || RECORDS == 0 || OUTBOX < 2 {
            return Err(WorkerError::Capacity);
        }
        let spec = view.spec();
        let cluster_pixels =
            u64::from(layout.rows(place.cluster, spec.height)) * u64::from(spec.width);
        let node = layout.node(place.cluster, place.position);
        Ok(Worker {
            view,
            slab,
            partition,
            place,
            node,
            generation,
            cursor: 0,
            cluster_pixels,
            rays: Deque::new(),
            shadows: Deque::new(),
            records: [None; RECORDS],
            in_use: 0,
            outbox: Deque::new(),
            batch: PixelSet::default(),
            stats: NodeStats {
                node,
                ..NodeStats::default()
            },
            #[cfg(feature = "mutants")]
            mutants: Mutants::default(),
        })
    }

    /// This node's id.
    pub fn node(&self) -> u16 {
        self.node
    }

    /// Statistics so far.
    pub fn stats(&self) -> NodeStats {
        self.stats
    }

    /// Work counters so far.
    pub fn counters(&self) -> Counters {
        self.stats.counters
    }

    /// Whether this worker has nothing left: every primary ray generated, every record
    /// complete, every ray and message gone, every pixel sent. (A forwarded ray arriving later
    /// makes it busy again.)
    pub fn is_finished(&self) -> bool {
        self.generation_done()
            && self.rays.is_empty()
            && self.shadows.is_empty()
            && self.outbox.is_empty()
            && self.in_use == 0
            && self.batch.count == 0
    }

    fn generation_done(&self) -> bool {
        match self.generation {
            Generation::Distributed => self.cursor >= self.cluster_pixels,
            Generation::Centralized => {
                self.place.position != 0 || self.cursor >= self.cluster_pixels
            }
        }
    }

    fn outbox_free(&self) -> usize {
        OUTBOX - self.outbox.len()
    }

    /// Do a bounded amount of work: send what waits, read messages (resolved parts first,
    /// then rays), trace one ray, or — when nothing at all is pending — generate a primary ray.
    pub fn poll(&mut self, port: &mut impl Port) -> Progress {
        let mut worked = self.flush(port);
        while self.outbox_free() >= 2 {
            let Some(m) = port.try_recv(Class::Resolved) else {
                break;
            };
            self.receive(m);
            worked = true;
        }
        while RAYS - self.rays.len() > RESERVE && SHADOWS - self.shadows.len() > RESERVE {
            let Some(m) = port.try_recv(Class::Ray) else {
                break;
            };
            self.receive(m);
            worked = true;
        }
        while let Some(m) = port.try_recv(Class::Control) {
            // Nothing of this class is addressed to a worker yet.
            self.receive(m);
            worked = true;
        }
        let traced = self.outbox_free() >= 2 && self.trace_one();
        // A new primary ray only when nothing at all is pending (the paper's reading rule).
        let generated = !traced
            && !worked
            && port.pending() == 0
            && self.rays.is_empty()
            && self.shadows.is_empty()
            && self.outbox_free() >= 2
            && self.generate();
        worked |= traced || generated;
        if !worked && self.batch.count > 0 && self.outbox_free() >= 1 {
            self.flush_batch();
            worked = true;
        }
        worked |= self.flush(port);
        if worked {
            Progress::Busy
        } else {
            Progress::Idle
        }
    }

    /// Hand waiting messages to the port until it refuses one.
    fn flush(&mut self, port: &mut impl Port) -> bool {
        let mut sent = false;
        while let Some((to, msg)) = self.outbox.pop_front() {
            if let Err(msg) = port.try_send(to, msg) {
                // Room: the slot was just freed.
                let _ = self.outbox.push_front((to, msg));
                break;
            }
            sent = true;
        }
        sent
    }

    fn send(&mut self, to: Dest, msg: Msg) {
        self.stats.sent[msg.kind() as usize] += 1;
        if self.outbox.push_back((to, msg)).is_err() {
            // Unreachable while every step checks its room first; counted, never a panic.
            self.stats.protocol_errors += 1;
        }
    }

    fn receive(&mut self, msg: Msg) {
        match msg {
            Msg::Ray(t) => {
                let full = if t.ray.kind == RayKind::Shadow {
                    self.shadows.push_back(t).is_err()
                } else {
                    self.rays.push_back(t).is_err()
                };
                if full {
                    self.stats.protocol_errors += 1;
                }
            }
            Msg::Hit(h) => self.apply_hit(&h),
            Msg::Resolved(r) => self.apply_resolved(&r),
            _ => self.stats.protocol_errors += 1,
        }
    }

    /// Trace the next ray that can be traced now; whether one was.
    fn trace_one(&mut self) -> bool {
        if let Some(t) = self.shadows.pop_front() {
            self.trace(t);
            return true;
        }
        if SHADOWS - self.shadows.len() < MAX_LIGHTS {
            return false;
        }
        for _ in 0..self.rays.len() {
            let Some(mut t) = self.rays.pop_front() else {
                return false;
            };
            if t.reply.home == NO_HOME {
                // A primary ray sent by the generator: adopt it, if a record is free.
                match self.reserve(t.ray.pixel) {
                    Some(slot) => {
                        t.reply = Reply {
                            home: self.node,
                            slot,
                            hit: 0,
                            light: NO_LIGHT,
                        };
                        self.stats.counters.primary_rays += 1;
                    }
                    None => {
                        let _ = self.rays.push_back(t);
                        continue;
                    }
                }
            }
            self.trace(t);
            return true;
        }
        false
    }

    fn trace(&mut self, mut t: Travel) {
        match march(self.view, &self.slab, &mut t.ray, &mut self.stats.counters) {
            Stop::Leave { plane } => self.forward(t, plane),
            Stop::Hit(hit) => self.on_hit(t, hit),
            Stop::Exit | Stop::Terminated => self.finish(t),
        }
    }

    fn forward(&mut self, t: Travel, plane: u32) {
        let to = self.partition.owner(plane) as u16;
        let me = self.place.position;
        match to {
            _ if to == me => {
                // `march` leaves only for planes it does not own.
                self.stats.protocol_errors += 1;
                return;
            }
            _ if to == me + 1 => self.stats.forwarded_next += 1,
            _ if to + 1 == me => self.stats.forwarded_prev += 1,
            _ => self.stats.forwarded_far += 1,
        }
        #[cfg(feature = "mutants")]
        let t = self.mutate_forwarded(t);
        let node = self.place.layout.node(self.place.cluster, to);
        self.send(Dest::Node(node), Msg::Ray(t));
    }

    #[cfg(feature = "mutants")]
    fn mutate_forwarded(&self, mut t: Travel) -> Travel {
        if self.mutants.shorten_step_at_boundary {
            t.ray.lattice.t_entry -= 0.25 * t.ray.lattice.dt;
        }
        t
    }

    fn on_hit(&mut self, t: Travel, hit: Hit) {
        let view = self.view;
        let Mode::Surfaces(surfaces) = &view.spec().mode else {
            self.stats.protocol_errors += 1;
            return;
        };
        let Some(surface) = surfaces.get(usize::from(hit.surface)) else {
            self.stats.protocol_errors += 1;
            return;
        };
        let ray = &t.ray;
        let light = lighting(
            view,
            &self.slab,
            surface.color,
            hit.point,
            hit.cap_normal,
            ray.ray.dir_world,
            &mut self.stats.counters,
        );
        let alpha = surface.opacity();
        let mut shadow_mask = 0u8;
        for l in 0..MAX_LIGHTS {
            if light.shadow_mask & (1 << l) == 0 {
                continue;
            }
            let (to_light, distance) = light.to_light[l];
            if let Some(shadow) = view.shadow_ray(ray.pixel, hit.point, to_light, distance) {
                self.stats.counters.shadow_rays += 1;
                shadow_mask |= 1 << l;
                let reply = Reply {
                    light: l as u8,
                    hit: ray.depth,
                    ..t.reply
                };
                // Room: trace_one checked SHADOWS has MAX_LIGHTS free.
                if self
                    .shadows
                    .push_back(Travel { ray: shadow, reply })
                    .is_err()
                {
                    self.stats.protocol_errors += 1;
                }
            }
        }
        let next = view.continuation(ray, alpha);
        let record = HitRecord {
            reply: Reply {
                hit: ray.depth,
                light: NO_LIGHT,
                ..t.reply
            },
            pixel: ray.pixel,
            alpha,
            ambient: light.ambient,
            direct: light.direct,
            shadow_mask,
            lights: light.lights,
            continues: next.is_some(),
        };
        match next {
            Some(next) => {
                self.stats.counters.transparency_rays += 1;
                let reply = Reply {
                    hit: next.depth,
                    ..t.reply
                };
                // Room: the ray being traced freed its slot.
                if self.rays.push_back(Travel { ray: next, reply }).is_err() {
                    self.stats.protocol_errors += 1;
                }
            }
            None => self.stats.counters.early_terminations += u64::from(alpha < 1.0),
        }
        if record.reply.home == self.node {
            self.apply_hit(&record);
        } else {
            self.stats.returned += 1;
            self.send(Dest::Node(record.reply.home), Msg::Hit(record));
        }
    }

    fn finish(&mut self, t: Travel) {
        let ray = &t.ray;
        let outcome = match (ray.kind, &self.view.spec().mode) {
            (RayKind::Shadow, _) => Outcome::Shadow {
                visibility: ray.weight,
            },
            (_, Mode::Composite(_)) => {
                Outcome::Color(ray.color + self.view.spec().background * ray.weight)
            }
            (_, Mode::Surfaces(_)) => Outcome::ChainEnd { hits: ray.depth },
        };
        let resolved = Resolved {
            reply: t.reply,
            pixel: ray.pixel,
            outcome,
        };
        if t.reply.home == self.node {
            self.apply_resolved(&resolved);
        } else {
            self.stats.returned += 1;
            self.send(Dest::Node(t.reply.home), Msg::Resolved(resolved));
        }
    }

    fn reserve(&mut self, pixel: u32) -> Option<u16> {
        let slot = self.records.iter().position(Option::is_none)?;
        self.records[slot] = Some(PixelRecord::new(pixel));
        self.in_use += 1;
        Some(slot as u16)
    }

    fn apply_hit(&mut self, h: &HitRecord) {
        let slot = usize::from(h.reply.slot);
        let added = match self.records.get_mut(slot) {
            Some(Some(record)) => record.add_hit(h.reply.hit, h).is_ok(),
            _ => false,
        };
        if added {
            self.try_complete(slot);
        } else {
            self.stats.protocol_errors += 1;
        }
    }

    fn apply_resolved(&mut self, r: &Resolved) {
        let slot = usize::from(r.reply.slot);
        let added = match self.records.get_mut(slot) {
            Some(Some(record)) => record
                .add_outcome(r.pixel, r.reply.hit, r.reply.light, r.outcome)
                .is_ok(),
            _ => false,
        };
        if added {
            self.try_complete(slot);
        } else {
            self.stats.protocol_errors += 1;
        }
    }

    fn try_complete(&mut self, slot: usize) {
        let background = self.view.spec().background;
        let Some(Some(record)) = self.records.get(slot) else {
            return;
        };
        let Some(color) = record.color(background) else {
            return;
        };
        let pixel = record.pixel();
        self.stats.counters.non_finite_pixels += u64::from(!color.is_finite());
        self.records[slot] = None;
        self.in_use -= 1;
        self.emit(pixel, rgba8(color));
    }

    fn emit(&mut self, pixel: u32, rgba: [u8; 4]) {
        if self.batch.push(pixel, rgba).is_err() {
            self.flush_batch();
            let _ = self.batch.push(pixel, rgba);
        }
        if self.batch.is_full() {
            self.flush_batch();
        }
    }

    fn flush_batch(&mut self) {
        let set = core::mem::take(&mut self.batch);
        self.send(Dest::Host, Msg::Pixels(set));
    }

    /// Generate primary rays up to one kept (or one row scanned); whether anything was done.
    fn generate(&mut self) -> bool {
        if self.generation_done() || RAYS - self.rays.len() <= RESERVE {
            return false;
        }
        let generator = self.place.position == 0;
        if self.generation == Generation::Distributed && self.in_use >= RECORDS {
            return false;
        }
        let spec = self.view.spec();
        let width = u64::from(spec.width);
        let end = (self.cursor + width).min(self.cluster_pixels);
        while self.cursor < end {
            let n = self.cursor;
            let row = self
                .place
                .layout
                .row(self.place.cluster, (n / width) as u32);
            let pixel = row * spec.width + (n % width) as u32;
            let Some(ray) = self.view.primary_ray(pixel) else {
                self.cursor += 1;
                if generator {
                    // A ray that misses the volume sees the background; ring position 0 says so.
                    self.emit(pixel, rgba8(spec.background));
                    return true;
                }
                continue;
            };
            let first = ray.ray.at(ray.lattice.t(0));
            let owner = self
                .partition
                .owner(self.slab.grid().owner_plane(first.x, spec.model))
                as u16;
            match self.generation {
                Generation::Distributed if owner == self.place.position => {
                    let Some(slot) = self.reserve(pixel) else {
                        return true;
                    };
                    self.cursor += 1;
                    self.stats.counters.primary_rays += 1;
                    let reply = Reply {
                        home: self.node,
                        slot,
                        hit: 0,
                        light: NO_LIGHT,
                    };
                    let _ = self.rays.push_back(Travel { ray, reply });
                    return true;
                }
                Generation::Distributed => self.cursor += 1,
                Generation::Centralized => {
                    self.cursor += 1;
                    let reply = Reply {
                        home: NO_HOME,
                        slot: 0,
                        hit: 0,
                        light: NO_LIGHT,
                    };
                    if owner == self.place.position {
                        let _ = self.rays.push_back(Travel { ray, reply });
                    } else {
                        let node = self.place.layout.node(self.place.cluster, owner);
                        self.send(Dest::Node(node), Msg::Ray(Travel { ray, reply }));
                    }
                    return true;
                }
            }
        }
        true
    }
}
