//! The lighting of one point before shadowing: its ambient term, each light's direct term, and
//! which lights need a shadow ray. A surface hit's [`Lighting`] is what a distributed trace
//! sends to the pixel's home; the home multiplies in the visibilities that come back and
//! combines them by [`crate::trace::tree::surface_color`], exactly as the in-process tracer does. A
//! composited sample, which no shadow darkens, gets the same colour from [`Unshadowed`]
//! without the record.
//!
//! Invariant: `direct[l]` is zero for every light `l ≥ lights`; a light needs a shadow ray only
//! if it casts shadows and lights the point (`direct[l] ≠ 0`).

use crate::counters::Counters;
use crate::optics::shade::{self, Light, MAX_LIGHTS};
use crate::optics::shading_table::ShadingTable;
use crate::trace::tree;
use crate::trace::view::View;
use crate::volume::field::{self, Site};
use crate::volume::nodes;
use crate::volume::sample::Sample;
use crate::volume::slab::Slab;
use glam::Vec3;

/// A point's light, before shadowing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lighting {
    /// Ambient term (the unlit colour when the view has no shading).
    pub ambient: Vec3,
    /// Each light's Lambert + Phong term.
    pub direct: [Vec3; MAX_LIGHTS],
    /// World direction toward each light and its distance (for shadow rays).
    pub to_light: [(Vec3, f32); MAX_LIGHTS],
    /// Lights that contribute (the view's lights, or 0 without shading).
    pub lights: u8,
    /// Bit `l` set: light `l` needs a shadow ray.
    pub shadow_mask: u8,
}

impl Lighting {
    /// The point's colour given each light's visibility (1 where no shadow ray was traced).
    pub fn color(&self, visibility: &[f32; MAX_LIGHTS]) -> Vec3 {
        let n = usize::from(self.lights).min(MAX_LIGHTS);
        tree::surface_color(self.ambient, &self.direct[..n], &visibility[..n])
    }
}

/// The lighting of a point of colour `base` at index-space `p`, seen along `view_dir`. Uses the
/// cut-face normal when given, else the gradient's.
pub fn lighting<T: Sample>(
    view: &View,
    slab: &Slab<'_, T>,
    base: Vec3,
    p: Vec3,
    cap_normal: Option<Vec3>,
    view_dir: Vec3,
    counters: &mut Counters,
) -> Lighting {
    let spec = view.spec();
    let mut out = Lighting {
        ambient: base,
        direct: [Vec3::ZERO; MAX_LIGHTS],
        to_light: [(Vec3::ZERO, 0.0); MAX_LIGHTS],
        lights: 0,
        shadow_mask: 0,
    };
    let Some(shading) = &spec.shading else {
        return out;
    };
    let n = normal(view, slab, (p, None, None), cap_normal, view_dir, counters);
    let world = view.to_world(p);
    out.ambient = base * shading.ambient;
    out.lights = spec.lights.len() as u8;
    for (l, light) in spec.lights.iter().enumerate() {
        let Some(toward) = light.toward(world) else {
            continue;
        };
        out.to_light[l] = toward;
        out.direct[l] = shade::direct(
            shading,
            view.highlights(),
            base,
            n,
            view_dir,
            toward.0,
            light.color,
        );
        if light.shadows && out.direct[l] != Vec3::ZERO {
            out.shadow_mask |= 1 << l;
        }
    }
    out
}

/// The colour of points that no shadow darkens (composited samples), equal in every bit to
/// [`lighting`]'s `.color` with every light fully visible, and counted alike: the same terms
/// summed in the same order, a visibility of 1 multiplying each exactly. It keeps no
/// [`Lighting`] (directions, distances, shadow mask), which compositing never reads, and it
/// finds once what is the same at every point: the direction toward each light when every
/// light is directional, so that no point is carried into world space for them.
#[derive(Clone, Debug)]
pub struct Unshadowed<'v> {
    view: &'v View,
    /// Each light's direction toward it and its colour, when every light is directional and
    /// no table is read; `None` when some light is a point light, whose direction depends on
    /// the point, and where the table holds the lights.
    fixed: Option<heapless::Vec<(Vec3, Vec3), MAX_LIGHTS>>,
    /// The direction the points are seen along.
    view_dir: Vec3,
    /// The fast tier's shading by normal direction, where the view has one built for
    /// `view_dir` (every ray of the views that have one is).
    table: Option<&'v ShadingTable>,
}

