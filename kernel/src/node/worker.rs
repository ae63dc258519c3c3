//! The worker: one node's sans-IO state machine. It generates the primary rays of its
//! cluster's rows that start in its slab, traces rays through its slab, forwards those that
//! leave to the node owning their next sample, keeps the pixel records of the primary rays it
//! generated, sends finished pixels to the host in pixel sets, keeps the ack counters of
//! [`crate::node::flow`], and passes its cluster's termination token. It is driven by
//! [`Worker::poll`] and talks only through a [`Port`].
//!
//! Where the paper keeps a primary-ray descriptor on the node of the first intersection,
//! voxcube keeps it on the node that generated the ray (its *home*), reserved before the ray
//! starts. Every hit's lighting and every secondary ray's result returns there, and the pixel
//! is combined there by [`crate::trace::tree`]'s formula. So a ray never waits for memory on another
//! node, and "all pixels of my primary rays are final" (the token's condition) is a local
//! fact. A worker that is a ring of one holds the whole volume: it traces each of its pixels'
//! whole ray tree in place ([`crate::trace::tracer`]), with nothing to send, wait for or record.
//!
//! One step traces one primary or transparency ray through the slab, and at a hit also every
//! shadow ray it spawns (as the paper does). A continuation past a semi-transparent surface
//! waits in the local queue of its X direction. Reading follows the paper's priority: acks,
//! then results, then rays, each class in its own queue. A ray is read only when it can start
//! at once: it needs credit for every message its step may send (`r_imax` per class and
//! destination), room for its continuation, and for an unadopted primary a free record. A new
//! primary ray is generated only when nothing at all is pending.
//!
//! Termination. Tokens, one per cluster, start at the ring end nearest the viewpoint and pass
//! in the direction rays travel. A worker passes its token once:
//! - every primary ray it generates has been generated, its pixel final and sent;
//! - nothing waits in its queues;
//! - every message it sent has been acknowledged (all `n_i = 0`).
//!
//! The last worker gives the token to the host. The host, holding all `m` tokens, asks every
//! worker for its statistics. A worker answers only once all its `n_i = 0` again and its own
//! acks are sent. The invariant that makes this correct:
//! - a pixel is final only when its whole ray tree is back, and never reopens;
//! - a worker generates no ray after its token passed;
//! - every ray or result in flight belongs to a pixel that is not final.
//!
//! So once every home's pixels are final, no ray or result message exists anywhere. The host
//! then ends after the last statistics, when every `n_i = 0` and no message of any kind is in
//! flight. The simulator checks this at the end of every run.
//!
//! Memory: all state is in fixed-capacity containers (const generics) or fixed arrays. A step
//! runs only with room for all it can produce, so no item is ever dropped: a full container is
//! back-pressure.

use crate::counters::Counters;
use crate::node::flow::{r_imax, Class, Credits, FlowControl, CREDIT_CLASSES};
use crate::node::msg::{
    HitRecord, Msg, Outcome, PixelSet, Reply, Resolved, Travel, NO_HOME, NO_LIGHT,
};
use crate::node::partition::{Partition, MAX_CLUSTER};
use crate::node::port::{Dest, Port};
use crate::node::record::Records;
use crate::node::stats::NodeStats;
use crate::node::topology::Layout;
use crate::optics::shade::MAX_LIGHTS;
use crate::trace::lighting::lighting;
use crate::trace::march::{march, Hit, RayKind, RayState, Stop};
use crate::trace::pixel::rgba8;
use crate::trace::starts;
use crate::trace::tracer::trace_primary;
use crate::trace::view::{Mode, View};
use crate::volume::sample::Sample;
use crate::volume::slab::{stored_planes, Slab};
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

/// Whether this build carries the test-only faults of `Mutants` (the `mutants` feature). A
/// product build must not: the host reports it, and CI checks the release binary's report.
pub const TEST_FAULTS: bool = cfg!(feature = "mutants");

/// Faults that tests switch on to show that the test suite catches them (negative controls).
#[cfg(feature = "mutants")]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Mutants {
    /// Move a forwarded ray's lattice back by a quarter step: a shortened step at the boundary.
    pub shorten_step_at_boundary: bool,
    /// Start rays without the `r_imax` headroom (only `n_i < i_max` at each send is kept).
    pub no_headroom: bool,
    /// Send an ack only with a credit of headroom toward its receiver, as if it were a message.
    pub acks_need_credit: bool,
    /// Pass the token once generation is done, before the pixels are final.
    pub early_token: bool,
    /// Finish a pixel as soon as its hits are in, before its shadow rays return.
    pub early_pixel: bool,
    /// Pass the token once the pixels are final, with messages still unacknowledged or
    /// queued (the token rule without its "every `n_i = 0`").
    pub token_unquiet: bool,
    /// Pass the token against the direction rays travel (it still starts at the ring end
    /// nearest the viewpoint).
    pub token_backwards: bool,
}

