//! NIfTI-1 volumes (`.nii`, `.nii.gz`, and `.hdr` or `.hdr.gz` with its `.img` or `.img.gz`),
//! their headers parsed by the `nifti` crate: `dim`, `datatype`, `vox_offset`, `pixdim` (the
//! spacing) and `scl_slope`/`scl_inter` (the value scaling) are honoured; `qform`/`sform`
//! orientation is not applied (index space).
//!
//! Invariants: each file is read once, gzip-decoded as it streams in; what the header
//! declares is checked against what the file holds before the samples are kept, and a gzip
//! stream's CRC-32 and length are checked before any sample is taken from it.
//!
//! A fourth dimension of length 1 is accepted (a single volume of a series); any other 4-D
//! file, complex and RGB samples, and NIfTI-2 (a 540-byte header the crate does not read) are
//! errors that name the field.

use super::{decode, rescale, Endian, FileType, LoadError, LoadErrorKind};
use crate::input::dataset::Volume;
use nifti::{NiftiHeader, NiftiType};
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};
use voxcube_kernel::Vec3;

fn header_err(msg: impl Into<String>) -> LoadErrorKind {
    LoadErrorKind::Header(msg.into())
}

fn file_type(t: NiftiType) -> Result<FileType, LoadErrorKind> {
    Ok(match t {
        NiftiType::Uint8 => FileType::U8,
        NiftiType::Int8 => FileType::I8,
        NiftiType::Uint16 => FileType::U16,
        NiftiType::Int16 => FileType::I16,
        NiftiType::Float32 => FileType::F32,
        NiftiType::Int32 => FileType::I32,
        NiftiType::Uint32 => FileType::U32,
        NiftiType::Float64 => FileType::F64,
        other => {
            return Err(header_err(format!(
                "datatype {other:?} is not supported (scalar uint8, int8, uint16, int16, int32, uint32, float32, float64)"
            )))
        }
    })
}

/// Bytes of a NIfTI-1 header: every NIfTI-1 file, or the `.hdr` of a pair, starts with one.
const HEADER_BYTES: usize = 348;

/// Where a single file's samples start when its `vox_offset` says less: after the header and
/// the four bytes that say whether extensions follow.
const FIRST_SAMPLE: u64 = 352;

/// Whether `path` names a gzip-compressed file (`.nii.gz`).
fn is_gzip(path: &Path) -> bool {
    path.to_string_lossy().to_ascii_lowercase().ends_with(".gz")
}

/// Read `path` once, gzip-decoded where its name ends in `.gz`: its first `first` bytes, then
/// as many more as `more` finds those bytes to call for, kept. What a gzip stream holds past
/// them is decoded into nothing, so that its CRC-32 and length (ISIZE) are checked before any
/// sample is taken (a flipped bit in the deflate data can decode to other samples without a
/// deflate error); where `more` refuses the first bytes, a corrupt stream is reported as
/// such rather than as the damage it did to them. Memory follows the bytes the file really
/// holds, never only what they declare: a plain file shorter than declared is refused before
/// anything is kept for it, and a compressed one grows its buffer as its data arrives.
fn read_once<H>(
    path: &Path,
    first: usize,
    more: impl FnOnce(&[u8]) -> Result<(u64, H), LoadErrorKind>,
) -> Result<(Vec<u8>, H), LoadErrorKind> {
    let file = std::fs::File::open(path)?;
    let stored = file.metadata()?.len();
    let gz = is_gzip(path);
    let mut stream: Box<dyn Read> = match gz {
        true => Box::new(flate2::read::GzDecoder::new(BufReader::new(file))),
        false => Box::new(BufReader::new(file)),
    };
    let read_err = |e: std::io::Error| match gz {
        true => super::corrupt_gzip(e),
        false => LoadErrorKind::Io(e),
    };
    let mut bytes = Vec::new();
    (&mut stream)
        .take(first as u64)
        .read_to_end(&mut bytes)
        .map_err(read_err)?;
    let drain = |stream: &mut Box<dyn Read>| match gz {
        true => std::io::copy(stream, &mut std::io::sink())
            .map(drop)
            .map_err(super::corrupt_gzip),
        false => Ok(()),
    };
    let (more, found) = match more(&bytes) {
        Ok(m) => m,
        Err(e) => {
            drain(&mut stream)?;
            return Err(e);
        }
    };
    let expected = first as u64 + more;
    if !gz && stored < expected {
        return Err(LoadErrorKind::Truncated {
            expected,
            actual: stored,
        });
    }
    (&mut stream)
        .take(more)
        .read_to_end(&mut bytes)
        .map_err(read_err)?;
    drain(&mut stream)?;
    Ok((bytes, found))
}

/// What a header says about the samples: the parsed header, the grid and the sample type,
/// each field checked with an error that names it.
struct Declared {
    header: NiftiHeader,
    dims: [u32; 3],
    ty: FileType,
}

