//! The MPI fabric (cargo feature `mpi`): rank 0 is the host, rank `r` runs node `r − 1`, each
//! with the same `Worker` behind an MPI [`Port`]. Launch with `mpirun -np <P+1>`.
//!
//! Sends are standard-mode MPI sends of at most a few hundred bytes, far below Open MPI's
//! eager limit. So they complete locally without waiting for the receiver; ack-counter flow
//! control bounds how many are outstanding, exactly as on the other fabrics. Each node keeps
//! its received messages in per-class queues with the simulator's byte capacity: exceeding it
//! would be an error, never silent.
//!
//! The host starts every phase of a view itself ([`Start`]: the machine, the rows it traces,
//! the node each rank runs, and a message tag of its own), so a message of an abandoned
//! phase is never taken by a later one and no barrier, which a hung rank would never reach,
//! is needed.
//!
//! Balanced views (`RunConfig::shift`): the host sends the cuts it chose, and every node
//! starts on its uniform slab and shifts planes to its neighbours by slab-plane messages
//! before rendering, round `r` under its own tag ([`TAG_SHIFT`]` + r`), so a chunk sent by a
//! node already in the next round waits in MPI's queue until its receiver gets there. Each
//! node then tells the host what it sent.
//!
//! Faults: every node sends the host a heartbeat every [`HEARTBEAT`]. A node the host has not
//! heard from for `RunConfig::lost_after`, before it reported, is declared lost; the other
//! clusters re-trace its cluster's unfinished rows and render every later view alone
//! (`super::recovery`). With no cluster left the run fails, naming the lost pixels. How the
//! job then ends, with a rank that never finalises, is [`end`]'s to decide. A rank that dies
//! outright ends the whole job unless `mpirun --enable-recovery` keeps it alive.
//! `--stop-node NODE@STEPS[:exit]` makes a node's rank hang (or exit) after so many polls.

use super::harness::{node_worker, Plan};
use super::recovery::{self, LostNode, Retraced};
use super::shift::{self as planes, Counted, ShiftFailure, ShiftReport};
use super::{Distributed, Recovery, RunConfig, RunError};
use crate::input::dataset::{Volume, VolumeData};
use mpi::datatype::Equivalence;
use mpi::point_to_point::{Destination, Source};
use mpi::topology::{Communicator, SimpleCommunicator};
use std::collections::VecDeque;
use std::ops::Range;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Mutex, PoisonError};
use std::time::{Duration, Instant};
use voxcube_kernel::node::flow::Class;
use voxcube_kernel::node::msg::{Msg, MAX_MSG_LEN};
use voxcube_kernel::node::partition::Partition;
use voxcube_kernel::node::port::{Dest, Port};
use voxcube_kernel::node::topology::{Layout, Rows};
use voxcube_kernel::node::worker::Progress;
use voxcube_kernel::trace::view::View;
use voxcube_kernel::volume::grid::Grid;
use voxcube_kernel::volume::sample::Sample;
use voxcube_kernel::volume::slab::{stored_planes, Slab};

/// Tag of the host's [`Start`] of a phase.
const TAG_START: i32 = 1;
/// Tag of a phase's ranks, by node, after its start.
const TAG_RANKS: i32 = 4;
/// Tag of a phase's slab cuts, after its ranks.
const TAG_CUTS: i32 = 5;
/// Kernel messages of phase `e` go under tag `TAG_MSG_BASE + e` ([`phase_tag`]).
const TAG_MSG_BASE: i32 = 1000;
/// Tag of heartbeats.
const TAG_BEAT: i32 = 2;
/// Tag of a node's account of its plane shift: messages, bytes, peak samples, rounds.
const TAG_SHIFT_REPORT: i32 = 3;
/// Tag of a node's account of its set-up: the phase's tag, the microseconds from its start
/// until the node could trace (its plane shift included), its rank's peak resident bytes
/// then, the planes its rank holds, and their least and greatest value (`f64` bits).
const TAG_SETUP: i32 = 6;
/// Tag of the plane shift's first round; round `r` uses `TAG_SHIFT + r`.
pub const TAG_SHIFT: i32 = 16;
/// How often a node tells the host it is alive.
pub const HEARTBEAT: Duration = Duration::from_millis(250);

struct MpiPort<'w> {
    world: &'w SimpleCommunicator,
    /// Where each node of the phase runs, and the phase's tag.
    ranks: PhaseRanks,
    tag: i32,
    local: [VecDeque<(Dest, Msg)>; 7],
    used: usize,
    peak: usize,
    capacity: usize,
    overflow: bool,
}

impl MpiPort<'_> {
    /// Move every arrived kernel message into the class queues.
    fn pump(&mut self) -> Result<(), RunError> {
        let mut buf = [0u8; MAX_MSG_LEN];
        while let Some((message, status)) = self
            .world
            .any_process()
            .immediate_matched_probe_with_tag(self.tag)
        {
            let from = status.source_rank();
            let len = status.count(u8::equivalent_datatype()) as usize;
            message.matched_receive_into(&mut buf[..]);
            let msg =
                Msg::decode(&buf[..len.min(MAX_MSG_LEN)]).map_err(|error| RunError::Decode {
                    from: from as u16,
                    error,
                })?;
            let source = match (from, self.ranks.node(from)) {
                (0, _) => Dest::Host,
                (_, Some(n)) => Dest::Node(n),
                // No node of this phase runs there: not a message of this phase.
                (_, None) => continue,
            };
            self.used += msg.kind().encoded_len();
            self.peak = self.peak.max(self.used);
            self.overflow |= self.used > self.capacity;
            self.local[msg.class().index()].push_back((source, msg));
        }
        Ok(())
    }
}

