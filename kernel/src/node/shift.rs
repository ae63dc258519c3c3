//! Moving slab planes between ring neighbours when the cuts change (static load balancing):
//! which planes each node sends and takes ([`Plan`]), and a sans-IO state machine that does
//! it in fixed memory ([`Shift`]).
//!
//! Invariants: every new cut lies between the old cuts on either side of it, so a plane a
//! node needs and lacks is held by a neighbour: planes left of its old stored range come from
//! the left neighbour, planes right of it from the right one ([`plan`] refuses other cuts). A
//! node first sends what its neighbours need, then moves the planes it keeps to their new
//! places, then takes what it needs: it never holds more than the larger of its old and new
//! stored ranges. A node waits only on the neighbour it sends to, and each boundary carries
//! planes one way, so waits run one way along the line of ring positions and cannot form a
//! cycle: the exchange cannot deadlock.

use crate::node::msg::{Msg, PlaneChunk, PLANE_CHUNK};
use crate::node::partition::Partition;
use crate::node::port::{Dest, Port};
use crate::node::worker::{Place, Progress};
use crate::volume::grid::Grid;
use crate::volume::sample::Sample;
use crate::volume::slab::stored_planes;
use core::fmt;
use core::ops::Range;

/// Why planes cannot be shifted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShiftError {
    /// The partitions have different numbers of slabs, or the place is not in them.
    Shape,
    /// Cut `index` moved past an old neighbouring cut: some node would need planes no
    /// neighbour holds.
    TooFar {
        /// Index of the cut.
        index: usize,
    },
    /// The storage holds fewer samples than the larger of the old and new stored ranges.
    Storage {
        /// Samples needed.
        needed: usize,
        /// Samples given.
        given: usize,
    },
}

impl fmt::Display for ShiftError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            ShiftError::Shape => write!(f, "the old and new partitions do not match the place"),
            ShiftError::TooFar { index } => write!(
                f,
                "cut {index} moves past a neighbouring old cut: planes would have to cross a node"
            ),
            ShiftError::Storage { needed, given } => write!(
                f,
                "shift storage holds {given} samples, the larger slab needs {needed}"
            ),
        }
    }
}

impl core::error::Error for ShiftError {}

/// What one ring position sends and takes: all ranges are X planes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Plan {
    /// Planes stored before.
    pub old: Range<u32>,
    /// Planes stored after.
    pub new: Range<u32>,
    /// Planes sent to the left neighbour (it takes them on its right).
    pub send_left: Range<u32>,
    /// Planes sent to the right neighbour.
    pub send_right: Range<u32>,
    /// Planes taken from the left neighbour.
    pub take_left: Range<u32>,
    /// Planes taken from the right neighbour.
    pub take_right: Range<u32>,
}

/// One round towards `target`: each cut moves towards its target cut, but not past the
/// current cuts on either side of it, so the round is a shift between neighbours
/// ([`plan`] accepts it). Every cut not yet at its target moves at least one plane, never
/// past it, and the cuts stay strictly increasing; rounds from any partition reach any
/// other of the same slabs in at most `nx` rounds (in practice a few).
pub fn next_step(current: &Partition, target: &Partition) -> Result<Partition, ShiftError> {
    let (c, t) = (current.cuts(), target.cuts());
    if c.len() != t.len() || c.last() != t.last() {
        return Err(ShiftError::Shape);
    }
    let mut next: heapless::Vec<u32, { crate::node::partition::MAX_CLUSTER + 1 }> =
        heapless::Vec::new();
    for i in 0..c.len() {
        let cut = if i == 0 || i + 1 == c.len() {
            c[i]
        } else {
            t[i].clamp(c[i - 1], c[i + 1])
        };
        next.push(cut).map_err(|_| ShiftError::Shape)?;
    }
    Partition::new(&next, c[c.len() - 1]).map_err(|_| ShiftError::Shape)
}

/// The planes ring position `j` lacks on its left and right after the change.
fn takes(old: &Range<u32>, new: &Range<u32>) -> (Range<u32>, Range<u32>) {
    let left = new.start..new.end.min(old.start).max(new.start);
    let right = new.start.max(old.end).min(new.end)..new.end;
    (left, right)
}

