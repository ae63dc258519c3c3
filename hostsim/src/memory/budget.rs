//! The memory of one node: its slab with ghost planes, its receive buffer, the worker's
//! fixed-capacity state, and a fixed allowance for code and stack. All of it must fit the
//! machine profile's node memory (4 MiB on the nCUBE 2).
//!
//! The host checks this for every node of every view before any view renders. A configuration
//! that does not fit is refused, with the bytes needed and available and the smallest cluster
//! size that would fit. After a simulated run each node's measured high-water mark (the same
//! parts, with the buffer at its real peak) is checked against the same budget; exceeding it
//! is an error, never silent.

use crate::profile::{MachineProfile, BUILT_IN};
use std::fmt;
use std::sync::OnceLock;
use voxcube_kernel::node::partition::Partition;
use voxcube_kernel::volume::grid::Grid;
use voxcube_kernel::volume::slab::stored_planes;

/// A node's worker on the host's fabrics: continuations per direction, pixel records, outbox,
/// and ack counters for the largest ring. Defined with the budget that counts its bytes; the
/// fabrics' harness builds it.
pub type NodeWorker<'a, T> = voxcube_kernel::node::worker::Worker<'a, T, 32, 64, 16>;

/// Bytes set aside on every node for code and stack.
pub const CODE_AND_STACK: usize = 256 * 1024;

/// A machine's node, as far as memory goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Profile {
    /// Name, as `--machine` takes it.
    pub name: &'static str,
    /// Memory of one node, bytes.
    pub node_memory: usize,
}

impl Profile {
    /// The node memory of a shipped machine profile (`hostsim/profiles/<name>.toml`), read
    /// once: the TOML file is the one place it is written.
    pub fn builtin(name: &str) -> Option<Profile> {
        static SHIPPED: OnceLock<Vec<Profile>> = OnceLock::new();
        let shipped = SHIPPED.get_or_init(|| {
            BUILT_IN
                .iter()
                .filter_map(|(n, _)| {
                    MachineProfile::load(n).ok().map(|p| Profile {
                        name: n,
                        node_memory: p.node_memory,
                    })
                })
                .collect()
        });
        shipped.iter().find(|p| p.name == name).copied()
    }

    /// This machine as `nodes` nodes that run in this process (the direct, sim and threads
    /// fabrics): its physical memory ([`crate::memory::resident::physical`]) shared evenly
    /// among them, as a program with one thread per core would have it. `None` where the
    /// system does not say how much it has.
    pub fn host(nodes: u32) -> Option<Profile> {
        crate::memory::resident::physical().map(|bytes| Profile::sharing(bytes, nodes))
    }

    /// `bytes` of one machine shared evenly by `nodes` nodes (one at least): [`Profile::host`]
    /// of a machine of `bytes`.
    pub fn sharing(bytes: u64, nodes: u32) -> Profile {
        let each = bytes / u64::from(nodes.max(1));
        Profile {
            name: "host",
            node_memory: usize::try_from(each).unwrap_or(usize::MAX),
        }
    }

    /// The nCUBE 2 of the paper (4 MiB per node).
    pub fn ncube2() -> Profile {
        // The shipped file is checked by a test; a broken one is a build defect.
        #[allow(
            clippy::expect_used,
            reason = "the shipped profile is valid; a test checks it"
        )]
        Profile::builtin("ncube2").expect("the shipped ncube2 profile is valid")
    }
}

/// The worker's fixed-capacity state in the simulator and threads fabrics, and the view it
/// traces, bytes. The view keeps room for the fast tier's classification table in either
/// tier, so a tier never changes what a node must hold.
pub fn worker_bytes() -> usize {
    size_of::<NodeWorker<'static, u8>>() + size_of::<voxcube_kernel::trace::view::View>()
}

/// Bytes of the structures a slab owning planes `owned` of `grid` keeps beside its planes (and
/// ghost planes of `needs`):
/// its min/max blocks, with the leap maps of `needs` (a byte per block each,
/// [`voxcube_kernel::skip::leaps`]), its view's cell mask ([`voxcube_kernel::skip::cells`])
/// and which blocks keep a cell (a bit each, [`voxcube_kernel::skip::blocks::kept_bits`]),
/// its cell leap maps (a byte per cell each, [`voxcube_kernel::skip::cell_leaps`]), its depth
/// bounds ([`voxcube_kernel::skip::depths`]), its node field
/// ([`voxcube_kernel::volume::nodes`]), its cells' value ranges
/// ([`voxcube_kernel::skip::cell_ranges`]) and its view's pre-integration table
/// ([`voxcube_kernel::optics::segments`]).
pub fn structure_bytes(grid: &Grid, owned: std::ops::Range<u32>, needs: ViewNeeds) -> usize {
    let stored = stored_planes(grid, owned.clone(), needs.ghost);
    needs.node_bytes * voxcube_kernel::volume::nodes::len_for(grid, owned)
        + voxcube_kernel::skip::blocks::extent_for(grid, stored.clone()).2
            * (size_of::<voxcube_kernel::skip::blocks::Range>()
                + needs.maps * size_of::<u8>()
                + size_of::<voxcube_kernel::skip::cells::CellMask>()
                + needs.cell_maps * voxcube_kernel::skip::cell_leaps::PER_BLOCK
                + needs.cell_ranges)
        + voxcube_kernel::skip::blocks::kept_bytes(grid, stored)
        + needs.depths
        + needs.segments
}

