//! Built-in volumes, generated in code so that voxcube renders with no files:
//! - `molecule`: a 97×97×116 u8 "electron density" in the character of the paper's SOD map
//!   (Gaussian atoms along a folded chain, two heavy-metal peaks), from a fixed seed;
//! - `marschner-lobb`: the Marschner–Lobb test function sampled on 41³, f32;
//! - `sphere`: a 64³ f32 signed distance to a sphere of radius 24 cells centred in the grid,
//!   positive inside, for analytic tests of silhouettes (iso value 0).
//!
//! Invariant: every volume is the same bits on every machine: a fixed seed, integer-exact
//! arithmetic where possible, and libm (not the platform's maths library) for the rest.

use crate::input::dataset::{plane_major_from_fn, Volume, VolumeData};
use crate::rng::SplitMix;
use voxcube_kernel::volume::grid::Grid;
use voxcube_kernel::Vec3;

/// The names `builtin = "…"` accepts.
pub const NAMES: [&str; 3] = ["molecule", "marschner-lobb", "sphere"];

/// The built-in volume called `name`.
pub fn volume(name: &str) -> Option<Volume> {
    match name {
        "molecule" => Some(molecule()),
        "marschner-lobb" => Some(marschner_lobb()),
        "sphere" => Some(sphere(64, 24.0)),
        _ => None,
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

/// The Marschner–Lobb function (f_M = 6, α = 1/4) on `[-1, 1]³`, 41 samples per axis.
pub fn marschner_lobb() -> Volume {
    const N: u32 = 41;
    let (fm, alpha) = (6.0f64, 0.25f64);
    let pi = core::f64::consts::PI;
    let c = |i: u32| -1.0 + 2.0 * f64::from(i) / f64::from(N - 1);
    let dims = [N; 3];
    let data = plane_major_from_fn(dims, |x, y, z| {
        let (x, y, z) = (c(x), c(y), c(z));
        let r = libm::sqrt(x * x + y * y);
        let rho = libm::cos(2.0 * pi * fm * libm::cos(pi * r / 2.0));
        ((1.0 - libm::sin(pi * z / 2.0) + alpha * (1.0 + rho)) / (2.0 * (1.0 + alpha))) as f32
    });
    volume_from(dims, VolumeData::F32(data))
}

/// Signed distance (cells) to a sphere of `radius` centred in an `n³` grid, positive inside.
pub fn sphere(n: u32, radius: f64) -> Volume {
    let c = f64::from(n - 1) / 2.0;
    let data = plane_major_from_fn([n; 3], |x, y, z| {
        let d = [x, y, z].map(|g| f64::from(g) - c);
        (radius - libm::sqrt(d.iter().map(|v| v * v).sum())) as f32
    });
    volume_from([n; 3], VolumeData::F32(data))
}

fn volume_from(dims: [u32; 3], data: VolumeData) -> Volume {
    // Fixed, valid dimensions and unit spacing: this cannot fail.
    #[allow(clippy::expect_used, reason = "constant, valid dimensions")]
    let grid = Grid::new(dims, Vec3::ONE).expect("built-in grids are valid");
    Volume::new(grid, data)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtins_have_their_documented_shape() {
        let m = molecule();
        assert_eq!(m.grid.dims(), [97, 97, 116]);
        let s = m.stats();
        assert_eq!((s.min, s.max), (0.0, 255.0));
        // SOD itself: min 0, max 255, mean 7.46.
        assert!(s.mean > 4.0 && s.mean < 12.0, "{s}");
        assert_eq!(marschner_lobb().grid.dims(), [41; 3]);
        let sp = sphere(8, 2.0).stats();
        assert!(sp.max > 1.0 && sp.min < -3.0);
    }

    #[test]
    fn the_molecule_is_the_same_every_time() {
        assert_eq!(molecule(), molecule());
    }
}