impl<'v> Unshadowed<'v> {
    /// The unshadowed lighting of `view`'s points seen along `view_dir` (a ray's direction).
    pub fn new(view: &'v View, view_dir: Vec3) -> Unshadowed<'v> {
        let fixed = |light: &Light| Some((light.toward_everywhere()?, light.color));
        let table = view.shading_table().filter(|t| t.view_dir() == view_dir);
        Unshadowed {
            view,
            // Collected for every ray segment: not where the table, built once, holds them.
            fixed: match table {
                Some(_) => None,
                None => view.spec().lights.iter().map(fixed).collect(),
            },
            view_dir,
            table,
        }
    }

    /// The fast tier's shading table, where this view's points read it.
    #[inline(always)]
    pub(crate) fn table(&self) -> Option<&'v ShadingTable> {
        self.table
    }

    /// Count `n` points shaded by the table with gradients read with their values, as
    /// [`Unshadowed::color`] counts each given its gradient, `fallbacks` of them by the
    /// fallback normal.
    #[inline(always)]
    pub(crate) fn count_tabled(&self, n: u64, fallbacks: u64, counters: &mut Counters) {
        counters.shadings += n;
        counters.interpolations += n * self.view.interpolations_per_gradient();
        counters.gradients += n;
        counters.normal_fallbacks += fallbacks;
    }

    /// The colour at index-space `p` of a point of colour `base`.
    /// `site` is where `p` reads the grid under the view's model ([`field::locate`]), which
    /// the sample loop has found already, and `gradient` the gradient there where it has
    /// that too (from the node field's lanes, [`nodes::lanes_at`]): counted as the read it
    /// stands for.
    #[inline(always)]
    pub fn color<T: Sample>(
        &self,
        slab: &Slab<'_, T>,
        base: Vec3,
        (p, site, gradient_known): (Vec3, &Site, Option<Vec3>),
        counters: &mut Counters,
    ) -> Vec3 {
        let (view, view_dir) = (self.view, self.view_dir);
        let spec = view.spec();
        let Some(shading) = &spec.shading else {
            return base;
        };
        if let Some(table) = self.table {
            counters.shadings += 1;
            let g = gradient(view, slab, (p, Some(site), gradient_known), counters);
            let (color, fallback) = table.color(base, g);
            counters.normal_fallbacks += u64::from(fallback);
            return color;
        }
        let n = normal(
            view,
            slab,
            (p, Some(site), gradient_known),
            None,
            view_dir,
            counters,
        );
        let mut color = base * shading.ambient;
        let lit = |toward: Vec3, light: Vec3| {
            shade::direct(shading, view.highlights(), base, n, view_dir, toward, light)
        };
        match &self.fixed {
            Some(lights) => {
                for &(toward, light) in lights {
                    color += lit(toward, light);
                }
            }
            None => {
                let world = view.to_world(p);
                for light in &spec.lights {
                    // An unlit light adds its zero term, as `tree::surface_color` does.
                    color += light
                        .toward(world)
                        .map_or(Vec3::ZERO, |toward| lit(toward.0, light.color));
                }
            }
        }
        color
    }
}

