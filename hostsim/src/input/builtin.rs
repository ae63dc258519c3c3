//! Built-in volumes, generated in code so that voxcube renders with no files:
//! - `molecule`: a 97×97×116 u8 "electron density" in the character of the paper's SOD map
//!   (Gaussian atoms along a folded chain, two heavy-metal peaks), from a fixed seed;
//! - `marschner-lobb`: the Marschner–Lobb test function sampled on 41³, f32;
//! - `sphere`: a 64³ f32 signed distance to a sphere of radius 24 cells centred in the grid,
//!   positive inside, for analytic tests of silhouettes (iso value 0);
//! - `head`: a 128³ i16 CT-like head in Hounsfield units, after Shepp and Logan's phantom
//!   (ellipsoids of scalp, skull, brain, ventricles and lesions, their edges a sample wide as
//!   a scanner's partial volume blurs them, and a scanner's noise), for CT's sample kind.
//!
//! Each can also be generated at any edge `n` (a scene's `size`), so that a volume of any
//! size renders without a download: the molecule resampled onto `n`³, the Marschner–Lobb
//! function sampled on `n`³, the sphere and the head on `n`³ scaled alike.
//!
//! Invariant: every volume is the same bits on every machine: a fixed seed, integer-exact
//! arithmetic where possible, and libm (not the platform's maths library) for the rest.

use crate::input::dataset::{plane_major_window, planes_on_cores, Volume, VolumeData};
use crate::rng::SplitMix;
use std::ops::Range;
use voxcube_kernel::volume::grid::Grid;
use voxcube_kernel::Vec3;

/// The names `builtin = "…"` accepts.
pub const NAMES: [&str; 4] = ["molecule", "marschner-lobb", "sphere", "head"];

/// The smallest `size`: a cell needs two samples a side.
pub const MIN_SIZE: u32 = 2;

/// The built-in volume called `name`, on `size`³ samples where given (at least [`MIN_SIZE`];
/// the caller checks it against what memory it allows), else on its own grid.
pub fn volume(name: &str, size: Option<u32>) -> Option<Volume> {
    let size = size.map(|n| n.max(MIN_SIZE));
    match (name, size) {
        ("molecule", None) => Some(molecule()),
        ("molecule", Some(n)) => Some(molecule_at(n)),
        ("marschner-lobb", n) => Some(marschner_lobb(n.unwrap_or(41))),
        ("sphere", None) => Some(sphere(64, 24.0)),
        ("sphere", Some(n)) => Some(sphere(n, 0.375 * f64::from(n))),
        ("head", n) => Some(head(n.unwrap_or(HEAD_SIZE))),
        _ => None,
    }
}

/// The grid of the built-in volume called `name` at `size` (as [`volume`] takes them), known
/// without generating a sample.
pub fn grid(name: &str, size: Option<u32>) -> Option<Grid> {
    let n = size.map(|n| n.max(MIN_SIZE));
    let dims = match (name, n) {
        ("molecule", None) => [97, 97, 116],
        ("marschner-lobb", n) => [n.unwrap_or(41); 3],
        ("sphere", n) => [n.unwrap_or(64); 3],
        ("head", n) => [n.unwrap_or(HEAD_SIZE); 3],
        ("molecule", Some(n)) => [n; 3],
        _ => return None,
    };
    Grid::new(dims, Vec3::ONE).ok()
}

/// Of the built-in volume called `name` at `size`, the X planes `planes` alone: the same
/// samples as [`volume`]'s, generated without the others where the volume is big (a sized
/// one), so that a node's rank holds only what its slab stores. `None` for an unknown name
/// or planes past the grid.
pub fn window(name: &str, size: Option<u32>, planes: Range<u32>) -> Option<Volume> {
    let grid = grid(name, size)?;
    if planes.start > planes.end || planes.end > grid.dims()[0] {
        return None;
    }
    let n = size.map(|n| n.max(MIN_SIZE));
    match (name, n) {
        ("molecule", Some(n)) => Some(molecule_planes(n, planes)),
        ("marschner-lobb", Some(n)) => Some(marschner_lobb_planes(n, planes)),
        ("sphere", Some(n)) => Some(sphere_planes(n, 0.375 * f64::from(n), planes)),
        ("head", n) => Some(head_planes(n.unwrap_or(HEAD_SIZE), planes)),
        // The volumes of their own size are small: generated whole, then cut.
        _ => volume(name, size)?.planes(planes),
    }
}

