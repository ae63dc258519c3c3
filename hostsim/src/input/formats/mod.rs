//! Reading datasets from files — raw, NRRD, Levoy `.den`, NIfTI-1, MetaImage, VTK (legacy
//! and XML image data) and DICOM series — and the errors they report. Each loader checks the
//! sample count exactly (a truncated file and trailing bytes are both errors, but for the
//! sections a legacy VTK file may hold after its samples), applies the
//! file's value scaling, and returns the samples plane-major in index space with the file's
//! spacing; orientation and origin are not applied (docs/datasets.md says which fields).

pub mod den;
pub mod dicom;
pub mod dicom_frames;
pub mod dicom_lengths;
pub mod metaimage;
pub mod mrc;
pub mod nifti;
pub mod nrrd;
pub mod raw;
mod vti_arrays;
pub mod vtk;

use crate::input::dataset::{Volume, VolumeData};
use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
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
    /// Signed 16-bit.
    I16,
    /// 32-bit IEEE float.
    F32,
    /// Signed 32-bit (converted to f32, rounded to nearest beyond 2^24).
    I32,
    /// Unsigned 32-bit (converted to f32, rounded to nearest beyond 2^24).
    U32,
    /// 64-bit IEEE float (converted to f32, rounded to nearest).
    F64,
}

impl FileType {
    /// Bytes per sample.
    pub fn bytes(self) -> usize {
        match self {
            FileType::U8 | FileType::I8 => 1,
            FileType::U16 | FileType::I16 => 2,
            FileType::F32 | FileType::I32 | FileType::U32 => 4,
            FileType::F64 => 8,
        }
    }

    /// Whether converting to voxcube's samples keeps every value exactly.
    pub fn exact(self) -> bool {
        !matches!(self, FileType::I32 | FileType::U32 | FileType::F64)
    }
}

/// The file formats voxcube reads, as the scene's `format` key names them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Format {
    /// Headerless samples described by the scene.
    Raw,
    /// NRRD, attached (`.nrrd`) or detached (`.nhdr`).
    Nrrd,
    /// Levoy's `.den`.
    Den,
    /// NIfTI-1 (`.nii`, `.nii.gz`, `.hdr`/`.img` pairs).
    Nifti,
    /// MetaImage (`.mha`, or `.mhd` naming its data file).
    MetaImage,
    /// VTK legacy `STRUCTURED_POINTS` (`.vtk`) or XML image data (`.vti`).
    Vtk,
    /// A folder of DICOM slices (or one multi-frame DICOM file).
    Dicom,
    /// A CCP4/MRC density map (`.map`, `.mrc`, `.ccp4`, gzipped or not).
    Mrc,
}

impl Format {
    /// Every format, as the scene file spells it.
    pub const NAMES: &'static str = "raw, nrrd, den, nifti, metaimage, vtk, dicom, mrc";

    /// The format a path's extension names, if any.
    pub fn from_extension(path: &Path) -> Option<Format> {
        let name = path.file_name()?.to_str()?.to_ascii_lowercase();
        let ext = name.rsplit('.').next()?;
        Some(match ext {
            "nrrd" | "nhdr" => Format::Nrrd,
            "den" => Format::Den,
            "nii" | "hdr" => Format::Nifti,
            "gz" if name.ends_with(".nii.gz") || name.ends_with(".hdr.gz") => Format::Nifti,
            "mha" | "mhd" => Format::MetaImage,
            "vtk" | "vti" => Format::Vtk,
            "dcm" | "dicom" => Format::Dicom,
            "map" | "mrc" | "ccp4" => Format::Mrc,
            "gz" if [".map.gz", ".mrc.gz", ".ccp4.gz"]
                .iter()
                .any(|e| name.ends_with(e)) =>
            {
                Format::Mrc
            }
            _ => return None,
        })
    }