impl Port for MpiPort<'_> {
    fn try_send(&mut self, to: Dest, msg: Msg) -> Result<(), Msg> {
        let rank = match to {
            Dest::Host => 0,
            Dest::Node(n) => match self.ranks.rank(n) {
                Some(rank) => rank,
                None => return Err(msg),
            },
        };
        let mut buf = [0u8; MAX_MSG_LEN];
        let len = msg.encode(&mut buf);
        self.world
            .process_at_rank(rank)
            .send_with_tag(&buf[..len], self.tag);
        Ok(())
    }

    fn peek(&mut self, class: Class) -> Option<&Msg> {
        self.local[class.index()].front().map(|(_, m)| m)
    }

    fn try_recv(&mut self, class: Class) -> Option<(Dest, Msg)> {
        let (from, msg) = self.local[class.index()].pop_front()?;
        self.used = self.used.saturating_sub(msg.kind().encoded_len());
        Some((from, msg))
    }

    fn pending(&self) -> usize {
        self.local.iter().map(VecDeque::len).sum()
    }
}

/// The plane shift's port for one round: messages are taken from MPI one at a time, when the
/// kernel asks, under the round's tag, so later rounds' chunks wait in MPI's queue.
struct RoundPort<'w> {
    world: &'w SimpleCommunicator,
    tag: i32,
    next: Option<(Dest, Msg)>,
    error: Option<RunError>,
}

impl RoundPort<'_> {
    fn fill(&mut self) {
        if self.next.is_some() || self.error.is_some() {
            return;
        }
        let Some((message, status)) = self
            .world
            .any_process()
            .immediate_matched_probe_with_tag(self.tag)
        else {
            return;
        };
        let mut buf = [0u8; MAX_MSG_LEN];
        let from = status.source_rank();
        let len = status.count(u8::equivalent_datatype()) as usize;
        message.matched_receive_into(&mut buf[..]);
        match Msg::decode(&buf[..len.min(MAX_MSG_LEN)]) {
            Ok(msg) => self.next = Some((Dest::Node((from - 1) as u16), msg)),
            Err(error) => {
                self.error = Some(RunError::Decode {
                    from: from as u16,
                    error,
                })
            }
        }
    }
}

impl Port for RoundPort<'_> {
    fn try_send(&mut self, to: Dest, msg: Msg) -> Result<(), Msg> {
        let Dest::Node(n) = to else { return Err(msg) };
        let mut buf = [0u8; MAX_MSG_LEN];
        let len = msg.encode(&mut buf);
        self.world
            .process_at_rank(i32::from(n) + 1)
            .send_with_tag(&buf[..len], self.tag);
        Ok(())
    }

    fn peek(&mut self, _: Class) -> Option<&Msg> {
        self.fill();
        self.next.as_ref().map(|(_, m)| m)
    }

    fn try_recv(&mut self, _: Class) -> Option<(Dest, Msg)> {
        self.fill();
        self.next.take()
    }

    fn pending(&self) -> usize {
        usize::from(self.next.is_some())
    }
}

/// Tell the host this node is alive, if [`HEARTBEAT`] has passed since `last`.
fn heartbeat(world: &SimpleCommunicator, last: &mut Instant) {
    if last.elapsed() >= HEARTBEAT {
        world.process_at_rank(0).send_with_tag(&[0u8][..], TAG_BEAT);
        *last = Instant::now();
    }
}

/// How a node's plane shift ended.
enum Shifted<T> {
    /// Its storage (its new stored planes) and its account (messages, bytes, peak samples,
    /// rounds).
    Done(Vec<T>, [u64; 4]),
    /// The host started another phase first: this node's cluster was declared lost (a
    /// neighbour stopped in the middle of the shift).
    Abandoned(Start),
}

/// Node `node`'s plane shift from the `old` cuts to the `new` ones, in `cfg`'s machine. It
/// heartbeats to the host while it waits, as it does while rendering, and gives up when the
/// host starts another phase. `polls` counts its polls in the phase (the injected fault's
/// clock).
#[allow(
    clippy::too_many_arguments,
    reason = "one call site: the node's place and the cuts"
)]
fn shift<T: Sample>(
    world: &SimpleCommunicator,
    grid: &Grid,
    mut storage: Vec<T>,
    cfg: &RunConfig,
    node: u16,
    (old, new): (&Partition, &Partition),
    ghost: u32,
    (beat, polls): (&mut Instant, &mut u64),
) -> Result<Shifted<T>, RunError> {
    let layout = cfg.layout;
    let rounds = planes::rounds(old, new)?;
    let mut account = [0, 0, storage.len() as u64, rounds.len() as u64];
    for (r, (from, to)) in rounds.iter().enumerate() {
        let (mut shift, held) = planes::start(grid, layout, node, (from, to), ghost, &mut storage)?;
        account[2] = account[2].max(held as u64);
        let mut port = Counted::new(RoundPort {
            world,
            tag: TAG_SHIFT + r as i32,
            next: None,
            error: None,
        });
        while !shift.done() {
            injected_fault(cfg, *polls);
            *polls += 1;
            if let Some(start) = try_start(world) {
                return Ok(Shifted::Abandoned(start));
            }
            let progress = shift.poll(&mut port);
            if let Some(e) = port.port.error.take() {
                return Err(e);
            }
            heartbeat(world, beat);
            if progress == Progress::Idle {
                std::thread::sleep(Duration::from_micros(20));
            }
        }
        if shift.strays() > 0 {
            return Err(ShiftFailure::Strays { node }.into());
        }
        let stored = shift.stored();
        planes::keep(grid, &mut storage, &stored);
        account[0] += port.sent;
        account[1] += port.sent_bytes;
    }
    Ok(Shifted::Done(storage, account))
}