/// Random unit vectors for the molecule's chain.
fn unit_vector(rng: &mut SplitMix) -> [f64; 3] {
    loop {
        let v = [rng.signed(), rng.signed(), rng.signed()];
        let n2 = v.iter().map(|c| c * c).sum::<f64>();
        if n2 > 1e-4 && n2 <= 1.0 {
            let n = libm::sqrt(n2);
            return v.map(|c| c / n);
        }
    }
}

/// An atom: centre (grid units), peak density, Gaussian width.
struct Atom {
    at: [f64; 3],
    peak: f64,
    sigma: f64,
}

/// The procedural electron-density map.
pub fn molecule() -> Volume {
    const DIMS: [u32; 3] = [97, 97, 116];
    let mut rng = SplitMix(0x050D_1992);
    let mid = DIMS.map(|d| f64::from(d - 1) / 2.0);
    let mut atoms = Vec::new();
    // SOD is a dimer: two chains, each folded inside its own ellipsoid, side by side along Z.
    for (subunit, dz) in [(0usize, -24.0f64), (1, 24.0)] {
        let centre = [mid[0], mid[1], mid[2] + dz];
        let reach = [36.0, 36.0, 26.0];
        let mut pos = [
            centre[0] - 20.0,
            centre[1] + 10.0 * subunit as f64,
            centre[2],
        ];
        let mut dir = [1.0, 0.0, 0.0];
        for residue in 0..400 {
            // Persistent direction plus a random turn, pulled back inside the ellipsoid.
            let r = unit_vector(&mut rng);
            let mut pull = [0.0; 3];
            let mut outside = 0.0;
            for a in 0..3 {
                let u = (pos[a] - centre[a]) / reach[a];
                outside += u * u;
                pull[a] = -u;
            }
            let k = if outside > 1.0 { 0.9 } else { 0.02 };
            let mut d = [0.0; 3];
            for a in 0..3 {
                d[a] = 0.65 * dir[a] + 0.55 * r[a] + k * pull[a];
            }
            let n = libm::sqrt(d.iter().map(|c| c * c).sum::<f64>());
            dir = d.map(|c| c / n);
            for a in 0..3 {
                pos[a] += 3.8 * dir[a];
            }
            atoms.push(Atom {
                at: pos,
                peak: 105.0,
                sigma: 1.3,
            });
            // Side-chain atoms off the backbone.
            let mut s = pos;
            for _ in 0..2 + residue % 3 {
                let o = unit_vector(&mut rng);
                for a in 0..3 {
                    s[a] += 1.5 * o[a];
                }
                atoms.push(Atom {
                    at: s,
                    peak: 75.0,
                    sigma: 1.15,
                });
            }
        }
    }
    // Two heavy-metal peaks (SOD's copper and zinc) near the middle of the chain.
    for i in [500usize, 2300] {
        let a = &atoms[i];
        atoms.push(Atom {
            at: [a.at[0] + 2.0, a.at[1] - 1.5, a.at[2] + 1.0],
            peak: 900.0,
            sigma: 1.3,
        });
    }
    let [nx, ny, nz] = DIMS.map(|d| d as usize);
    let mut density = vec![0.0f64; nx * ny * nz];
    for atom in &atoms {
        let cut = 3.5 * atom.sigma;
        let lo = |a: usize| (atom.at[a] - cut).ceil().max(0.0) as usize;
        let hi = |a: usize, n: usize| {
            ((atom.at[a] + cut).floor().max(-1.0) as i64 + 1).clamp(0, n as i64) as usize
        };
        for z in lo(2)..hi(2, nz) {
            for y in lo(1)..hi(1, ny) {
                for x in lo(0)..hi(0, nx) {
                    let d2 = [x, y, z]
                        .iter()
                        .zip(atom.at)
                        .map(|(&g, c)| (g as f64 - c).powi(2))
                        .sum::<f64>();
                    density[(z * ny + y) * nx + x] +=
                        atom.peak * libm::exp(-d2 / (2.0 * atom.sigma * atom.sigma));
                }
            }
        }
    }
    let file_order: Vec<u8> = density
        .iter()
        .map(|&d| d.round().clamp(0.0, 255.0) as u8)
        .collect();
    volume_from(
        DIMS,
        VolumeData::U8(crate::input::dataset::to_plane_major(&file_order, DIMS)),
    )
}