/// `core::fmt::Write` into a hasher, in chunks: [`Worker::digest`] hashes `Debug` forms
/// without allocating, and a hasher fed a few bytes a call spends most of its time per call.
struct HashWriter<'h, H: core::hash::Hasher> {
    hasher: &'h mut H,
    chunk: [u8; 256],
    len: usize,
}

impl<H: core::hash::Hasher> HashWriter<'_, H> {
    fn flush(&mut self) {
        self.hasher.write(&self.chunk[..self.len]);
        self.len = 0;
    }
}

impl<H: core::hash::Hasher> fmt::Write for HashWriter<'_, H> {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        let mut rest = s.as_bytes();
        while !rest.is_empty() {
            if self.len == self.chunk.len() {
                self.flush();
            }
            let n = (self.chunk.len() - self.len).min(rest.len());
            if let (Some(to), Some(from)) =
                (self.chunk.get_mut(self.len..self.len + n), rest.get(..n))
            {
                to.copy_from_slice(from);
            }
            self.len += n;
            rest = rest.get(n..).unwrap_or_default();
        }
        Ok(())
    }
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
    /// The ring has more positions than the worker's counters (its `RING`).
    Ring {
        /// Positions in the ring.
        size: u16,
        /// Positions the worker counts.
        capacity: usize,
    },
    /// `i_max` leaves no ray room to start: it must be at least `needed`.
    Credit {
        /// `i_max` given.
        i_max: u16,
        /// The smallest that works for this view.
        needed: u16,
    },
}

impl fmt::Display for WorkerError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            WorkerError::Place => {
                f.write_str("the node's place does not fit the layout or the partition")
            }
            WorkerError::Slab => {
                f.write_str("the slab does not hold this position's planes and ghost planes")
            }
            WorkerError::Capacity => f.write_str("a worker capacity is too small to make progress"),
            WorkerError::Ring { size, capacity } => write!(
                f,
                "a ring of {size} positions is more than the worker's counters hold ({capacity})"
            ),
            WorkerError::Credit { i_max, needed } => write!(
                f,
                "i_max {i_max} leaves no ray room to start (r_imax + 1 = {needed} needed)"
            ),
        }
    }
}

impl core::error::Error for WorkerError {}

/// Primary rays (or runs of certain misses) a poll generates at most while nothing else is
/// pending, unless the [`Setup`] says otherwise: a poll's machinery around one ray cost about
/// as much as the ray's own set-up.
pub const RAYS_PER_POLL: u8 = 4;

/// What a poll did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Progress {
    /// Something happened; poll again.
    Busy,
    /// Nothing to do until a message arrives.
    Idle,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Token {
    /// Not here (yet).
    Away,
    /// Here, to pass on once this worker is done.
    Holding,
    /// Passed on.
    Passed,
}

/// What a worker is built from.
#[derive(Debug)]
pub struct Setup<'a, T: Sample> {
    /// The view it renders.
    pub view: &'a View,
    /// Its slab, which must own `partition`'s planes for its ring position, with the view's
    /// ghost planes.
    pub slab: Slab<'a, T>,
    /// The machine's partition of the volume into slabs.
    pub partition: &'a Partition,
    /// Its cluster and ring position.
    pub place: Place,
    /// How its primary rays are generated.
    pub generation: Generation,
    /// Its flow control.
    pub flow: FlowControl,
    /// Primary rays a poll generates at most while nothing else is pending (at least 1;
    /// [`RAYS_PER_POLL`] unless a host models time per poll, as the timed simulator does:
    /// there a node reads its links between any two rays).
    pub rays_per_poll: u8,
}

/// A [`Setup`] that [`Worker::check`] found fit: the only way to [`Worker::new`].
#[derive(Debug)]
pub struct Checked<'a, T: Sample>(Setup<'a, T>);

/// One node. `PENDING` bounds each direction's continuation queue, `RECORDS` the pixel
/// records, `OUTBOX` the messages waiting for the port.
#[derive(Clone, Debug)]
pub struct Worker<
    'a,
    T: Sample,
    const PENDING: usize,
    const RECORDS: usize,
    const OUTBOX: usize,
    const RING: usize = MAX_CLUSTER,
