//! A porting base for multicomputer boards: two nodes and a host, every byte of their state
//! in `static` storage and no allocator anywhere, talking through in-memory "link registers"
//! (single-producer single-consumer FIFOs) as a board's link driver would. On a real board:
//! - `VOLUME` is the slab loaded from disk;
//! - the FIFOs are the link hardware;
//! - the host side runs on the front-end.
//!
//! Nothing else changes. See PORTING.md. Run: `cargo run -p voxcube-kernel --example board`.

use heapless::spsc::{Consumer, Producer, Queue};
use heapless::Deque;
use static_cell::StaticCell;
use voxcube_kernel::counters::Counters;
use voxcube_kernel::node::flow::{Class, FlowControl, CLASSES};
use voxcube_kernel::node::msg::{Msg, MAX_MSG_LEN};
use voxcube_kernel::node::partition::Partition;
use voxcube_kernel::node::port::{Dest, Port};
use voxcube_kernel::node::topology::Layout;
use voxcube_kernel::node::worker::{Generation, Place, Setup, Worker, RAYS_PER_POLL};
use voxcube_kernel::optics::surface::IsoSurface;
use voxcube_kernel::trace::camera::{Camera, Projection};
use voxcube_kernel::trace::pixel::rgba8;
use voxcube_kernel::trace::tracer::trace_pixel;
use voxcube_kernel::trace::view::{Mode, View, ViewSpec};
use voxcube_kernel::volume::grid::{Grid, Model};
use voxcube_kernel::volume::slab::{stored_planes, Slab};
use voxcube_kernel::Vec3;

/// The volume: `N³` samples of a ball, built at compile time, plane-major.
const N: usize = 24;
static VOLUME: [u8; N * N * N] = ball();

const fn ball() -> [u8; N * N * N] {
    let mut v = [0u8; N * N * N];
    let mut i = 0;
    while i < N * N * N {
        // Plane-major: x slowest, then z, then y.
        let (x, z, y) = (i / (N * N), i / N % N, i % N);
        let c = N / 2;
        let (dx, dy, dz) = (x.abs_diff(c), y.abs_diff(c), z.abs_diff(c));
        let d2 = dx * dx + dy * dy + dz * dz;
        v[i] = if d2 < 64 {
            200
        } else if d2 < 100 {
            90
        } else {
            0
        };
        i += 1;
    }
    v
}

const W: usize = 32;
const H: usize = 24;
/// One encoded message and its length: what a link register holds.
type Frame = ([u8; MAX_MSG_LEN], u16);
/// A link: 32 frames deep.
type Link = Queue<Frame, 32>;
/// The worker as a board holds it: continuation queues, pixel records, outbox, and ack
/// counters for its ring of two.
type BoardWorker = Worker<'static, u8, 8, 16, 8, 2>;

static VIEW: StaticCell<View> = StaticCell::new();
static PARTITION: StaticCell<Partition> = StaticCell::new();
static WORKERS: [StaticCell<BoardWorker>; 2] = [StaticCell::new(), StaticCell::new()];
static LINKS: [StaticCell<Link>; 6] = [const { StaticCell::new() }; 6];
static IMAGE: StaticCell<[[u8; 4]; W * H]> = StaticCell::new();

/// A board's side of its links: to and from the other board, to and from the host.
struct LinkPort {
    peer: u16,
    to_peer: Producer<'static, Frame, 32>,
    from_peer: Consumer<'static, Frame, 32>,
    to_host: Producer<'static, Frame, 32>,
    from_host: Consumer<'static, Frame, 32>,
    inbox: [Deque<(Dest, Msg), 16>; 7],
}

impl LinkPort {
    /// Move arrived frames into the class queues (the link driver's receive interrupt).
    fn pump(&mut self) {
        let peer = self.peer;
        for (from, rx) in [
            (Dest::Node(peer), &mut self.from_peer),
            (Dest::Host, &mut self.from_host),
        ] {
            while let Some((bytes, len)) = rx.peek().copied() {
                let Ok(msg) = Msg::decode(&bytes[..usize::from(len)]) else {
                    let _ = rx.dequeue();
                    continue;
                };
                if self.inbox[msg.class().index()]
                    .push_back((from, msg))
                    .is_err()
                {
                    break; // Full: leave it in the link register; flow control keeps this rare.
                }
                let _ = rx.dequeue();
            }
        }
    }
}

impl Port for LinkPort {
    fn try_send(&mut self, to: Dest, msg: Msg) -> Result<(), Msg> {
        let mut bytes = [0u8; MAX_MSG_LEN];
        let len = msg.encode(&mut bytes) as u16;
        let tx = if to == Dest::Host {
            &mut self.to_host
        } else {
            &mut self.to_peer
        };
        tx.enqueue((bytes, len)).map_err(|_| msg)
    }

    fn peek(&mut self, class: Class) -> Option<&Msg> {
        self.pump();
        self.inbox[class.index()].front().map(|(_, m)| m)
    }

    fn try_recv(&mut self, class: Class) -> Option<(Dest, Msg)> {
        self.pump();
        self.inbox[class.index()].pop_front()
    }

    fn pending(&self) -> usize {
        CLASSES.iter().map(|c| self.inbox[c.index()].len()).sum()
    }
}