/// The molecule resampled trilinearly onto `n`³ samples (its 97×97×116 box stretched to a
/// cube), rounded to u8: a volume of the molecule's character at any size. The interpolation
/// is separable, along X, then Z, then Y (each a lerp in `f32`), so that a sample costs one
/// lerp and a gigabyte takes seconds, not minutes.
pub fn molecule_at(n: u32) -> Volume {
    let n = n.max(MIN_SIZE);
    molecule_planes(n, 0..n)
}

/// [`molecule_at`]'s X planes `planes` alone (within `0..n`, `n` at least [`MIN_SIZE`]).
fn molecule_planes(n: u32, planes: Range<u32>) -> Volume {
    let m = molecule();
    let [mx, my, mz] = m.grid.dims().map(|d| d as usize);
    let VolumeData::U8(src) = &m.data else {
        unreachable!("the molecule is u8")
    };
    // Per axis and output index: the source's lower node and the weight of the upper one.
    let taps = |d: usize| -> Vec<(usize, f32)> {
        let scale = (d - 1) as f32 / (n - 1) as f32;
        (0..n)
            .map(|i| {
                let p = i as f32 * scale;
                let lo = (p as usize).min(d - 2);
                (lo, p - lo as f32)
            })
            .collect()
    };
    let (tx, ty, tz) = (taps(mx), taps(my), taps(mz));
    let lerp = |a: f32, b: f32, w: f32| a + w * (b - a);
    // Plane-major source: plane x, then z, then y fastest.
    let plane = |x: usize| &src[x * mz * my..][..mz * my];
    let nn = n as usize;
    let data = planes_on_cores([n; 3], planes.clone(), |x, out| {
        let (x, wx) = tx[x as usize];
        let (a, b) = (plane(x), plane(x + 1));
        let along_x: Vec<f32> = a
            .iter()
            .zip(b)
            .map(|(&a, &b)| lerp(f32::from(a), f32::from(b), wx))
            .collect();
        let mut along_z = vec![0.0f32; my];
        for (&(z, wz), row) in tz.iter().zip(out.chunks_mut(nn)) {
            let (a, b) = (&along_x[z * my..][..my], &along_x[(z + 1) * my..][..my]);
            for (o, (&a, &b)) in along_z.iter_mut().zip(a.iter().zip(b)) {
                *o = lerp(a, b, wz);
            }
            for (slot, &(y, wy)) in row.iter_mut().zip(&ty) {
                let v = lerp(along_z[y], along_z[y + 1], wy);
                *slot = v.round().clamp(0.0, 255.0) as u8;
            }
        }
    });
    window_from([n; 3], planes.start, VolumeData::U8(data))
}

/// The Marschner–Lobb function (f_M = 6, α = 1/4) on `[-1, 1]³`, `n` samples per axis (41 by
/// default).
pub fn marschner_lobb(n: u32) -> Volume {
    let n = n.max(MIN_SIZE);
    marschner_lobb_planes(n, 0..n)
}

/// [`marschner_lobb`]'s X planes `planes` alone.
fn marschner_lobb_planes(n: u32, planes: Range<u32>) -> Volume {
    let (fm, alpha) = (6.0f64, 0.25f64);
    let pi = core::f64::consts::PI;
    let c = |i: u32| -1.0 + 2.0 * f64::from(i) / f64::from(n - 1);
    let dims = [n; 3];
    let first = planes.start;
    let data = plane_major_window(dims, planes, |x, y, z| {
        let (x, y, z) = (c(x), c(y), c(z));
        let r = libm::sqrt(x * x + y * y);
        let rho = libm::cos(2.0 * pi * fm * libm::cos(pi * r / 2.0));
        ((1.0 - libm::sin(pi * z / 2.0) + alpha * (1.0 + rho)) / (2.0 * (1.0 + alpha))) as f32
    });
    window_from(dims, first, VolumeData::F32(data))
}