> {
    view: &'a View,
    slab: Slab<'a, T>,
    partition: &'a Partition,
    place: Place,
    node: u16,
    generation: Generation,
    rays_per_poll: u8,
    cursor: u64,
    /// Ring position 0 only: the pixels from the cursor up to here (in its row) certainly
    /// miss, so it sends their background without setting up their rays.
    misses_until: u64,
    /// The pixels below this one have had their rays' set-up counted: a ray that could not
    /// start yet is set up again on the next poll, but the paper's program held it, so the
    /// count (which prices the generation) takes each pixel once.
    set_up_through: u64,
    cluster_pixels: u64,
    pending_up: Deque<Travel, PENDING>,
    pending_down: Deque<Travel, PENDING>,
    records: Records<RECORDS>,
    outbox: Deque<(Dest, Msg), OUTBOX>,
    batch: PixelSet,
    flow: FlowControl,
    shadow_lights: u8,
    /// `n_i`: per ring position and credit class, messages sent and not yet acknowledged.
    unacked: Credits<RING>,
    /// Reads per ring position and credit class not yet acknowledged.
    acks_due: Credits<RING>,
    /// The sum of `acks_due`: a poll with nothing (or, while busy, less than a batch) to
    /// acknowledge skips looking through every ring position and class, which otherwise
    /// dominates the polls of a large ring.
    acks_owed: u32,
    token: Token,
    token_upward: bool,
    collecting: bool,
    reported: bool,
    stats: NodeStats,
    /// Test-only faults.
    #[cfg(feature = "mutants")]
    pub mutants: Mutants,
}