/// The injected fault (`--stop-node`), when it is this node's in this phase: once the node has
/// polled so many times it stops answering, as a hung node would, or its process exits, as a
/// crashed one would.
fn injected_fault(cfg: &RunConfig, polls: u64) {
    if cfg.schedule.stop.is_some_and(|(_, after)| polls >= after) {
        if cfg.schedule.crash {
            std::process::exit(3);
        }
        loop {
            std::thread::sleep(Duration::from_secs(1));
        }
    }
}

/// What the host tells a node rank before each phase of a view: a phase to run, or the view
/// is over for it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Start {
    /// Run node `node` of a machine of `clusters` clusters of `size` tracing the rows from
    /// `first` every `step`, its kernel messages under `tag`; `shift`: start on uniform slabs
    /// and shift to the cuts that follow ([`TAG_CUTS`]); `cuts`: load those cuts' slabs.
    Phase {
        tag: i32,
        clusters: u32,
        size: u32,
        rows: Rows,
        node: u16,
        cuts: bool,
        shift: bool,
    },
    /// This view is over for this rank (or it sits it out: its cluster lost a node).
    Over,
    /// The job is over: exit without finalising MPI (a lost rank would never join
    /// `MPI_Finalize`, and under `--enable-recovery` `mpirun` accepts such an exit).
    Exit,
}

impl Start {
    fn encode(self) -> [u32; 8] {
        match self {
            Start::Over => [0; 8],
            Start::Exit => [8, 0, 0, 0, 0, 0, 0, 0],
            Start::Phase {
                tag,
                clusters,
                size,
                rows,
                node,
                cuts,
                shift,
            } => [
                1 + u32::from(cuts) * 2 + u32::from(shift) * 4,
                tag as u32,
                clusters,
                size,
                rows.first(),
                rows.step(),
                u32::from(node),
                0,
            ],
        }
    }

    fn decode(words: [u32; 8]) -> Start {
        match words[0] & 1 {
            0 if words[0] & 8 != 0 => Start::Exit,
            0 => Start::Over,
            _ => Start::Phase {
                tag: words[1] as i32,
                clusters: words[2],
                size: words[3],
                rows: Rows::new(words[4], words[5]),
                node: words[6] as u16,
                cuts: words[0] & 2 != 0,
                shift: words[0] & 4 != 0,
            },
        }
    }
}

/// The kernel-message tag of phase `epoch`: phases never share one, so a message of an
/// abandoned phase (a lost cluster's) is never taken by a later one.
fn phase_tag(epoch: u32) -> i32 {
    TAG_MSG_BASE + (epoch % 30_000) as i32
}

/// Phases the host has begun, across views.
static EPOCH: AtomicU32 = AtomicU32::new(0);

/// Nodes (of the configured machine) lost in this run: they stay lost for every later view.
static LOST: Mutex<Vec<u16>> = Mutex::new(Vec::new());

/// What the host says before it ends a job that lost a node by aborting it: everything is
/// written by then, whatever `mpirun` does next.
pub const ENDING: &str = "voxcube: every output is written; a node was lost, so the host ends the job (MPI_Abort, status 0)";

/// Each rank's process, by rank, as the host learnt it at start-up: its pid and a hash of its
/// machine's name. The host fences a lost rank with it.
static PROCESSES: Mutex<Vec<Process>> = Mutex::new(Vec::new());

/// A rank's process: where it runs, so that the host can fence it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Process {
    pid: u32,
    machine: u64,
}

impl Process {
    /// This process.
    fn me() -> Self {
        use std::hash::{Hash, Hasher};
        // `DefaultHasher::new` has fixed keys: every rank hashes a name to the same value.
        let mut h = std::collections::hash_map::DefaultHasher::new();
        mpi::environment::processor_name()
            .unwrap_or_default()
            .hash(&mut h);
        Self {
            pid: std::process::id(),
            machine: h.finish(),
        }
    }
}

/// At start-up, on every rank: tell the host where this rank's process runs.
pub fn enroll(world: &SimpleCommunicator) {
    use mpi::collective::Root;
    let me = Process::me();
    let words = [u64::from(me.pid), me.machine];
    let root = world.process_at_rank(0);
    if world.rank() == 0 {
        let mut all = vec![0u64; 2 * world.size() as usize];
        root.gather_into_root(&words[..], &mut all[..]);
        *PROCESSES.lock().unwrap_or_else(PoisonError::into_inner) = all
            .chunks_exact(2)
            .map(|w| Process {
                pid: w[0] as u32,
                machine: w[1],
            })
            .collect();
    } else {
        root.gather_into(&words[..]);
    }
}

/// On a node rank, after its last view: wait for the host's word before finalising MPI, and
/// exit without finalising if the host says so ([`end`]). A rank in `MPI_Finalize` waits for
/// every other, a hung one too, and Open MPI 4.1 then fails to end the job when the host
/// aborts it (its `mpirun` crashes or hangs); a rank polling here is ended cleanly.
pub fn await_end(world: &SimpleCommunicator) {
    let mut beat = Instant::now();
    if receive_start(world, &mut beat) == Start::Exit {
        std::process::exit(0);
    }
}