/// What a view asks of every node's memory besides its planes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ViewNeeds {
    /// Ghost planes each side of a slab.
    pub ghost: u32,
    /// Leap maps: one per octant of ray directions the view takes (one for a parallel
    /// projection without shadows, at most eight).
    pub maps: usize,
    /// Cell leap maps: none is needed, a node holds them where they fit
    /// ([`crate::run::render::node_skipping`]).
    pub cell_maps: usize,
    /// Bytes of depth bounds: none are needed, a node holds them where they fit
    /// ([`crate::run::render::node_skipping`]).
    pub depths: usize,
    /// Bytes per grid node of the fast tier's node field: none is needed, a node holds it
    /// where it fits ([`crate::run::render::node_skipping`]); 0 holds none.
    pub node_bytes: usize,
    /// Bytes per min/max block of its cells' value ranges: none is needed, a node holds them
    /// where they fit ([`crate::run::render::node_skipping`]); 0 holds none.
    pub cell_ranges: usize,
    /// Bytes of the view's pre-integration table ([`voxcube_kernel::optics::segments`]),
    /// which every node of a pre-integrated view holds; 0 for any other view.
    pub segments: usize,
}

impl ViewNeeds {
    /// What `view` needs.
    pub fn of(view: &voxcube_kernel::trace::view::View) -> ViewNeeds {
        ViewNeeds {
            ghost: view.ghost_planes(),
            maps: voxcube_kernel::skip::leaps::octants(view).count_ones() as usize,
            cell_maps: 0,
            depths: 0,
            node_bytes: 0,
            cell_ranges: 0,
            segments: match view.segments() {
                Some(_) => voxcube_kernel::optics::segments::BYTES,
                None => 0,
            },
        }
    }

    /// The same, with `cell_maps` cell leap maps.
    pub fn with_cell_maps(self, cell_maps: usize) -> ViewNeeds {
        ViewNeeds { cell_maps, ..self }
    }

    /// The same, with a node field of `node_bytes` bytes per grid node.
    pub fn with_node_bytes(self, node_bytes: usize) -> ViewNeeds {
        ViewNeeds { node_bytes, ..self }
    }

    /// The same, with cells' value ranges of `cell_ranges` bytes per min/max block.
    pub fn with_cell_ranges(self, cell_ranges: usize) -> ViewNeeds {
        ViewNeeds {
            cell_ranges,
            ..self
        }
    }

    /// The same, with depth bounds of `depths` bytes.
    pub fn with_depths(self, depths: usize) -> ViewNeeds {
        ViewNeeds { depths, ..self }
    }
}

/// One node's memory, by part.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NodeMemory {
    /// Owned and ghost planes, with their min/max blocks for empty-space skipping.
    pub slab: usize,
    /// Receive buffer (its capacity, or its measured peak).
    pub buffer: usize,
    /// Worker state: queues, pixel records, outbox, ack counters.
    pub worker: usize,
    /// Code and stack.
    pub allowance: usize,
}

impl NodeMemory {
    /// All parts.
    pub fn total(&self) -> usize {
        self.slab + self.buffer + self.worker + self.allowance
    }
}

/// Why a configuration does not fit.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BudgetError {
    /// The profile.
    pub profile: Profile,
    /// Nodes per cluster asked for.
    pub cluster_size: u32,
    /// The largest node's memory.
    pub needed: NodeMemory,
    /// The smallest power-of-two cluster size that fits, if any does.
    pub fits_at: Option<u32>,
}

impl fmt::Display for BudgetError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let n = &self.needed;
        write!(
            f,
            "a node of a cluster of {} needs {} bytes (slab {} + receive buffer {} + worker {} + code and stack {}); the {} has {} bytes per node",
            self.cluster_size,
            n.total(),
            n.slab,
            n.buffer,
            n.worker,
            n.allowance,
            self.profile.name,
            self.profile.node_memory
        )?;
        let fixed = n.buffer + n.worker + n.allowance;
        match self.fits_at {
            Some(size) => write!(f, "; the smallest cluster that fits has {size} nodes"),
            // The buffer alone leaves no room for any slab: blame the buffer, not the volume.
            None if fixed >= self.profile.node_memory => write!(
                f,
                "; the receive buffer alone leaves no room for a slab: at most {} bytes of buffer fit beside the worker and code (--buffer)",
                self.profile.node_memory.saturating_sub(n.worker + n.allowance)
            ),
            None => write!(f, "; no cluster size fits this volume"),
        }
    }
}

