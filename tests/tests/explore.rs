//! Flow control, deadlock freedom and termination, shown by schedule exploration: with flow
//! control on, every run over many configurations and schedules completes with the reference
//! image and every invariant intact; with it off, or with any of the mutants, the explorer
//! catches the fault. `VOXCUBE_LONG=1` runs the long mode (over 10,000 schedules).

use voxcube::experiments::explore::{configs, explore, scenes, Config};
use voxcube::fabric::sim;
use voxcube::fabric::{RunConfig, RunError};
use voxcube_kernel::node::flow;
use voxcube_kernel::node::worker::Mutants;

fn seeds() -> u64 {
    if std::env::var_os("VOXCUBE_LONG").is_some() {
        32
    } else {
        1
    }
}

#[test]
fn flow_control_on_no_deadlock_no_violation_identical_images() {
    let job = scenes().expect("exploration scenes");
    let all = configs(&job);
    assert!(all.len() >= 50, "{} configurations", all.len());
    let found = explore(&job, &all, seeds(), &|_| {});
    eprintln!("{found}");
    assert_eq!(found.failures(), 0, "{found}");
    if seeds() > 1 {
        assert!(
            found.runs >= 10_000,
            "long mode ran only {} schedules",
            found.runs
        );
    }
    let (peak, cap) = found.worst_occupancy;
    assert!(peak <= cap && peak > 0, "{peak} of {cap}");
}

/// A few configurations with small buffers and shadows, where faults show.
fn tight(job: &voxcube::input::scene::DatasetJob) -> Vec<Config> {
    configs(job)
        .into_iter()
        .filter(|c| c.view < 2 && c.size >= 2 && c.buffer <= flow::buffer_bytes(c.size as usize, 8))
        .collect()
}

#[test]
fn flow_control_off_deadlocks_with_a_replayable_trace() {
    let job = scenes().expect("exploration scenes");
    let small: Vec<Config> = tight(&job)
        .into_iter()
        .map(|c| Config { buffer: 400, ..c })
        .collect();
    let found = explore(&job, &small, 2, &|cfg| cfg.flow_control = false);
    eprintln!("{found}");
    assert!(
        found.deadlocks > 0,
        "without flow control small buffers must deadlock: {found}"
    );
    let first = found.first_failure.expect("a failure is described");
    assert!(
        first.contains("seed") && first.contains("last events"),
        "{first}"
    );
}

#[test]
fn a_deadlock_replays_from_its_seed() {
    let job = scenes().expect("exploration scenes");
    let view = &job.views[0].view;
    let mut found = None;
    for seed in 0..50 {
        let cfg = RunConfig {
            buffer_bytes: Some(400),
            flow_control: false,
            ..RunConfig::cluster(4, seed).expect("layout")
        };
        if let Err(e @ RunError::Deadlock { .. }) = sim::run(&job.volume, view, &cfg) {
            found = Some((cfg, e.to_string()));
            break;
        }
    }
    let (cfg, first) = found.expect("a deadlock without flow control");
    let again = sim::run(&job.volume, view, &cfg).expect_err("the same seed deadlocks again");
    assert_eq!(
        again.to_string(),
        first,
        "replay from the seed gives the same trace"
    );
}

fn caught(name: &str, mutants: Mutants) {
    let job = scenes().expect("exploration scenes");
    let found = explore(&job, &tight(&job), 3, &|cfg| cfg.mutants = mutants);
    eprintln!("{name}:\n{found}");
    assert!(
        found.failures() > 0,
        "mutant {name} was not caught: {found}"
    );
}

#[test]
fn mutant_no_headroom_is_caught() {
    caught(
        "no r_imax headroom",
        Mutants {
            no_headroom: true,
            ..Mutants::default()
        },
    );
}

/// The start rule is checked where it happens: the simulator's invariant after every step
/// (`n_i` stays below `i_max`) is what catches rays started without the `r_imax` headroom,
/// by name, in every configuration where the mutant shows at all.
#[test]
fn rays_started_without_headroom_break_the_start_rule_check() {
    let job = scenes().expect("exploration scenes");
    let found = explore(&job, &tight(&job), 3, &|cfg| {
        cfg.mutants = Mutants {
            no_headroom: true,
            ..Mutants::default()
        }
    });
    let first = found.first_failure.clone().expect("the mutant is caught");
    assert!(first.contains("start rule broken"), "{first}");
    assert_eq!(found.deadlocks, 0, "caught before any deadlock: {found}");
}