/// On the host, after the last view: let every live node rank finalise, or end the job,
/// successfully, with everything written.
///
/// With a node lost, `MPI_Finalize` would wait for it forever, so the job ends one of two
/// ways. Under `mpirun --enable-recovery` (the only way a job outlives a dead rank) the host
/// fences each lost rank (kills its process, which must run on the host's machine), and every
/// rank then exits without finalising, which that `mpirun` accepts; it would hang on an
/// abort, and after a death `MPI_Finalize` sometimes never returns. Otherwise a lost rank is
/// hung, not dead (a death would have ended the job), and the host aborts the job with
/// status 0.
///
/// A rank of a lost cluster may be stuck where it cannot hear the host (in a plane shift's
/// send to the lost rank, which never completes); one that has not exited `patience` after
/// the host's word is fenced too.
pub fn end(world: &SimpleCommunicator, patience: Duration) {
    let lost: Vec<u16> = LOST.lock().unwrap_or_else(PoisonError::into_inner).clone();
    let live: Vec<i32> = (1..world.size())
        .filter(|&rank| !lost.iter().any(|&n| i32::from(n) + 1 == rank))
        .collect();
    if lost.is_empty() {
        live.iter()
            .for_each(|&rank| send_start(world, rank, Start::Over));
        return;
    }
    let fenced = |n: &u16| fence(i32::from(*n) + 1, "was lost");
    if recovery_enabled() && lost.iter().all(fenced) {
        live.iter()
            .for_each(|&rank| send_start(world, rank, Start::Exit));
        let deadline = Instant::now() + patience;
        for &rank in &live {
            while matches!(running(rank), Some(Some(_))) && Instant::now() < deadline {
                std::thread::sleep(Duration::from_millis(10));
            }
            fence(rank, "did not exit when told");
        }
        use std::io::Write;
        let _ = std::io::stdout().flush();
        std::process::exit(0);
    }
    eprintln!("{ENDING}");
    world.abort(0);
}

/// Whether `mpirun` runs this job with `--enable-recovery`: a rank's death does not end it.
fn recovery_enabled() -> bool {
    std::env::var("OMPI_MCA_orte_enable_recovery").is_ok_and(|v| v == "1" || v == "true")
}

/// Rank `rank`'s process, if it still runs: its pid; `None` when the host cannot tell (it
/// runs on another machine). A pid whose executable is not this one's is gone (its number
/// reused).
fn running(rank: i32) -> Option<Option<u32>> {
    let processes = PROCESSES.lock().unwrap_or_else(PoisonError::into_inner);
    let (me, other) = (processes.first()?, processes.get(rank as usize)?);
    if other.machine != me.machine {
        return None;
    }
    let exe = |pid: u32| std::fs::read_link(format!("/proc/{pid}/exe")).ok();
    let runs = exe(other.pid).is_some() && exe(other.pid) == exe(me.pid);
    Some(runs.then_some(other.pid))
}

/// Make sure rank `rank` runs no more: kill its process if it still runs; `false` when the
/// host cannot (the rank runs on another machine).
fn fence(rank: i32, why: &str) -> bool {
    match running(rank) {
        None => false,
        Some(None) => true,
        Some(Some(pid)) => {
            let Some(id) = rustix::process::Pid::from_raw(pid as i32) else {
                return false;
            };
            match rustix::process::kill_process(id, rustix::process::Signal::KILL) {
                Ok(()) => {
                    eprintln!("voxcube: warning: rank {rank} (pid {pid}) {why}, so it is stopped (SIGKILL) for the job to end");
                    true
                }
                // Gone in between.
                Err(rustix::io::Errno::SRCH) => true,
                Err(_) => false,
            }
        }
    }
}

/// On a node rank: serve `view`, phase by phase as the host starts them, until the host says
/// the view is over for this rank. A phase started while one runs ends the running one
/// unreported: its cluster was declared lost.
pub fn serve(
    world: &SimpleCommunicator,
    volume: &Volume,
    view: &View,
    cfg: &RunConfig,
) -> Result<(), RunError> {
    match &volume.data {
        VolumeData::U8(d) => serve_typed(world, volume, d, view, cfg),
        VolumeData::U16(d) => serve_typed(world, volume, d, view, cfg),
        VolumeData::I16(d) => serve_typed(world, volume, d, view, cfg),
        VolumeData::F32(d) => serve_typed(world, volume, d, view, cfg),
    }
}

fn serve_typed<T: Sample + Sync>(
    world: &SimpleCommunicator,
    volume: &Volume,
    data: &[T],
    view: &View,
    cfg: &RunConfig,
) -> Result<(), RunError> {
    let host = world.process_at_rank(0);
    let mut beat = Instant::now();
    host.send_with_tag(&[0u8][..], TAG_BEAT);
    let mut next = receive_start(world, &mut beat);
    loop {
        let Start::Phase {
            tag,
            clusters,
            size,
            rows,
            node,
            cuts,
            shift,
        } = next
        else {
            return Ok(());
        };
        let layout = Layout::new(clusters, size)
            .map_err(|e| RunError::Host(format!("the host's phase: {e}")))?
            .with_rows(rows);
        let mut by_node = vec![0i32; layout.nodes() as usize];
        host.receive_into_with_tag(&mut by_node[..], TAG_RANKS);
        let ranks = PhaseRanks { by_node };
        let cuts = match cuts {
            true => {
                let mut cuts = vec![0u32; size as usize + 1];
                host.receive_into_with_tag(&mut cuts[..], TAG_CUTS);
                Some(cuts)
            }
            false => None,
        };
        // The injected faults: the first stops its node in the configured machine, the second
        // a node of the configured machine (this rank's) in a re-trace (a phase of only some
        // rows: a machine of every row is a view's own).
        let me = (world.rank() - 1) as u16;
        let stop = match (layout == cfg.layout, rows == Rows::ALL) {
            (true, _) => cfg.schedule.stop.filter(|&(n, _)| n == node),
            (false, false) => cfg.schedule.retrace_stop.filter(|&(n, _)| n == me),
            (false, true) => None,
        };
        let phase = RunConfig {
            layout,
            cuts,
            shift,
            schedule: super::Schedule {
                stop,
                ..cfg.schedule
            },
            ..cfg.clone()
        };
        let at = (node, tag, &ranks);
        next = match serve_phase(world, volume, data, view, &phase, at, &mut beat)? {
            Some(start) => start,
            None => receive_start(world, &mut beat),
        };
    }
}

