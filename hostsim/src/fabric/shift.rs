//! The plane shift before a balanced render: every node of every cluster starts with its
//! uniform slab and runs the kernel's [`Shift`] over byte-bounded receive buffers until it
//! holds its slab of the new cuts, as the paper's workers do.
//!
//! Cuts that move past their old neighbours are reached in rounds, each a shift between
//! neighbours ([`next_step`]). Invariants: each node's storage is its own (nothing is copied
//! from the volume after the start); a round ends only when every node is done, and a pass
//! over the nodes in which none can move is an error, never a hang. Time, when a profile is
//! given, is each node's own message work (send: latency, write and bytes; receive: read);
//! a round takes as long as its busiest node, since all nodes shift at once.

use crate::profile::MachineProfile;
use std::collections::VecDeque;
use std::fmt;
use voxcube_kernel::node::flow::Class;
use voxcube_kernel::node::msg::Msg;
use voxcube_kernel::node::partition::Partition;
use voxcube_kernel::node::port::{Dest, Port};
use voxcube_kernel::node::shift::{next_step, plan, Shift, ShiftError};
use voxcube_kernel::node::topology::Layout;
use voxcube_kernel::node::worker::{Place, Progress};
use voxcube_kernel::volume::grid::Grid;
use voxcube_kernel::volume::sample::Sample;
use voxcube_kernel::volume::slab::stored_planes;

/// What the shift did.
#[derive(Clone, Debug, PartialEq)]
pub struct ShiftReport {
    /// Slab-plane messages delivered, all nodes.
    pub messages: u64,
    /// Their bytes.
    pub bytes: u64,
    /// Simulated seconds: each round as long as its busiest node, the rounds one after
    /// another (timed runs only).
    pub seconds: Option<f64>,
    /// Each node's simulated seconds sending and receiving, in node-id order (timed runs
    /// only).
    pub per_node: Vec<(f64, f64)>,
    /// The largest storage any node needed during the shift, samples.
    pub peak_samples: usize,
    /// Rounds of shifts between neighbours.
    pub rounds: u32,
}

/// Why the shift failed.
#[derive(Debug)]
pub enum ShiftFailure {
    /// The cuts or storage were refused.
    Plan(ShiftError),
    /// A round passed in which no node could do anything.
    Stalled {
        /// Nodes not done.
        unfinished: usize,
    },
    /// A node received chunks that were no planes it takes.
    Strays {
        /// The node.
        node: u16,
    },
}

impl fmt::Display for ShiftFailure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ShiftFailure::Plan(e) => write!(f, "plane shift: {e}"),
            ShiftFailure::Stalled { unfinished } => {
                write!(f, "plane shift stalled with {unfinished} nodes unfinished")
            }
            ShiftFailure::Strays { node } => {
                write!(
                    f,
                    "plane shift: node {node} received planes it does not take"
                )
            }
        }
    }
}

impl std::error::Error for ShiftFailure {}

/// A node's receive buffer: messages and the bytes they hold.
#[derive(Default)]
struct Inbox {
    queue: VecDeque<(Dest, Msg)>,
    bytes: usize,
}

struct ShiftPort<'n> {
    inboxes: &'n mut [Inbox],
    capacity: usize,
    me: u16,
}

impl Port for ShiftPort<'_> {
    fn try_send(&mut self, to: Dest, msg: Msg) -> Result<(), Msg> {
        let Dest::Node(n) = to else { return Err(msg) };
        let len = msg.kind().encoded_len();
        let Some(inbox) = self.inboxes.get_mut(usize::from(n)) else {
            return Err(msg);
        };
        if inbox.bytes + len > self.capacity {
            return Err(msg);
        }
        inbox.bytes += len;
        inbox.queue.push_back((Dest::Node(self.me), msg));
        Ok(())
    }

    fn peek(&mut self, _: Class) -> Option<&Msg> {
        self.inboxes
            .get(usize::from(self.me))
            .and_then(|i| i.queue.front())
            .map(|(_, m)| m)
    }

    fn try_recv(&mut self, _: Class) -> Option<(Dest, Msg)> {
        let inbox = self.inboxes.get_mut(usize::from(self.me))?;
        let (from, msg) = inbox.queue.pop_front()?;
        inbox.bytes = inbox.bytes.saturating_sub(msg.kind().encoded_len());
        Some((from, msg))
    }

    fn pending(&self) -> usize {
        self.inboxes
            .get(usize::from(self.me))
            .map_or(0, |i| i.queue.len())
    }
}