/// The plan of ring position `j` when the cuts change from `old` to `new` (`ghost` planes
/// each side). Every position computes every plan alike from the two partitions.
pub fn plan(
    grid: &Grid,
    old: &Partition,
    new: &Partition,
    ghost: u32,
    j: usize,
) -> Result<Plan, ShiftError> {
    let n = old.slabs();
    if new.slabs() != n || j >= n {
        return Err(ShiftError::Shape);
    }
    let (oc, nc) = (old.cuts(), new.cuts());
    for i in 1..n {
        if !(oc[i - 1] <= nc[i] && nc[i] <= oc[i + 1]) {
            return Err(ShiftError::TooFar { index: i });
        }
    }
    let stored = |p: &Partition, i: usize| stored_planes(grid, p.planes(i), ghost);
    let (o, w) = (stored(old, j), stored(new, j));
    let (take_left, take_right) = takes(&o, &w);
    let empty = o.start..o.start;
    let send_left = match j.checked_sub(1) {
        Some(l) => takes(&stored(old, l), &stored(new, l)).1,
        None => empty.clone(),
    };
    let send_right = if j + 1 < n {
        takes(&stored(old, j + 1), &stored(new, j + 1)).0
    } else {
        empty
    };
    // What the neighbours take, this node must hold: true of neighbouring cuts (checked).
    let held = |r: &Range<u32>| r.is_empty() || (o.start <= r.start && r.end <= o.end);
    if !held(&send_left) || !held(&send_right) {
        return Err(ShiftError::TooFar { index: j });
    }
    Ok(Plan {
        old: o,
        new: w,
        send_left,
        send_right,
        take_left,
        take_right,
    })
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    Send,
    Take,
    Done,
}

/// A position in the sample bytes of a range of planes: plane, and byte offset in it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Cursor {
    plane: u32,
    offset: u32,
}

/// One node's shift: sends, then moves what it keeps, then takes; see the module invariants.
#[derive(Debug)]
pub struct Shift<'a, T> {
    plan: Plan,
    storage: &'a mut [T],
    plane_bytes: u32,
    left: Option<u16>,
    right: Option<u16>,
    to_left: Cursor,
    to_right: Cursor,
    phase: Phase,
    /// Bytes still to take.
    missing: u64,
    /// Chunks that were not planes this node takes (counted, never a panic).
    strays: u32,
}