    /// The format a file's first bytes show (a folder is a DICOM series), if any.
    pub fn sniff(path: &Path) -> Option<Format> {
        use std::io::Read;
        if path.is_dir() {
            return Some(Format::Dicom);
        }
        let mut head = Vec::with_capacity(512);
        std::fs::File::open(path)
            .ok()?
            .take(512)
            .read_to_end(&mut head)
            .ok()?;
        let text = String::from_utf8_lossy(&head).to_string();
        if head.len() >= 132 && &head[128..132] == b"DICM" {
            Some(Format::Dicom)
        } else if head.len() >= 348 && matches!(&head[344..348], b"n+1\0" | b"ni1\0") {
            Some(Format::Nifti)
        } else if head.len() >= 212 && &head[208..212] == b"MAP " {
            Some(Format::Mrc)
        } else if text.starts_with("NRRD000") {
            Some(Format::Nrrd)
        } else if text.starts_with("# vtk DataFile") || text.contains("<VTKFile") {
            Some(Format::Vtk)
        } else if text.starts_with("ObjectType") || text.starts_with("NDims") {
            Some(Format::MetaImage)
        } else {
            None
        }
    }
}

/// A gzip stream that does not decode, or fails its CRC-32 or length (ISIZE) check: the one
/// error every reader of gzip data gives.
pub(crate) fn corrupt_gzip(e: std::io::Error) -> LoadErrorKind {
    LoadErrorKind::Corrupt(format!(
        "the gzip stream does not decode or fails its CRC-32 or length check ({e})"
    ))
}

/// Load `path` as `format` (not raw: a raw file needs the scene's layout). `spacing`
/// overrides the file's.
pub fn load(path: &Path, format: Format, spacing: Option<Vec3>) -> Result<Volume, LoadError> {
    match format {
        Format::Raw => Err(LoadError::new(
            path,
            LoadErrorKind::Header("a raw file needs dims and type from the scene".into()),
        )),
        Format::Nrrd => nrrd::load(path, spacing),
        Format::Den => den::load(path, spacing),
        Format::Nifti => nifti::load(path, spacing),
        Format::MetaImage => metaimage::load(path, spacing),
        Format::Vtk => vtk::load(path, spacing),
        Format::Dicom => dicom::load(path, spacing),
        Format::Mrc => mrc::load(path, spacing),
    }
}

/// Of `path` as `format`, the X planes `planes` alone where the format streams them
/// ([`streams`]: through [`raw::load_window`], neither the file nor the other planes held); a
/// file read whole is kept whole.
pub fn load_window(
    path: &Path,
    format: Format,
    spacing: Option<Vec3>,
    planes: std::ops::Range<u32>,
) -> Result<Volume, LoadError> {
    match streamed(path, format, spacing)? {
        Some(Streamed {
            data,
            layout,
            scale: (slope, intercept),
        }) => {
            let window = raw::load_window(&data, &layout, planes)?;
            // Checked by the format's `streamed` to scale every value of the type finitely.
            rescale(window, slope, intercept).map_err(|k| LoadError::new(path, k))
        }
        None => load(path, format, spacing),
    }
}

/// Whether [`load_window`] streams `path` as `format`, holding only the planes asked for:
/// a NRRD, MetaImage or NIfTI-1 file whose samples are uncompressed at an offset its header
/// gives, or a binary legacy VTK file.
pub fn streams(path: &Path, format: Format, spacing: Option<Vec3>) -> Result<bool, LoadError> {
    Ok(streamed(path, format, spacing)?.is_some())
}

/// Where and how a file's samples lie when they can be streamed as a raw file.
pub(crate) struct Streamed {
    /// The file that holds them.
    pub(crate) data: PathBuf,
    /// Their layout there.
    pub(crate) layout: raw::RawLayout,
    /// The linear scaling (slope, intercept) the header asks of their values.
    pub(crate) scale: (f64, f64),
}

/// Where and how the samples of `path` as `format` lie when they can be streamed.
fn streamed(
    path: &Path,
    format: Format,
    spacing: Option<Vec3>,
) -> Result<Option<Streamed>, LoadError> {
    let unscaled = |s: Option<(PathBuf, raw::RawLayout)>| {
        s.map(|(data, layout)| Streamed {
            data,
            layout,
            scale: (1.0, 0.0),
        })
    };
    match format {
        Format::Nrrd => nrrd::streamed(path, spacing).map(unscaled),
        Format::MetaImage => metaimage::streamed(path, spacing).map(unscaled),
        Format::Nifti => nifti::streamed(path, spacing),
        Format::Vtk => vtk::streamed(path, spacing).map(unscaled),
        _ => Ok(None),
    }
}