fn main() {
    let grid = match Grid::new([N as u32; 3], Vec3::ONE) {
        Ok(g) => g,
        Err(e) => return eprintln!("grid: {e}"),
    };
    let c = Vec3::splat((N - 1) as f32 / 2.0);
    let Ok(camera) = Camera::look_at(
        c + Vec3::new(40.0, 25.0, 30.0),
        c,
        Vec3::Y,
        Projection::Orthographic { width: 36.0 },
    ) else {
        return eprintln!("camera");
    };
    let mut surfaces = heapless::Vec::new();
    let _ = surfaces.push(IsoSurface {
        iso: 150.0,
        color: Vec3::new(1.0, 0.7, 0.3),
        transparency: 0.0,
    });
    let _ = surfaces.push(IsoSurface {
        iso: 60.0,
        color: Vec3::new(0.3, 0.5, 1.0),
        transparency: 0.6,
    });
    let spec = ViewSpec {
        width: W as u32,
        height: H as u32,
        camera,
        model: Model::Cell,
        dt: 0.5,
        gradient_distance: 1.0,
        mode: Mode::Surfaces(surfaces),
        shading: Some(Default::default()),
        lights: heapless::Vec::new(),
        background: Vec3::ZERO,
        cutoff: 1.0 / 512.0,
        max_depth: 4,
        refine_steps: 2,
        accuracy: voxcube_kernel::trace::view::Accuracy::Exact,
        compositing: voxcube_kernel::trace::view::Compositing::Sampled,
    };
    let view: &'static View = match View::new(spec, &grid) {
        Ok(v) => VIEW.init(v),
        Err(e) => return eprintln!("view: {e}"),
    };
    let Ok(partition) = Partition::uniform(N as u32, 2) else {
        return eprintln!("partition");
    };
    let partition: &'static Partition = PARTITION.init(partition);
    let Ok(layout) = Layout::new(1, 2) else {
        return eprintln!("layout");
    };
    let flow = FlowControl {
        enabled: true,
        i_max: 8,
        ack_batch: 2,
    };
    let plane = grid.plane_len();
    let [ab, ba, a_host, b_host, host_a, host_b] = LINKS.each_ref().map(|l| l.init(Queue::new()));
    let (to_b, from_a) = ab.split();
    let (to_a, from_b) = ba.split();
    let (a_up, host_from_a) = a_host.split();
    let (b_up, host_from_b) = b_host.split();
    let (mut host_to_a, a_down) = host_a.split();
    let (mut host_to_b, b_down) = host_b.split();
    let mut ports = [
        LinkPort {
            peer: 1,
            to_peer: to_b,
            from_peer: from_b,
            to_host: a_up,
            from_host: a_down,
            inbox: Default::default(),
        },
        LinkPort {
            peer: 0,
            to_peer: to_a,
            from_peer: from_a,
            to_host: b_up,
            from_host: b_down,
            inbox: Default::default(),
        },
    ];
    let mut workers: [&'static mut BoardWorker; 2] = [0u16, 1].map(|j| {
        let planes = partition.planes(usize::from(j));
        let stored = stored_planes(&grid, planes.clone(), view.ghost_planes());
        let data: &'static [u8] =
            &VOLUME[stored.start as usize * plane..stored.end as usize * plane];
        let slab = Slab::new(grid, planes, view.ghost_planes(), data).ok();
        let checked = slab.and_then(|slab| {
            BoardWorker::check(Setup {
                view,
                slab,
                partition,
                place: Place {
                    layout,
                    cluster: 0,
                    position: j,
                },
                generation: Generation::Distributed,
                flow,
                rays_per_poll: RAYS_PER_POLL,
            })
            .ok()
        });
        // Built in its static cell, not on a stack that may be smaller than a worker.
        match checked {
            Some(c) => WORKERS[usize::from(j)].init_with(|| Worker::new(c)),
            None => panic!("board {j}: the example's fixed configuration is valid"),
        }
    });
    // The host: pixels and the token in, then the request for statistics, then statistics.
    let image = IMAGE.init([[0; 4]; W * H]);
    let (mut received, mut token, mut reports, mut asked) = (0usize, false, 0usize, false);
    let mut host_rx = [host_from_a, host_from_b];
    while reports < 2 || received < W * H {
        for (w, p) in workers.iter_mut().zip(&mut ports) {
            w.poll(p);
        }
        for rx in &mut host_rx {
            while let Some((bytes, len)) = rx.dequeue() {
                match Msg::decode(&bytes[..usize::from(len)]) {
                    Ok(Msg::Pixels(set)) => {
                        for &(pixel, rgba) in set.entries() {
                            image[pixel as usize] = rgba;
                            received += 1;
                        }
                    }
                    Ok(Msg::Token { .. }) => token = true,
                    Ok(Msg::Stats(_)) => reports += 1,
                    other => eprintln!("host: unexpected {other:?}"),
                }
            }
        }
        if token && !asked {
            let mut bytes = [0u8; MAX_MSG_LEN];
            let len = Msg::Collect.encode(&mut bytes) as u16;
            asked =
                host_to_a.enqueue((bytes, len)).is_ok() && host_to_b.enqueue((bytes, len)).is_ok();
        }
    }
    // Check against the in-process tracer over the whole volume.
    let Ok(whole) = Slab::whole(grid, &VOLUME[..]) else {
        return eprintln!("slab");
    };
    let mut counters = Counters::default();
    let same =
        (0..W * H).all(|p| rgba8(trace_pixel(view, &whole, p as u32, &mut counters)) == image[p]);
    let lit = image.iter().filter(|p| p[..3] != [0, 0, 0]).count();
    println!("two boards rendered {W}x{H} ({lit} pixels lit) through link registers, all state static: identical to one node: {same}");
    println!(
        "static worker state: {} bytes per board",
        size_of::<BoardWorker>()
    );
    if !same {
        std::process::exit(1);
    }
}
