//! A loaded dataset: its grid and samples, held plane-major (X slowest, then Z, then Y) so
//! that any range of X planes — a slab — is one contiguous slice, with no copy.
//!
//! Invariants: `data` holds exactly the samples of the X planes [`Volume::held`] names: every
//! plane (`nx·ny·nz` samples), unless an MPI node's rank loaded only a window of them, those
//! its slab stores; float samples are finite (loaders reject NaN and infinities, naming the
//! first one's position).

use std::fmt;
use std::ops::Range;
use voxcube_kernel::volume::grid::Grid;
use voxcube_kernel::volume::sample::SampleKind;

/// Samples of a dataset, plane-major.
#[derive(Clone, Debug, PartialEq)]
pub enum VolumeData {
    /// Unsigned 8-bit.
    U8(Vec<u8>),
    /// Unsigned 16-bit.
    U16(Vec<u16>),
    /// Signed 16-bit (CT series in Hounsfield units, for one).
    I16(Vec<i16>),
    /// 32-bit float (also holds files of other types, converted: exactly for `i8`).
    F32(Vec<f32>),
}

impl VolumeData {
    /// The sample kind.
    pub fn kind(&self) -> SampleKind {
        match self {
            VolumeData::U8(_) => SampleKind::U8,
            VolumeData::U16(_) => SampleKind::U16,
            VolumeData::I16(_) => SampleKind::I16,
            VolumeData::F32(_) => SampleKind::F32,
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        match self {
            VolumeData::U8(v) => v.len(),
            VolumeData::U16(v) => v.len(),
            VolumeData::I16(v) => v.len(),
            VolumeData::F32(v) => v.len(),
        }
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Minimum, maximum and mean of a dataset's values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stats {
    /// Smallest value.
    pub min: f64,
    /// Largest value.
    pub max: f64,
    /// Mean value.
    pub mean: f64,
}

impl fmt::Display for Stats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "min {} max {} mean {:.2}", self.min, self.max, self.mean)
    }
}

/// A dataset in memory.
#[derive(Clone, Debug, PartialEq)]
pub struct Volume {
    /// The grid.
    pub grid: Grid,
    /// The samples, plane-major, of the planes from `first` on.
    pub data: VolumeData,
    /// The first X plane `data` holds: 0 for a whole volume.
    pub first: u32,
    /// What is built once from `data` (a new volume for new samples starts with nothing).
    pub built: crate::memory::built::Built,
}

impl Volume {
    /// The volume of `data` on `grid`, with nothing built from it yet.
    pub fn new(grid: Grid, data: VolumeData) -> Volume {
        Volume {
            grid,
            data,
            first: 0,
            built: crate::memory::built::Built::default(),
        }
    }

    /// The window of `grid`'s X planes from `first` whose samples are `data`: what a node's
    /// rank holds when it loads only the planes its slab stores.
    pub fn window(grid: Grid, first: u32, data: VolumeData) -> Volume {
        Volume {
            first,
            ..Volume::new(grid, data)
        }
    }

    /// The X planes `data` holds.
    pub fn held(&self) -> Range<u32> {
        let planes = self.data.len() / self.grid.plane_len().max(1);
        self.first..self.first + planes as u32
    }

    /// Whether it holds every plane of its grid.
    pub fn is_whole(&self) -> bool {
        self.held() == (0..self.grid.dims()[0])
    }

    /// Value statistics (exact sums in `f64`).
    pub fn stats(&self) -> Stats {
        fn of<T: Copy + Into<f64>>(v: &[T]) -> Stats {
            let (mut min, mut max, mut sum) = (f64::INFINITY, f64::NEG_INFINITY, 0.0f64);
            for &x in v {
                let x: f64 = x.into();
                min = min.min(x);
                max = max.max(x);
                sum += x;
            }
            Stats {
                min,
                max,
                mean: sum / v.len().max(1) as f64,
            }
        }
        match &self.data {
            VolumeData::U8(v) => of(v),
            VolumeData::U16(v) => of(v),
            VolumeData::I16(v) => of(v),
            VolumeData::F32(v) => of(v),
        }
    }

    /// The least and greatest value of the planes it holds (`None` for none), computed once
    /// in the samples' own type, a pass the compiler vectorises, and kept with what is built
    /// from them: what the warnings of a view that draws nothing test against, and what a
    /// node's rank tells a host that holds no sample.
    pub fn held_range(&self) -> Option<(f64, f64)> {
        fn of<T: Copy + Into<f64>>(
            v: &[T],
            least: fn(T, T) -> T,
            most: fn(T, T) -> T,
        ) -> Option<(f64, f64)> {
            let (&first, rest) = v.split_first()?;
            let (lo, hi) = rest
                .iter()
                .fold((first, first), |(lo, hi), &x| (least(lo, x), most(hi, x)));
            Some((lo.into(), hi.into()))
        }
        self.built.summary(self.held(), || match &self.data {
            VolumeData::U8(v) => of(v, u8::min, u8::max),
            VolumeData::U16(v) => of(v, u16::min, u16::max),
            VolumeData::I16(v) => of(v, i16::min, i16::max),
            VolumeData::F32(v) => of(v, f32::min, f32::max),
        })
    }

