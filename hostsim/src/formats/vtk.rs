//! VTK image data, read with the `vtkio` crate: legacy `STRUCTURED_POINTS` files (`.vtk`,
//! ASCII or big-endian binary) and XML `ImageData` files (`.vti`, inline or appended data,
//! raw or zlib-compressed). The first point-data array of one component is the volume; the
//! spacing is the file's, the origin is not applied (index space).

use super::{decode, Endian, FileType, LoadError, LoadErrorKind};
use crate::dataset::Volume;
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

/// A compressed XML file's bytes with every data array's block header saying the size of its
/// last block. VTK writes 0 there when the last block is full (the data a multiple of the
/// block size, 32,768 bytes by default) and its reader takes 0 to mean a full block; `vtkio`
/// takes the 0 literally, loses the last block, and finds no array. The header
/// `[blocks][block size][last block size]…` opens each array's data in base64, inline or
/// appended; only that one field changes, in place, the same length.
fn full_last_blocks(bytes: &[u8]) -> std::borrow::Cow<'_, [u8]> {
    use base64::Engine;
    let b64 = base64::engine::general_purpose::STANDARD;
    let find = |from: usize, what: &[u8]| {
        bytes
            .get(from..)
            .and_then(|rest| rest.windows(what.len()).position(|w| w == what))
            .map(|i| from + i)
    };
    // The attribute `name="…"` of the tag that starts at `at`.
    let attribute = |at: usize, name: &str| -> Option<String> {
        let end = find(at, b">")?;
        let tag = std::str::from_utf8(&bytes[at..end]).ok()?;
        let key = format!(" {name}=\"");
        let start = tag.find(&key)? + key.len();
        Some(tag[start..].split('"').next()?.to_string())
    };
    let Some(file) = find(0, b"<VTKFile") else {
        return std::borrow::Cow::Borrowed(bytes);
    };
    if attribute(file, "compressor").is_none() {
        return std::borrow::Cow::Borrowed(bytes);
    }
    let width = match attribute(file, "header_type").as_deref() {
        Some("UInt64") => 8,
        _ => 4,
    };
    let big = attribute(file, "byte_order").as_deref() == Some("BigEndian");
    // A header's first three numbers, patched where the last block is said to be empty.
    let mend = |header: &mut [u8]| {
        let number = |i: usize, h: &[u8]| {
            let word = &h[i * width..(i + 1) * width];
            let mut full = [0u8; 8];
            match big {
                true => full[8 - width..].copy_from_slice(word),
                false => full[..width].copy_from_slice(word),
            }
            if big {
                u64::from_be_bytes(full)
            } else {
                u64::from_le_bytes(full)
            }
        };
        if number(0, header) > 0 && number(2, header) == 0 {
            let size = number(1, header);
            let bytes = if big {
                size.to_be_bytes()
            } else {
                size.to_le_bytes()
            };
            let word = if big {
                &bytes[8 - width..]
            } else {
                &bytes[..width]
            };
            header[2 * width..3 * width].copy_from_slice(word);
        }
    };
    let mut out = bytes.to_vec();
    // In base64, the header's first 3·width bytes are exactly its first 4·width characters.
    let mend_text = |out: &mut [u8], at: usize| {
        let Some(text) = out.get(at..at + 4 * width) else {
            return;
        };
        let Ok(mut header) = b64.decode(text) else {
            return;
        };
        mend(&mut header);
        let text = b64.encode(&header);
        out[at..at + 4 * width].copy_from_slice(text.as_bytes());
    };
    // Appended data in base64 (`vtkio` reads no raw appended data: it says so itself).
    let appended = find(0, b"<AppendedData")
        .filter(|&at| attribute(at, "encoding").as_deref() == Some("base64"))
        .and_then(|at| Some(find(at, b"_")? + 1));
    let mut at = file;
    while let Some(array) = find(at + 1, b"<DataArray") {
        at = array;
        match attribute(array, "format").as_deref() {
            Some("binary") => {
                let Some(start) = find(array, b">") else {
                    break;
                };
                let first = bytes[start + 1..]
                    .iter()
                    .position(|b| !b.is_ascii_whitespace())
                    .map(|i| start + 1 + i);
                if let Some(first) = first {
                    mend_text(&mut out, first);
                }
            }
            Some("appended") => {
                let offset = attribute(array, "offset").and_then(|o| o.parse::<usize>().ok());
                if let (Some(base), Some(offset)) = (appended, offset) {
                    mend_text(&mut out, base + offset);
                }
            }
            _ => {}
        }
    }
    match out == bytes {
        true => std::borrow::Cow::Borrowed(bytes),
        false => std::borrow::Cow::Owned(out),
    }
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
        let bytes = full_last_blocks(&bytes);
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
    // `vtkio` has decoded the arrays by now: the cap still keeps such a volume out of the
    // renderer's memory.
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
    use super::{full_last_blocks, without_blank_header_lines};
    use base64::Engine;

    #[test]
    fn an_empty_last_block_is_read_as_full_for_every_header_width_and_byte_order() {
        let b64 = base64::engine::general_purpose::STANDARD;
        for (width, big) in [(4usize, false), (4, true), (8, false), (8, true)] {
            let word = |n: u64| -> Vec<u8> {
                match big {
                    true => n.to_be_bytes()[8 - width..].to_vec(),
                    false => n.to_le_bytes()[..width].to_vec(),
                }
            };
            let header: Vec<u8> = [2, 32_768, 0, 100, 90].into_iter().flat_map(word).collect();
            let file = format!(
                "<VTKFile type=\"ImageData\" byte_order=\"{}\" header_type=\"UInt{}\" compressor=\"vtkZLibDataCompressor\">\n<DataArray type=\"UInt8\" format=\"binary\">\n  {}AAAA\n</DataArray>",
                if big { "BigEndian" } else { "LittleEndian" },
                width * 8,
                b64.encode(&header)
            );
            let mended = full_last_blocks(file.as_bytes());
            let text = std::str::from_utf8(&mended).unwrap();
            let start = text.find("  ").unwrap() + 2;
            let header = b64.decode(&text[start..start + 4 * width]).unwrap();
            let expected: Vec<u8> = [2, 32_768, 32_768].into_iter().flat_map(word).collect();
            assert_eq!(header, expected, "UInt{} big {big}", width * 8);
            // Nothing else moved.
            assert_eq!(mended.len(), file.len());
        }
        // A last block that is not full, and an uncompressed file, are left as they are.
        let file = "<VTKFile compressor=\"vtkZLibDataCompressor\">\n<DataArray format=\"binary\">AQAAAAAAAQAHAAAA</DataArray>";
        assert!(matches!(
            full_last_blocks(file.as_bytes()),
            std::borrow::Cow::Borrowed(_)
        ));
        let file = "<VTKFile>\n<DataArray format=\"binary\">AQAAAAAAAQAAAAAA</DataArray>";
        assert!(matches!(
            full_last_blocks(file.as_bytes()),
            std::borrow::Cow::Borrowed(_)
        ));
    }

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
