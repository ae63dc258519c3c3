//! Reading datasets from files: raw, NRRD and the Levoy `.den` format, and the errors they
//! report. Each loader reads the whole file, checks its size exactly (a truncated file and
//! trailing bytes are both errors), decodes the samples and returns them plane-major.

pub mod den;
pub mod nrrd;
pub mod raw;

use crate::dataset::{to_plane_major, Volume, VolumeData};
use std::fmt;
use std::path::{Path, PathBuf};
use voxcube_kernel::volume::grid::{Grid, GridError};
use voxcube_kernel::Vec3;

/// Sample types a file may hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileType {
    /// Unsigned 8-bit.
    U8,
    /// Unsigned 16-bit.
    U16,
    /// Signed 8-bit (converted to f32 exactly).
    I8,
    /// Signed 16-bit (converted to f32 exactly).
    I16,
    /// 32-bit IEEE float.
    F32,
}

impl FileType {
    /// Bytes per sample.
    pub fn bytes(self) -> usize {
        match self {
            FileType::U8 | FileType::I8 => 1,
            FileType::U16 | FileType::I16 => 2,
            FileType::F32 => 4,
        }
    }
}

/// Byte order of multi-byte samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Endian {
    /// Least significant byte first.
    Little,
    /// Most significant byte first.
    Big,
}

/// What is wrong with a dataset file.
#[derive(Debug, thiserror::Error)]
pub enum LoadErrorKind {
    /// The file could not be read.
    #[error("cannot read: {0}")]
    Io(#[from] std::io::Error),
    /// Fewer bytes than the header and dimensions require.
    #[error("truncated: expected {expected} bytes, found {actual}")]
    Truncated {
        /// Bytes required.
        expected: u64,
        /// Bytes present.
        actual: u64,
    },
    /// More bytes than the header and dimensions account for.
    #[error("{extra} trailing bytes: expected {expected} bytes, found {actual} (wrong dims, type or header size?)")]
    Trailing {
        /// Bytes required.
        expected: u64,
        /// Bytes present.
        actual: u64,
        /// The difference.
        extra: u64,
    },
    /// The grid is unusable.
    #[error("{0}")]
    Grid(#[from] GridError),
    /// A float sample is NaN or infinite.
    #[error("sample at (x {x}, y {y}, z {z}) is {value}; float volumes must be finite")]
    NonFinite {
        /// Position.
        x: u32,
        /// Position.
        y: u32,
        /// Position.
        z: u32,
        /// The value.
        value: f32,
    },
    /// A header field is missing, malformed or unsupported.
    #[error("{0}")]
    Header(String),
}

/// A dataset file that could not be loaded.
#[derive(Debug)]
pub struct LoadError {
    /// The file.
    pub path: PathBuf,
    /// What is wrong.
    pub kind: LoadErrorKind,
}

impl fmt::Display for LoadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.path.display(), self.kind)
    }
}

impl std::error::Error for LoadError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        Some(&self.kind)
    }
}

impl LoadError {
    /// `kind` at `path`.
    pub fn new(path: &Path, kind: impl Into<LoadErrorKind>) -> LoadError {
        LoadError {
            path: path.to_path_buf(),
            kind: kind.into(),
        }
    }
}

/// Read a whole file.
pub fn read(path: &Path) -> Result<Vec<u8>, LoadError> {
    std::fs::read(path).map_err(|e| LoadError::new(path, e))
}

/// Check that `bytes` holds a header of `header` bytes and exactly `count` samples of `ty`.
pub fn check_size(
    bytes: &[u8],
    header: u64,
    count: u64,
    ty: FileType,
) -> Result<(), LoadErrorKind> {
    let expected = count
        .checked_mul(ty.bytes() as u64)
        .and_then(|b| b.checked_add(header))
        .ok_or(LoadErrorKind::Grid(GridError::TooManySamples))?;
    let actual = bytes.len() as u64;
    if actual < expected {
        return Err(LoadErrorKind::Truncated { expected, actual });
    }
    if actual > expected {
        return Err(LoadErrorKind::Trailing {
            expected,
            actual,
            extra: actual - expected,
        });
    }
    Ok(())
}

/// Decode `samples` (file order, exactly `nx·ny·nz` samples of `ty`) into a plane-major volume.
pub fn decode(
    samples: &[u8],
    dims: [u32; 3],
    spacing: Vec3,
    ty: FileType,
    endian: Endian,
) -> Result<Volume, LoadErrorKind> {
    let grid = Grid::new(dims, spacing)?;
    let count = dims.iter().map(|&d| u64::from(d)).product::<u64>();
    if samples.len() as u64 != count * ty.bytes() as u64 {
        return Err(LoadErrorKind::Truncated {
            expected: count * ty.bytes() as u64,
            actual: samples.len() as u64,
        });
    }
    let u16s = |b: &[u8]| match endian {
        Endian::Little => u16::from_le_bytes([b[0], b[1]]),
        Endian::Big => u16::from_be_bytes([b[0], b[1]]),
    };
    let data = match ty {
        FileType::U8 => VolumeData::U8(to_plane_major(samples, dims)),
        FileType::U16 => {
            let v: Vec<u16> = samples.chunks_exact(2).map(u16s).collect();
            VolumeData::U16(to_plane_major(&v, dims))
        }
        FileType::I8 => {
            let v: Vec<f32> = samples.iter().map(|&b| f32::from(b as i8)).collect();
            VolumeData::F32(to_plane_major(&v, dims))
        }
        FileType::I16 => {
            let v: Vec<f32> = samples
                .chunks_exact(2)
                .map(|b| f32::from(u16s(b) as i16))
                .collect();
            VolumeData::F32(to_plane_major(&v, dims))
        }
        FileType::F32 => {
            let v: Vec<f32> = samples
                .chunks_exact(4)
                .map(|b| {
                    let b = [b[0], b[1], b[2], b[3]];
                    match endian {
                        Endian::Little => f32::from_le_bytes(b),
                        Endian::Big => f32::from_be_bytes(b),
                    }
                })
                .collect();
            if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                let [nx, ny, _] = dims.map(|d| d as usize);
                return Err(LoadErrorKind::NonFinite {
                    x: (i % nx) as u32,
                    y: (i / nx % ny) as u32,
                    z: (i / (nx * ny)) as u32,
                    value: v[i],
                });
            }
            VolumeData::F32(to_plane_major(&v, dims))
        }
    };
    Ok(Volume { grid, data })
}