    /// The root-mean-square deviation of the values from their `mean` (σ), what density maps
    /// are contoured in: a pass of its own about the mean (no cancellation between two large
    /// sums), taken only where it is asked for, not with every view's [`Volume::stats`].
    pub fn rms(&self, mean: f64) -> f64 {
        fn of<T: Copy + Into<f64>>(v: &[T], mean: f64) -> f64 {
            let squares: f64 = v.iter().map(|&x| (x.into() - mean).powi(2)).sum();
            (squares / v.len().max(1) as f64).sqrt()
        }
        match &self.data {
            VolumeData::U8(v) => of(v, mean),
            VolumeData::U16(v) => of(v, mean),
            VolumeData::I16(v) => of(v, mean),
            VolumeData::F32(v) => of(v, mean),
        }
    }

    /// The window of the X planes `planes` (of those it holds): one contiguous copy, what a
    /// node's rank keeps of a volume generated whole; `None` where it does not hold them all.
    pub fn planes(&self, planes: Range<u32>) -> Option<Volume> {
        fn cut<T: Clone>(v: &[T], r: Range<usize>) -> Option<Vec<T>> {
            v.get(r).map(<[T]>::to_vec)
        }
        let held = self.held();
        if planes.start < held.start || planes.end > held.end || planes.start > planes.end {
            return None;
        }
        let n = self.grid.plane_len();
        let r = (planes.start - self.first) as usize * n..(planes.end - self.first) as usize * n;
        let data = match &self.data {
            VolumeData::U8(v) => VolumeData::U8(cut(v, r)?),
            VolumeData::U16(v) => VolumeData::U16(cut(v, r)?),
            VolumeData::I16(v) => VolumeData::I16(cut(v, r)?),
            VolumeData::F32(v) => VolumeData::F32(cut(v, r)?),
        };
        Some(Volume::window(self.grid, planes.start, data))
    }
}

/// Samples `f(x, y, z)` for every node of a `dims` grid, plane-major, called one node at a
/// time in that order, so that `f` may keep state (a test's random stream); a built-in's
/// window, whose samples depend on their nodes alone, takes [`plane_major_window`].
pub fn plane_major_from_fn<T>(dims: [u32; 3], mut f: impl FnMut(u32, u32, u32) -> T) -> Vec<T> {
    let [nx, ny, nz] = dims;
    let mut out = Vec::with_capacity(nx as usize * ny as usize * nz as usize);
    for x in 0..nx {
        for z in 0..nz {
            for y in 0..ny {
                out.push(f(x, y, z));
            }
        }
    }
    out
}

/// Samples a thread of [`planes_on_cores`] takes at least: below twice this many a window is
/// filled on the calling thread alone.
const SAMPLES_PER_THREAD: usize = 1 << 20;

/// Samples `f(x, y, z)` for every node of a `dims` grid on the X planes `planes`, plane-major,
/// on the machine's cores ([`planes_on_cores`]).
pub fn plane_major_window<T: Clone + Default + Send>(
    dims: [u32; 3],
    planes: Range<u32>,
    f: impl Fn(u32, u32, u32) -> T + Sync,
) -> Vec<T> {
    let [_, ny, nz] = dims;
    planes_on_cores(dims, planes, |x, plane| {
        let nodes = (0..nz).flat_map(|z| (0..ny).map(move |y| (y, z)));
        for (slot, (y, z)) in plane.iter_mut().zip(nodes) {
            *slot = f(x, y, z);
        }
    })
}

/// The X planes `planes` of a `dims` grid, plane-major, each written by `fill(x, plane)`, the
/// planes shared among the machine's cores: a built-in volume of 512³ computes its samples,
/// not reads them, and a plane that depends on its index alone is the same whichever thread
/// computes it.
pub fn planes_on_cores<T: Clone + Default + Send>(
    dims: [u32; 3],
    planes: Range<u32>,
    fill: impl Fn(u32, &mut [T]) + Sync,
) -> Vec<T> {
    use crate::memory::parts::{even_parts, split_sizes};
    let [_, ny, nz] = dims;
    let per_plane = ny as usize * nz as usize;
    let mut out = vec![T::default(); planes.len() * per_plane];
    let cores = std::thread::available_parallelism().map_or(1, usize::from);
    let threads = cores.min(out.len() / SAMPLES_PER_THREAD).max(1);
    let parts = even_parts(planes.len() as u32, threads as u32);
    let run = |xs: Range<u32>, piece: &mut [T]| {
        for (x, plane) in xs.zip(piece.chunks_mut(per_plane.max(1))) {
            fill(x, plane);
        }
    };
    // Threads of its own rather than `parts::run_parts`, whose parts may fail and leave
    // nothing built: a volume has no such fallback, and a fill that panics must end the load.
    let sizes = parts.iter().map(|p| p.len() * per_plane);
    let pieces: Vec<(Range<u32>, &mut [T])> = parts
        .iter()
        .map(|p| p.start + planes.start..p.end + planes.start)
        .zip(split_sizes(&mut out, sizes))
        .collect();
    std::thread::scope(|scope| {
        let mut pieces = pieces.into_iter();
        let mine = pieces.next();
        for (xs, piece) in pieces {
            scope.spawn(|| run(xs, piece));
        }
        if let Some((xs, piece)) = mine {
            run(xs, piece);
        }
    });
    out
}