/// The most bytes of a file a streamed read takes for its header: a header that does not end
/// within them is read with the whole file.
const HEADER_AT_MOST: u64 = 1 << 16;

/// The first bytes of `path`, at most [`HEADER_AT_MOST`], and whether they are all of it.
pub(crate) fn head(path: &Path) -> Result<(Vec<u8>, bool), LoadError> {
    use std::io::Read;
    let io = |e| LoadError::new(path, e);
    let mut head = Vec::new();
    std::fs::File::open(path)
        .map_err(io)?
        .take(HEADER_AT_MOST)
        .read_to_end(&mut head)
        .map_err(io)?;
    let whole = (head.len() as u64) < HEADER_AT_MOST;
    Ok((head, whole))
}

/// Where `need` bytes of samples start in a file: `skip` bytes after `offset`, or, for a
/// skip of -1, where they end the file (`length`, asked only then, at least `offset`); `None`
/// for another skip, which the whole read refuses by name.
pub(crate) fn samples_start(
    offset: u64,
    skip: i64,
    need: u64,
    length: impl FnOnce() -> Result<u64, LoadError>,
) -> Result<Option<u64>, LoadError> {
    Ok(match skip {
        -1 => Some(length()?.saturating_sub(need).max(offset)),
        s if s >= 0 => Some(offset + s as u64),
        _ => None,
    })
}

/// Apply a file's linear value scaling `v·slope + intercept` (NIfTI `scl_slope`/`scl_inter`,
/// DICOM rescale). The identity keeps the samples' type. A scaling that takes every value
/// the samples' type can hold to a whole number in `i16`'s range (8-bit samples shifted to
/// Hounsfield units, say) makes them `i16`: decided by the type and the scaling alone, so a
/// window of planes gets the kind the whole volume gets. Any other makes them f32, computed
/// in f64 and rounded once.
pub fn rescale(volume: Volume, slope: f64, intercept: f64) -> Result<Volume, LoadErrorKind> {
    if slope == 1.0 && intercept == 0.0 {
        return Ok(volume);
    }
    if !(slope.is_finite() && intercept.is_finite()) || slope == 0.0 {
        return Err(LoadErrorKind::Header(format!(
            "value scaling slope {slope}, intercept {intercept}: expected finite numbers and a slope other than 0"
        )));
    }
    let y = |x: f64| x * slope + intercept;
    let range = match volume.data {
        VolumeData::U8(_) => Some((0.0, 255.0)),
        VolumeData::U16(_) => Some((0.0, 65_535.0)),
        VolumeData::I16(_) => Some((-32_768.0, 32_767.0)),
        VolumeData::F32(_) => None,
    };
    // The scaling is linear: its ends bound it.
    let narrow = range.is_some_and(|(lo, hi)| whole_i16(y(lo)) && whole_i16(y(hi)));
    // Each kind's samples in one monomorphic pass: a volume's worth of them.
    fn scaled<T: Copy + Into<f64>>(v: &[T], narrow: bool, y: impl Fn(f64) -> f64) -> VolumeData {
        match narrow {
            true => VolumeData::I16(v.iter().map(|&x| y(x.into()) as i16).collect()),
            false => VolumeData::F32(v.iter().map(|&x| y(x.into()) as f32).collect()),
        }
    }
    let data = match &volume.data {
        VolumeData::U8(v) => scaled(v, narrow, y),
        VolumeData::U16(v) => scaled(v, narrow, y),
        VolumeData::I16(v) => scaled(v, narrow, y),
        VolumeData::F32(v) => scaled(v, narrow, y),
    };
    if let VolumeData::F32(v) = &data {
        if v.iter().any(|x| !x.is_finite()) {
            return Err(LoadErrorKind::Header(format!(
                "value scaling slope {slope}, intercept {intercept} overflows 32-bit floats"
            )));
        }
    }
    // A window of planes stays that window.
    Ok(Volume::window(volume.grid, volume.first, data))
}