impl std::error::Error for BudgetError {}

/// The largest node's memory when `grid` of `sample_bytes` samples is cut uniformly into
/// `cluster_size` slabs with the ghost planes and leap maps of `needs` and `buffer` bytes of
/// receive buffer.
pub fn largest_node(
    grid: &Grid,
    sample_bytes: usize,
    cluster_size: u32,
    needs: ViewNeeds,
    buffer: usize,
) -> Option<NodeMemory> {
    let partition = Partition::uniform(grid.dims()[0], cluster_size as usize).ok()?;
    let slab = (0..cluster_size as usize)
        .map(|j| {
            let s = stored_planes(grid, partition.planes(j), needs.ghost);
            (s.end - s.start) as usize * grid.plane_len() * sample_bytes
                + structure_bytes(grid, partition.planes(j), needs)
        })
        .max()?;
    Some(NodeMemory {
        slab,
        buffer,
        worker: worker_bytes(),
        allowance: CODE_AND_STACK,
    })
}

/// The most planes a slab may own in `grid` (samples of `sample_bytes`, the ghost planes and
/// leap maps of `needs`, `buffer` bytes of receive buffer) and still fit `profile`'s node
/// memory: the cap static load balancing keeps every slab under. 0 when not even one plane
/// fits.
pub fn max_owned_planes(
    profile: Profile,
    grid: &Grid,
    sample_bytes: usize,
    needs: ViewNeeds,
    buffer: usize,
) -> u32 {
    let nx = grid.dims()[0];
    let fits = |owned: u32| {
        // An interior slab stores its ghosts on both sides: the most a slab of this size does.
        let first = needs.ghost.min(nx.saturating_sub(owned));
        let stored = stored_planes(grid, first..first + owned, needs.ghost);
        let memory = NodeMemory {
            slab: (stored.end - stored.start) as usize * grid.plane_len() * sample_bytes
                + structure_bytes(grid, first..first + owned, needs),
            buffer,
            worker: worker_bytes(),
            allowance: CODE_AND_STACK,
        };
        memory.total() <= profile.node_memory
    };
    (1..=nx)
        .take_while(|&owned| fits(owned))
        .last()
        .unwrap_or(0)
}

