//! The MPI fabric (cargo feature `mpi`): rank 0 is the host, rank `r` runs node `r − 1`, each
//! with the same `Worker` behind an MPI [`Port`]. Launch with `mpirun -np <P+1>`.
//!
//! Sends are standard-mode MPI sends of at most a few hundred bytes, far below Open MPI's
//! eager limit. So they complete locally without waiting for the receiver; ack-counter flow
//! control bounds how many are outstanding, exactly as on the other fabrics. Each node keeps
//! its received messages in per-class queues with the simulator's byte capacity: exceeding it
//! would be an error, never silent.
//!
//! Views run one after another; a barrier ends each, so no message of the next view reaches a
//! host still ending this one.
//!
//! Balanced views (`RunConfig::shift`): the host broadcasts the cuts it chose, and every node
//! starts on its uniform slab and shifts planes to its neighbours by slab-plane messages
//! before rendering, round `r` under its own tag ([`TAG_SHIFT`]` + r`), so a chunk sent by a
//! node already in the next round waits in MPI's queue until its receiver gets there: no
//! barrier is needed. Each node then tells the host what it sent.
//!
//! Faults: every node sends the host a heartbeat every [`HEARTBEAT`]. A node the host has not
//! heard from for [`TIMEOUT`], before it reported, is declared lost. The host names it and the
//! pixels it lacks, and the run fails (the caller aborts the job, so no rank hangs). A rank that
//! dies outright is caught by `mpirun` itself, which ends the whole job with an error. The test
//! hook `VOXCUBE_MPI_STOP=<rank>:<milliseconds>[:exit]` makes a rank hang (or die) mid-render.

use super::harness::{node_worker, Plan};
use super::shift::{self as planes, Counted, ShiftFailure, ShiftReport};
use super::{Distributed, RunConfig, RunError};
use crate::dataset::{Volume, VolumeData};
use mpi::collective::{CommunicatorCollectives, Root};
use mpi::datatype::Equivalence;
use mpi::point_to_point::{Destination, Source};
use mpi::topology::{Communicator, SimpleCommunicator};
use std::collections::VecDeque;
use std::time::{Duration, Instant};
use voxcube_kernel::node::flow::Class;
use voxcube_kernel::node::msg::{Msg, MAX_MSG_LEN};
use voxcube_kernel::node::partition::Partition;
use voxcube_kernel::node::port::{Dest, Port};
use voxcube_kernel::node::topology::Layout;
use voxcube_kernel::node::worker::Progress;
use voxcube_kernel::trace::view::View;
use voxcube_kernel::volume::grid::Grid;
use voxcube_kernel::volume::sample::Sample;
use voxcube_kernel::volume::slab::{stored_planes, Slab};

/// Tag of kernel messages.
const TAG_MSG: i32 = 1;
/// Tag of heartbeats.
const TAG_BEAT: i32 = 2;
/// Tag of a node's account of its plane shift: messages, bytes, peak samples, rounds.
const TAG_SHIFT_REPORT: i32 = 3;
/// Tag of the plane shift's first round; round `r` uses `TAG_SHIFT + r`.
pub const TAG_SHIFT: i32 = 16;
/// How often a node tells the host it is alive.
pub const HEARTBEAT: Duration = Duration::from_millis(250);
/// How long the host waits for a node before declaring it lost.
pub const TIMEOUT: Duration = Duration::from_secs(3);

struct MpiPort<'w> {
    world: &'w SimpleCommunicator,
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
            .immediate_matched_probe_with_tag(TAG_MSG)
        {
            let from = status.source_rank();
            let len = status.count(u8::equivalent_datatype()) as usize;
            message.matched_receive_into(&mut buf[..]);
            let msg =
                Msg::decode(&buf[..len.min(MAX_MSG_LEN)]).map_err(|error| RunError::Decode {
                    from: from as u16,
                    error,
                })?;
            let source = if from == 0 {
                Dest::Host
            } else {
                Dest::Node((from - 1) as u16)
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
            Dest::Node(n) => i32::from(n) + 1,
        };
        let mut buf = [0u8; MAX_MSG_LEN];
        let len = msg.encode(&mut buf);
        self.world
            .process_at_rank(rank)
            .send_with_tag(&buf[..len], TAG_MSG);
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

/// Node `node`'s plane shift from the `old` cuts to the `new` ones: its storage (its new
/// stored planes) and its account (messages, bytes, peak samples, rounds). It heartbeats to
/// the host while it waits, as it does while rendering.
#[allow(
    clippy::too_many_arguments,
    reason = "one call site: the node's place and the cuts"
)]
fn shift<T: Sample>(
    world: &SimpleCommunicator,
    grid: &Grid,
    data: &[T],
    layout: Layout,
    node: u16,
    (old, new): (&Partition, &Partition),
    ghost: u32,
    beat: &mut Instant,
) -> Result<(Vec<T>, [u64; 4]), RunError> {
    let mut storage = planes::load(grid, data, layout, old, ghost, node);
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
    Ok((storage, account))
}