/// Wait for the host's next [`Start`], heartbeating meanwhile.
fn receive_start(world: &SimpleCommunicator, beat: &mut Instant) -> Start {
    loop {
        if let Some(start) = try_start(world) {
            return start;
        }
        heartbeat(world, beat);
        std::thread::sleep(Duration::from_micros(50));
    }
}

/// The host's next [`Start`], if it has come.
fn try_start(world: &SimpleCommunicator) -> Option<Start> {
    let (message, _) = world
        .process_at_rank(0)
        .immediate_matched_probe_with_tag(TAG_START)?;
    let mut words = [0u32; 8];
    message.matched_receive_into(&mut words[..]);
    Some(Start::decode(words))
}

/// Run node `node` of `cfg`'s machine for one phase until it has reported; `Some` start when
/// the host started another phase first (this node's cluster was declared lost).
fn serve_phase<T: Sample + Sync>(
    world: &SimpleCommunicator,
    volume: &Volume,
    data: &[T],
    view: &View,
    cfg: &RunConfig,
    (node, tag, ranks): (u16, i32, &PhaseRanks),
    beat: &mut Instant,
) -> Result<Option<Start>, RunError> {
    let began = Instant::now();
    let grid = volume.grid;
    let plan = Plan::new(&grid, view, cfg)?;
    let (view, flow, capacity, ghost) = (&*plan.view, plan.flow, plan.capacity, plan.ghost);
    let layout = cfg.layout;
    let (nx, size) = (grid.dims()[0], usize::from(layout.size()));
    let uniform = Partition::uniform(nx, size)?;
    let position = layout.place(node).1;
    let j = usize::from(position);
    let host = world.process_at_rank(0);
    // Balanced: the host's cuts, reached from the uniform slab by shifting planes (or, in a
    // re-trace, loaded at once).
    let mut polls = 0u64;
    let (partition, shifted) = match (&cfg.cuts, cfg.shift) {
        (Some(cuts), true) => {
            let partition = Partition::new(cuts, nx)?;
            let start = held(volume, data, stored_planes(&grid, uniform.planes(j), ghost))?;
            let shifted = shift(
                world,
                &grid,
                start.to_vec(),
                cfg,
                node,
                (&uniform, &partition),
                ghost,
                (beat, &mut polls),
            )?;
            let (storage, account) = match shifted {
                Shifted::Done(storage, account) => (storage, account),
                Shifted::Abandoned(start) => return Ok(Some(start)),
            };
            host.send_with_tag(&account[..], TAG_SHIFT_REPORT);
            (partition, Some(storage))
        }
        (Some(cuts), false) => (Partition::new(cuts, nx)?, None),
        (None, _) => (uniform, None),
    };
    let stored = stored_planes(&grid, partition.planes(j), ghost);
    // This node's slab only.
    let slab = Slab::new(
        grid,
        partition.planes(j),
        ghost,
        match &shifted {
            Some(storage) => storage.as_slice(),
            None => held(volume, data, stored.clone())?,
        },
    )?;
    // Depth bounds for this node's cluster's rows only, as its budget counts them.
    let rows = layout.cluster_rows(layout.place(node).0);
    let cells =
        crate::memory::storage::cell_range_bytes(view, cfg.skipping, volume.data.kind()) > 0;
    let hold = crate::memory::storage::holds_node_field(view, cfg.skipping);
    let (skipping, field, values, segments) = beating(world, beat, || {
        let ranges = volume.built.ranges(&slab, cells, 1);
        let skipping =
            crate::memory::storage::Skipping::build_for(&slab, &ranges, view, cfg.skipping, rows);
        let values = volume
            .held_range()
            .unwrap_or((f64::INFINITY, f64::NEG_INFINITY));
        let segments = crate::memory::segments::SegmentTable::of(view);
        (
            skipping,
            volume.built.field(&slab, hold, 1),
            values,
            segments,
        )
    });
    let slab = segments.apply(field.apply(skipping.apply(slab)));
    let resident = crate::memory::resident::peak().unwrap_or(0);
    let window = volume.held();
    let setup = [
        tag as u64,
        began.elapsed().as_micros() as u64,
        resident,
        u64::from(window.start),
        u64::from(window.end),
        values.0.to_bits(),
        values.1.to_bits(),
    ];
    host.send_with_tag(&setup[..], TAG_SETUP);
    let mut worker = node_worker(view, slab, &partition, cfg, node, flow)?;
    let mut port = MpiPort {
        world,
        ranks: ranks.clone(),
        tag,
        local: Default::default(),
        used: 0,
        peak: 0,
        capacity,
        overflow: false,
    };
    while !worker.has_reported() || port.pending() > 0 {
        injected_fault(cfg, polls);
        polls += 1;
        if let Some(start) = try_start(world) {
            return Ok(Some(start));
        }
        port.pump()?;
        if port.overflow {
            return Err(RunError::Buffer {
                bytes: capacity,
                size: usize::from(layout.size()),
                i_max: usize::from(flow.i_max),
                needed: 0,
                min_bytes: port.peak,
            });
        }
        let progress = worker.poll(&mut port);
        heartbeat(world, beat);
        if progress == Progress::Idle {
            std::thread::sleep(Duration::from_micros(20));
        }
    }
    Ok(None)
}

/// The samples of the X planes `planes` among those `volume` holds (`data`, its samples from
/// its first plane on): a rank may hold only the planes its slab stores.
fn held<'d, T>(volume: &Volume, data: &'d [T], planes: Range<u32>) -> Result<&'d [T], RunError> {
    let plane = volume.grid.plane_len();
    let at = |p: u32| p.checked_sub(volume.first).map(|p| p as usize * plane);
    at(planes.start)
        .zip(at(planes.end))
        .and_then(|(a, b)| data.get(a..b))
        .ok_or_else(|| {
            RunError::Host(format!(
                "this rank holds the volume's planes {:?}; its node needs {planes:?}",
                volume.held()
            ))
        })
}