/// Check that every node fits `profile` with the ghost planes and leap maps of `needs`;
/// `buffer_for(size)` gives the receive buffer of a cluster of `size`.
pub fn check(
    profile: Profile,
    grid: &Grid,
    sample_bytes: usize,
    cluster_size: u32,
    needs: ViewNeeds,
    buffer_for: &dyn Fn(u32) -> usize,
) -> Result<NodeMemory, BudgetError> {
    let fits = |size: u32| {
        largest_node(grid, sample_bytes, size, needs, buffer_for(size))
            .filter(|m| m.total() <= profile.node_memory)
    };
    if let Some(m) = fits(cluster_size) {
        return Ok(m);
    }
    let needed = largest_node(
        grid,
        sample_bytes,
        cluster_size,
        needs,
        buffer_for(cluster_size),
    )
    .unwrap_or_default();
    let fits_at = (0..=10)
        .map(|k| 1u32 << k)
        .filter(|&s| s <= grid.dims()[0])
        .find(|&s| fits(s).is_some());
    Err(BudgetError {
        profile,
        cluster_size,
        needed,
        fits_at,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use voxcube_kernel::Vec3;

    #[test]
    fn the_plane_cap_is_the_largest_slab_that_fits() {
        let grid = Grid::new([208, 208, 208], Vec3::ONE).unwrap();
        let (ghost, buffer) = (3, 16 * 1024);
        let needs = ViewNeeds {
            ghost,
            maps: 1,
            cell_maps: 0,
            depths: 0,
            node_bytes: 0,
            cell_ranges: 0,
            segments: 0,
        };
        let cap = max_owned_planes(Profile::ncube2(), &grid, 1, needs, buffer);
        assert!(cap > 0 && cap < 208, "{cap}");
        let memory = |owned: u32| {
            let stored = 0..owned + 2 * ghost;
            stored.len() * grid.plane_len()
                + structure_bytes(&grid, ghost..ghost + owned, needs)
                + buffer
                + worker_bytes()
                + CODE_AND_STACK
        };
        assert!(memory(cap) <= Profile::ncube2().node_memory);
        assert!(memory(cap + 1) > Profile::ncube2().node_memory);
    }

    #[test]
    fn each_leap_map_costs_a_byte_per_block_and_each_cell_leap_map_a_byte_per_cell() {
        let grid = Grid::new([97, 97, 116], Vec3::ONE).unwrap();
        let blocks = voxcube_kernel::skip::blocks::extent_for(&grid, 0..10).2;
        assert_eq!(blocks, 3 * 24 * 29);
        let needs = |maps: usize, cell_maps: usize| ViewNeeds {
            ghost: 3,
            maps,
            cell_maps,
            depths: 0,
            node_bytes: 0,
            cell_ranges: 0,
            segments: 0,
        };
        // Per block its range (8 bytes), a leap map's byte and a mask (8); per column of
        // blocks along Y (24 of them: one word) its which-keep word.
        assert_eq!(
            structure_bytes(&grid, 3..7, needs(1, 0)),
            blocks * 17 + 3 * 29 * 8
        );
        // A node field of 8 bytes a node over the owned planes and one more each side.
        let with_field = ViewNeeds {
            node_bytes: 8,
            ..needs(1, 0)
        };
        assert_eq!(
            structure_bytes(&grid, 3..7, with_field) - structure_bytes(&grid, 3..7, needs(1, 0)),
            6 * 97 * 116 * 8
        );
        assert_eq!(
            structure_bytes(&grid, 3..7, needs(8, 0)) - structure_bytes(&grid, 3..7, needs(1, 0)),
            blocks * 7
        );
        assert_eq!(
            structure_bytes(&grid, 3..7, needs(1, 2)) - structure_bytes(&grid, 3..7, needs(1, 0)),
            blocks * 2 * 64
        );
        // Byte samples' cells' ranges: two bytes a cell and two masks a block.
        let with_ranges = ViewNeeds {
            cell_ranges: size_of::<voxcube_kernel::skip::cell_ranges::BlockCells<u8>>(),
            ..needs(1, 0)
        };
        assert_eq!(
            structure_bytes(&grid, 3..7, with_ranges) - structure_bytes(&grid, 3..7, needs(1, 0)),
            blocks * (2 * 64 + 2 * 8)
        );
    }

    #[test]
    fn the_host_s_memory_is_shared_evenly_by_its_nodes() {
        let gib = 1u64 << 30;
        assert_eq!(Profile::sharing(24 * gib, 1).node_memory, 24 << 30);
        assert_eq!(Profile::sharing(24 * gib, 2).node_memory, 12 << 30);
        assert_eq!(Profile::sharing(24 * gib + 7, 8).node_memory, 3 << 30);
        // No nodes is taken as one, never a division by zero.
        assert_eq!(Profile::sharing(gib, 0).node_memory, 1 << 30);
        assert_eq!(Profile::sharing(gib, 2).name, "host");
    }

    #[test]
    fn a_gigabyte_volume_is_refused_on_one_modern_node_naming_the_cluster_that_fits() {
        // 1024³ bytes: the volume alone is the modern node's whole gibibyte.
        let grid = Grid::new([1024; 3], Vec3::ONE).unwrap();
        let profile = Profile::builtin("modern").unwrap();
        let buffer = |s: u32| {
            voxcube_kernel::node::flow::buffer_bytes(s as usize, crate::fabric::DEFAULT_I_MAX)
        };
        let needs = ViewNeeds {
            ghost: 1,
            maps: 1,
            cell_maps: 0,
            depths: 0,
            node_bytes: 0,
            cell_ranges: 0,
            segments: 0,
        };
        let err = check(profile, &grid, 1, 1, needs, &buffer).unwrap_err();
        let msg = err.to_string();
        assert!(
            msg.contains("a node of a cluster of 1 needs")
                && msg.contains("the modern has 1073741824 bytes per node")
                && msg.contains("smallest cluster that fits has 2 nodes"),
            "{msg}"
        );
        assert!(check(profile, &grid, 1, 2, needs, &buffer).is_ok());
    }

    #[test]
    fn a_big_volume_needs_a_bigger_cluster() {
        let grid = Grid::new([208, 208, 208], Vec3::ONE).unwrap();
        let buffer = |_| 16 * 1024;
        let on = |size| {
            check(
                Profile::ncube2(),
                &grid,
                1,
                size,
                ViewNeeds {
                    ghost: 3,
                    maps: 1,
                    cell_maps: 0,
                    depths: 0,
                    node_bytes: 0,
                    cell_ranges: 0,
                    segments: 0,
                },
                &buffer,
            )
        };
        let err = on(2).unwrap_err();
        assert_eq!(err.fits_at, Some(4));
        let msg = err.to_string();
        assert!(
            msg.contains("4194304 bytes per node")
                && msg.contains("smallest cluster that fits has 4 nodes"),
            "{msg}"
        );
        let ok = on(4).unwrap();
        assert!(ok.total() <= Profile::ncube2().node_memory);
    }
}