/// The test hook: `VOXCUBE_MPI_STOP=<rank>:<ms>[:exit]` stops that rank after `ms`
/// milliseconds, hanging (stops answering) or, with `:exit`, exiting at once (dies).
fn stop_hook(rank: i32) -> Option<(Duration, bool)> {
    let spec = std::env::var("VOXCUBE_MPI_STOP").ok()?;
    let mut parts = spec.split(':');
    let r: i32 = parts.next()?.trim().parse().ok()?;
    let ms: u64 = parts.next()?.trim().parse().ok()?;
    let die = parts.next().is_some_and(|p| p.trim() == "exit");
    (r == rank).then_some((Duration::from_millis(ms), die))
}

/// On a node rank: run this rank's worker for `view` until it has reported to the host.
pub fn serve(
    world: &SimpleCommunicator,
    volume: &Volume,
    view: &View,
    cfg: &RunConfig,
) -> Result<(), RunError> {
    match &volume.data {
        VolumeData::U8(d) => serve_typed(world, volume, d, view, cfg),
        VolumeData::U16(d) => serve_typed(world, volume, d, view, cfg),
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
    let grid = volume.grid;
    let plan = Plan::new(&grid, view, cfg)?;
    let (view, flow, capacity, ghost) = (&*plan.view, plan.flow, plan.capacity, plan.ghost);
    let layout = cfg.layout;
    let rank = world.rank();
    let node = (rank - 1) as u16;
    let (nx, size) = (grid.dims()[0], usize::from(layout.size()));
    let uniform = Partition::uniform(nx, size)?;
    let position = layout.place(node).1;
    let j = usize::from(position);
    let plane = grid.plane_len();
    let mut beat = Instant::now();
    let host = world.process_at_rank(0);
    host.send_with_tag(&[0u8][..], TAG_BEAT);
    // Balanced: the host's cuts, reached from the uniform slab by shifting planes.
    let (partition, shifted) = if cfg.shift {
        let mut cuts = vec![0u32; size + 1];
        host.broadcast_into(&mut cuts[..]);
        let partition = Partition::new(&cuts, nx)?;
        let (storage, account) = shift(
            world,
            &grid,
            data,
            layout,
            node,
            (&uniform, &partition),
            ghost,
            &mut beat,
        )?;
        host.send_with_tag(&account[..], TAG_SHIFT_REPORT);
        (partition, Some(storage))
    } else {
        (uniform, None)
    };
    let stored = stored_planes(&grid, partition.planes(j), ghost);
    // This node's slab only.
    let slab = Slab::new(
        grid,
        partition.planes(j),
        ghost,
        match &shifted {
            Some(storage) => storage.as_slice(),
            None => &data[stored.start as usize * plane..stored.end as usize * plane],
        },
    )?;
    // Depth bounds for this node's cluster's rows only, as its budget counts them.
    let rows = layout.cluster_rows(layout.place(node).0);
    let skipping = crate::storage::Skipping::build_for(&slab, view, cfg.skipping, rows);
    let slab = skipping.apply(slab);
    let mut worker = node_worker(view, slab, &partition, cfg, node, flow)?;
    let mut port = MpiPort {
        world,
        local: Default::default(),
        used: 0,
        peak: 0,
        capacity,
        overflow: false,
    };
    let start = Instant::now();
    let stop = stop_hook(rank);
    while !worker.has_reported() || port.pending() > 0 {
        if let Some((after, die)) = stop {
            if start.elapsed() >= after {
                if die {
                    // The test hook: die, as a crashed node would.
                    std::process::exit(3);
                }
                // The test hook: stop answering, as a hung node would.
                loop {
                    std::thread::sleep(Duration::from_secs(1));
                }
            }
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
        heartbeat(world, &mut beat);
        if progress == Progress::Idle {
            std::thread::sleep(Duration::from_micros(20));
        }
    }
    // Views are separated: no node starts the next view before the host has ended this one.
    world.barrier();
    Ok(())
}

/// On rank 0: be the host for `view`: collect pixels, tokens and statistics; declare lost any
/// node not heard from for [`TIMEOUT`].
pub fn host(
    world: &SimpleCommunicator,
    volume: &Volume,
    view: &View,
    cfg: &RunConfig,
) -> Result<Distributed, RunError> {
    let grid = volume.grid;
    let plan = Plan::new(&grid, view, cfg)?;
    let layout = cfg.layout;
    let nodes = plan.nodes();
    let mut host = plan.host();
    let failed = RunError::Host;
    let size = usize::from(layout.size());
    // Balanced: every node takes the cuts, and shifts to them before rendering.
    if let (Some(cuts), true) = (&cfg.cuts, cfg.shift) {
        if plan.partition.slabs() != size {
            return Err(failed(format!(
                "{} cuts for clusters of {size}",
                cuts.len()
            )));
        }
        let mut cuts = cuts.clone();
        world.process_at_rank(0).broadcast_into(&mut cuts[..]);
    }
    let mut accounts: Vec<Option<[u64; 4]>> = vec![None; if cfg.shift { nodes } else { 0 }];
    let mut heard = vec![Instant::now(); nodes];
    let mut buf = [0u8; MAX_MSG_LEN];
    while !host.done() {
        let mut any = false;
        while let Some((message, status)) = world
            .any_process()
            .immediate_matched_probe_with_tag(TAG_SHIFT_REPORT)
        {
            let mut account = [0u64; 4];
            message.matched_receive_into(&mut account[..]);
            let n = (status.source_rank() - 1) as usize;
            if let Some(a) = accounts.get_mut(n) {
                *a = Some(account);
            }
            if let Some(h) = heard.get_mut(n) {
                *h = Instant::now();
            }
            any = true;
        }
        while let Some((message, status)) = world
            .any_process()
            .immediate_matched_probe_with_tag(TAG_BEAT)
        {
            let mut beat = [0u8; 1];
            message.matched_receive_into(&mut beat[..]);
            if let Some(h) = heard.get_mut((status.source_rank() - 1) as usize) {
                *h = Instant::now();
            }
            any = true;
        }
        while let Some((message, status)) = world
            .any_process()
            .immediate_matched_probe_with_tag(TAG_MSG)
        {
            let from = status.source_rank();
            let len = status.count(u8::equivalent_datatype()) as usize;
            message.matched_receive_into(&mut buf[..]);
            if let Some(h) = heard.get_mut((from - 1) as usize) {
                *h = Instant::now();
            }
            any = true;
            let msg =
                Msg::decode(&buf[..len.min(MAX_MSG_LEN)]).map_err(|error| RunError::Decode {
                    from: from as u16,
                    error,
                })?;
            if host.receive(msg).map_err(failed)? {
                let mut out = [0u8; MAX_MSG_LEN];
                let len = Msg::Collect.encode(&mut out);
                for n in 0..nodes {
                    world
                        .process_at_rank(n as i32 + 1)
                        .send_with_tag(&out[..len], TAG_MSG);
                }
            }
        }
        if let Some(n) = (0..nodes).find(|&n| !host.has_report(n) && heard[n].elapsed() > TIMEOUT) {
            return Err(RunError::Lost {
                node: n as u16,
                waiting: 0,
                missing: host.missing(),
                rows: host.missing_rows(),
            });
        }
        if !any {
            std::thread::sleep(Duration::from_micros(50));
        }
    }
    let (image, reports) = host.finish().map_err(failed)?;
    // A node that reported its statistics sent its shift account before them: waiting for
    // it cannot hang.
    for (n, account) in accounts.iter_mut().enumerate() {
        if account.is_none() {
            let mut a = [0u64; 4];
            world
                .process_at_rank(n as i32 + 1)
                .receive_into_with_tag(&mut a[..], TAG_SHIFT_REPORT);
            *account = Some(a);
        }
    }
    let shift = (!accounts.is_empty()).then(|| {
        let all = accounts.iter().flatten();
        ShiftReport {
            messages: all.clone().map(|a| a[0]).sum(),
            bytes: all.clone().map(|a| a[1]).sum(),
            seconds: None,
            per_node: Vec::new(),
            peak_samples: all.clone().map(|a| a[2] as usize).max().unwrap_or(0),
            rounds: all.map(|a| a[3] as u32).max().unwrap_or(0),
        }
    });
    // Views are separated: every node waits here until the host has ended this view.
    world.barrier();
    let capacity = plan.capacity;
    Ok(plan.finish(
        cfg,
        &grid,
        volume.data.kind().bytes(),
        image,
        reports,
        &|_| capacity,
        &|_| Duration::ZERO,
        shift,
    ))
}
