//! Every schedule of small machines: rings of 2 and 3 nodes rendering a handful of rays with
//! shadows and transparency, on the smallest receive buffers flow control admits, every
//! interleaving of deliveries and steps walked (states seen before pruned): 0 deadlocks,
//! 0 invariant violations, one image, the direct render's. The random explorer
//! (tests/tests/explore.rs) covers the large configurations.

use voxcube::experiments::explore::{exhaustive_walks, few_rays, tight_ring};
use voxcube::fabric::sim::exhaustive::explore;
use voxcube::fabric::RunConfig;
use voxcube_kernel::node::worker::Mutants;

#[test]
fn every_schedule_of_rings_of_two_and_three_ends_with_the_one_image() {
    for (label, found, reference) in exhaustive_walks().unwrap_or_else(|e| panic!("{e}")) {
        eprintln!("{label}:\n{found}\n");
        assert!(!found.truncated, "{label}: the walk is complete");
        assert_eq!(
            (found.deadlocks, found.violations),
            (0, 0),
            "{label}: {found}"
        );
        assert_eq!(found.images.len(), 1, "{label}: {found}");
        assert!(
            found.images.contains(&reference),
            "{label}: the direct render's image"
        );
        // Rays cross slabs: many schedules meet in the same states.
        assert!(
            found.states > 100 && found.transitions > 2 * found.states,
            "{label}: {found}"
        );
    }
}

#[test]
fn negative_controls_a_broken_token_rule_is_found_by_the_walk() {
    // Faults that need full buffers (no headroom, acks needing credit) or a shadow result
    // arriving late (an early pixel) do not show with so few rays; the random explorer
    // catches them on larger machines. The token's faults show here.
    let job = few_rays(3, 2).unwrap_or_else(|e| panic!("{e}"));
    for (name, mutants) in [
        (
            "token before the pixels are final",
            Mutants {
                early_token: true,
                ..Mutants::default()
            },
        ),
        (
            "token while n_i > 0",
            Mutants {
                token_unquiet: true,
                ..Mutants::default()
            },
        ),
        (
            "token passed against the rays",
            Mutants {
                token_backwards: true,
                ..Mutants::default()
            },
        ),
    ] {
        let cfg = RunConfig {
            mutants,
            ..tight_ring(2).unwrap_or_else(|e| panic!("{e}"))
        };
        let found = explore(&job.volume, &job.views[0].view, &cfg, 2_000_000)
            .unwrap_or_else(|e| panic!("{e}"));
        eprintln!("{name}:\n{found}\n");
        assert!(
            found.violations > 0 && found.first_failure.is_some(),
            "{name}: {found}"
        );
    }
}

#[test]
fn negative_control_a_node_that_stops_leaves_states_with_nothing_to_do() {
    // The walk's deadlock detection: node 1 of a ring of 2 stops after its third step, so
    // every schedule ends with the host waiting.
    let job = few_rays(2, 1).unwrap_or_else(|e| panic!("{e}"));
    let mut cfg = tight_ring(2).unwrap_or_else(|e| panic!("{e}"));
    cfg.schedule.stop = Some((1, 3));
    let found =
        explore(&job.volume, &job.views[0].view, &cfg, 2_000_000).unwrap_or_else(|e| panic!("{e}"));
    eprintln!("{found}");
    assert!(found.deadlocks > 0 && found.ends == 0, "{found}");
    let first = found.first_failure.unwrap_or_default();
    assert!(first.contains("node 1"), "{first}");
}