/// `work` (a node's set-up: its value ranges, skipping structures and node field, seconds on
/// a big slab) on a thread beside this one, which heartbeats until it ends: a node that is
/// building is not silent, and is not declared lost for it. MPI is called from this thread
/// alone (the funnelled threading level `crate::commands::render` asks for).
fn beating<R: Send>(
    world: &SimpleCommunicator,
    beat: &mut Instant,
    work: impl FnOnce() -> R + Send,
) -> R {
    std::thread::scope(|scope| {
        let building = scope.spawn(work);
        while !building.is_finished() {
            heartbeat(world, beat);
            std::thread::sleep(Duration::from_millis(2));
        }
        match building.join() {
            Ok(built) => built,
            Err(panic) => std::panic::resume_unwind(panic),
        }
    })
}

/// Which world rank runs each node of a phase's machine: rank `n + 1` runs node `n` of the
/// configured machine; a re-trace's node `r` runs on the rank of the surviving node at its
/// ring position.
#[derive(Clone, Debug, PartialEq, Eq)]
struct PhaseRanks {
    by_node: Vec<i32>,
}

impl PhaseRanks {
    /// The rank of node `n`.
    fn rank(&self, n: u16) -> Option<i32> {
        self.by_node.get(usize::from(n)).copied()
    }

    /// The node a rank runs, if it runs one.
    fn node(&self, rank: i32) -> Option<u16> {
        self.by_node
            .iter()
            .position(|&r| r == rank)
            .map(|n| n as u16)
    }
}

/// On rank 0: be the host for `view`: collect pixels, tokens and statistics; declare lost any
/// node not heard from for the configured time (`RunConfig::lost_after`). With another
/// cluster to spare, the surviving clusters re-trace the lost cluster's unfinished rows, and
/// every later view runs on the clusters that lost no node; without, the run fails.
pub fn host(
    world: &SimpleCommunicator,
    volume: &Volume,
    view: &View,
    cfg: &RunConfig,
) -> Result<Distributed, RunError> {
    let grid = volume.grid;
    let layout = cfg.layout;
    let epoch = EPOCH.fetch_add(1, Ordering::Relaxed);
    let lost_before: Vec<u16> = LOST.lock().unwrap_or_else(PoisonError::into_inner).clone();
    let lost_clusters: Vec<u16> = lost_before.iter().map(|&n| layout.place(n).0).collect();
    let live: Vec<u16> = (0..layout.clusters())
        .filter(|c| !lost_clusters.contains(c))
        .collect();
    if live.is_empty() {
        return Err(RunError::Host(
            "every cluster lost a node in an earlier view: none is left to render".into(),
        ));
    }
    // A node lost in an earlier view: this view runs on the clusters that lost none.
    let (run_cfg, ranks) = match lost_before.is_empty() {
        true => (cfg.clone(), configured_ranks(layout)),
        false => survivors(cfg, &live, Rows::ALL)?,
    };
    let plan = Plan::new(&grid, view, &run_cfg)?;
    let mut phase = run_phase(world, &plan, &run_cfg, &ranks, phase_tag(epoch))?;
    // Ranks the phase left out sit this view out; the lost ones get nothing.
    let sitting_out = (1..world.size()).filter(|r| !ranks.contains(r));
    for rank in sitting_out.filter(|r| !lost_before.contains(&((r - 1) as u16))) {
        send_start(world, rank, Start::Over);
    }
    let (image, reports, recovered) = match phase.lost {
        None => {
            let (image, reports) = phase.host.finish().map_err(RunError::Host)?;
            (image, reports, None)
        }
        Some(lost) => {
            // The phase's node `n` runs on rank `ranks[n]`, which runs node `rank - 1` of the
            // configured machine: LOST keeps those.
            let configured = |n: u16| ranks.get(usize::from(n)).map(|&rank| (rank - 1) as u16);
            LOST.lock()
                .unwrap_or_else(PoisonError::into_inner)
                .extend(configured(lost.node));
            let retrace = |survivors_cfg: &RunConfig, survivors: &[u16]| {
                let by_node = ranks_of(run_cfg.layout, survivors_cfg.layout, survivors, &ranks);
                let plan = Plan::new(&grid, view, survivors_cfg)?;
                // Every re-trace has a tag of its own: one abandoned is never heard again.
                let tag = phase_tag(EPOCH.fetch_add(1, Ordering::Relaxed));
                let again = run_phase(world, &plan, survivors_cfg, &by_node, tag)?;
                if let Some(also) = again.lost {
                    let rank = by_node.get(usize::from(also.node));
                    LOST.lock()
                        .unwrap_or_else(PoisonError::into_inner)
                        .extend(rank.map(|&rank| (rank - 1) as u16));
                    return Err(recovery::lost_in_retrace(also.node));
                }
                Ok(Retraced {
                    host: again.host,
                    peaks: vec![plan.capacity; by_node.len()],
                    messages: [0; 9],
                    bytes: 0,
                    events: 0,
                    time: None,
                })
            };
            let mut done = recovery::complete(view, &run_cfg, lost, phase.host, &retrace)?;
            done.recovery.late = phase.late;
            phase.accounts.clear();
            (done.image, done.stats, Some(done.recovery))
        }
    };
    // The view is over: every rank not lost goes on to the next.
    let lost_now: Vec<u16> = LOST.lock().unwrap_or_else(PoisonError::into_inner).clone();
    for &rank in &ranks {
        if !lost_now.contains(&((rank - 1) as u16)) {
            send_start(world, rank, Start::Over);
        }
    }
    let shift = (!phase.accounts.is_empty()).then(|| {
        let all = phase.accounts.iter().flatten();
        ShiftReport {
            messages: all.clone().map(|a| a[0]).sum(),
            bytes: all.clone().map(|a| a[1]).sum(),
            seconds: None,
            per_node: Vec::new(),
            peak_samples: all.clone().map(|a| a[2] as usize).max().unwrap_or(0),
            rounds: all.map(|a| a[3] as u32).max().unwrap_or(0),
        }
    });
    let capacity = plan.capacity;
    let setups = phase.setups;
    let mut run = plan.finish(
        &run_cfg,
        &grid,
        volume.data.kind(),
        image,
        reports,
        &|_| capacity,
        &|_| Duration::ZERO,
        shift,
    );
    // Each rank set up its own node, side by side: the view waited for the slowest. After a
    // loss the re-trace's nodes set up again, and no figure is claimed.
    if recovered.is_none() {
        run.setup = setups
            .iter()
            .map(|s| s.map(|[micros, ..]| Duration::from_micros(micros)))
            .collect::<Option<Vec<_>>>()
            .and_then(|all| all.into_iter().max());
        for (node, setup) in run.nodes.iter_mut().zip(&setups) {
            node.resident_peak = setup.map(|[_, bytes, ..]| bytes).filter(|&b| b > 0);
            node.held = setup.map(|[_, _, first, end, ..]| first as u32..end as u32);
        }
        // Every node's planes together are the whole volume, whatever each rank held.
        run.data_range = setups
            .iter()
            .map(|s| s.map(|[.., lo, hi]| (f64::from_bits(lo), f64::from_bits(hi))))
            .collect::<Option<Vec<_>>>()
            .and_then(|all| {
                all.into_iter()
                    .reduce(|(a, b), (c, d)| (a.min(c), b.max(d)))
            });
    }
    run.recovery = match (recovered, lost_before.first()) {
        (Some(r), _) => Some(r),
        (None, Some(&node)) => Some(Recovery {
            node,
            cluster: layout.place(node).0,
            declared_after_events: None,
            declared_after_ms: None,
            rows: "every row (the node was lost in an earlier view)".into(),
            by: live,
            retraced: view.pixel_count(),
            dropped: 0,
            late: 0,
            also_lost: Vec::new(),
        }),
        (None, None) => None,
    };
    Ok(run)
}

