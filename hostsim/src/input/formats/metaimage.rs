//! MetaImage volumes (ITK's format): a text header of `Key = Value` lines, then the samples
//! (`.mha`, `ElementDataFile = LOCAL`) or in a file the header names (`.mhd`).
//!
//! Read: `NDims` (3), `DimSize`, `ElementType`, `ElementNumberOfChannels` (1),
//! `ElementSpacing` (or `ElementSize`), `BinaryDataByteOrderMSB`/`ByteOrderMSB`/
//! `ElementByteOrderMSB` (ITK's three names for the byte order; two that disagree are an error),
//! `CompressedData` (zlib), `HeaderSize` (bytes to skip in the data file; -1: the data
//! is the file's last bytes), `ElementDataFile`. `Offset`, `TransformMatrix` and
//! `AnatomicalOrientation` are not applied (index space). A short header needs no crate.

use super::{check_length, decode, read, Endian, FileType, LoadError, LoadErrorKind};
use crate::input::dataset::Volume;
use std::path::{Path, PathBuf};
use voxcube_kernel::Vec3;

fn header_err(msg: impl Into<String>) -> LoadErrorKind {
    LoadErrorKind::Header(msg.into())
}

fn element_type(v: &str) -> Result<FileType, LoadErrorKind> {
    Ok(match v {
        "MET_UCHAR" => FileType::U8,
        "MET_CHAR" => FileType::I8,
        "MET_USHORT" => FileType::U16,
        "MET_SHORT" => FileType::I16,
        "MET_FLOAT" => FileType::F32,
        "MET_INT" | "MET_LONG" => FileType::I32,
        "MET_UINT" | "MET_ULONG" => FileType::U32,
        "MET_DOUBLE" => FileType::F64,
        other => {
            return Err(header_err(format!(
                "ElementType \"{other}\" is not supported (MET_UCHAR, MET_CHAR, MET_USHORT, MET_SHORT, MET_INT, MET_UINT, MET_FLOAT, MET_DOUBLE)"
            )))
        }
    })
}

fn three<T: std::str::FromStr>(key: &str, v: &str) -> Result<[T; 3], LoadErrorKind> {
    let bad = || header_err(format!("{key}: expected three numbers, found \"{v}\""));
    let parts: Vec<T> = v
        .split_whitespace()
        .map(|p| p.parse::<T>().map_err(|_| bad()))
        .collect::<Result<_, _>>()?;
    parts.try_into().map_err(|_| bad())
}

fn truthy(key: &str, v: &str) -> Result<bool, LoadErrorKind> {
    match v.to_ascii_lowercase().as_str() {
        "true" | "1" => Ok(true),
        "false" | "0" => Ok(false),
        _ => Err(header_err(format!(
            "{key}: expected True or False, found \"{v}\""
        ))),
    }
}

/// The header: fields voxcube uses, and the offset of the byte after `ElementDataFile`'s line.
#[derive(Debug, Default)]
struct Header {
    dims: Option<[u32; 3]>,
    ty: Option<FileType>,
    spacing: Option<Vec3>,
    big_endian: bool,
    /// The key that set the byte order, when one did.
    order_key: Option<String>,
    compressed: bool,
    header_size: i64,
    data_file: Option<String>,
    end: usize,
}

