//! NIfTI-1 volumes (`.nii`, `.nii.gz`, and `.hdr` or `.hdr.gz` with its `.img` or `.img.gz`),
//! read with the `nifti`
//! crate: `dim`, `datatype`, `pixdim` (the spacing) and `scl_slope`/`scl_inter` (the value
//! scaling) are honoured; `qform`/`sform` orientation is not applied (index space).
//!
//! A fourth dimension of length 1 is accepted (a single volume of a series); any other 4-D
//! file, complex and RGB samples, and NIfTI-2 (a 540-byte header the crate does not read) are
//! errors that name the field.

use super::{decode, rescale, Endian, FileType, LoadError, LoadErrorKind};
use crate::dataset::Volume;
use nifti::{NiftiObject, NiftiType, ReaderOptions};
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

/// The first bytes say NIfTI-2, which the reader does not handle: say so rather than "invalid".
fn is_nifti2(path: &Path) -> bool {
    use std::io::Read;
    let mut head = [0u8; 4];
    let plain = std::fs::File::open(path).and_then(|mut f| f.read_exact(&mut head));
    let read = if is_gzip(path) {
        std::fs::File::open(path)
            .and_then(|f| flate2::read::GzDecoder::new(f).read_exact(&mut head))
    } else {
        plain
    };
    read.is_ok() && (head == 540i32.to_le_bytes() || head == 540i32.to_be_bytes())
}

/// Whether `path` names a gzip-compressed file (`.nii.gz`).
fn is_gzip(path: &Path) -> bool {
    path.to_string_lossy().to_ascii_lowercase().ends_with(".gz")
}

/// Decode the whole gzip stream of `path` into nothing, so that its CRC-32 and length (ISIZE)
/// are checked before any sample is taken from it: the `nifti` crate stops reading at the
/// last sample, before the trailer, and a flipped bit in the deflate data can decode to other
/// samples without a deflate error. Streamed: memory stays bounded whatever the file says.
fn verify_gzip(path: &Path) -> Result<(), LoadErrorKind> {
    let file = std::fs::File::open(path)?;
    let mut stream = flate2::read::GzDecoder::new(std::io::BufReader::new(file));
    std::io::copy(&mut stream, &mut std::io::sink()).map_err(super::corrupt_gzip)?;
    Ok(())
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
    // Every gzip stream the samples come through is checked whole first.
    for stream in std::iter::once(path).chain(image.as_deref()) {
        if is_gzip(stream) {
            verify_gzip(stream).map_err(|k| LoadError::new(stream, k))?;
        }
    }
    if is_nifti2(path) {
        return Err(at(header_err(
            "NIfTI-2 (540-byte header) is not supported; convert to NIfTI-1 (for example `nifti_tool -copy_image -convert2dtype` or nibabel's Nifti1Image)",
        )));
    }
    let read = match &image {
        Some(image) => ReaderOptions::new().read_file_pair(path, image),
        None => ReaderOptions::new().read_file(path),
    };
    let object = read.map_err(|e| {
        at(match e {
            nifti::NiftiError::Io(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
                header_err(
                    "truncated: the file ends before the header's dims and datatype are filled",
                )
            }
            nifti::NiftiError::Io(io) => LoadErrorKind::Io(io),
            nifti::NiftiError::InvalidFormat => {
                header_err("not a NIfTI-1 file: magic is not \"n+1\" or \"ni1\" (bytes 344-347)")
            }
            nifti::NiftiError::IncompatibleLength(got, expected) => LoadErrorKind::Truncated {
                expected: expected as u64,
                actual: got as u64,
            },
            other => header_err(other.to_string()),
        })
    })?;
    let h = object.header();
    let dim = h.dim().map_err(|e| at(header_err(format!("dim: {e}"))))?;
    let dims: [u32; 3] = match dim {
        [x, y, z] | [x, y, z, 1] => [*x, *y, *z].map(u32::from),
        other => {
            return Err(at(header_err(format!(
                "dim is {other:?}; voxcube reads one 3-D scalar volume"
            ))))
        }
    };
    let ty = h
        .data_type()
        .map_err(|e| at(header_err(format!("datatype: {e}"))))
        .and_then(|t| file_type(t).map_err(at))?;
    let spacing = match spacing {
        Some(s) => s,
        None => {
            let p = Vec3::new(h.pixdim[1], h.pixdim[2], h.pixdim[3]).abs();
            if !(p.is_finite() && p.min_element() > 0.0) {
                return Err(at(header_err(format!(
                    "pixdim[1..4] is {:?}; expected three spacings > 0 (or give spacing in the scene)",
                    &h.pixdim[1..4]
                ))));
            }
            p
        }
    };
    let endian = match h.endianness {
        nifti::Endianness::Little => Endian::Little,
        nifti::Endianness::Big => Endian::Big,
    };
    // `scl_slope = 0` means "no scaling" in NIfTI-1.
    let (slope, inter) = if h.scl_slope == 0.0 {
        (1.0, 0.0)
    } else {
        (f64::from(h.scl_slope), f64::from(h.scl_inter))
    };
    let raw = object.volume().raw_data();
    let expected = dims.iter().map(|&d| u64::from(d)).product::<u64>() * ty.bytes() as u64;
    if raw.len() as u64 != expected {
        return Err(at(LoadErrorKind::Truncated {
            expected,
            actual: raw.len() as u64,
        }));
    }
    let volume = decode(raw, dims, spacing, ty, endian).map_err(at)?;
    rescale(volume, slope, inter).map_err(|k| at(header_err(format!("scl_slope/scl_inter: {k}"))))
}
