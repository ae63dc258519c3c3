//! VTK image data, read with the `vtkio` crate: legacy `STRUCTURED_POINTS` files (`.vtk`,
//! ASCII or big-endian binary) and XML `ImageData` files (`.vti`, inline or appended data,
//! raw or zlib-compressed). The first point-data array of one component is the volume; the
//! spacing is the file's, the origin is not applied (index space). A binary legacy file whose
//! header reads as `vtkio` reads it also streams by planes (`streamed`): `vtkio` parses a
//! file whole and says nothing of where its samples lie.

use super::{decode, Endian, FileType, LoadError, LoadErrorKind};
use crate::input::dataset::Volume;
use std::path::{Path, PathBuf};
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

/// Where and how a legacy file's samples lie when they can be streamed as a raw file
/// (`super::load_window`): binary `STRUCTURED_POINTS` (big-endian, as the format writes binary
/// samples) whose header lines are those `vtkio` reads, in its order, and whose first
/// point-data attribute is one component of `SCALARS` of a type the whole read takes, its
/// samples right after its `LOOKUP_TABLE` line. Anything else (an ASCII or XML file, other
/// attributes first, a header this does not follow) is left to the whole read, which decides
/// and names what is wrong: a file streams only where the whole read would read the same
/// samples.
pub(super) fn streamed(
    path: &Path,
    spacing: Option<Vec3>,
) -> Result<Option<(PathBuf, super::raw::RawLayout)>, LoadError> {
    let (head, _) = super::head(path)?;
    let Some(header) = legacy_header(&head) else {
        return Ok(None);
    };
    let spacing = spacing.unwrap_or(Vec3::from_array(header.spacing).abs());
    if !(spacing.is_finite() && spacing.min_element() > 0.0) {
        return Ok(None);
    }
    Ok(Some((
        path.to_path_buf(),
        super::raw::RawLayout {
            dims: header.dims,
            ty: header.ty,
            endian: Endian::Big,
            header_bytes: header.samples_at as u64,
            spacing,
            // The line end VTK writes after binary samples, and any attributes after them.
            trailing: true,
        },
    )))
}

/// What a binary legacy header says of its samples ([`legacy_header`]).
#[derive(Debug, PartialEq)]
struct LegacyHeader {
    dims: [u32; 3],
    spacing: [f32; 3],
    ty: FileType,
    /// The byte the samples start at.
    samples_at: usize,
}

/// A binary `STRUCTURED_POINTS` header in `bytes` (a file's first bytes) as `vtkio` reads it,
/// blank lines between its keyword lines skipped as [`load`] does: the version line, the
/// title, `BINARY`, `DATASET STRUCTURED_POINTS`, then `DIMENSIONS`, `ORIGIN` and `SPACING` (or
/// `ASPECT_RATIO`) once each in any order, `POINT_DATA` with every point, `SCALARS name type`
/// of one component and at once its `LOOKUP_TABLE name` line, whose end is where the samples
/// start. Keywords in any case, as `vtkio` takes them; `None` for anything else.
fn legacy_header(bytes: &[u8]) -> Option<LegacyHeader> {
    let mut at = 0;
    // Each line with its end: `\n` or `\r\n`, as `vtkio` ends lines.
    let next_line = |at: &mut usize| -> Option<&str> {
        let rest = bytes.get(*at..)?;
        let end = rest.iter().position(|&b| b == b'\n')?;
        *at += end + 1;
        let line = &rest[..end];
        std::str::from_utf8(line.strip_suffix(b"\r").unwrap_or(line)).ok()
    };
    let keyword_line = |at: &mut usize| loop {
        let line = next_line(at)?;
        if !line.trim().is_empty() {
            return Some(line.split_whitespace().collect::<Vec<_>>());
        }
    };
    let is = |word: &str, expected: &str| word.eq_ignore_ascii_case(expected);
    // `# vtk DataFile Version 3.0`, as `load` tells a legacy file; a title of one character
    // at least, which `vtkio` needs.
    let version = next_line(&mut at)?;
    match version.split_whitespace().collect::<Vec<_>>().as_slice() {
        ["#", vtk, data_file, word, number]
            if version.starts_with("# vtk DataFile")
                && is(vtk, "vtk")
                && is(data_file, "DataFile")
                && is(word, "Version")
                && number
                    .split_once('.')
                    .is_some_and(|(a, b)| a.parse::<u32>().is_ok() && b.parse::<u32>().is_ok()) => {
        }
        _ => return None,
    }
    if next_line(&mut at)?.is_empty() {
        return None;
    }
    match keyword_line(&mut at)?.as_slice() {
        [binary] if is(binary, "BINARY") => {}
        _ => return None,
    }
    match keyword_line(&mut at)?.as_slice() {
        [dataset, points] if is(dataset, "DATASET") && is(points, "STRUCTURED_POINTS") => {}
        _ => return None,
    }
    let (mut dims, mut origin, mut spacing) = (None, None, None);
    for _ in 0..3 {
        let words = keyword_line(&mut at)?;
        let [key, x, y, z] = words.as_slice() else {
            return None;
        };
        let floats = || Some([x.parse().ok()?, y.parse().ok()?, z.parse().ok()?]);
        let slot: &mut Option<[f32; 3]> = if is(key, "DIMENSIONS") {
            dims = match dims {
                None => Some([x.parse().ok()?, y.parse().ok()?, z.parse().ok()?]),
                Some(_) => return None,
            };
            continue;
        } else if is(key, "ORIGIN") {
            &mut origin
        } else if is(key, "SPACING") || is(key, "ASPECT_RATIO") {
            &mut spacing
        } else {
            return None;
        };
        if slot.replace(floats()?).is_some() {
            return None;
        }
    }
    let (dims, _, spacing): ([u32; 3], [f32; 3], [f32; 3]) = (dims?, origin?, spacing?);
    let points = dims
        .iter()
        .try_fold(1u64, |n, &d| n.checked_mul(u64::from(d)))?;
    match keyword_line(&mut at)?.as_slice() {
        [key, n] if is(key, "POINT_DATA") && n.parse::<u64>().ok()? == points => {}
        _ => return None,
    }
    let ty = match keyword_line(&mut at)?.as_slice() {
        [key, _name, ty] | [key, _name, ty, "1"] if is(key, "SCALARS") => scalar_type(ty)?,
        _ => return None,
    };
    // At once: a blank line here would be samples to `vtkio`.
    match next_line(&mut at)?
        .split_whitespace()
        .collect::<Vec<_>>()
        .as_slice()
    {
        [key, _table] if is(key, "LOOKUP_TABLE") => {}
        _ => return None,
    }
    Some(LegacyHeader {
        dims,
        spacing,
        ty,
        samples_at: at,
    })
}