impl<
        'a,
        T: Sample,
        const PENDING: usize,
        const RECORDS: usize,
        const OUTBOX: usize,
        const RING: usize,
    > Worker<'a, T, PENDING, RECORDS, OUTBOX, RING>
{
    /// Whether a worker can be built from `setup`. The checks come apart from building,
    /// which [`Worker::new`] does and which cannot fail, so that a host can build a worker
    /// where it stays: a worker is tens of kilobytes, and one built in a `Result` was copied
    /// whole twice on its way into its box.
    pub fn check(setup: Setup<'a, T>) -> Result<Checked<'a, T>, WorkerError> {
        let Setup {
            view,
            slab,
            partition,
            place,
            flow,
            rays_per_poll,
            ..
        } = &setup;
        let layout = place.layout;
        if place.cluster >= layout.clusters()
            || place.position >= layout.size()
            || partition.slabs() != usize::from(layout.size())
        {
            return Err(WorkerError::Place);
        }
        let planes = partition.planes(usize::from(place.position));
        if slab.owned() != planes
            || slab.stored() != stored_planes(slab.grid(), planes, view.ghost_planes())
        {
            return Err(WorkerError::Slab);
        }
        if PENDING == 0 || RECORDS == 0 || OUTBOX < 3 || *rays_per_poll == 0 {
            return Err(WorkerError::Capacity);
        }
        if usize::from(layout.size()) > RING {
            return Err(WorkerError::Ring {
                size: layout.size(),
                capacity: RING,
            });
        }
        let shadow_lights = view.effects().shadow_lights;
        let needed = r_imax(RayKind::Primary, shadow_lights) as u16 + 1;
        if flow.enabled && layout.size() > 1 && flow.i_max < needed {
            return Err(WorkerError::Credit {
                i_max: flow.i_max,
                needed,
            });
        }
        Ok(Checked(setup))
    }

    /// The worker that [`Worker::check`] allowed.
    #[inline(always)]
    pub fn new(checked: Checked<'a, T>) -> Self {
        let Setup {
            view,
            slab,
            partition,
            place,
            generation,
            flow,
            rays_per_poll,
        } = checked.0;
        let layout = place.layout;
        let shadow_lights = view.effects().shadow_lights;
        let spec = view.spec();
        let cluster_pixels =
            u64::from(layout.rows(place.cluster, spec.height)) * u64::from(spec.width);
        let node = layout.node(place.cluster, place.position);
        // The token starts at the ring end nearest the viewpoint: rays travel from there.
        let token_upward = !(spec.camera.forward().x < 0.0);
        let starter = if token_upward { 0 } else { layout.size() - 1 };
        Worker {
            view,
            slab,
            partition,
            place,
            node,
            generation,
            rays_per_poll,
            cursor: 0,
            misses_until: 0,
            set_up_through: 0,
            cluster_pixels,
            pending_up: Deque::new(),
            pending_down: Deque::new(),
            records: Records::default(),
            outbox: Deque::new(),
            batch: PixelSet::default(),
            flow,
            shadow_lights,
            unacked: Credits::clamped(usize::from(layout.size())),
            acks_due: Credits::clamped(usize::from(layout.size())),
            acks_owed: 0,
            token: if place.position == starter {
                Token::Holding
            } else {
                Token::Away
            },
            token_upward,
            collecting: false,
            reported: false,
            stats: NodeStats {
                node,
                ..NodeStats::default()
            },
            #[cfg(feature = "mutants")]
            mutants: Mutants::default(),
        }
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

    /// The flow-control settings.
    pub fn flow(&self) -> FlowControl {
        self.flow
    }

    /// The largest `n_i` now, over destinations and classes.
    pub fn max_unacked(&self) -> u16 {
        self.unacked.max()
    }

    /// Whether this worker has sent its statistics to the host: its part is over.
    pub fn has_reported(&self) -> bool {
        self.reported
    }

    /// Feed into `h` everything of this worker that its future behaviour depends on, and
    /// nothing else: two workers that feed the same bytes act alike from here on. The set-up
    /// it was built with (view, slab, place, settings) is left out, being the same for every
    /// state of one node; so are its statistics, history that never steers it, except the
    /// pixels it has sent and the protocol errors it has counted, which its report carries.
    /// An exhaustive explorer of schedules prunes states it has seen by this.
    pub fn digest<H: core::hash::Hasher>(&self, h: &mut H) {
        // Destructured without `..`: a field added to the worker must be placed here, in or
        // out of the digest, or this does not compile.
        let Worker {
            view: _,
            slab: _,
            partition: _,
            place: _,
            node: _,
            generation: _,
            rays_per_poll: _,
            cursor,
            misses_until,
            set_up_through: _,
            cluster_pixels,
            pending_up,
            pending_down,
            records,
            outbox,
            batch,
            flow: _,
            shadow_lights: _,
            unacked,
            acks_due,
            acks_owed,
            token,
            token_upward: _,
            collecting,
            reported,
            stats,
            #[cfg(feature = "mutants")]
                mutants: _,
        } = self;
        let mut w = HashWriter {
            hasher: h,
            chunk: [0; 256],
            len: 0,
        };
        // `Debug` forms are complete and exact (floats print their shortest exact form);
        // writing into a hasher allocates nothing. Counters are written for the ring's
        // positions only, pixel sets and records for their live entries only.
        let _ = fmt::Write::write_fmt(
            &mut w,
            format_args!(
                "{cursor}|{misses_until}|{cluster_pixels}|{pending_up:?}|{pending_down:?}|{outbox:?}|{:?}|{acks_owed}|{token:?}|{collecting}|{reported}|{}|{}|",
                batch.entries(),
                stats.pixels_sent,
                stats.protocol_errors
            ),
        );
        let _ = records.digest(&mut w);
        for counts in [unacked, acks_due] {
            for p in 0..counts.size() {
                for class in CREDIT_CLASSES {
                    let _ =
                        fmt::Write::write_fmt(&mut w, format_args!("{},", counts.get(p, class)));
                }
            }
        }
        w.flush();
    }

    /// Whether every primary ray this worker generates is generated, its pixel final and sent.
    pub fn pixels_final(&self) -> bool {
        self.generation_done() && self.records.in_use() == 0 && self.batch.count == 0
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

    fn position_of(&self, node: u16) -> usize {
        usize::from(self.place.layout.place(node).1)
    }

    /// Do a bounded amount of work: send what waits, read acks and results, start one ray
    /// (a queued continuation first, then a received ray), or — when nothing at all is
    /// pending — generate up to its setup's `rays_per_poll` primary rays; pass the token,
    /// answer the host.
    pub fn poll(&mut self, port: &mut impl Port) -> Progress {
        let mut worked = self.flush(port);
        while let Some((from, msg)) = port.try_recv(Class::Ack) {
            self.receive(from, msg);
            worked = true;
        }
        while self.outbox_free() >= 3 {
            let Some((from, msg)) = port.try_recv(Class::Result) else {
                break;
            };
            self.receive(from, msg);
            worked = true;
        }
        while let Some((from, msg)) = port.try_recv(Class::Control) {
            self.receive(from, msg);
            worked = true;
        }
        let stepped = self.outbox_free() >= 3 && (self.step_pending() || self.step_received(port));
        let mut generated = false;
        if !stepped && !worked {
            let mut budget = u32::from(self.rays_per_poll);
            while budget > 0 {
                let free = port.pending() == 0
                    && self.pending_up.is_empty()
                    && self.pending_down.is_empty()
                    && self.outbox_free() >= 3;
                let used = if free { self.generate(budget) } else { 0 };
                if used == 0 {
                    break;
                }
                budget = budget.saturating_sub(used);
                generated = true;
            }
        }
        worked |= stepped || generated;
        if !worked && self.batch.count > 0 && self.outbox_free() >= 1 {
            self.flush_batch();
            worked = true;
        }
        worked |= self.send_acks(!worked);
        worked |= self.pass_token();
        worked |= self.report();
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
        self.stats.peak_outbox = self.stats.peak_outbox.max(self.outbox.len() as u64);
        sent
    }

    #[inline]
    fn enqueue(&mut self, to: Dest, msg: Msg) {
        self.stats.sent[msg.kind() as usize] += 1;
        if self.outbox.push_back((to, msg)).is_err() {
            // Unreachable while every step checks its room first; counted, never a panic.
            self.stats.protocol_errors += 1;
        }
        self.stats.peak_outbox = self.stats.peak_outbox.max(self.outbox.len() as u64);
    }

    /// Send to the node at ring position `to`, counting the credit it takes.
    // Inlined, as `enqueue` is: a message handed down by value was copied whole at each call
    // (288 bytes, a ray's 96 among them).
    #[inline]
    fn send(&mut self, to: usize, msg: Msg) {
        if let Some(n) = self.unacked.add_one(to, msg.class()) {
            self.stats.peak_unacked = self.stats.peak_unacked.max(u64::from(n));
        }
        let node = self.place.layout.node(self.place.cluster, to as u16);
        self.enqueue(Dest::Node(node), msg);
    }

    fn receive(&mut self, from: Dest, msg: Msg) {
        if let Dest::Node(node) = from {
            let p = self.position_of(node);
            let before = self.acks_due.get(p, msg.class());
            // A count at its ceiling stays there: `acks_owed` sums what the counters hold.
            if self
                .acks_due
                .add_one(p, msg.class())
                .is_some_and(|n| n > before)
            {
                self.acks_owed += 1;
            }
        }
        match msg {
            Msg::Ack { from, class, count } => {
                let p = self.position_of(from);
                let taken = Class::from_credit_index(class)
                    .is_some_and(|class| self.unacked.take(p, class, count));
                if !taken {
                    self.stats.protocol_errors += 1;
                }
            }
            Msg::Hit(h) => self.apply_hit(&h),
            Msg::Resolved(r) => self.apply_resolved(&r),
            Msg::Ray(t) => self.trace(t),
            Msg::Token { .. } if self.token == Token::Away => self.token = Token::Holding,
            Msg::Collect => self.collecting = true,
            _ => self.stats.protocol_errors += 1,
        }
    }

    /// Whether a step of ray `t` can start now: credit for everything it may send, room for a
    /// continuation, and a record for an unadopted primary ray.
    fn can_start(&self, t: &Travel, from_pending: bool) -> bool {
        let kind = t.ray.kind;
        let own = Class::of_ray(kind, t.ray.ray.dir.x);
        if kind != RayKind::Shadow {
            let queue = if own == Class::RayDown {
                &self.pending_down
            } else {
                &self.pending_up
            };
            if !from_pending && queue.is_full() {
                return false;
            }
            if t.reply.home == NO_HOME && self.records.in_use() >= RECORDS {
                return false;
            }
        }
        if !self.flow.enabled {
            return true;
        }
        #[cfg(feature = "mutants")]
        if self.mutants.no_headroom {
            return true;
        }
        let r = r_imax(kind, self.shadow_lights) as u16;
        let i_max = self.flow.i_max;
        // Results go home.
        if t.reply.home != NO_HOME && t.reply.home != self.node {
            let home = self.position_of(t.reply.home);
            if self.unacked.get(home, Class::Result).saturating_add(r) >= i_max {
                return false;
            }
        }
        let size = usize::from(self.place.layout.size());
        if size == 1 {
            // A ring of one has no position ahead either way: nothing below can refuse.
            return true;
        }
        self.unacked.room_ahead(
            usize::from(self.place.position),
            kind,
            own,
            self.shadow_lights,
            i_max,
        )
    }

    /// Step the oldest startable continuation; whether one was.
    fn step_pending(&mut self) -> bool {
        for down in [false, true] {
            let queue = if down {
                &self.pending_down
            } else {
                &self.pending_up
            };
            let Some(front) = queue.front() else { continue };
            if self.can_start(front, true) {
                let t = if down {
                    self.pending_down.pop_front()
                } else {
                    self.pending_up.pop_front()
                };
                if let Some(t) = t {
                    self.trace(t);
                    return true;
                }
            }
        }
        false
    }

    /// Read and step one received ray that can start now, shadow rays first; whether one was.
    fn step_received(&mut self, port: &mut impl Port) -> bool {
        for class in [
            Class::ShadowUp,
            Class::ShadowDown,
            Class::RayUp,
            Class::RayDown,
        ] {
            let ready = match port.peek(class) {
                Some(Msg::Ray(t)) => self.can_start(t, false),
                Some(_) => true,
                None => false,
            };
            if ready {
                if let Some((from, msg)) = port.try_recv(class) {
                    self.receive(from, msg);
                    return true;
                }
            }
        }
        false
    }

    fn trace(&mut self, mut t: Travel) {
        if t.reply.home == NO_HOME {
            // A primary ray from the generator: adopt it (can_start checked a record is free).
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
                    self.stats.protocol_errors += 1;
                    return;
                }
            }
        }
        match march(self.view, &self.slab, &mut t.ray, &mut self.stats.counters) {
            Stop::Leave { plane } => self.forward(t, plane),
            Stop::Hit(hit) => self.on_hit(t, hit),
            Stop::Exit | Stop::Terminated => self.finish(t),
        }
    }

    fn forward(&mut self, t: Travel, plane: u32) {
        let to = self.partition.owner(plane);
        let me = usize::from(self.place.position);
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
        self.send(to, Msg::Ray(t));
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
        let ray = t.ray;
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
        let next = view.continuation(&ray, alpha);
        let mut shadow_mask = 0u8;
        let mut shadows: [Option<RayState>; MAX_LIGHTS] = [None; MAX_LIGHTS];
        for (l, slot) in shadows.iter_mut().enumerate() {
            if light.shadow_mask & (1 << l) == 0 {
                continue;
            }
            let (to_light, distance) = light.to_light[l];
            if let Some(shadow) = view.shadow_ray(ray.pixel, hit.point, to_light, distance) {
                self.stats.counters.shadow_rays += 1;
                shadow_mask |= 1 << l;
                *slot = Some(shadow);
            }
        }
        // The hit record first, so the home learns how many shadow results to wait for.
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
        self.deliver_hit(record);
        for (l, shadow) in shadows.into_iter().enumerate() {
            if let Some(shadow) = shadow {
                let reply = Reply {
                    light: l as u8,
                    hit: ray.depth,
                    ..t.reply
                };
                self.trace(Travel { ray: shadow, reply });
            }
        }
        match next {
            Some(next) => {
                self.stats.counters.transparency_rays += 1;
                let cont = Travel {
                    ray: next,
                    reply: Reply {
                        hit: next.depth,
                        ..t.reply
                    },
                };
                let queue = if Class::of_ray(next.kind, next.ray.dir.x) == Class::RayDown {
                    &mut self.pending_down
                } else {
                    &mut self.pending_up
                };
                // Room: can_start checked it.
                if queue.push_back(cont).is_err() {
                    self.stats.protocol_errors += 1;
                }
                let waiting = (self.pending_up.len() + self.pending_down.len()) as u64;
                self.stats.peak_pending = self.stats.peak_pending.max(waiting);
            }
            None => self.stats.counters.early_terminations += u64::from(alpha < 1.0),
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
            let home = self.position_of(t.reply.home);
            self.send(home, Msg::Resolved(resolved));
        }
    }

    fn deliver_hit(&mut self, record: HitRecord) {
        if record.reply.home == self.node {
            self.apply_hit(&record);
        } else {
            self.stats.returned += 1;
            let home = self.position_of(record.reply.home);
            self.send(home, Msg::Hit(record));
        }
    }

    fn reserve(&mut self, pixel: u32) -> Option<u16> {
        let slot = self.records.open(pixel)?;
        self.stats.peak_records = self.stats.peak_records.max(self.records.in_use() as u64);
        Some(slot)
    }

    fn apply_hit(&mut self, h: &HitRecord) {
        let slot = usize::from(h.reply.slot);
        let added = match self.records.get_mut(slot) {
            Some(record) => record.add_hit(h.reply.hit, h).is_ok(),
            None => false,
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
            Some(record) => record
                .add_outcome(r.pixel, r.reply.hit, r.reply.light, r.outcome)
                .is_ok(),
            None => false,
        };
        if added {
            self.try_complete(slot);
        } else {
            self.stats.protocol_errors += 1;
        }
    }

    fn try_complete(&mut self, slot: usize) {
        let background = self.view.spec().background;
        let Some(record) = self.records.get(slot) else {
            return;
        };
        #[cfg(feature = "mutants")]
        let color = if self.mutants.early_pixel {
            record.color_without_waiting_for_shadows(background)
        } else {
            record.color(background)
        };
        #[cfg(not(feature = "mutants"))]
        let color = record.color(background);
        let Some(color) = color else { return };
        let pixel = record.pixel();
        self.stats.counters.non_finite_pixels += u64::from(!color.is_finite());
        self.records.close(slot);
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
        self.stats.pixels_sent += u64::from(set.count);
        self.enqueue(Dest::Host, Msg::Pixels(set));
    }

    /// Acknowledge reads: a class's batch once full, everything when `idle`.
    fn send_acks(&mut self, idle: bool) -> bool {
        // No entry is due (or, while busy, none holds a batch) when their sum says so.
        if self.acks_owed == 0 || (!idle && self.acks_owed < u32::from(self.flow.ack_batch)) {
            return false;
        }
        let mut sent = false;
        let size = usize::from(self.place.layout.size());
        for p in 0..size {
            for (c, class) in CREDIT_CLASSES.into_iter().enumerate() {
                let due = self.acks_due.get(p, class);
                if due == 0 || (!idle && due < self.flow.ack_batch) || self.outbox_free() < 2 {
                    continue;
                }
                #[cfg(feature = "mutants")]
                if self.mutants.acks_need_credit && self.unacked.any_full(p, self.flow.i_max) {
                    continue;
                }
                self.acks_due.clear(p, class);
                self.acks_owed -= u32::from(due);
                let node = self.place.layout.node(self.place.cluster, p as u16);
                self.enqueue(
                    Dest::Node(node),
                    Msg::Ack {
                        from: self.node,
                        class: c as u8,
                        count: due,
                    },
                );
                sent = true;
            }
        }
        sent
    }

    fn quiet(&self) -> bool {
        self.pending_up.is_empty()
            && self.pending_down.is_empty()
            && self.outbox.is_empty()
            && self.unacked.all_zero()
            && self.acks_due.all_zero()
    }

    /// Pass the token on once this worker's pixels are final and it is quiet.
    fn pass_token(&mut self) -> bool {
        if self.token != Token::Holding || self.outbox_free() < 1 {
            return false;
        }
        #[cfg(feature = "mutants")]
        let ready = if self.mutants.early_token {
            self.generation_done()
        } else if self.mutants.token_unquiet {
            self.pixels_final()
        } else {
            self.pixels_final() && self.quiet()
        };
        #[cfg(not(feature = "mutants"))]
        let ready = self.pixels_final() && self.quiet();
        if !ready {
            return false;
        }
        self.token = Token::Passed;
        let (me, last) = (self.place.position, self.place.layout.size() - 1);
        #[cfg(feature = "mutants")]
        let upward = self.token_upward != self.mutants.token_backwards;
        #[cfg(not(feature = "mutants"))]
        let upward = self.token_upward;
        let next = if upward {
            (me < last).then(|| me + 1)
        } else {
            me.checked_sub(1)
        };
        let msg = Msg::Token {
            cluster: self.place.cluster,
        };
        match next {
            Some(p) => {
                let node = self.place.layout.node(self.place.cluster, p);
                self.enqueue(Dest::Node(node), msg);
            }
            None => self.enqueue(Dest::Host, msg),
        }
        true
    }

    /// Answer the host's request once every message this worker sent is acknowledged.
    fn report(&mut self) -> bool {
        if !self.collecting || self.reported || !self.quiet() || self.outbox_free() < 1 {
            return false;
        }
        self.reported = true;
        self.stats.sent[crate::node::msg::MsgKind::Stats as usize] += 1;
        let stats = self.stats;
        let _ = self.outbox.push_back((Dest::Host, Msg::Stats(stats)));
        true
    }

    /// Generate primary rays up to one started (or one row scanned; a ring of one, up to
    /// `budget` traced along a row); how many of the poll's rays that took (0: nothing was
    /// done).
    fn generate(&mut self, budget: u32) -> u32 {
        if self.generation_done() {
            return 0;
        }
        let generator = self.place.position == 0;
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
            let row_end = (n / width + 1) * width;
            if n < self.misses_until {
                // Certain misses (see below): the background, without setting up their rays,
                // to the end of the run or until a batch of pixels has gone to the outbox (one
                // message a poll, as for a ray): one pixel a poll would spend a poll's
                // machinery on each, where there is nothing to trace.
                let run = self.misses_until.min(row_end) - n;
                for k in 0..run {
                    self.cursor += 1;
                    self.emit(pixel + k as u32, rgba8(spec.background));
                    if self.batch.count == 0 {
                        break;
                    }
                }
                return 1;
            }
            if n >= self.set_up_through {
                self.stats.counters.rays_set_up += 1;
                self.set_up_through = n + 1;
            }
            let Some(ray) = self.view.primary_ray(pixel) else {
                // The pixels after a miss that certainly miss too are no position's rays.
                let run_end = (n + 1 + u64::from(self.view.misses_after(pixel))).min(row_end);
                if generator {
                    // A ray that misses the volume sees the background; ring position 0 says
                    // so, for this pixel and the certain misses after it.
                    self.misses_until = run_end;
                    self.cursor += 1;
                    self.emit(pixel, rgba8(spec.background));
                    return 1;
                }
                self.cursor = run_end;
                continue;
            };
            if self.place.layout.size() == 1 {
                let along = u32::try_from(row_end - n).unwrap_or(u32::MAX).min(budget);
                return self.trace_along(ray, pixel, along);
            }
            let first = ray.ray.at(ray.lattice.t(0));
            let owner = self
                .partition
                .owner(self.slab.grid().owner_plane(first.x, spec.model));
            let mine = owner == usize::from(self.place.position);
            let unadopted = Travel {
                ray,
                reply: Reply {
                    home: NO_HOME,
                    slot: 0,
                    hit: 0,
                    light: NO_LIGHT,
                },
            };
            match self.generation {
                Generation::Distributed if mine => {
                    if !self.can_start(&unadopted, false) {
                        return 0;
                    }
                    self.cursor += 1;
                    self.trace(unadopted);
                    return 1;
                }
                Generation::Distributed => {
                    // Not this position's ray: pass over the pixels along the row that are
                    // certainly not this position's either (and, at position 0, which sends
                    // the background of those that miss, certainly hit).
                    // Probing a pixel ahead sets up its ray too: counted with the rest.
                    let probes = core::cell::Cell::new(0u64);
                    let passed = match self.view.row_leaps() {
                        Some(leaps) => starts::passable(
                            leaps,
                            first.x,
                            &ray.lattice,
                            starts::Claim::of(self.slab.owned(), self.slab.grid(), spec.model),
                            u32::try_from(row_end - n - 1).unwrap_or(u32::MAX),
                            generator,
                            |k| {
                                probes.set(probes.get() + 1);
                                self.view.primary_ray(pixel + k).map(|far| far.lattice)
                            },
                        ),
                        None => 0,
                    };
                    self.stats.counters.rays_set_up += probes.get();
                    self.cursor = n
                        .saturating_add(1)
                        .saturating_add(u64::from(passed))
                        .min(row_end);
                }
                Generation::Centralized if mine => {
                    if !self.can_start(&unadopted, false) {
                        return 0;
                    }
                    self.cursor += 1;
                    self.trace(unadopted);
                    return 1;
                }
                Generation::Centralized => {
                    let class = Class::of_ray(ray.kind, ray.ray.dir.x);
                    if self.flow.enabled
                        && self.unacked.get(owner, class).saturating_add(1) >= self.flow.i_max
                    {
                        return 0;
                    }
                    self.cursor += 1;
                    self.send(owner, Msg::Ray(unadopted));
                    return 1;
                }
            }
        }
        1
    }

    /// A ring of one's pixels along a row from `pixel`, whose primary ray `ray` meets the
    /// volume, at most `along` of them: each traced whole where it is generated, until a
    /// pixel set has gone to the outbox (at most one message a call, as for any ray) or a ray
    /// misses (left to [`Worker::generate`], which sends the certain misses after it); how
    /// many were traced. A ring of one holds the whole volume, so the ray is its own, and every
    /// ray of the pixel's tree starts and ends here: nothing is sent, waited for or recorded.
    /// Each pixel is the same colour with the same counts as on the records' path of larger
    /// rings, and the same as one pixel a call: traced on along the row, a pixel costs none of
    /// the call's and the poll's checks, which cost as much as its ray's set-up.
    fn trace_along(&mut self, mut ray: RayState, pixel: u32, along: u32) -> u32 {
        let mut traced = 0;
        loop {
            self.cursor += 1;
            let color = trace_primary(self.view, &self.slab, ray, &mut self.stats.counters);
            self.stats.counters.non_finite_pixels += u64::from(!color.is_finite());
            self.emit(pixel + traced, rgba8(color));
            traced += 1;
            if self.batch.count == 0 || traced >= along {
                return traced;
            }
            // Set up once, as `generate` counts it: a ray that misses is not set up again there.
            self.stats.counters.rays_set_up += 1;
            self.set_up_through = self.cursor + 1;
            match self.view.primary_ray(pixel + traced) {
                Some(next) => ray = next,
                None => return traced,
            }
        }
    }
}
