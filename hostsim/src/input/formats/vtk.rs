//! VTK image data, read with the `vtkio` crate: legacy `STRUCTURED_POINTS` files (`.vtk`,
//! ASCII or big-endian binary) and XML `ImageData` files (`.vti`, inline or appended data,
//! raw or zlib-compressed). The first point-data array of one component is the volume; the
//! spacing is the file's, the origin is not applied (index space).

use super::{decode, Endian, FileType, LoadError, LoadErrorKind};
use crate::input::dataset::Volume;
use std::path::Path;
use voxcube_kernel::Vec3;
use vtkio::model::{Attribute, DataSet, ElementType, IOBuffer};
use vtkio::Vtk;

fn header_err(msg: impl Into<String>) -> LoadErrorKind {
    LoadErrorKind::Header(msg.into())
}

/// What a legacy file's text says about itself, for a message when `vtkio` refuses it.
fn diagnose_legacy(bytes: &[u8], parse: &vtkio::Error) -> LoadErrorKind {
    let text = String::from_utf8_lossy(&bytes[..bytes.len().min(4096)]);
    let field = |key: &str| {
        text.lines()
            .find(|l| l.trim_start().starts_with(key))
            .map(|l| l.trim()[key.len()..].trim().to_string())
    };
    if let Some(kind) = field("DATASET") {
        if kind != "STRUCTURED_POINTS" {
            return header_err(format!(
                "DATASET {kind}: voxcube reads STRUCTURED_POINTS (image data)"
            ));
        }
    }
    if text.contains("CELL_DATA") && !text.contains("POINT_DATA") {
        return header_err("CELL_DATA only: voxcube samples values at points (POINT_DATA)");
    }
    let dims: Option<Vec<u64>> = field("DIMENSIONS").map(|d| {
        d.split_whitespace()
            .filter_map(|n| n.parse().ok())
            .collect()
    });
    let scalars = field("SCALARS");
    let ty_bytes = scalars.as_deref().and_then(|s| {
        Some(match s.split_whitespace().nth(1)? {
            "unsigned_char" | "char" => 1,
            "unsigned_short" | "short" => 2,
            "unsigned_int" | "int" | "float" => 4,
            "double" | "long" | "unsigned_long" => 8,
            _ => return None,
        })
    });
    if let (Some(d), Some(b), true) = (dims, ty_bytes, text.contains("BINARY")) {
        let expected = d.iter().product::<u64>() * b;
        // The samples follow the LOOKUP_TABLE line.
        let start = text
            .find("LOOKUP_TABLE")
            .and_then(|i| text[i..].find('\n').map(|j| i + j + 1));
        if let Some(start) = start {
            let actual = (bytes.len() - start.min(bytes.len())) as u64;
            if actual < expected {
                return LoadErrorKind::Truncated { expected, actual };
            }
        }
    }
    header_err(format!(
        "not a readable VTK STRUCTURED_POINTS file ({parse})"
    ))
}

/// The samples of a one-component buffer, as little-endian bytes and their type.
fn buffer_bytes(buffer: IOBuffer) -> Result<(Vec<u8>, FileType), LoadErrorKind> {
    fn le<T: Copy, const N: usize>(v: &[T], f: impl Fn(T) -> [u8; N]) -> Vec<u8> {
        v.iter().flat_map(|&x| f(x)).collect()
    }
    Ok(match buffer {
        IOBuffer::U8(v) => (v, FileType::U8),
        IOBuffer::I8(v) => (le(&v, i8::to_le_bytes), FileType::I8),
        IOBuffer::U16(v) => (le(&v, u16::to_le_bytes), FileType::U16),
        IOBuffer::I16(v) => (le(&v, i16::to_le_bytes), FileType::I16),
        IOBuffer::U32(v) => (le(&v, u32::to_le_bytes), FileType::U32),
        IOBuffer::I32(v) => (le(&v, i32::to_le_bytes), FileType::I32),
        IOBuffer::F32(v) => (le(&v, f32::to_le_bytes), FileType::F32),
        IOBuffer::F64(v) => (le(&v, f64::to_le_bytes), FileType::F64),
        other => {
            return Err(header_err(format!(
            "point data of type {:?} is not supported (8-, 16-, 32-bit integers, float, double)",
            other.scalar_type()
        )))
        }
    })
}

/// A legacy file's bytes without the blank lines between its header's keyword lines, which
/// VTK's own reader skips and `vtkio` refuses (VTK's sample `ironProt.vtk` has one after
/// `ASCII`). The first two lines are kept as they are (the second, the title, may be
/// blank), and everything after the `LOOKUP_TABLE` line, where the samples begin (binary
/// ones may hold any bytes), is left untouched.
fn without_blank_header_lines(bytes: &[u8]) -> std::borrow::Cow<'_, [u8]> {
    let mut out = Vec::with_capacity(bytes.len());
    let mut rest = bytes;
    for n in 0.. {
        let Some(end) = rest.iter().position(|&b| b == b'\n') else {
            break;
        };
        let (line, after) = rest.split_at(end + 1);
        let blank = line.iter().all(u8::is_ascii_whitespace);
        if n < 2 || !blank {
            out.extend_from_slice(line);
        }
        rest = after;
        if line.trim_ascii_start().starts_with(b"LOOKUP_TABLE") {
            break;
        }
    }
    if out.len() + rest.len() == bytes.len() {
        return std::borrow::Cow::Borrowed(bytes);
    }
    out.extend_from_slice(rest);
    std::borrow::Cow::Owned(out)
}