/// The sample type a legacy `SCALARS` line names, of those the whole read takes (`vtkio`
/// reads no `unsigned_short`, and `bit` and the 64-bit integers are refused by name).
fn scalar_type(name: &str) -> Option<FileType> {
    [
        ("unsigned_char", FileType::U8),
        ("char", FileType::I8),
        ("short", FileType::I16),
        ("int", FileType::I32),
        ("unsigned_int", FileType::U32),
        ("float", FileType::F32),
        ("double", FileType::F64),
    ]
    .into_iter()
    .find_map(|(named, ty)| name.eq_ignore_ascii_case(named).then_some(ty))
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
    use super::{legacy_header, without_blank_header_lines, FileType, LegacyHeader};
    use crate::input::formats::{load, load_window, raw, streams, Format};

    /// A binary legacy header of `nx × 3 × 4` points of `ty` with `lines` between the
    /// dataset's line and `POINT_DATA`, its lines ended by `end`.
    fn header(ty: &str, lines: &[&str], end: &str) -> String {
        let mut text = [
            "# vtk DataFile Version 3.0",
            "samples",
            "BINARY",
            "DATASET STRUCTURED_POINTS",
        ]
        .join(end);
        for line in lines {
            text += end;
            text += line;
        }
        text + end
            + &[
                "POINT_DATA 60",
                &format!("SCALARS v {ty}"),
                "LOOKUP_TABLE default",
            ]
            .join(end)
            + end
    }

    const GEOMETRY: [&str; 3] = ["DIMENSIONS 5 3 4", "ORIGIN 0 0 0", "SPACING 1 2 0.5"];

    #[test]
    fn a_binary_header_says_where_its_samples_start() {
        let text = header("short", &GEOMETRY, "\n");
        assert_eq!(
            legacy_header(text.as_bytes()),
            Some(LegacyHeader {
                dims: [5, 3, 4],
                spacing: [1.0, 2.0, 0.5],
                ty: FileType::I16,
                samples_at: text.len(),
            })
        );
        // Lines ended by CRLF, blank lines between keyword lines, keywords in another case and
        // order, `ASPECT_RATIO`, a component count of one: read as `vtkio` reads them.
        let loose = header(
            "float 1",
            &[
                "",
                "aspect_ratio 1 2 0.5",
                "Origin 0 0 0",
                "  ",
                "dimensions 5 3 4",
            ],
            "\r\n",
        );
        let read = legacy_header(loose.as_bytes()).expect("a header");
        assert_eq!((read.ty, read.samples_at), (FileType::F32, loose.len()));
        assert_eq!((read.dims, read.spacing), ([5, 3, 4], [1.0, 2.0, 0.5]));
        // What the whole read is left to decide: ASCII samples, an empty title (which `vtkio`
        // refuses), a type it does not read, several components, a point count that is not
        // the grid's, a geometry line twice or missing, no lookup table line, a blank line
        // before it, and a header cut off.
        let refused = [
            header("short", &GEOMETRY, "\n").replace("BINARY", "ASCII"),
            header("short", &GEOMETRY, "\n").replace("samples", ""),
            header("unsigned_short", &GEOMETRY, "\n"),
            header("long", &GEOMETRY, "\n"),
            header("short 3", &GEOMETRY, "\n"),
            header("short", &GEOMETRY, "\n").replace("POINT_DATA 60", "POINT_DATA 61"),
            header(
                "short",
                &["DIMENSIONS 5 3 4", "DIMENSIONS 5 3 4", "SPACING 1 1 1"],
                "\n",
            ),
            header("short", &GEOMETRY[..2], "\n"),
            header("short", &GEOMETRY, "\n").replace("LOOKUP_TABLE default\n", ""),
            header("short", &GEOMETRY, "\n").replace("\nLOOKUP", "\n\nLOOKUP"),
            header("short", &GEOMETRY, "\n").replace("DataFile", "DataFiles"),
        ];
        for text in refused {
            assert_eq!(legacy_header(text.as_bytes()), None, "{text}");
        }
        let text = header("short", &GEOMETRY, "\n");
        assert_eq!(legacy_header(&text.as_bytes()[..text.len() - 1]), None);
    }

    /// A binary legacy file streamed by X planes is the whole read's planes, bit for bit, for
    /// two- and four-byte big-endian samples, a line end after them, and a loose header; a
    /// truncated file is refused by size, naming the file; files whose samples the
    /// whole read must find (ASCII, no lookup table line) are read whole. A window whose
    /// samples started two bytes late would differ: the check can fail.
    #[test]
    fn a_streamed_window_is_the_whole_read_s_planes() {
        use super::super::windows::{assert_read_whole, assert_streamed, big_endian_u16, write};
        let dir = tempfile::tempdir().expect("tempdir");
        let samples = big_endian_u16(60);
        let floats: Vec<u8> = (0..60u16)
            .flat_map(|i| (f32::from(i) * 1.25 - 7.0).to_be_bytes())
            .collect();
        // Ended by the line end VTK's writers put after binary samples.
        let shorts = write(
            dir.path(),
            "s.vtk",
            &[header("short", &GEOMETRY, "\n").as_bytes(), &samples, b"\n"].concat(),
        );
        let loose = header(
            "float 1",
            &[
                "aspect_ratio 1 2 0.5",
                "",
                "Origin 0 0 0",
                "dimensions 5 3 4",
            ],
            "\r\n",
        );
        let loose = write(dir.path(), "f.vtk", &[loose.as_bytes(), &floats].concat());
        for path in [&shorts, &loose] {
            assert_streamed(path, Format::Vtk, 5);
        }
        let ascii_samples: Vec<String> = (0..60).map(|i| (i * 3).to_string()).collect();
        let ascii = header("short", &GEOMETRY, "\n").replace("BINARY", "ASCII")
            + &ascii_samples.join(" ")
            + "\n";
        let ascii = write(dir.path(), "a.vtk", ascii.as_bytes());
        let untabled = header("short", &GEOMETRY, "\n").replace("LOOKUP_TABLE default\n", "");
        let untabled = write(
            dir.path(),
            "u.vtk",
            &[untabled.as_bytes(), &samples].concat(),
        );
        assert_read_whole(&ascii, Format::Vtk);
        let whole = assert_read_whole(&untabled, Format::Vtk);
        assert_eq!(whole, load(&shorts, Format::Vtk, None).unwrap());
        // The negative control: the same layout two bytes later reads other planes.
        let late = raw::RawLayout {
            header_bytes: header("short", &GEOMETRY, "\n").len() as u64 + 2,
            dims: [5, 3, 4],
            ty: FileType::I16,
            endian: super::Endian::Big,
            spacing: voxcube_kernel::Vec3::new(1.0, 2.0, 0.5),
            trailing: true,
        };
        let padded = [
            header("short", &GEOMETRY, "\n").as_bytes(),
            &samples,
            &[0, 0],
        ]
        .concat();
        let padded = write(dir.path(), "p.vtk", &padded);
        let shifted = raw::load_window(&padded, &late, 0..2).unwrap();
        assert_ne!(Some(shifted), whole.planes(0..2));
        assert!(streams(&shorts, Format::Vtk, None).unwrap());
        let cut = [header("short", &GEOMETRY, "\n").as_bytes(), &samples[1..]].concat();
        let cut = write(dir.path(), "c.vtk", &cut);
        let refused = load_window(&cut, Format::Vtk, None, 0..2)
            .unwrap_err()
            .to_string();
        assert!(
            refused.contains("c.vtk") && refused.contains("truncated"),
            "{refused}"
        );
        assert_eq!(
            load_window(&shorts, Format::Vtk, None, 1..3).unwrap(),
            whole.planes(1..3).unwrap()
        );
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