/// A port that counts the messages a node sends (and their bytes) and receives: every
/// fabric's shift reports them alike.
#[derive(Debug)]
pub struct Counted<P> {
    /// The fabric's port.
    pub port: P,
    /// Messages sent.
    pub sent: u64,
    /// Their encoded bytes.
    pub sent_bytes: u64,
    /// Messages received.
    pub received: u64,
}

impl<P> Counted<P> {
    /// Counting from zero.
    pub fn new(port: P) -> Counted<P> {
        Counted {
            port,
            sent: 0,
            sent_bytes: 0,
            received: 0,
        }
    }
}

impl<P: Port> Port for Counted<P> {
    fn try_send(&mut self, to: Dest, msg: Msg) -> Result<(), Msg> {
        let len = msg.kind().encoded_len();
        self.port.try_send(to, msg)?;
        self.sent += 1;
        self.sent_bytes += len as u64;
        Ok(())
    }

    fn peek(&mut self, class: Class) -> Option<&Msg> {
        self.port.peek(class)
    }

    fn try_recv(&mut self, class: Class) -> Option<(Dest, Msg)> {
        let got = self.port.try_recv(class)?;
        self.received += 1;
        Some(got)
    }

    fn pending(&self) -> usize {
        self.port.pending()
    }
}

/// The rounds from `old` to `new` as `(from, to)` cuts, each a shift between neighbours
/// ([`next_step`]); none when they are equal.
pub fn rounds(
    old: &Partition,
    new: &Partition,
) -> Result<Vec<(Partition, Partition)>, ShiftFailure> {
    let mut out = Vec::new();
    let mut current = old.clone();
    while current != *new {
        let next = next_step(&current, new).map_err(ShiftFailure::Plan)?;
        out.push((current, next.clone()));
        current = next;
    }
    Ok(out)
}

/// What node `node` loads before any shift: its stored planes of the `old` cuts.
pub fn load<T: Sample>(
    grid: &Grid,
    data: &[T],
    layout: Layout,
    old: &Partition,
    ghost: u32,
    node: u16,
) -> Vec<T> {
    let plane = grid.plane_len();
    let j = usize::from(layout.place(node).1);
    let s = stored_planes(grid, old.planes(j), ghost);
    data[s.start as usize * plane..s.end as usize * plane].to_vec()
}

/// Node `node`'s part in the round `cuts` (from, to): its plan, its storage grown to the
/// larger of its stored ranges before and after, and the kernel's [`Shift`] over it, with the
/// samples the storage now holds (the node's peak in this round). Once the shift is done,
/// [`Shift::stored`] is what to keep ([`keep`]).
pub fn start<'s, T: Sample>(
    grid: &Grid,
    layout: Layout,
    node: u16,
    cuts: (&Partition, &Partition),
    ghost: u32,
    storage: &'s mut Vec<T>,
) -> Result<(Shift<'s, T>, usize), ShiftFailure> {
    let (cluster, position) = layout.place(node);
    let p = plan(grid, cuts.0, cuts.1, ghost, usize::from(position)).map_err(ShiftFailure::Plan)?;
    storage.resize(
        p.old.len().max(p.new.len()) * grid.plane_len(),
        T::default(),
    );
    let place = Place {
        layout,
        cluster,
        position,
    };
    let held = storage.len();
    let shift = Shift::new(grid, p, place, storage).map_err(ShiftFailure::Plan)?;
    Ok((shift, held))
}

/// Cut a node's storage down to the planes `stored` after a round.
pub fn keep<T>(grid: &Grid, storage: &mut Vec<T>, stored: &std::ops::Range<u32>) {
    storage.truncate(stored.len() * grid.plane_len());
}

/// A shift of every node's planes from the `old` cuts to the `new` ones, whichever fabric
/// carries it.
#[derive(Clone, Debug)]
pub struct ShiftJob<'a> {
    /// The volume's grid.
    pub grid: &'a Grid,
    /// The machine.
    pub layout: Layout,
    /// The cuts the nodes load their slabs of (uniform).
    pub old: Partition,
    /// The cuts they shift to.
    pub new: &'a Partition,
    /// Ghost planes each slab stores on either side.
    pub ghost: u32,
    /// Each receive buffer's bytes.
    pub capacity: usize,
}