/// Signed distance (cells) to a sphere of `radius` centred in an `n³` grid, positive inside.
pub fn sphere(n: u32, radius: f64) -> Volume {
    sphere_planes(n, radius, 0..n)
}

/// [`sphere`]'s X planes `planes` alone.
fn sphere_planes(n: u32, radius: f64, planes: Range<u32>) -> Volume {
    let c = f64::from(n - 1) / 2.0;
    let first = planes.start;
    let data = plane_major_window([n; 3], planes, |x, y, z| {
        let d = [x, y, z].map(|g| f64::from(g) - c);
        (radius - libm::sqrt(d.iter().map(|v| v * v).sum())) as f32
    });
    window_from([n; 3], first, VolumeData::F32(data))
}

/// The head's edge, samples, where a scene gives no `size`.
const HEAD_SIZE: u32 = 128;

/// One ellipsoid of the head: its centre and semi-axes in the head's frame (`[-1, 1]` across
/// the grid; X from ear to ear, Y up, Z from front to back), its turn about Y, and what it
/// adds inside, Hounsfield units.
struct Ellipsoid {
    centre: [f64; 3],
    semi: [f64; 3],
    turn_degrees: f64,
    adds: f64,
}

/// Shepp and Logan's ellipses (modified, as Toft gives them) laid in the axial plane (their
/// y along Z), each given a height, the brain's a little smaller so that the skull is two
/// samples thick at 64³, under a scalp; their densities as tissues: air -1000 HU outside,
/// scalp +40, skull +1000, brain +40, ventricles +10 (fluid), small lesions +70 to +80.
#[rustfmt::skip] // One ellipsoid a row reads as the phantom's table.
const HEAD: [Ellipsoid; 11] = [
    Ellipsoid { centre: [0.0, 0.0, 0.0], semi: [0.74, 0.95, 0.97], turn_degrees: 0.0, adds: 1040.0 },
    Ellipsoid { centre: [0.0, 0.0, 0.0], semi: [0.69, 0.9, 0.92], turn_degrees: 0.0, adds: 960.0 },
    Ellipsoid { centre: [0.0, 0.0, -0.0184], semi: [0.64, 0.86, 0.85], turn_degrees: 0.0, adds: -960.0 },
    Ellipsoid { centre: [0.22, 0.0, 0.0], semi: [0.11, 0.25, 0.31], turn_degrees: -18.0, adds: -30.0 },
    Ellipsoid { centre: [-0.22, 0.0, 0.0], semi: [0.16, 0.3, 0.41], turn_degrees: 18.0, adds: -30.0 },
    Ellipsoid { centre: [0.0, 0.1, 0.35], semi: [0.21, 0.2, 0.25], turn_degrees: 0.0, adds: 30.0 },
    Ellipsoid { centre: [0.0, 0.0, 0.1], semi: [0.046, 0.046, 0.046], turn_degrees: 0.0, adds: 30.0 },
    Ellipsoid { centre: [0.0, 0.0, -0.1], semi: [0.046, 0.046, 0.046], turn_degrees: 0.0, adds: 30.0 },
    Ellipsoid { centre: [-0.08, -0.25, -0.605], semi: [0.046, 0.04, 0.023], turn_degrees: 0.0, adds: 40.0 },
    Ellipsoid { centre: [0.0, -0.25, -0.606], semi: [0.023, 0.04, 0.023], turn_degrees: 0.0, adds: 40.0 },
    Ellipsoid { centre: [0.06, -0.25, -0.605], semi: [0.023, 0.04, 0.046], turn_degrees: 0.0, adds: 40.0 },
];

/// The head phantom on `n`³ samples (at least [`MIN_SIZE`]).
pub fn head(n: u32) -> Volume {
    let n = n.max(MIN_SIZE);
    head_planes(n, 0..n)
}