#[test]
fn mutant_acks_needing_credit_is_caught() {
    caught(
        "acks that need credit",
        Mutants {
            acks_need_credit: true,
            ..Mutants::default()
        },
    );
}

#[test]
fn mutant_early_token_is_caught() {
    caught(
        "token before the pixels are final",
        Mutants {
            early_token: true,
            ..Mutants::default()
        },
    );
}

#[test]
fn mutant_token_with_messages_unacknowledged_is_caught() {
    caught(
        "token while n_i > 0",
        Mutants {
            token_unquiet: true,
            ..Mutants::default()
        },
    );
}

#[test]
fn mutant_token_passed_against_the_rays_is_caught() {
    caught(
        "token passed the other way",
        Mutants {
            token_backwards: true,
            ..Mutants::default()
        },
    );
}

#[test]
fn mutant_early_pixel_is_caught() {
    caught(
        "pixel before its shadow rays return",
        Mutants {
            early_pixel: true,
            ..Mutants::default()
        },
    );
}

#[test]
fn a_buffer_too_small_for_any_ray_is_refused_with_the_smallest_that_works() {
    let job = scenes().expect("exploration scenes");
    let view = &job.views[0].view;
    let needed = flow::min_i_max(view.effects().shadow_lights);
    let smallest = flow::buffer_bytes(4, needed);
    let cfg = RunConfig {
        buffer_bytes: Some(smallest - 1),
        ..RunConfig::cluster(4, 1).expect("layout")
    };
    let err = sim::run(&job.volume, view, &cfg).expect_err("refused");
    let msg = err.to_string();
    assert!(msg.contains(&format!("at least {smallest} bytes")), "{msg}");
    let cfg = RunConfig {
        buffer_bytes: Some(smallest),
        ..cfg
    };
    sim::run(&job.volume, view, &cfg).expect("the smallest buffer that works, works");
}

mod buffer_limits {
    use super::*;
    use proptest::prelude::*;
    use voxcube::fabric::Scheduler;
    use voxcube::run::render::render;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(if std::env::var_os("VOXCUBE_LONG").is_some() { 400 } else { 48 }))]

        /// Random buffers from the smallest that admits one ray up, random cube shapes, scenes,
        /// schedulers and seeds: the run completes, the image is the reference, and every
        /// invariant holds (the simulator checks them after every event and at the end).
        #[test]
        fn any_admissible_buffer_completes_with_the_reference_image(
            view in 0usize..3,
            shape in prop::sample::select(vec![(1u32, 2u32), (1, 3), (1, 5), (2, 2), (1, 4), (4, 2), (2, 4), (1, 8), (8, 1)]),
            extra_bytes in prop_oneof![Just(0usize), 0usize..200, 0usize..20_000],
            scheduler in 0u8..4,
            seed in any::<u64>(),
        ) {
            let job = scenes().expect("exploration scenes");
            let v = &job.views[view].view;
            let (clusters, size) = shape;
            let smallest = flow::buffer_bytes(size as usize, flow::min_i_max(v.effects().shadow_lights));
            let scheduler = match scheduler {
                0 => Scheduler::Uniform,
                1 => Scheduler::NewestFirst,
                2 => Scheduler::DelayAcks,
                _ => Scheduler::Starve { from: 0, to: u16::from(size > 1) },
            };
            let mut cfg = RunConfig {
                buffer_bytes: Some(smallest + extra_bytes),
                ..RunConfig::machine(clusters, size, seed).expect("layout")
            };
            cfg.schedule.scheduler = scheduler;
            let run = sim::run(&job.volume, v, &cfg).map_err(|e| TestCaseError::fail(e.to_string()))?;
            let reference = render(&job.volume, v).expect("renders").pixels;
            prop_assert!(run.pixels == reference, "image differs");
            for n in &run.nodes {
                prop_assert!(n.peak_buffer <= run.buffer_capacity);
                prop_assert!(n.stats.peak_unacked <= u64::from(run.i_max));
            }
        }
    }
}