/// Load a VTK image-data volume. `spacing` overrides the file's.
pub fn load(path: &Path, spacing: Option<Vec3>) -> Result<Volume, LoadError> {
    let at = |k| LoadError::new(path, k);
    let bytes = super::read(path)?;
    let legacy = bytes.starts_with(b"# vtk DataFile");
    let vtk = if legacy {
        let bytes = without_blank_header_lines(&bytes);
        Vtk::parse_legacy_be(&bytes[..]).map_err(|e| at(diagnose_legacy(&bytes, &e)))?
    } else {
        let bytes = super::vti_arrays::checked(&bytes).map_err(at)?;
        Vtk::parse_xml(&bytes[..])
            .map_err(|e| at(header_err(format!("not a readable VTK XML file ({e})"))))?
    };
    let (extent, file_spacing, pieces) = match vtk.data {
        DataSet::ImageData {
            extent,
            spacing,
            pieces,
            ..
        } => (extent, spacing, pieces),
        other => {
            let kind = match other {
                DataSet::PolyData { .. } => "POLYDATA",
                DataSet::StructuredGrid { .. } => "STRUCTURED_GRID",
                DataSet::RectilinearGrid { .. } => "RECTILINEAR_GRID",
                DataSet::UnstructuredGrid { .. } => "UNSTRUCTURED_GRID",
                _ => "FIELD",
            };
            return Err(at(header_err(format!(
                "DATASET {kind}: voxcube reads image data (STRUCTURED_POINTS, ImageData)"
            ))));
        }
    };
    let dims = extent.into_dims();
    // An XML file's extents were checked before its arrays were decoded; a legacy file's is
    // checked here, after `vtkio` has read it.
    super::declared_samples(&dims.map(u64::from)).map_err(at)?;
    let [piece]: [_; 1] = pieces.try_into().map_err(|p: Vec<_>| {
        at(header_err(format!(
            "{} pieces; voxcube reads image data of one piece",
            p.len()
        )))
    })?;
    let piece = piece
        .into_loaded_piece_data(None)
        .map_err(|e| at(header_err(format!("piece: {e}"))))?;
    let scalars = piece.data.point.into_iter().find_map(|a| match a {
        Attribute::DataArray(array) => match array.elem {
            ElementType::Scalars { num_comp: 1, .. } | ElementType::Generic(1) => Some(array),
            _ => None,
        },
        Attribute::Field { .. } => None,
    });
    let Some(array) = scalars else {
        return Err(at(header_err(if piece.data.cell.is_empty() {
            "no point-data array of one component (SCALARS name type 1)"
        } else {
            "cell data only: voxcube samples values at points (POINT_DATA)"
        })));
    };
    let spacing = spacing.unwrap_or(Vec3::from_array(file_spacing).abs());
    if !(spacing.is_finite() && spacing.min_element() > 0.0) {
        return Err(at(header_err(format!(
            "SPACING {spacing}: expected three spacings > 0"
        ))));
    }
    let (samples, ty) = buffer_bytes(array.data).map_err(at)?;
    let expected = dims.iter().map(|&d| u64::from(d)).product::<u64>() * ty.bytes() as u64;
    if samples.len() as u64 != expected {
        return Err(at(header_err(format!(
            "array \"{}\" holds {} bytes; DIMENSIONS {dims:?} of {ty:?} need {expected}",
            array.name,
            samples.len()
        ))));
    }
    decode(&samples, dims, spacing, ty, Endian::Little).map_err(at)
}

#[cfg(test)]
mod tests {
    use super::without_blank_header_lines;

    #[test]
    fn blank_header_lines_go_and_the_title_and_the_samples_stay() {
        let samples = b"\n\n \n\x00\n";
        let file = [
            &b"# vtk DataFile Version 3.0\n\nBINARY\n\nDATASET STRUCTURED_POINTS\n  \n"[..],
            b"LOOKUP_TABLE default\n",
            samples,
        ]
        .concat();
        let kept = without_blank_header_lines(&file);
        let expected = [
            &b"# vtk DataFile Version 3.0\n\nBINARY\nDATASET STRUCTURED_POINTS\n"[..],
            b"LOOKUP_TABLE default\n",
            samples,
        ]
        .concat();
        assert_eq!(&kept[..], &expected[..]);
        // A file without blank lines is the file itself, not a copy.
        assert!(matches!(
            without_blank_header_lines(&expected),
            std::borrow::Cow::Borrowed(_)
        ));
    }
}
