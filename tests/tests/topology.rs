//! The hypercube topology, for every cube dimension `k ≤ 10` and every cluster count: every
//! ring edge is one hypercube hop, every node has exactly one place, e-cube routes are
//! shortest paths through neighbours.

use proptest::prelude::*;
use voxcube_kernel::node::topology::{ecube_route, hops, Layout};

#[test]
fn every_ring_edge_is_one_hop_and_every_node_has_one_place() {
    for k in 0..=10u32 {
        for i in 0..=k {
            let (m, cd) = (1u32 << i, 1u32 << (k - i));
            let layout = Layout::new(m, cd).expect("a hypercube layout");
            assert!(layout.is_hypercube());
            assert_eq!(layout.dimension(), Some(k));
            let mut seen = vec![false; 1 << k];
            for c in 0..m as u16 {
                for j in 0..cd as u16 {
                    let node = layout.node(c, j);
                    assert!(
                        (node as usize) < seen.len(),
                        "k {k} i {i}: node {node} out of the cube"
                    );
                    assert!(
                        !seen[node as usize],
                        "k {k} i {i}: node {node} placed twice"
                    );
                    seen[node as usize] = true;
                    assert_eq!(layout.place(node), (c, j));
                    if cd > 1 {
                        let next = layout.node(c, (j + 1) % cd as u16);
                        assert_eq!(
                            hops(node, next),
                            1,
                            "k {k} i {i}: ring edge {j} of cluster {c} is not one hop"
                        );
                    }
                }
            }
            assert!(seen.iter().all(|&s| s), "k {k} i {i}: a node has no place");
        }
    }
}

#[test]
fn rings_of_other_lengths_number_plainly() {
    let layout = Layout::new(2, 3).expect("layout");
    assert!(!layout.is_hypercube());
    assert_eq!(
        (0..3).map(|j| layout.node(1, j)).collect::<Vec<_>>(),
        vec![3, 4, 5]
    );
    assert_eq!(layout.place(4), (1, 1));
}

proptest! {
    #[test]
    fn e_cube_routes_are_shortest_neighbour_paths(k in 1u32..=10, a in any::<u16>(), b in any::<u16>()) {
        let mask = (1u16 << k) - 1;
        let (a, b) = (a & mask, b & mask);
        let route: Vec<u16> = ecube_route(a, b).collect();
        prop_assert_eq!(route.len() as u32, hops(a, b));
        let mut at = a;
        for &n in &route {
            prop_assert_eq!(hops(at, n), 1);
            prop_assert!(n <= mask);
            at = n;
        }
        prop_assert_eq!(at, b);
    }
}