/// Whether `y` is a whole number a 16-bit signed sample holds exactly.
pub(crate) fn whole_i16(y: f64) -> bool {
    y.fract() == 0.0 && (-32_768.0..=32_767.0).contains(&y)
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
    /// The header declares more samples than a read may take.
    #[error("dimensions {} declare {} samples, more than the {cap} a volume may have (--max-samples raises it)", dims.iter().map(u64::to_string).collect::<Vec<_>>().join(" × "), samples.map_or("more than 2^64".to_string(), |s| s.to_string()))]
    TooLarge {
        /// The dimensions declared.
        dims: Vec<u64>,
        /// Their product, `None` where it overflows.
        samples: Option<u64>,
        /// The cap.
        cap: u64,
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
    /// A compressed stream does not decode, or fails its checksum or declared length.
    #[error("corrupt compressed data: {0}")]
    Corrupt(String),
    /// X planes asked of a volume that does not have them.
    #[error("X planes {start}..{end} asked of a volume of {planes}")]
    Window {
        /// The first plane asked for.
        start: u32,
        /// One past the last.
        end: u32,
        /// The volume's X planes.
        planes: u32,
    },
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

/// The most samples a volume's header may declare unless `--max-samples` says otherwise:
/// 2^32, a 1,625³ volume (4 GiB of bytes, 16 GiB of floats). A reader checks what a header
/// declares against it before it decompresses or keeps anything for the samples, so that a
/// small compressed file cannot make it take memory out of proportion.
pub const DEFAULT_MAX_SAMPLES: u64 = 1 << 32;

static MAX_SAMPLES: AtomicU64 = AtomicU64::new(DEFAULT_MAX_SAMPLES);

/// Set the most samples a header may declare for every read from now on (the command line's
/// `--max-samples`, read once at start).
pub fn set_max_samples(samples: u64) {
    MAX_SAMPLES.store(samples, Ordering::Relaxed);
}

/// The samples `dims` declare, refused past the cap ([`set_max_samples`]) or past what `u64`
/// holds.
pub fn declared_samples(dims: &[u64]) -> Result<u64, LoadErrorKind> {
    let cap = MAX_SAMPLES.load(Ordering::Relaxed);
    match dims.iter().try_fold(1u64, |a, &d| a.checked_mul(d)) {
        Some(samples) if samples <= cap => Ok(samples),
        samples => Err(LoadErrorKind::TooLarge {
            dims: dims.to_vec(),
            samples,
            cap,
        }),
    }
}

/// Decode `stream`, keeping at most its first `keep` bytes; the rest is decoded into nothing,
/// so that the stream's own check (a gzip member's CRC-32 and ISIZE, zlib's Adler-32) runs at
/// its end however long it is, without memory for it. Returns the kept bytes and the whole
/// decoded length.
pub(crate) fn inflate_at_most(
    mut stream: impl std::io::Read,
    keep: u64,
) -> std::io::Result<(Vec<u8>, u64)> {
    use std::io::Read;
    let mut bytes = Vec::new();
    (&mut stream).take(keep).read_to_end(&mut bytes)?;
    let rest = std::io::copy(&mut stream, &mut std::io::sink())?;
    let length = bytes.len() as u64 + rest;
    Ok((bytes, length))
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
    check_length(bytes.len() as u64, header, count, ty)
}

/// [`check_size`] of data `actual` bytes long (a decoded stream's whole length, of which a
/// reader kept no more than it needs: `inflate_at_most`).
pub fn check_length(
    actual: u64,
    header: u64,
    count: u64,
    ty: FileType,
) -> Result<(), LoadErrorKind> {
    let expected = count
        .checked_mul(ty.bytes() as u64)
        .and_then(|b| b.checked_add(header))
        .ok_or(LoadErrorKind::Grid(GridError::TooManySamples))?;
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

/// One sample of a type held as `f32` (`I8`, `I16`, `I32`, `U32`, `F32`, `F64`; the others read
/// as their unsigned value), from its bytes in `endian` order: through `f64`, so that every
/// integer and `f32` is exact and an `f64` rounds once.
pub fn sample_f32(b: &[u8], ty: FileType, endian: Endian) -> f32 {
    let mut w = [0u8; 8];
    let n = b.len().min(8);
    w[..n].copy_from_slice(&b[..n]);
    if endian == Endian::Big {
        w[..n].reverse();
    }
    let word = match ty {
        FileType::U8 => f64::from(w[0]),
        FileType::I8 => f64::from(w[0] as i8),
        FileType::U16 => f64::from(u16::from_le_bytes([w[0], w[1]])),
        FileType::I16 => f64::from(i16::from_le_bytes([w[0], w[1]])),
        FileType::F32 => f64::from(f32::from_le_bytes([w[0], w[1], w[2], w[3]])),
        FileType::I32 => f64::from(i32::from_le_bytes([w[0], w[1], w[2], w[3]])),
        FileType::U32 => f64::from(u32::from_le_bytes([w[0], w[1], w[2], w[3]])),
        FileType::F64 => f64::from_le_bytes(w),
    };
    word as f32
}

/// The samples of X planes `planes` of a `dims` grid of `ty` in `endian` order, read from
/// `reader` at the first sample (file order: X fastest, then Y, then Z), a row at a time,
/// into plane-major order: `u8`, `u16` and `i16` kept, every other type as `f32`
/// ([`sample_f32`]), a non-finite one refused at its node. The one conversion of every
/// reader, whole ([`decode`]) or by planes (`raw::load_window`).
pub(crate) fn decode_planes(
    reader: &mut impl std::io::Read,
    dims: [u32; 3],
    ty: FileType,
    endian: Endian,
    planes: std::ops::Range<u32>,
) -> Result<VolumeData, LoadErrorKind> {
    let u16_of = move |b: &[u8]| match endian {
        Endian::Little => u16::from_le_bytes([b[0], b[1]]),
        Endian::Big => u16::from_be_bytes([b[0], b[1]]),
    };
    let size = ty.bytes();
    Ok(match ty {
        FileType::U8 => VolumeData::U8(columns(reader, dims, size, planes, |b, _| Ok(b[0]))?),
        FileType::U16 => {
            VolumeData::U16(columns(reader, dims, size, planes, |b, _| Ok(u16_of(b)))?)
        }
        FileType::I16 => VolumeData::I16(columns(reader, dims, size, planes, |b, _| {
            Ok(u16_of(b).cast_signed())
        })?),
        _ => VolumeData::F32(columns(reader, dims, size, planes, |b, at| {
            let v = sample_f32(b, ty, endian);
            match v.is_finite() {
                true => Ok(v),
                false => Err(LoadErrorKind::NonFinite {
                    x: at[0],
                    y: at[1],
                    z: at[2],
                    value: v,
                }),
            }
        })?),
    })
}

/// The samples of X planes `planes` of every row of `reader` (samples of `size` bytes in file
/// order), each converted by `sample` from its bytes and its node, into plane-major order.
fn columns<T: Copy + Default>(
    reader: &mut impl std::io::Read,
    dims: [u32; 3],
    size: usize,
    planes: std::ops::Range<u32>,
    sample: impl Fn(&[u8], [u32; 3]) -> Result<T, LoadErrorKind>,
) -> Result<Vec<T>, LoadErrorKind> {
    let [nx, ny, nz] = dims.map(|d| d as usize);
    let (first, kept) = (planes.start as usize, planes.len());
    if kept == 0 {
        // No plane kept (a host whose nodes hold theirs): nothing to read.
        return Ok(Vec::new());
    }
    let mut out = vec![T::default(); kept * ny * nz];
    let mut row = vec![0u8; nx * size];
    for z in 0..nz {
        for y in 0..ny {
            reader.read_exact(&mut row)?;
            let columns = row.chunks_exact(size).enumerate().skip(first).take(kept);
            for (x, bytes) in columns {
                let at = [x as u32, y as u32, z as u32];
                out[((x - first) * nz + z) * ny + y] = sample(bytes, at)?;
            }
        }
    }
    Ok(out)
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
    let data = decode_planes(&mut &samples[..], dims, ty, endian, 0..dims[0])?;
    Ok(Volume::new(grid, data))
}

/// What the streamed reads' tests share: a window of a file is the whole read's planes.
#[cfg(test)]
pub(super) mod windows {
    use super::{load, load_window, streams, Format};
    use crate::input::dataset::Volume;
    use std::path::{Path, PathBuf};

    /// `count` big-endian two-byte samples in no pattern a misplaced byte could keep.
    pub fn big_endian_u16(count: u32) -> Vec<u8> {
        (0..count)
            .map(|i| (i.wrapping_mul(2_654_435_761) >> 16) as u16)
            .flat_map(u16::to_be_bytes)
            .collect()
    }

    /// `bytes` written to `name` in `dir`.
    pub fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
        let path = dir.join(name);
        std::fs::write(&path, bytes).expect("written");
        path
    }

    /// `path` streams as `format`, and its windows (all `nx` planes, at the ends, inside, of
    /// one plane and of none) are the whole read's planes, bit for bit.
    pub fn assert_streamed(path: &Path, format: Format, nx: u32) {
        assert!(streams(path, format, None).unwrap(), "{}", path.display());
        let whole = load(path, format, None).unwrap();
        for planes in [0..nx, 0..2, 1..4, nx - 1..nx, 3..3] {
            let window = load_window(path, format, None, planes.clone()).unwrap();
            assert_eq!(window.held(), planes, "{}", path.display());
            assert_eq!(Some(window), whole.planes(planes), "{}", path.display());
        }
    }

    /// `path` does not stream as `format`: a window read is the whole volume, which this
    /// returns.
    pub fn assert_read_whole(path: &Path, format: Format) -> Volume {
        assert!(!streams(path, format, None).unwrap(), "{}", path.display());
        let whole = load(path, format, None).unwrap();
        assert_eq!(load_window(path, format, None, 1..2).unwrap(), whole);
        whole
    }
}

#[cfg(test)]
mod rescaling {
    use super::{rescale, VolumeData};
    use crate::input::dataset::Volume;
    use voxcube_kernel::volume::grid::Grid;

    fn volume(data: VolumeData) -> Volume {
        let grid = Grid::new([2, 1, 1], voxcube_kernel::Vec3::ONE).unwrap();
        Volume::new(grid, data)
    }

    #[test]
    fn a_scaling_to_whole_numbers_within_i16_keeps_sixteen_bits_and_any_other_makes_floats() {
        // Bytes shifted to Hounsfield units: every byte lands on a whole number in i16.
        let shifted = rescale(volume(VolumeData::U8(vec![0, 255])), 1.0, -1024.0).unwrap();
        assert_eq!(shifted.data, VolumeData::I16(vec![-1024, -769]));
        let doubled = rescale(volume(VolumeData::I16(vec![-3, 7])), 2.0, 1.0).unwrap();
        assert_eq!(
            doubled.data,
            VolumeData::F32(vec![-5.0, 15.0]),
            "±65,535 is beyond i16"
        );
        // Decided by the type, not the values: 0 and 1 would fit, 65,535 - 1024 would not.
        let wide = rescale(volume(VolumeData::U16(vec![0, 1])), 1.0, -1024.0).unwrap();
        assert_eq!(wide.data, VolumeData::F32(vec![-1024.0, -1023.0]));
        let halves = rescale(volume(VolumeData::U8(vec![1, 2])), 0.5, 0.0).unwrap();
        assert_eq!(halves.data, VolumeData::F32(vec![0.5, 1.0]));
        let floats = rescale(volume(VolumeData::F32(vec![1.0, 2.0])), 1.0, 3.0).unwrap();
        assert_eq!(floats.data, VolumeData::F32(vec![4.0, 5.0]));
        // The identity keeps the type, i16 among them.
        let same = rescale(volume(VolumeData::I16(vec![-2, 2])), 1.0, 0.0).unwrap();
        assert_eq!(same.data, VolumeData::I16(vec![-2, 2]));
    }
}