/// Carry out `job` in one thread, in rounds of shifts between neighbours ([`next_step`]).
/// `data` is the whole volume, from which each node loads its old slab at the start; a timed
/// run charges its messages on `profile`. Returns each node's storage (its new stored planes,
/// plane-major), in node-id order, and the report.
pub fn run<T: Sample>(
    job: &ShiftJob<'_>,
    data: &[T],
    profile: Option<&MachineProfile>,
) -> Result<(Vec<Vec<T>>, ShiftReport), ShiftFailure> {
    let ShiftJob {
        grid,
        layout,
        ref old,
        new,
        ghost,
        capacity,
    } = *job;
    let nodes = layout.nodes() as usize;
    // Each node loads its slab of the old cuts; from here on it has only its own storage.
    let mut storages: Vec<Vec<T>> = (0..nodes as u16)
        .map(|node| load(grid, data, layout, old, ghost, node))
        .collect();
    let mut report = ShiftReport {
        messages: 0,
        bytes: 0,
        seconds: profile.map(|_| 0.0),
        per_node: if profile.is_some() {
            vec![(0.0, 0.0); nodes]
        } else {
            Vec::new()
        },
        peak_samples: storages.iter().map(Vec::len).max().unwrap_or(0),
        rounds: 0,
    };
    for (from, to) in rounds(old, new)? {
        round(
            grid,
            &mut storages,
            layout,
            (&from, &to),
            ghost,
            capacity,
            profile,
            &mut report,
        )?;
    }
    Ok((storages, report))
}

/// One round: every node shifts from `cuts.0` to `cuts.1` (neighbouring cuts), in parallel.
#[allow(
    clippy::too_many_arguments,
    reason = "one call site: the round's shape"
)]
fn round<T: Sample>(
    grid: &Grid,
    storages: &mut [Vec<T>],
    layout: Layout,
    cuts: (&Partition, &Partition),
    ghost: u32,
    capacity: usize,
    profile: Option<&MachineProfile>,
    report: &mut ShiftReport,
) -> Result<(), ShiftFailure> {
    let nodes = storages.len();
    let mut shifts = Vec::with_capacity(nodes);
    for (node, storage) in storages.iter_mut().enumerate() {
        let (shift, held) = start(grid, layout, node as u16, cuts, ghost, storage)?;
        report.peak_samples = report.peak_samples.max(held);
        shifts.push(shift);
    }
    let mut inboxes: Vec<Inbox> = (0..nodes).map(|_| Inbox::default()).collect();
    let (mut sent, mut sent_bytes, mut received) =
        (vec![0u64; nodes], vec![0u64; nodes], vec![0u64; nodes]);
    loop {
        let unfinished = shifts.iter().filter(|s| !s.done()).count();
        if unfinished == 0 {
            break;
        }
        let mut moved = false;
        for (node, shift) in shifts.iter_mut().enumerate() {
            let mut port = Counted::new(ShiftPort {
                inboxes: &mut inboxes,
                capacity,
                me: node as u16,
            });
            moved |= shift.poll(&mut port) == Progress::Busy;
            sent[node] += port.sent;
            sent_bytes[node] += port.sent_bytes;
            received[node] += port.received;
        }
        if !moved {
            return Err(ShiftFailure::Stalled { unfinished });
        }
    }
    if let Some(node) = shifts.iter().position(|s| s.strays() > 0) {
        return Err(ShiftFailure::Strays { node: node as u16 });
    }
    let stored: Vec<_> = shifts.iter().map(Shift::stored).collect();
    drop(shifts);
    for (storage, s) in storages.iter_mut().zip(&stored) {
        keep(grid, storage, s);
    }
    report.rounds += 1;
    report.messages += sent.iter().sum::<u64>();
    report.bytes += sent_bytes.iter().sum::<u64>();
    if let Some(p) = profile {
        let m = p.message_costs();
        let mut slowest = 0.0f64;
        for (n, total) in report.per_node.iter_mut().enumerate() {
            let send = sent[n] as f64 * (m.latency + m.write) + sent_bytes[n] as f64 * m.per_byte;
            let receive = received[n] as f64 * m.read;
            total.0 += send;
            total.1 += receive;
            slowest = slowest.max(send + receive);
        }
        // The rounds follow one another; within one, every node shifts at once.
        report.seconds = report.seconds.map(|s| s + slowest);
    }
    Ok(())
}