/// Reorder samples from file order (X fastest, then Y, then Z) to plane-major.
pub fn to_plane_major<T: Copy + Default>(file_order: &[T], dims: [u32; 3]) -> Vec<T> {
    let [nx, ny, nz] = dims.map(|d| d as usize);
    let mut out = vec![T::default(); file_order.len()];
    for z in 0..nz {
        for y in 0..ny {
            let row = &file_order[(z * ny + y) * nx..][..nx];
            for (x, &v) in row.iter().enumerate() {
                out[(x * nz + z) * ny + y] = v;
            }
        }
    }
    out
}

/// Reorder plane-major samples back to file order (X fastest, then Y, then Z): the inverse
/// of [`to_plane_major`], for a peer renderer that reads raw files.
pub fn to_file_order<T: Copy + Default>(plane_major: &[T], dims: [u32; 3]) -> Vec<T> {
    let [nx, ny, nz] = dims.map(|d| d as usize);
    let mut out = vec![T::default(); plane_major.len()];
    for x in 0..nx {
        let plane = &plane_major[x * nz * ny..][..nz * ny];
        for (zy, &v) in plane.iter().enumerate() {
            let (z, y) = (zy / ny, zy % ny);
            out[(z * ny + y) * nx + x] = v;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_window_filled_on_the_cores_is_its_planes_in_order() {
        // More samples than one thread's share, so that two cores or more split the planes.
        let dims = [41, 200, 300];
        let f = |x: u32, y: u32, z: u32| {
            x.wrapping_mul(73_856_093) ^ y.wrapping_mul(19_349_663) ^ z.wrapping_mul(83_492_791)
        };
        let whole = plane_major_from_fn(dims, f);
        let per_plane = 200 * 300;
        assert!(whole.len() > 2 * SAMPLES_PER_THREAD);
        for planes in [0..41, 7..33, 40..41, 5..5] {
            let window = plane_major_window(dims, planes.clone(), f);
            let expected =
                &whole[planes.start as usize * per_plane..planes.end as usize * per_plane];
            assert!(window == expected, "planes {planes:?}");
        }
    }

    #[test]
    fn plane_major_puts_each_x_plane_together() {
        // 2×2×2, file order value = x + 2y + 4z.
        let file: Vec<u8> = (0..8).collect();
        let pm = to_plane_major(&file, [2, 2, 2]);
        // Plane x = 0 holds (y, z) = (0,0), (1,0), (0,1), (1,1).
        assert_eq!(pm, vec![0, 2, 4, 6, 1, 3, 5, 7]);
        assert_eq!(
            plane_major_from_fn([2, 2, 2], |x, y, z| (x + 2 * y + 4 * z) as u8),
            pm
        );
    }

    /// The range a rank reports is its planes' least and greatest value, as the statistics
    /// give them, for every sample type; a window of no planes has none.
    #[test]
    fn the_held_range_is_the_statistics_extremes() {
        let grid = Grid::new([3, 2, 2], voxcube_kernel::Vec3::ONE).unwrap();
        let u8s: Vec<u8> = vec![9, 3, 250, 7, 1, 2, 3, 4, 5, 6, 7, 8];
        for data in [
            VolumeData::U8(u8s.clone()),
            VolumeData::U16(u8s.iter().map(|&v| u16::from(v) * 250).collect()),
            VolumeData::F32(u8s.iter().map(|&v| f32::from(v) - 100.5).collect()),
        ] {
            let volume = Volume::new(grid, data);
            let stats = volume.stats();
            assert_eq!(volume.held_range(), Some((stats.min, stats.max)));
            let window = volume.planes(1..2).unwrap();
            let stats = window.stats();
            assert_eq!(window.held_range(), Some((stats.min, stats.max)));
            assert_ne!(window.held_range(), volume.held_range());
            assert_eq!(volume.planes(2..2).unwrap().held_range(), None);
        }
    }

    #[test]
    fn file_order_undoes_plane_major_on_uneven_dims() {
        let dims = [3, 4, 5];
        let file: Vec<u16> = (0..60).collect();
        let pm = to_plane_major(&file, dims);
        assert_ne!(pm, file);
        assert_eq!(to_file_order(&pm, dims), file);
    }
}
