//! A prefetch is a hint: slabs whose composited rays ask for every evaluated sample's cell of
//! the node field a few samples ahead, and slabs whose rays never do, give every pixel the
//! same bits and count the same work, in both tiers (the fast tier reads the field's values
//! and gradients, the exact tier its gradients) and pre-integrated, through the interior's
//! runs and the general step, skipping or not, on the whole volume and on slabs of it.
//!
//! No negative control is possible: a prefetch takes its storage by shared reference and
//! returns nothing, so it has no way to change a value; the test shows that the loops that
//! ask for it compute what the loops that do not compute.

use voxcube::input::dataset::{Volume, VolumeData};
use voxcube::memory::ranges::SlabRanges;
use voxcube::memory::segments::SegmentTable;
use voxcube::memory::storage::{holds_node_field, SkipMode, Skipping};
use voxcube_kernel::counters::Counters;
use voxcube_kernel::optics::shade::Light;
use voxcube_kernel::trace::view::{Accuracy, Compositing, View};
use voxcube_kernel::volume::grid::Model;
use voxcube_kernel::volume::slab::{stored_planes, Slab};
use voxcube_kernel::Vec3;
use voxcube_tests::{colour_bits, constant_transfer, lit, ortho, spec, volume_u8};

/// Two soft blobs and a ridge over a faint floor: empty space around them to skip, and
/// cells of every value to composite.
fn blobs() -> Volume {
    volume_u8([29, 23, 26], Vec3::new(1.0, 0.9, 1.1), |x, y, z| {
        let d = |c: [u32; 3]| {
            x.abs_diff(c[0]).pow(2) + y.abs_diff(c[1]).pow(2) + z.abs_diff(c[2]).pow(2)
        };
        let blob =
            240u32.saturating_sub(d([9, 11, 8]) * 6) + 200u32.saturating_sub(d([20, 9, 17]) * 9);
        let ridge = if (x + 2 * z) % 13 == 0 { 90 } else { 0 };
        (blob + ridge + (x * 7 + y * 3 + z) % 5).min(255) as u8
    })
}

/// The view of `volume` in `tier`, composited `compositing`, parallel (with depth bounds and
/// cell leap maps where the mode builds them), lit by a directional light.
fn view(volume: &Volume, tier: Accuracy, compositing: Compositing) -> View {
    let [nx, ny, nz] = volume.grid.dims().map(|n| n as f32);
    let centre = Vec3::new(nx * 0.5, ny * 0.45, nz * 0.55);
    let light = Light::directional(Vec3::new(0.3, -0.6, -1.0), Vec3::ONE, false).expect("light");
    let camera = ortho(centre + Vec3::new(40.0, 13.0, -22.0), centre, Vec3::Y, 38.0);
    let mut s = lit(
        spec(camera, 40, 32, Model::Cell, 0.5, constant_transfer(0.03)),
        &[light],
    );
    s.accuracy = tier;
    s.compositing = compositing;
    View::new(s, &volume.grid).expect("valid view")
}

/// Every pixel's colour as bits, and the counters, of `view` on `slab` prefetching node
/// fields of `from` bytes and more (on a slab of part of the volume, each ray's part in it).
fn traced(view: &View, slab: Slab<'_, u8>, from: usize) -> (Vec<[u32; 3]>, Counters) {
    colour_bits(view, &slab.prefetching_from(from))
}

#[test]
fn rays_that_prefetch_and_rays_that_do_not_give_every_colour_in_the_same_bits() {
    let volume = blobs();
    let VolumeData::U8(data) = &volume.data else {
        unreachable!("blobs are bytes")
    };
    let grid = volume.grid;
    let plane = grid.plane_len();
    let nx = grid.dims()[0];
    let no_depths = SkipMode {
        depths: false,
        ..SkipMode::ALL
    };
    let mut compared = 0;
    let ways = [
        (Accuracy::Fast, Compositing::Sampled),
        (Accuracy::Exact, Compositing::Sampled),
        (Accuracy::Fast, Compositing::PreIntegrated),
    ];
    for (tier, compositing) in ways {
        let view = view(&volume, tier, compositing);
        // Empty for a sampled view; a pre-integrated one composites by nothing else.
        let table = SegmentTable::of(&view);
        for owned in [0..nx, 3..nx / 2, nx / 3..nx] {
            // Two ghost planes: a node field reads one plane past the planes it holds.
            let stored = stored_planes(&grid, owned.clone(), 2);
            let samples = &data[stored.start as usize * plane..stored.end as usize * plane];
            let slab = Slab::new(grid, owned.clone(), 2, samples).expect("slab");
            for mode in [SkipMode::ALL, no_depths, SkipMode::BLOCKS, SkipMode::OFF] {
                let field = volume.built.field(&slab, holds_node_field(&view, mode), 1);
                let ranges = SlabRanges::build(&slab, mode.ranges, 1);
                let skipping = Skipping::build(&slab, &ranges, &view, mode);
                let ready = table.apply(skipping.apply(field.apply(slab)));
                // The field the rays ask for is held, in either tier.
                assert!(
                    ready.nodes().is_some(),
                    "{tier:?} {compositing:?} {owned:?} {mode:?}"
                );
                let (asked, counted) = traced(&view, ready, 0);
                let (never, also) = traced(&view, ready, usize::MAX);
                let what = format!("{tier:?} {compositing:?} {owned:?} {mode:?}");
                assert_eq!(counted, also, "{what}");
                assert!(asked == never, "{what}: a colour differs");
                // Not a blank image: the comparison sees composited, shaded samples.
                let lit = asked.iter().filter(|c| **c != [0; 3]).count();
                assert!(lit > asked.len() / 10, "{what}: {lit} pixels lit");
                assert!(counted.samples > 0 && counted.shadings > 0, "{what}");
                compared += 1;
            }
        }
    }
    assert_eq!(compared, 3 * 3 * 4);
}