/// The clusters `live` of `cfg`'s machine as a machine of their own tracing `rows`, and the
/// world rank of each of its nodes.
fn survivors(cfg: &RunConfig, live: &[u16], rows: Rows) -> Result<(RunConfig, Vec<i32>), RunError> {
    let layout = cfg.layout;
    let machine = Layout::new(live.len() as u32, u32::from(layout.size()))
        .map_err(|e| RunError::Host(format!("the surviving clusters: {e}")))?
        .with_rows(rows);
    Ok((
        RunConfig {
            layout: machine,
            ..cfg.clone()
        },
        ranks_of(layout, machine, live, &configured_ranks(layout)),
    ))
}

/// Rank `n + 1` runs node `n` of the configured machine.
fn configured_ranks(layout: Layout) -> Vec<i32> {
    (1..=layout.nodes() as i32).collect()
}

/// The world rank of each node of `machine`, whose cluster `k` is `layout`'s cluster
/// `kept[k]`: the node at each ring position runs where that cluster's node does, on rank
/// `ranks[n]` for `layout`'s node `n`.
fn ranks_of(layout: Layout, machine: Layout, kept: &[u16], ranks: &[i32]) -> Vec<i32> {
    (0..machine.nodes() as u16)
        .map(|r| {
            let (k, p) = machine.place(r);
            let c = kept.get(usize::from(k)).copied().unwrap_or(k);
            ranks
                .get(usize::from(layout.node(c, p)))
                .copied()
                .unwrap_or(0)
        })
        .collect()
}

/// Tell `rank` what to do next.
fn send_start(world: &SimpleCommunicator, rank: i32, start: Start) {
    world
        .process_at_rank(rank)
        .send_with_tag(&start.encode()[..], TAG_START);
}

/// What the host holds after one phase: its host, the node it declared lost, and each node's
/// plane-shift account.
struct PhaseEnd {
    host: crate::fabric::host::Host,
    lost: Option<LostNode>,
    /// Messages of the lost cluster that came after it was declared lost, dropped.
    late: u64,
    accounts: Vec<Option<[u64; 4]>>,
    /// Each node's set-up: microseconds, its rank's peak resident bytes, the planes it holds
    /// and their least and greatest value ([`TAG_SETUP`]).
    setups: Vec<Option<[u64; 6]>>,
}