/// [`head`]'s X planes `planes` alone. Each sample depends on its node alone (the noise is
/// a hash of the node's index), so a window is the whole volume's planes.
fn head_planes(n: u32, planes: Range<u32>) -> Volume {
    let n = n.max(MIN_SIZE);
    let half = f64::from(n - 1) / 2.0;
    let at = |i: u32| (f64::from(i) - half) / half;
    // A sample's width in the head's frame: each edge ramps over about one sample.
    let sample = 1.0 / half;
    // Per ellipsoid, what every sample asks of it: its turn's cosine and sine, the half-width
    // of the box that bounds it and its ramp, and its least semi-axis.
    let shapes: Vec<(f64, f64, f64, f64)> = HEAD
        .iter()
        .map(|e| {
            let t = e.turn_degrees.to_radians();
            let reach = e.semi[0].max(e.semi[1]).max(e.semi[2]) + sample;
            let least = e.semi[0].min(e.semi[1]).min(e.semi[2]);
            (libm::cos(t), libm::sin(t), reach, least)
        })
        .collect();
    let first = planes.start;
    let data = plane_major_window([n; 3], planes, |x, y, z| {
        let p = [at(x), at(y), at(z)];
        let mut hu = -1000.0;
        for (e, &(c, s, reach, least)) in HEAD.iter().zip(&shapes) {
            let d = [p[0] - e.centre[0], p[1] - e.centre[1], p[2] - e.centre[2]];
            // Outside the box that bounds it and its ramp, nothing to add.
            if d.iter().any(|v| v.abs() > reach) {
                continue;
            }
            let (u, w) = (c * d[0] - s * d[2], s * d[0] + c * d[2]);
            // Squares multiplied out (`powi`'s precision may differ between platforms).
            let sq = |v: f64| v * v;
            let r = libm::sqrt(sq(u / e.semi[0]) + sq(d[1] / e.semi[1]) + sq(w / e.semi[2]));
            // Inside by the distance to the surface along the least semi-axis, in samples:
            // full beyond half a sample in, none beyond half a sample out.
            let inside = ((1.0 - r) * least / sample + 0.5).clamp(0.0, 1.0);
            hu += e.adds * inside;
        }
        // A scanner's noise, a triangle of ±20 HU from two uniform draws keyed by the node.
        let key = (u64::from(z) * u64::from(n) + u64::from(y)) * u64::from(n) + u64::from(x);
        let mut rng = SplitMix(key ^ 0x6865_6164);
        let noise = 10.0 * (rng.signed() + rng.signed());
        (hu + noise).round().clamp(-32_768.0, 32_767.0) as i16
    });
    window_from([n; 3], first, VolumeData::I16(data))
}

fn volume_from(dims: [u32; 3], data: VolumeData) -> Volume {
    window_from(dims, 0, data)
}

