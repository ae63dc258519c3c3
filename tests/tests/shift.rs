//! Slab planes shifted between ring neighbours to new cuts: rounds reach any partition, no
//! slab outgrows the larger of its sizes before and after on the way (so a memory cap that
//! holds for both holds throughout), and every node of every cluster ends with exactly the
//! planes of its new slab, ghosts included, on the simulator and on OS threads.

use proptest::prelude::*;
use voxcube::fabric::{shift, threads};
use voxcube_kernel::node::partition::Partition;
use voxcube_kernel::node::shift::{next_step, plan};
use voxcube_kernel::node::topology::Layout;
use voxcube_kernel::volume::grid::Grid;
use voxcube_kernel::volume::slab::stored_planes;
use voxcube_kernel::Vec3;

/// `n` slabs of `nx` planes with cuts drawn from `picks`.
fn partition(nx: u32, n: usize, picks: &[u32]) -> Partition {
    let mut inner: Vec<u32> = Vec::new();
    let mut pool: Vec<u32> = (1..nx).collect();
    for &p in picks.iter().take(n - 1) {
        inner.push(pool.remove(p as usize % pool.len()));
    }
    inner.sort_unstable();
    let cuts: Vec<u32> = std::iter::once(0).chain(inner).chain([nx]).collect();
    Partition::new(&cuts, nx).expect("cuts")
}

fn largest(p: &Partition) -> u32 {
    (0..p.slabs())
        .map(|j| p.planes(j).len() as u32)
        .max()
        .unwrap_or(0)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn rounds_reach_the_target_without_outgrowing_either_partition(
        nx in 2u32..60,
        n in 1usize..10,
        a in proptest::collection::vec(0u32..1000, 9),
        b in proptest::collection::vec(0u32..1000, 9),
        ghost in 0u32..3,
    ) {
        let n = n.min(nx as usize);
        let (old, target) = (partition(nx, n, &a), partition(nx, n, &b));
        let grid = Grid::new([nx, 1, 1], Vec3::ONE).expect("grid");
        let cap = largest(&old).max(largest(&target));
        let mut current = old.clone();
        let mut rounds = 0;
        while current != target {
            let next = next_step(&current, &target).expect("a step");
            prop_assert!(largest(&next) <= cap, "{:?} -> {:?}: {:?}", old.cuts(), target.cuts(), next.cuts());
            for j in 0..n {
                prop_assert!(plan(&grid, &current, &next, ghost, j).is_ok());
            }
            current = next;
            rounds += 1;
            prop_assert!(rounds <= nx);
        }
    }
}

#[test]
fn every_node_of_every_cluster_ends_with_its_new_slab() {
    let dims = [37, 5, 4];
    let grid = Grid::new(dims, Vec3::ONE).expect("grid");
    let data: Vec<u16> = (0..dims.iter().product::<u32>())
        .map(|i| (i * 40_503 % 65_521) as u16)
        .collect();
    let plane = grid.plane_len();
    let cases: [(u32, u32, &[u32]); 3] = [
        (2, 4, &[0, 2, 4, 30, 37]),
        (1, 8, &[0, 20, 22, 24, 26, 28, 30, 33, 37]),
        (4, 2, &[0, 1, 37]),
    ];
    for (clusters, size, cuts) in cases {
        let layout = Layout::new(clusters, size).expect("layout");
        let old = Partition::uniform(dims[0], size as usize).expect("uniform");
        let new = Partition::new(cuts, dims[0]).expect("cuts");
        for ((ghost, capacity), threads) in [(0, 300), (2, 1000), (3, 100_000)]
            .into_iter()
            .flat_map(|g| [(g, 0), (g, 1), (g, 3)])
        {
            // Threads 0: the simulator's driver; otherwise the threads fabric's, on so many
            // OS threads.
            let job = shift::ShiftJob {
                grid: &grid,
                layout,
                old: old.clone(),
                new: &new,
                ghost,
                capacity,
            };
            let (storages, report) = if threads == 0 {
                shift::run(&job, &data, None)
            } else {
                threads::shift(&job, &data, threads)
            }
            .expect("shifts");
            assert!(report.messages > 0 && report.rounds >= 1, "{report:?}");
            for (node, storage) in storages.iter().enumerate() {
                let j = usize::from(layout.place(node as u16).1);
                let s = stored_planes(&grid, new.planes(j), ghost);
                assert!(
                    storage[..] == data[s.start as usize * plane..s.end as usize * plane],
                    "node {node}, cuts {cuts:?}, ghost {ghost}, threads {threads}"
                );
            }
        }
    }
}