/// Start `plan`'s machine (`cfg`) on `ranks` under `tag` and be its host until it ends: with
/// every pixel, or with a cluster declared lost (when another can re-trace its rows).
fn run_phase(
    world: &SimpleCommunicator,
    plan: &Plan<'_>,
    cfg: &RunConfig,
    ranks: &[i32],
    tag: i32,
) -> Result<PhaseEnd, RunError> {
    let layout = cfg.layout;
    let nodes = plan.nodes();
    let mut host = plan.host();
    let failed = RunError::Host;
    let size = usize::from(layout.size());
    let ranks = PhaseRanks {
        by_node: ranks.to_vec(),
    };
    if cfg.cuts.is_some() && plan.partition.slabs() != size {
        return Err(failed(format!("the cuts are not for clusters of {size}")));
    }
    for n in 0..nodes as u16 {
        let start = Start::Phase {
            tag,
            clusters: u32::from(layout.clusters()),
            size: size as u32,
            rows: layout.traced(),
            node: n,
            cuts: cfg.cuts.is_some(),
            shift: cfg.shift,
        };
        let rank = ranks
            .rank(n)
            .ok_or_else(|| failed(format!("no rank for node {n}")))?;
        send_start(world, rank, start);
        world
            .process_at_rank(rank)
            .send_with_tag(&ranks.by_node[..], TAG_RANKS);
        if let Some(cuts) = &cfg.cuts {
            world
                .process_at_rank(rank)
                .send_with_tag(&cuts[..], TAG_CUTS);
        }
    }
    let mut accounts: Vec<Option<[u64; 4]>> = vec![None; if cfg.shift { nodes } else { 0 }];
    let mut setups: Vec<Option<[u64; 6]>> = vec![None; nodes];
    // A set-up of this phase (a node of an abandoned one may have sent one never read).
    let of_phase =
        |m: [u64; 7]| (m[0] == tag as u64).then_some([m[1], m[2], m[3], m[4], m[5], m[6]]);
    let started = Instant::now();
    let mut heard = vec![Instant::now(); nodes];
    let mut lost: Option<LostNode> = None;
    let mut late = 0;
    let mut buf = [0u8; MAX_MSG_LEN];
    let send_collect = |host: &crate::fabric::host::Host| {
        let mut out = [0u8; MAX_MSG_LEN];
        let len = Msg::Collect.encode(&mut out);
        for n in (0..nodes).filter(|&n| host.expects_report(n)) {
            if let Some(rank) = ranks.rank(n as u16) {
                world.process_at_rank(rank).send_with_tag(&out[..len], tag);
            }
        }
    };
    while !host.done() {
        let mut any = false;
        while let Some((message, status)) = world
            .any_process()
            .immediate_matched_probe_with_tag(TAG_SHIFT_REPORT)
        {
            let mut account = [0u64; 4];
            message.matched_receive_into(&mut account[..]);
            if let Some(n) = ranks.node(status.source_rank()).map(usize::from) {
                if let Some(a) = accounts.get_mut(n) {
                    *a = Some(account);
                }
                heard[n] = Instant::now();
            }
            any = true;
        }
        while let Some((message, status)) = world
            .any_process()
            .immediate_matched_probe_with_tag(TAG_SETUP)
        {
            let mut setup = [0u64; 7];
            message.matched_receive_into(&mut setup[..]);
            if let Some(n) = ranks.node(status.source_rank()).map(usize::from) {
                if let (Some(slot), Some(setup)) = (setups.get_mut(n), of_phase(setup)) {
                    *slot = Some(setup);
                }
                heard[n] = Instant::now();
            }
            any = true;
        }
        while let Some((message, status)) = world
            .any_process()
            .immediate_matched_probe_with_tag(TAG_BEAT)
        {
            let mut beat = [0u8; 1];
            message.matched_receive_into(&mut beat[..]);
            if let Some(n) = ranks.node(status.source_rank()) {
                heard[usize::from(n)] = Instant::now();
            }
            any = true;
        }
        while let Some((message, status)) =
            world.any_process().immediate_matched_probe_with_tag(tag)
        {
            let from = status.source_rank();
            let len = status.count(u8::equivalent_datatype()) as usize;
            message.matched_receive_into(&mut buf[..]);
            any = true;
            let Some(n) = ranks.node(from) else {
                continue;
            };
            heard[usize::from(n)] = Instant::now();
            if lost.is_some_and(|l| layout.place(n).0 == l.cluster) {
                // A late message of a cluster declared lost: its rows are re-traced.
                late += 1;
                continue;
            }
            let msg =
                Msg::decode(&buf[..len.min(MAX_MSG_LEN)]).map_err(|error| RunError::Decode {
                    from: from as u16,
                    error,
                })?;
            if host.receive(msg).map_err(failed)? {
                send_collect(&host);
            }
        }
        let silent = (0..nodes).find(|&n| {
            host.expects_report(n) && !host.has_report(n) && heard[n].elapsed() > cfg.lost_after
        });
        if let Some(n) = silent {
            let cluster = layout.place(n as u16).0;
            if layout.clusters() < 2 || lost.is_some() {
                return Err(RunError::Lost {
                    node: ranks.rank(n as u16).map_or(n as u16, |r| (r - 1) as u16),
                    waiting: 0,
                    missing: host.missing(),
                    rows: host.missing_rows(),
                });
            }
            lost = Some(LostNode {
                node: ranks.rank(n as u16).map_or(n as u16, |r| (r - 1) as u16),
                cluster,
                events: None,
                after: Some(started.elapsed()),
            });
            if host.declare_lost(cluster).map_err(failed)? {
                send_collect(&host);
            }
        }
        if !any {
            std::thread::sleep(Duration::from_micros(50));
        }
    }
    // A node that reported its statistics sent its shift account before them: waiting for
    // it cannot hang. A lost cluster's nodes owe none.
    for (n, account) in accounts.iter_mut().enumerate() {
        if account.is_none() && host.expects_report(n) {
            let mut a = [0u64; 4];
            if let Some(rank) = ranks.rank(n as u16) {
                world
                    .process_at_rank(rank)
                    .receive_into_with_tag(&mut a[..], TAG_SHIFT_REPORT);
            }
            *account = Some(a);
        }
    }
    // Likewise its set-up, sent before anything it traced.
    for (n, setup) in setups.iter_mut().enumerate() {
        let Some(rank) = ranks.rank(n as u16).filter(|_| host.expects_report(n)) else {
            continue;
        };
        while setup.is_none() {
            let mut m = [0u64; 7];
            world
                .process_at_rank(rank)
                .receive_into_with_tag(&mut m[..], TAG_SETUP);
            *setup = of_phase(m);
        }
    }
    Ok(PhaseEnd {
        host,
        lost,
        late,
        accounts,
        setups,
    })
}