/// The shading normal at `p` (whose [`Site`] and gradient are given where known): the cut
/// face's when given, else the gradient's, facing the viewer; counts the shading, the
/// gradient and any fallback.
#[inline(always)]
fn normal<T: Sample>(
    view: &View,
    slab: &Slab<'_, T>,
    at: (Vec3, Option<&Site>, Option<Vec3>),
    cap_normal: Option<Vec3>,
    view_dir: Vec3,
    counters: &mut Counters,
) -> Vec3 {
    counters.shadings += 1;
    match cap_normal {
        Some(n) => shade::face_viewer(n, view_dir),
        None => {
            let (n, fallback) = shade::normal(gradient(view, slab, at, counters), view_dir);
            counters.normal_fallbacks += u64::from(fallback);
            n
        }
    }
}

/// The gradient the tier shades by at `p` (whose [`Site`] and gradient are given where
/// known), counted as the reads the tier's definition makes.
#[inline(always)]
pub(crate) fn gradient<T: Sample>(
    view: &View,
    slab: &Slab<'_, T>,
    (p, site, known): (Vec3, Option<&Site>, Option<Vec3>),
    counters: &mut Counters,
) -> Vec3 {
    let spec = view.spec();
    match known {
        // Read with the sample's value, counted here as the reads it stands for.
        Some(g) => {
            counters.interpolations += view.interpolations_per_gradient();
            counters.gradients += 1;
            g
        }
        // The nodes' differences, where the tier's gradient is read from them: the fast tier
        // everywhere, the exact tier at points in the grid (there the same number as its six
        // reads, [`View::exact_node_gradients`]).
        None if view.node_gradients()
            || (view.exact_node_gradients() && nodes::in_grid(slab.grid(), p)) =>
        {
            let site = site.copied();
            let site = site.unwrap_or_else(|| field::locate(slab.grid(), spec.model, p));
            counters.interpolations += view.interpolations_per_gradient();
            counters.gradients += 1;
            nodes::lanes_at(slab, &site, counters).1
        }
        None => field::gradient(slab, spec.model, p, spec.gradient_distance, counters),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optics::shade::{Light, Shading};
    use crate::trace::view::ViewSpec;
    use crate::volume::grid::Grid;

    fn view(grid: &Grid, shading: Option<Shading>, lights: &[Light]) -> View {
        crate::testing::composited_view(grid, shading, lights)
    }

    /// `view` in the fast tier.
    fn fast(view: &View, grid: &Grid) -> View {
        let spec = ViewSpec {
            accuracy: crate::trace::view::Accuracy::Fast,
            ..view.spec().clone()
        };
        View::new(spec, grid).unwrap()
    }

    #[test]
    fn an_unshadowed_colour_is_the_lighting_of_every_light_fully_visible_in_every_bit() {
        const DIMS: [u32; 3] = crate::testing::HASHED_DIMS;
        let (data, grid) = crate::testing::hashed_field();
        let slab = Slab::whole(grid, &data).unwrap();
        // A point light right at a sample: that light lights nothing there. (A composited view
        // casts no shadows: no light may ask for them.)
        let at = Vec3::new(4.0, 3.0, 5.0);
        let lit = view(&grid, Some(Shading::default()), &[]);
        let lights = [
            Light::directional(Vec3::new(0.4, -0.5, 1.0), Vec3::new(1.0, 0.9, 0.8), false).unwrap(),
            Light::point(Vec3::new(-3.0, 12.0, 6.0), Vec3::splat(0.7), false).unwrap(),
            Light::point(lit.to_world(at), Vec3::ONE, false).unwrap(),
            Light::directional(Vec3::new(-1.0, 0.2, -0.3), Vec3::splat(0.5), false).unwrap(),
        ];
        // And the fast tier's, whose gradient comes from node differences.
        let fast = fast(&view(&grid, Some(Shading::default()), &lights), &grid);
        assert!(fast.node_gradients());
        let views = [
            view(&grid, None, &lights),
            lit,
            view(&grid, Some(Shading::default()), &lights),
            fast,
            // Directional lights only: their directions found once, not at each point.
            view(&grid, Some(Shading::default()), &[lights[0], lights[3]]),
        ];
        let mut next = crate::testing::xorshift(0x51ed_270b);
        let bits = |c: Vec3| c.to_array().map(f32::to_bits);
        for n in 0..6_000 {
            let mut p = if n == 0 { at } else { Vec3::ZERO };
            for a in (0..3).filter(|_| n > 0) {
                p[a] = (next() >> 8) as f32 / (1 << 24) as f32 * (DIMS[a] as f32 + 1.0) - 0.5;
            }
            let base = Vec3::new(0.9, 0.7, 0.3) * (next() % 5) as f32 * 0.25;
            let dir = Vec3::new(-0.8, -0.1, -0.5).normalize();
            for v in &views {
                let (mut c, mut d) = (Counters::default(), Counters::default());
                let full = lighting(v, &slab, base, p, None, dir, &mut c).color(&[1.0; MAX_LIGHTS]);
                let site = field::locate(&grid, v.spec().model, p);
                let fast = Unshadowed::new(v, dir).color(&slab, base, (p, &site, None), &mut d);
                assert_eq!(bits(fast), bits(full), "{p} {base}");
                assert_eq!(c, d, "{p}");
            }
        }
    }

    #[test]
    fn a_composited_fast_view_along_its_rays_shades_by_its_table_in_every_bit() {
        let (data, grid) = crate::testing::hashed_field();
        let slab = Slab::whole(grid, &data).unwrap();
        let lights = [
            Light::directional(Vec3::new(0.4, -0.5, 1.0), Vec3::new(1.0, 0.9, 0.8), false).unwrap(),
            Light::directional(Vec3::new(-1.0, 0.2, -0.3), Vec3::splat(0.5), false).unwrap(),
        ];
        // The exact tier's view of the same scene: the same counts, its own colours.
        let exact = view(&grid, Some(Shading::default()), &lights);
        let fast = fast(&exact, &grid);
        let table = fast
            .shading_table()
            .expect("parallel rays, directional lights");
        let along = fast.spec().camera.forward();
        assert_eq!(table.view_dir(), along);
        let mut next = crate::testing::xorshift(0x7ab1_e5ad);
        let unit = |n: u32| (n >> 8) as f32 / (1 << 24) as f32 - 0.5;
        let bits = |c: Vec3| c.to_array().map(f32::to_bits);
        let mut differ = 0;
        for n in 0..4_000 {
            let p = Vec3::new(4.0, 3.0, 5.0);
            let site = field::locate(&grid, fast.spec().model, p);
            let g = match n {
                0 => Vec3::ZERO,
                1 => Vec3::NAN,
                _ => Vec3::new(unit(next()), unit(next()), unit(next())) * 40.0,
            };
            let base = Vec3::new(0.9, 0.7, 0.3) * (next() % 5) as f32 * 0.25;
            let (mut c, mut d) = (Counters::default(), Counters::default());
            let lit = Unshadowed::new(&fast, along).color(&slab, base, (p, &site, Some(g)), &mut c);
            let (want, fallback) = table.color(base, g);
            assert_eq!(bits(lit), bits(want), "{g} {base}");
            assert_eq!(c.normal_fallbacks, u64::from(fallback));
            let by_terms =
                Unshadowed::new(&exact, along).color(&slab, base, (p, &site, Some(g)), &mut d);
            // Counted as the exact shading is, but for the gradient's reads (one
            // interpolation in this tier, six in the exact one).
            assert_eq!((c.shadings, c.gradients), (d.shadings, d.gradients));
            assert_eq!(c.normal_fallbacks, d.normal_fallbacks, "{g}");
            differ += usize::from(bits(by_terms) != bits(lit));
            // Along another direction, the table is not the shading.
            let other = Unshadowed::new(&fast, -along);
            assert!(other.table.is_none());
        }
        // The table is an approximation: most colours differ from the exact terms' bits.
        assert!(differ > 2_000, "{differ}");
    }
}