impl<'a, T: Sample> Shift<'a, T> {
    /// The shift of the node at `place`, whose `storage` begins with its old stored planes
    /// and holds at least the larger of the old and new stored ranges.
    pub fn new(
        grid: &Grid,
        plan: Plan,
        place: Place,
        storage: &'a mut [T],
    ) -> Result<Shift<'a, T>, ShiftError> {
        // A plan from anywhere but `plan` must still keep every read inside the storage.
        let within = |r: &Range<u32>, outer: &Range<u32>| {
            r.is_empty() || (outer.start <= r.start && r.end <= outer.end)
        };
        if !(within(&plan.send_left, &plan.old)
            && within(&plan.send_right, &plan.old)
            && within(&plan.take_left, &plan.new)
            && within(&plan.take_right, &plan.new)
            && plan.old.end <= grid.dims()[0]
            && plan.new.end <= grid.dims()[0])
        {
            return Err(ShiftError::Shape);
        }
        let plane = grid.plane_len();
        let planes = plan.old.len().max(plan.new.len());
        let needed = planes * plane;
        if storage.len() < needed {
            return Err(ShiftError::Storage {
                needed,
                given: storage.len(),
            });
        }
        let size = place.layout.size();
        let neighbour = |p: Option<u16>| {
            p.filter(|&p| p < size)
                .map(|p| place.layout.node(place.cluster, p))
        };
        let plane_bytes = (plane * T::KIND.bytes()) as u32;
        let missing =
            (plan.take_left.len() + plan.take_right.len()) as u64 * u64::from(plane_bytes);
        Ok(Shift {
            left: neighbour(place.position.checked_sub(1)),
            right: neighbour(place.position.checked_add(1)),
            to_left: Cursor {
                plane: plan.send_left.start,
                offset: 0,
            },
            to_right: Cursor {
                plane: plan.send_right.start,
                offset: 0,
            },
            plan,
            storage,
            plane_bytes,
            phase: Phase::Send,
            missing,
            strays: 0,
        })
    }

    /// Whether the node holds exactly its new stored planes.
    pub fn done(&self) -> bool {
        self.phase == Phase::Done
    }

    /// The planes stored once done, at the start of the storage.
    pub fn stored(&self) -> Range<u32> {
        self.plan.new.clone()
    }

    /// Chunks received that were no plane this node takes (always 0 between correct nodes).
    pub fn strays(&self) -> u32 {
        self.strays
    }

    /// Do what can be done now.
    pub fn poll(&mut self, port: &mut impl Port) -> Progress {
        let mut worked = false;
        if self.phase == Phase::Send {
            let (left, right) = (self.left, self.right);
            let range = self.plan.send_left.clone();
            worked |= self.send(port, left, range, true);
            let range = self.plan.send_right.clone();
            worked |= self.send(port, right, range, false);
            let finished = |c: &Cursor, r: &Range<u32>| r.is_empty() || c.plane >= r.end;
            if finished(&self.to_left, &self.plan.send_left)
                && finished(&self.to_right, &self.plan.send_right)
            {
                self.keep();
                self.phase = Phase::Take;
                worked = true;
            }
        }
        if self.phase == Phase::Take {
            while let Some((_, msg)) = port.try_recv(crate::node::flow::Class::Control) {
                if let Msg::Planes(chunk) = msg {
                    self.take(&chunk);
                } else {
                    self.strays += 1;
                }
                worked = true;
            }
            if self.missing == 0 {
                self.phase = Phase::Done;
                worked = true;
            }
        }
        if worked {
            Progress::Busy
        } else {
            Progress::Idle
        }
    }

    /// Send the chunks of `range` to `to` until the port refuses one; true if any went.
    fn send(
        &mut self,
        port: &mut impl Port,
        to: Option<u16>,
        range: Range<u32>,
        left: bool,
    ) -> bool {
        let Some(to) = to else {
            return false;
        };
        let mut sent = false;
        loop {
            let cursor = if left { self.to_left } else { self.to_right };
            if range.is_empty() || cursor.plane >= range.end {
                return sent;
            }
            let chunk = self.chunk(cursor);
            if port.try_send(Dest::Node(to), Msg::Planes(chunk)).is_err() {
                return sent;
            }
            sent = true;
            let mut next = cursor;
            next.offset += u32::from(chunk.len);
            if next.offset >= self.plane_bytes {
                next = Cursor {
                    plane: cursor.plane + 1,
                    offset: 0,
                };
            }
            if left {
                self.to_left = next;
            } else {
                self.to_right = next;
            }
        }
    }

    /// The chunk of old stored plane bytes at `c`.
    fn chunk(&self, c: Cursor) -> PlaneChunk {
        let width = T::KIND.bytes();
        let len = (self.plane_bytes - c.offset).min(PLANE_CHUNK as u32) as usize;
        let mut bytes = [0u8; PLANE_CHUNK];
        let plane_start =
            (c.plane - self.plan.old.start) as usize * (self.plane_bytes as usize / width);
        let first = plane_start + c.offset as usize / width;
        for (i, out) in bytes[..len].chunks_exact_mut(width).enumerate() {
            if let Some(v) = self.storage.get(first + i) {
                v.write_le(out);
            }
        }
        PlaneChunk {
            plane: c.plane,
            offset: c.offset,
            len: len as u16,
            bytes,
        }
    }

    /// Move the planes kept (old ∩ new) to their new places.
    fn keep(&mut self) {
        let (o, w) = (&self.plan.old, &self.plan.new);
        let kept = o.start.max(w.start)..o.end.min(w.end);
        if kept.is_empty() {
            return;
        }
        let plane = self.plane_bytes as usize / T::KIND.bytes();
        let from = (kept.start - o.start) as usize * plane;
        let to = (kept.start - w.start) as usize * plane;
        let len = kept.len() * plane;
        if from + len <= self.storage.len() && to + len <= self.storage.len() {
            self.storage.copy_within(from..from + len, to);
        }
    }

    /// Store a received chunk where its plane goes, if it is one this node takes.
    fn take(&mut self, chunk: &PlaneChunk) {
        let wanted = self.plan.take_left.contains(&chunk.plane)
            || self.plan.take_right.contains(&chunk.plane);
        let width = T::KIND.bytes();
        let len = usize::from(chunk.len);
        if !wanted
            || len % width != 0
            || len > PLANE_CHUNK
            || u64::from(chunk.offset) + len as u64 > u64::from(self.plane_bytes)
        {
            self.strays += 1;
            return;
        }
        let plane = self.plane_bytes as usize / width;
        let first =
            (chunk.plane - self.plan.new.start) as usize * plane + chunk.offset as usize / width;
        for (i, bytes) in chunk.bytes[..len].chunks_exact(width).enumerate() {
            if let (Some(slot), Some(v)) = (self.storage.get_mut(first + i), T::read_le(bytes)) {
                *slot = v;
            }
        }
        self.missing = self.missing.saturating_sub(len as u64);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::node::flow::Class;
    use crate::node::topology::Layout;
    use glam::Vec3;
    use heapless::{Deque, Vec};

    const NODES: usize = 8;

    /// Every node's receive queue, `capacity` chunks each.
    struct Net {
        queues: [Deque<(Dest, Msg), 16>; NODES],
        capacity: usize,
    }

    struct NodePort<'n> {
        net: &'n mut Net,
        me: u16,
    }

    impl Port for NodePort<'_> {
        fn try_send(&mut self, to: Dest, msg: Msg) -> Result<(), Msg> {
            let Dest::Node(n) = to else { return Err(msg) };
            let q = &mut self.net.queues[usize::from(n)];
            if q.len() >= self.net.capacity {
                return Err(msg);
            }
            q.push_back((Dest::Node(self.me), msg)).map_err(|(_, m)| m)
        }
        fn peek(&mut self, _: Class) -> Option<&Msg> {
            self.net.queues[usize::from(self.me)]
                .front()
                .map(|(_, m)| m)
        }
        fn try_recv(&mut self, _: Class) -> Option<(Dest, Msg)> {
            self.net.queues[usize::from(self.me)].pop_front()
        }
        fn pending(&self) -> usize {
            self.net.queues[usize::from(self.me)].len()
        }
    }

    /// Shift a `dims` u16 volume (value = global index) from `old` to `new` cuts on one
    /// cluster, polling nodes in a pseudo-random order from `seed`; checks every node ends
    /// with exactly its new stored planes.
    fn exchange(dims: [u32; 3], old: &[u32], new: &[u32], ghost: u32, capacity: usize, seed: u64) {
        let grid = Grid::new(dims, Vec3::ONE).unwrap();
        let n = old.len() - 1;
        let (po, pn) = (
            Partition::new(old, dims[0]).unwrap(),
            Partition::new(new, dims[0]).unwrap(),
        );
        let layout = Layout::new(1, n as u32).unwrap();
        let plane = grid.plane_len();
        let value = |i: usize| (i * 7919 % 65_521) as u16;
        let mut storage: [[u16; 512]; NODES] = [[0; 512]; NODES];
        let mut net = Net {
            queues: Default::default(),
            capacity,
        };
        let mut shifts: Vec<Shift<'_, u16>, NODES> = Vec::new();
        let mut nodes = [0u16; NODES];
        for (j, store) in storage.iter_mut().enumerate().take(n) {
            let plan = plan(&grid, &po, &pn, ghost, j).unwrap();
            let first = plan.old.start as usize * plane;
            for (i, s) in store.iter_mut().enumerate().take(plan.old.len() * plane) {
                *s = value(first + i);
            }
            let place = Place {
                layout,
                cluster: 0,
                position: j as u16,
            };
            nodes[j] = layout.node(0, j as u16);
            let shift = Shift::new(&grid, plan, place, store).unwrap();
            assert!(shifts.push(shift).is_ok());
        }
        let mut state = seed | 1;
        let mut idle = 0;
        while !shifts.iter().all(Shift::done) {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let j = (state % n as u64) as usize;
            let mut port = NodePort {
                net: &mut net,
                me: nodes[j],
            };
            match shifts[j].poll(&mut port) {
                Progress::Busy => idle = 0,
                Progress::Idle => idle += 1,
            }
            assert!(idle < 10_000, "no progress: the exchange is stuck");
        }
        for (j, shift) in shifts.iter().enumerate() {
            assert_eq!(shift.strays(), 0);
            let stored = shift.stored();
            assert_eq!(stored, stored_planes(&grid, pn.planes(j), ghost));
            let first = stored.start as usize * plane;
            for i in 0..stored.len() * plane {
                assert_eq!(shift.storage[i], value(first + i), "node {j}, sample {i}");
            }
        }
    }

    #[test]
    fn every_node_ends_with_its_new_planes_in_any_order() {
        // 16 planes of 3 x 2 samples: cuts move both ways, by up to a whole slab.
        let dims = [16, 3, 2];
        let cases: [(&[u32], &[u32]); 4] = [
            (&[0, 4, 8, 12, 16], &[0, 2, 9, 14, 16]),
            (&[0, 4, 8, 12, 16], &[0, 8, 12, 15, 16]),
            (&[0, 8, 16], &[0, 1, 16]),
            (
                &[0, 2, 4, 6, 8, 10, 12, 14, 16],
                &[0, 1, 3, 6, 8, 11, 12, 13, 16],
            ),
        ];
        for (old, new) in cases {
            for ghost in [0, 1, 2] {
                for (capacity, seed) in [(1, 1), (2, 7), (16, 99)] {
                    exchange(dims, old, new, ghost, capacity, seed);
                }
            }
        }
        // Nothing moves: every node is done at once.
        exchange(dims, &[0, 4, 8, 12, 16], &[0, 4, 8, 12, 16], 1, 1, 3);
    }

    #[test]
    fn rounds_between_neighbours_reach_any_partition() {
        let cases: [(&[u32], &[u32]); 4] = [
            (
                &[0, 5, 10, 15, 20, 25, 30, 35, 40],
                &[0, 10, 15, 20, 25, 30, 35, 38, 40],
            ),
            (
                &[0, 10, 15, 20, 25, 30, 35, 38, 40],
                &[0, 1, 2, 3, 4, 5, 6, 7, 40],
            ),
            (
                &[0, 1, 2, 3, 4, 5, 6, 7, 40],
                &[0, 33, 34, 35, 36, 37, 38, 39, 40],
            ),
            (&[0, 20, 40], &[0, 20, 40]),
        ];
        let grid = Grid::new([40, 1, 1], Vec3::ONE).unwrap();
        for (from, to) in cases {
            let target = Partition::new(to, 40).unwrap();
            let mut current = Partition::new(from, 40).unwrap();
            let mut rounds = 0;
            while current != target {
                let next = next_step(&current, &target).unwrap();
                for j in 0..current.slabs() {
                    assert!(plan(&grid, &current, &next, 1, j).is_ok(), "{next:?}");
                }
                let distance = |p: &Partition| -> u32 {
                    p.cuts().iter().zip(to).map(|(a, b)| a.abs_diff(*b)).sum()
                };
                assert!(distance(&next) < distance(&current));
                current = next;
                rounds += 1;
                assert!(rounds <= 40);
            }
        }
        let three = Partition::new(&[0, 20, 30, 40], 40).unwrap();
        let two = Partition::new(&[0, 20, 40], 40).unwrap();
        assert_eq!(next_step(&two, &three), Err(ShiftError::Shape));
    }

    #[test]
    fn cuts_that_move_too_far_or_storage_too_small_are_refused() {
        let grid = Grid::new([16, 3, 2], Vec3::ONE).unwrap();
        let old = Partition::new(&[0, 4, 8, 12, 16], 16).unwrap();
        let far = Partition::new(&[0, 9, 10, 12, 16], 16).unwrap();
        assert_eq!(
            plan(&grid, &old, &far, 1, 0),
            Err(ShiftError::TooFar { index: 1 })
        );
        let fewer = Partition::new(&[0, 8, 16], 16).unwrap();
        assert_eq!(plan(&grid, &old, &fewer, 1, 0), Err(ShiftError::Shape));
        let new = Partition::new(&[0, 6, 8, 12, 16], 16).unwrap();
        let p = plan(&grid, &old, &new, 1, 0).unwrap();
        assert_eq!((p.old.clone(), p.new.clone()), (0..5, 0..7));
        assert_eq!(p.take_right, 5..7);
        assert!(p.send_right.is_empty() && p.send_left.is_empty() && p.take_left.is_empty());
        let layout = Layout::new(1, 4).unwrap();
        let place = Place {
            layout,
            cluster: 0,
            position: 0,
        };
        let mut small = [0u16; 7 * 6 - 1];
        assert_eq!(
            Shift::new(&grid, p.clone(), place, &mut small).err(),
            Some(ShiftError::Storage {
                needed: 42,
                given: 41
            })
        );
        let mut bad = p;
        bad.send_right = 10..12;
        let mut storage = [0u16; 42];
        assert_eq!(
            Shift::new(&grid, bad, place, &mut storage).err(),
            Some(ShiftError::Shape)
        );
    }
}