/// The planes from `first` of a built-in volume on `dims`.
fn window_from(dims: [u32; 3], first: u32, data: VolumeData) -> Volume {
    // Fixed, valid dimensions and unit spacing: this cannot fail.
    #[allow(clippy::expect_used, reason = "constant, valid dimensions")]
    let grid = Grid::new(dims, Vec3::ONE).expect("built-in grids are valid");
    Volume::window(grid, first, data)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_head_is_a_ct_in_hounsfield_units() {
        let n = 64;
        let h = head(n);
        let VolumeData::I16(v) = &h.data else {
            panic!("the head is i16")
        };
        let at = |x: u32, y: u32, z: u32| v[((x * n + z) * n + y) as usize];
        let noisy = |got: i16, tissue: i16| (got - tissue).abs() <= 20;
        let c = n / 2;
        // Air at a corner, scalp where it crosses the X axis (0.69 to 0.74 of the
        // half-width), brain inside, bone between 0.64 and 0.69, fluid in a ventricle.
        assert!(noisy(at(0, 0, 0), -1000), "{}", at(0, 0, 0));
        let scalp = at(c - 23, c, c);
        assert!(noisy(scalp, 40), "{scalp}");
        assert!(
            noisy(at(c, c + 10, c - 10), 40),
            "{}",
            at(c, c + 10, c - 10)
        );
        let skull = (0..c).map(|x| at(x, c, c)).max().unwrap_or(0);
        assert!(skull > 700, "bone, however the samples fall: {skull}");
        let ventricle = at(c + 7, c, c);
        assert!(noisy(ventricle, 10), "{ventricle}");
        // Noise: not one value everywhere in the brain.
        let brain: std::collections::BTreeSet<i16> =
            (0..8).map(|d| at(c + d, c + 10, c - 10)).collect();
        assert!(brain.len() > 2, "{brain:?}");
    }

    #[test]
    fn builtins_have_their_documented_shape() {
        let m = molecule();
        assert_eq!(m.grid.dims(), [97, 97, 116]);
        let s = m.stats();
        assert_eq!((s.min, s.max), (0.0, 255.0));
        // SOD itself: min 0, max 255, mean 7.46.
        assert!(s.mean > 4.0 && s.mean < 12.0, "{s}");
        assert_eq!(marschner_lobb(41).grid.dims(), [41; 3]);
        let sp = sphere(8, 2.0).stats();
        assert!(sp.max > 1.0 && sp.min < -3.0);
    }

    /// A window of planes is the whole volume's planes, bit for bit, for every built-in, sized
    /// or not, at the ends and inside; its grid is the one [`grid`] names without generating;
    /// planes past the grid are refused.
    #[test]
    fn a_window_is_the_whole_volume_s_planes() {
        for name in NAMES {
            for size in [None, Some(7), Some(40)] {
                let whole = volume(name, size).unwrap_or_else(|| panic!("{name}"));
                assert_eq!(grid(name, size), Some(whole.grid), "{name} {size:?}");
                let nx = whole.grid.dims()[0];
                for planes in [0..nx, 0..1, 2..5, nx - 3..nx, 4..4] {
                    let window = window(name, size, planes.clone()).expect("a window");
                    assert_eq!(window.held(), planes, "{name} {size:?}");
                    assert!(window.is_whole() == (planes == (0..nx)));
                    assert_eq!(
                        Some(window),
                        whole.planes(planes.clone()),
                        "{name} {size:?} {planes:?}"
                    );
                }
                assert!(window(name, size, nx - 1..nx + 1).is_none());
            }
        }
        // The control: a window is not just any planes of the volume.
        let whole = molecule_at(40);
        assert_ne!(
            Some(window("molecule", Some(40), 10..12).unwrap()),
            whole
                .planes(11..13)
                .map(|v| Volume::window(v.grid, 10, v.data))
        );
    }

    #[test]
    fn every_builtin_takes_any_size() {
        for name in NAMES {
            let v = volume(name, Some(5)).unwrap_or_else(|| panic!("{name}"));
            assert_eq!(v.grid.dims(), [5; 3], "{name}");
        }
        assert_eq!(volume("sphere", None), Some(sphere(64, 24.0)));
        assert_eq!(
            volume("molecule", Some(1)).map(|v| v.grid.dims()),
            Some([2; 3])
        );
        assert_eq!(volume("nothing", Some(8)), None);
    }

    #[test]
    fn the_resampled_molecule_is_the_molecule_where_its_nodes_fall_on_the_molecule_s() {
        let m = molecule();
        let VolumeData::U8(src) = &m.data else {
            unreachable!()
        };
        // At 97 the X and Y axes map node onto node: plane x, row z' = 0, every y.
        let small = molecule_at(97);
        let VolumeData::U8(out) = &small.data else {
            unreachable!()
        };
        for x in [0usize, 40, 96] {
            assert_eq!(
                out[x * 97 * 97..][..97],
                src[x * 116 * 97..][..97],
                "plane {x}"
            );
        }
        // The first and last nodes of every axis are the molecule's corners.
        let big = molecule_at(200);
        let VolumeData::U8(b) = &big.data else {
            unreachable!()
        };
        let last = |d: usize, nz: usize, ny: usize| (d * nz) * ny;
        assert_eq!(b[last(199, 200, 200)], src[last(96, 116, 97)]);
        assert_eq!(b[b.len() - 1], src[src.len() - 1]);
        assert!(big.stats().max > 100.0, "{}", big.stats());
    }

    #[test]
    fn the_molecule_is_the_same_every_time() {
        assert_eq!(molecule(), molecule());
    }
}