impl Declared {
    /// The header at the start of `head` (at most [`HEADER_BYTES`] of a file's first bytes).
    fn of(head: &[u8]) -> Result<Declared, LoadErrorKind> {
        if head.len() < HEADER_BYTES {
            return Err(header_err(
                "truncated: the file ends before the header's dims and datatype are filled",
            ));
        }
        // NIfTI-2's first field is its 540-byte header's size, which the reader does not
        // handle: say so rather than "invalid".
        if head[..4] == 540i32.to_le_bytes() || head[..4] == 540i32.to_be_bytes() {
            return Err(header_err(
                "NIfTI-2 (540-byte header) is not supported; convert to NIfTI-1 (for example `nifti_tool -copy_image -convert2dtype` or nibabel's Nifti1Image)",
            ));
        }
        let header = NiftiHeader::from_reader(head).map_err(|e| match e {
            nifti::NiftiError::InvalidFormat => {
                header_err("not a NIfTI-1 file: magic is not \"n+1\" or \"ni1\" (bytes 344-347)")
            }
            nifti::NiftiError::Io(io) => LoadErrorKind::Io(io),
            other => header_err(other.to_string()),
        })?;
        let dim = header.dim().map_err(|e| header_err(format!("dim: {e}")))?;
        let dims: [u32; 3] = match dim {
            [x, y, z] | [x, y, z, 1] => [*x, *y, *z].map(u32::from),
            other => {
                return Err(header_err(format!(
                    "dim is {other:?}; voxcube reads one 3-D scalar volume"
                )))
            }
        };
        super::declared_samples(&dims.map(u64::from))?;
        let ty = header
            .data_type()
            .map_err(|e| header_err(format!("datatype: {e}")))
            .and_then(file_type)?;
        Ok(Declared { header, dims, ty })
    }

    /// Bytes of the samples.
    fn sample_bytes(&self) -> u64 {
        self.dims.iter().map(|&d| u64::from(d)).product::<u64>() * self.ty.bytes() as u64
    }

    /// Where the samples start: `vox_offset`, a whole number of bytes (at least
    /// [`FIRST_SAMPLE`] in a single file).
    fn offset(&self, single: bool) -> Result<u64, LoadErrorKind> {
        let v = self.header.vox_offset;
        if !(v.is_finite() && v >= 0.0 && v.fract() == 0.0 && v < 2f32.powi(40)) {
            return Err(header_err(format!(
                "vox_offset is {v}; expected the samples' byte offset, a whole number >= 0"
            )));
        }
        let v = v as u64;
        Ok(if single { v.max(FIRST_SAMPLE) } else { v })
    }
}

/// The image file beside a header `path` (`.hdr` or `.hdr.gz`): `.img` or `.img.gz`,
/// whichever exists, the one compressed as the header is taken first; `None` for a single file
/// (`.nii`, `.nii.gz`).
fn image_of(path: &Path) -> Option<PathBuf> {
    let name = path.file_name()?.to_str()?;
    let lower = name.to_ascii_lowercase();
    let (stem, gz) = match (lower.strip_suffix(".hdr.gz"), lower.strip_suffix(".hdr")) {
        (Some(s), _) => (&name[..s.len()], true),
        (None, Some(s)) => (&name[..s.len()], false),
        (None, None) => return None,
    };
    let order = if gz {
        [".img.gz", ".img"]
    } else {
        [".img", ".img.gz"]
    };
    let [first, second] = order.map(|ext| path.with_file_name(format!("{stem}{ext}")));
    Some(if second.is_file() && !first.is_file() {
        second
    } else {
        first
    })
}

/// Load a NIfTI-1 volume. `spacing` overrides `pixdim`.
pub fn load(path: &Path, spacing: Option<Vec3>) -> Result<Volume, LoadError> {
    let at = |k| LoadError::new(path, k);
    let image = image_of(path);
    if let Some(image) = image.as_deref().filter(|i| !i.is_file()) {
        let missing = std::io::Error::new(
            std::io::ErrorKind::NotFound,
            "the image file of this header (.img or .img.gz beside it) is missing",
        );
        return Err(LoadError::new(image, missing));
    }
    // Each file is read once, its header first: what the header declares is checked against
    // the file before the samples are kept.
    let (bytes, declared, start) = match &image {
        None => {
            let (bytes, (declared, start)) = read_once(path, HEADER_BYTES, |head| {
                let declared = Declared::of(head)?;
                if &declared.header.magic == b"ni1\0" {
                    return Err(header_err(
                        "magic \"ni1\" says the samples are in a separate .img file: name its .hdr file",
                    ));
                }
                let start = declared.offset(true)?;
                let more = start - HEADER_BYTES as u64 + declared.sample_bytes();
                Ok((more, (declared, start)))
            })
            .map_err(at)?;
            (bytes, declared, start)
        }
        Some(image) => {
            let (head, declared) = read_once(path, HEADER_BYTES, |head| {
                Declared::of(head).map(|d| (0, d))
            })
            .map_err(at)?;
            drop(head);
            let start = declared.offset(false).map_err(at)?;
            let total = start + declared.sample_bytes();
            let (bytes, ()) =
                read_once(image, 0, |_| Ok((total, ()))).map_err(|k| LoadError::new(image, k))?;
            (bytes, declared, start)
        }
    };
    let (dims, ty) = (declared.dims, declared.ty);
    let expected = start + declared.sample_bytes();
    let raw = bytes
        .get(start as usize..expected as usize)
        .ok_or(LoadErrorKind::Truncated {
            expected,
            actual: bytes.len() as u64,
        })
        .map_err(|k| LoadError::new(image.as_deref().unwrap_or(path), k))?;
    let Stored {
        spacing,
        endian,
        scale: (slope, inter),
    } = Stored::of(&declared.header, spacing).map_err(at)?;
    let volume = decode(raw, dims, spacing, ty, endian).map_err(at)?;
    rescale(volume, slope, inter).map_err(|k| at(scaling_err(k)))
}