fn parse_header(bytes: &[u8]) -> Result<Header, LoadErrorKind> {
    let mut h = Header::default();
    let mut pos = 0;
    let mut first = true;
    while pos < bytes.len() {
        let end = bytes[pos..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(bytes.len(), |i| pos + i);
        let line = std::str::from_utf8(&bytes[pos..end])
            .map_err(|_| header_err("header is not text"))?
            .trim();
        pos = (end + 1).min(bytes.len());
        if line.is_empty() {
            continue;
        }
        let Some((key, value)) = line.split_once('=') else {
            return Err(header_err(format!(
                "header line \"{}\" is not \"Key = Value\"",
                line.chars().take(60).collect::<String>()
            )));
        };
        let (key, value) = (key.trim(), value.trim());
        if first && !matches!(key, "ObjectType" | "NDims" | "Comment") {
            return Err(header_err(format!(
                "not a MetaImage header: first key is \"{key}\", expected ObjectType or NDims"
            )));
        }
        first = false;
        match key {
            "ObjectType" if value != "Image" => {
                return Err(header_err(format!(
                    "ObjectType is \"{value}\"; voxcube reads Image"
                )))
            }
            "NDims" if value != "3" => {
                return Err(header_err(format!(
                    "NDims is {value}; voxcube reads 3-D scalar volumes"
                )))
            }
            "DimSize" => h.dims = Some(three(key, value)?),
            "ElementType" => h.ty = Some(element_type(value)?),
            "ElementSpacing" => h.spacing = Some(Vec3::from_array(three(key, value)?)),
            "ElementSize" if h.spacing.is_none() => {
                h.spacing = Some(Vec3::from_array(three(key, value)?))
            }
            "ElementNumberOfChannels" if value != "1" => {
                return Err(header_err(format!(
                    "ElementNumberOfChannels is {value}; voxcube reads scalar volumes (1)"
                )))
            }
            "BinaryDataByteOrderMSB" | "ByteOrderMSB" | "ElementByteOrderMSB" => {
                let msb = truthy(key, value)?;
                if let Some(first) = h.order_key.as_ref().filter(|_| h.big_endian != msb) {
                    return Err(header_err(format!(
                        "{first} and {key} disagree on the byte order; give one"
                    )));
                }
                h.big_endian = msb;
                h.order_key = Some(key.to_string());
            }
            "CompressedData" => h.compressed = truthy(key, value)?,
            "HeaderSize" => {
                h.header_size = value
                    .parse()
                    .map_err(|_| header_err(format!("HeaderSize: \"{value}\" is not a number")))?
            }
            "ElementDataFile" => {
                if value == "LIST" || value.contains('%') {
                    return Err(header_err(
                        "ElementDataFile: lists and patterns of data files are not supported",
                    ));
                }
                h.data_file = Some(value.to_string());
                h.end = pos;
                return Ok(h);
            }
            _ => {}
        }
    }
    Err(header_err(
        "missing ElementDataFile (the header's last line: LOCAL or a file name)",
    ))
}

/// What header `h` (of the file at `path`) says of its samples, checked: the grid, type,
/// spacing (`spacing` overriding its own) and byte order.
fn samples_of(
    h: &Header,
    path: &Path,
    spacing: Option<Vec3>,
) -> Result<([u32; 3], FileType, Vec3, Endian), LoadError> {
    let at = |k| LoadError::new(path, k);
    let dims = h.dims.ok_or_else(|| at(header_err("missing DimSize")))?;
    let ty = h.ty.ok_or_else(|| at(header_err("missing ElementType")))?;
    let spacing = spacing.or(h.spacing).unwrap_or(Vec3::ONE);
    if !(spacing.is_finite() && spacing.min_element() > 0.0) {
        return Err(at(header_err(format!(
            "ElementSpacing {spacing}: expected three spacings > 0"
        ))));
    }
    let endian = if h.big_endian {
        Endian::Big
    } else {
        Endian::Little
    };
    Ok((dims, ty, spacing, endian))
}

/// Where and how a MetaImage file's samples lie when they can be streamed as a raw file
/// (`super::load_window`): uncompressed, at an offset the header gives, `LOCAL` or in its
/// data file.
pub(super) fn streamed(
    path: &Path,
    spacing: Option<Vec3>,
) -> Result<Option<(PathBuf, super::raw::RawLayout)>, LoadError> {
    let (head, whole) = super::head(path)?;
    // A header cut off by the limit, or one that does not parse: the whole read decides.
    let Ok(h) = parse_header(&head) else {
        return Ok(None);
    };
    if !whole && h.end >= head.len() {
        return Ok(None);
    }
    let (dims, ty, spacing, endian) = samples_of(&h, path, spacing)?;
    if h.compressed {
        return Ok(None);
    }
    let (data, offset) = match h.data_file.as_deref() {
        Some("LOCAL") | None => (path.to_path_buf(), h.end as u64),
        Some(name) => (path.parent().unwrap_or(Path::new(".")).join(name), 0),
    };
    // Named from the header, as the whole read names it: a missing data file is often a
    // misspelt `ElementDataFile`.
    let length = std::fs::metadata(&data)
        .map_err(|e| {
            LoadError::new(
                path,
                header_err(format!(
                    "ElementDataFile = {}: cannot read {}: {e}",
                    h.data_file.as_deref().unwrap_or("LOCAL"),
                    data.display()
                )),
            )
        })?
        .len();
    let count =
        super::declared_samples(&dims.map(u64::from)).map_err(|k| LoadError::new(path, k))?;
    let need = count.saturating_mul(ty.bytes() as u64);
    let Some(header_bytes) = super::samples_start(offset, h.header_size, need, || Ok(length))?
    else {
        return Ok(None);
    };
    let layout = super::raw::RawLayout {
        dims,
        ty,
        endian,
        header_bytes,
        spacing,
        trailing: false,
    };
    Ok(Some((data, layout)))
}

/// Load a MetaImage volume. `spacing` overrides the header's.
pub fn load(path: &Path, spacing: Option<Vec3>) -> Result<Volume, LoadError> {
    let bytes = read(path)?;
    let at = |k| LoadError::new(path, k);
    let h = parse_header(&bytes).map_err(at)?;
    let (dims, ty, spacing, endian) = samples_of(&h, path, spacing)?;
    let (data_path, payload): (PathBuf, Vec<u8>) = match h.data_file.as_deref() {
        Some("LOCAL") | None => (path.to_path_buf(), bytes[h.end..].to_vec()),
        Some(name) => {
            let file = path.parent().unwrap_or(Path::new(".")).join(name);
            // Named from the header, which holds the name: a missing data file is often a
            // misspelt `ElementDataFile`.
            let data = std::fs::read(&file).map_err(|e| {
                at(header_err(format!(
                    "ElementDataFile = {name}: cannot read {}: {e}",
                    file.display()
                )))
            })?;
            (file, data)
        }
    };
    let data_err = |k| LoadError::new(&data_path, k);
    let count = super::declared_samples(&dims.map(u64::from)).map_err(at)?;
    let need = count.saturating_mul(ty.bytes() as u64);
    let skip = match h.header_size {
        -1 if !h.compressed => (payload.len() as u64).saturating_sub(need),
        s if s >= 0 => s as u64,
        s => {
            return Err(at(header_err(format!(
                "HeaderSize {s}: only -1 (uncompressed data) or a count of bytes is meaningful"
            ))))
        }
    };
    // A zlib stream is decoded no further than the header accounts for: what follows is
    // decoded into nothing, for its Adler-32, and counted.
    let (payload, length) = if h.compressed {
        let start = (skip as usize).min(payload.len());
        super::inflate_at_most(flate2::read::ZlibDecoder::new(&payload[start..]), need)
            .map_err(|e| {
                data_err(LoadErrorKind::Corrupt(format!(
                    "CompressedData: the zlib stream does not decode or fails its Adler-32 check ({e})"
                )))
            })?
    } else {
        let length = payload.len() as u64;
        (payload, length)
    };
    let skip = if h.compressed { 0 } else { skip };
    check_length(length, skip, count, ty).map_err(data_err)?;
    decode(&payload[skip as usize..], dims, spacing, ty, endian).map_err(data_err)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The formats' read by planes, of a MetaImage file.
    fn load_window(
        path: &Path,
        spacing: Option<Vec3>,
        planes: std::ops::Range<u32>,
    ) -> Result<Volume, LoadError> {
        super::super::load_window(path, super::super::Format::MetaImage, spacing, planes)
    }

    #[test]
    fn header_fields_parse_and_bad_ones_are_named() {
        let text = b"ObjectType = Image\nNDims = 3\nDimSize = 2 3 4\nElementType = MET_SHORT\nElementSpacing = 1 2 0.5\nBinaryDataByteOrderMSB = True\nElementDataFile = LOCAL\nDATA";
        let h = parse_header(text).unwrap();
        // ITK's other name for the byte order is honoured too.
        let element = String::from_utf8_lossy(text).replace("BinaryData", "Element");
        assert!(parse_header(element.as_bytes()).unwrap().big_endian);
        assert_eq!(h.dims, Some([2, 3, 4]));
        assert_eq!(h.ty, Some(FileType::I16));
        assert_eq!(h.spacing, Some(Vec3::new(1.0, 2.0, 0.5)));
        assert!(h.big_endian);
        assert_eq!(&text[h.end..], b"DATA");
        for (text, needle) in [
            (&b"NDims = 2\n"[..], "NDims is 2"),
            (
                b"NDims = 3\nElementType = MET_RGB\n",
                "ElementType \"MET_RGB\"",
            ),
            (
                b"NDims = 3\nDimSize = 1 2\n",
                "DimSize: expected three numbers",
            ),
            (b"P6\n", "is not \"Key = Value\""),
            (
                b"NDims = 3\nBinaryDataByteOrderMSB = False\nElementByteOrderMSB = True\n",
                "BinaryDataByteOrderMSB and ElementByteOrderMSB disagree",
            ),
            (b"Foo = 1\n", "not a MetaImage header"),
            (b"NDims = 3\nDimSize = 1 1 1\n", "missing ElementDataFile"),
            (
                b"NDims = 3\nElementNumberOfChannels = 3\n",
                "ElementNumberOfChannels is 3",
            ),
        ] {
            let e = parse_header(text).unwrap_err().to_string();
            assert!(e.contains(needle), "{e}");
        }
    }

    /// A MetaImage file streamed by X planes is the whole read's planes, bit for bit: `LOCAL`
    /// and detached samples, a header size and the samples at the file's end (`-1`), two-byte
    /// big-endian samples; windows at the ends, inside and of no plane. Compressed data is not
    /// streamed: read whole, kept whole. A missing data file is named as the whole read
    /// names it.
    #[test]
    fn a_streamed_window_is_the_whole_read_s_planes() {
        use super::super::windows::{assert_read_whole, assert_streamed, big_endian_u16};
        let dir = tempfile::tempdir().expect("tempdir");
        let (nx, ny, nz) = (5u32, 3u32, 4u32);
        let samples = big_endian_u16(nx * ny * nz);
        let header = |extra: &str| {
            format!("ObjectType = Image\nNDims = 3\nDimSize = {nx} {ny} {nz}\nElementType = MET_USHORT\nElementSpacing = 1 2 0.5\nBinaryDataByteOrderMSB = True\n{extra}")
        };
        let write =
            |name: &str, bytes: &[u8]| super::super::windows::write(dir.path(), name, bytes);
        let local = write(
            "l.mha",
            &[
                header("HeaderSize = 3\nElementDataFile = LOCAL\n").as_bytes(),
                b"xyz",
                &samples,
            ]
            .concat(),
        );
        let at_end = write(
            "e.mha",
            &[
                header("HeaderSize = -1\nElementDataFile = LOCAL\n").as_bytes(),
                b"junk",
                &samples,
            ]
            .concat(),
        );
        write("d.raw", &samples);
        let detached = write("d.mhd", header("ElementDataFile = d.raw\n").as_bytes());
        for path in [&local, &at_end, &detached] {
            assert_streamed(path, super::super::Format::MetaImage, nx);
        }
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::fast());
        std::io::Write::write_all(&mut z, &samples).expect("compressed");
        let compressed = write(
            "c.mha",
            &[
                header("CompressedData = True\nElementDataFile = LOCAL\n").as_bytes(),
                &z.finish().expect("compressed"),
            ]
            .concat(),
        );
        let whole = assert_read_whole(&compressed, super::super::Format::MetaImage);
        assert_eq!(whole, load(&local, None).unwrap());
        let missing = write(
            "m.mhd",
            header("ElementDataFile = nowhere.raw\n").as_bytes(),
        );
        let (a, b) = (
            load(&missing, None).unwrap_err().to_string(),
            load_window(&missing, None, 0..1).unwrap_err().to_string(),
        );
        assert!(
            a.contains("ElementDataFile = nowhere.raw: cannot read"),
            "{a}"
        );
        assert!(
            b.contains("ElementDataFile = nowhere.raw: cannot read"),
            "{b}"
        );
    }
}