/// What the header says of the samples beyond their grid and type.
struct Stored {
    /// `pixdim`'s spacing, or the scene's.
    spacing: Vec3,
    endian: Endian,
    /// `scl_slope` and `scl_inter`: the identity where the slope is 0 ("no scaling").
    scale: (f64, f64),
}

impl Stored {
    fn of(h: &NiftiHeader, spacing: Option<Vec3>) -> Result<Stored, LoadErrorKind> {
        let spacing = match spacing {
            Some(s) => s,
            None => {
                let p = Vec3::new(h.pixdim[1], h.pixdim[2], h.pixdim[3]).abs();
                if !(p.is_finite() && p.min_element() > 0.0) {
                    return Err(header_err(format!(
                        "pixdim[1..4] is {:?}; expected three spacings > 0 (or give spacing in the scene)",
                        &h.pixdim[1..4]
                    )));
                }
                p
            }
        };
        let endian = match h.endianness {
            nifti::Endianness::Little => Endian::Little,
            nifti::Endianness::Big => Endian::Big,
        };
        let scale = if h.scl_slope == 0.0 {
            (1.0, 0.0)
        } else {
            (f64::from(h.scl_slope), f64::from(h.scl_inter))
        };
        Ok(Stored {
            spacing,
            endian,
            scale,
        })
    }
}

fn scaling_err(k: LoadErrorKind) -> LoadErrorKind {
    header_err(format!("scl_slope/scl_inter: {k}"))
}

/// Whether scaling every value of `ty` by `(slope, intercept)` stays a finite f32: then a
/// window's samples scale as the whole volume's would, and none of the file's others could
/// have refused it. Bounded by the type's range, so only integer types are.
fn scales_finitely(ty: FileType, (slope, intercept): (f64, f64)) -> bool {
    let (lo, hi): (f64, f64) = match ty {
        FileType::U8 => (0.0, 255.0),
        FileType::I8 => (-128.0, 127.0),
        FileType::U16 => (0.0, 65_535.0),
        FileType::I16 => (-32_768.0, 32_767.0),
        FileType::U32 => (0.0, 4_294_967_295.0),
        FileType::I32 => (-2_147_483_648.0, 2_147_483_647.0),
        FileType::F32 | FileType::F64 => return slope == 1.0 && intercept == 0.0,
    };
    slope.is_finite()
        && intercept.is_finite()
        && slope != 0.0
        && [lo, hi]
            .iter()
            .all(|v| ((v * slope + intercept) as f32).is_finite())
}

/// Where the samples of `path` lie when they can be streamed as a raw file
/// (`super::load_window`): uncompressed, in the `.nii` after `vox_offset` or in the `.img`
/// beside a `.hdr`, with the scaling the header asks of their values (an integer type's
/// whole range staying finite). Anything else, and any header the whole read would refuse,
/// is left to the whole read, which reports it.
pub(super) fn streamed(
    path: &Path,
    spacing: Option<Vec3>,
) -> Result<Option<super::Streamed>, LoadError> {
    let image = image_of(path);
    if is_gzip(path) || image.as_deref().is_some_and(|i| is_gzip(i) || !i.is_file()) {
        return Ok(None);
    }
    let (head, _) = super::head(path)?;
    let Ok(declared) = Declared::of(&head) else {
        return Ok(None);
    };
    let single = image.is_none();
    if single && &declared.header.magic == b"ni1\0" {
        return Ok(None);
    }
    let (Ok(start), Ok(stored)) = (
        declared.offset(single),
        Stored::of(&declared.header, spacing),
    ) else {
        return Ok(None);
    };
    if !scales_finitely(declared.ty, stored.scale) {
        return Ok(None);
    }
    let layout = super::raw::RawLayout {
        dims: declared.dims,
        ty: declared.ty,
        endian: stored.endian,
        header_bytes: start,
        spacing: stored.spacing,
        trailing: false,
    };
    Ok(Some(super::Streamed {
        data: image.unwrap_or_else(|| path.to_path_buf()),
        layout,
        scale: stored.scale,
    }))
}
