//! NRRD volumes (teem's format): attached `.nrrd` (header, blank line, data) and detached
//! `.nhdr` (header naming a `data file`), raw or gzip encoding, 3-D scalar data.
//!
//! Read: `type`, `dimension` (must be 3), `sizes`, `encoding`, `endian`, `spacings` or
//! `space directions`, `data file`, `byte skip`, `line skip`. Other fields are ignored, as
//! the format allows; a field voxcube cannot honour (another encoding, a list of data files)
//! is an error that names it.

use super::{check_length, decode, read, Endian, FileType, LoadError, LoadErrorKind};
use crate::input::dataset::Volume;
use std::path::{Path, PathBuf};
use voxcube_kernel::Vec3;

fn header_err(msg: impl Into<String>) -> LoadErrorKind {
    LoadErrorKind::Header(msg.into())
}

/// The fields of a NRRD header voxcube uses.
#[derive(Clone, Debug, Default, PartialEq)]
struct Header {
    ty: Option<FileType>,
    dimension: Option<u32>,
    sizes: Option<String>,
    gzip: Option<bool>,
    endian: Option<Endian>,
    spacing: Option<Vec3>,
    data_file: Option<String>,
    byte_skip: i64,
    line_skip: u64,
}

fn parse_type(v: &str) -> Result<FileType, LoadErrorKind> {
    Ok(match v {
        "uchar" | "unsigned char" | "uint8" | "uint8_t" => FileType::U8,
        "signed char" | "int8" | "int8_t" => FileType::I8,
        "ushort" | "unsigned short" | "unsigned short int" | "uint16" | "uint16_t" => FileType::U16,
        "short" | "short int" | "signed short" | "signed short int" | "int16" | "int16_t" => {
            FileType::I16
        }
        "float" => FileType::F32,
        other => {
            return Err(header_err(format!(
                "type \"{other}\" is not supported (uint8, int8, uint16, int16, float)"
            )))
        }
    })
}

fn parse_three<T: std::str::FromStr>(field: &str, v: &str) -> Result<[T; 3], LoadErrorKind> {
    let parts: Vec<&str> = v.split_whitespace().collect();
    let bad = || header_err(format!("{field}: expected three numbers, found \"{v}\""));
    if parts.len() != 3 {
        return Err(bad());
    }
    let mut out = Vec::with_capacity(3);
    for p in parts {
        out.push(p.parse::<T>().map_err(|_| bad())?);
    }
    out.try_into().map_err(|_| bad())
}

fn parse_space_directions(v: &str) -> Result<Vec3, LoadErrorKind> {
    let bad = || {
        header_err(format!(
            "space directions: expected three vectors \"(x,y,z)\", found \"{v}\""
        ))
    };
    let mut norms = Vec::new();
    for part in v.split(')').map(str::trim).filter(|p| !p.is_empty()) {
        let inner = part.strip_prefix('(').ok_or_else(bad)?;
        let comps: Result<Vec<f64>, _> =
            inner.split(',').map(|c| c.trim().parse::<f64>()).collect();
        let comps = comps.map_err(|_| bad())?;
        norms.push(comps.iter().map(|c| c * c).sum::<f64>().sqrt() as f32);
    }
    match norms[..] {
        [x, y, z] => Ok(Vec3::new(x, y, z)),
        _ => Err(bad()),
    }
}

/// Parse header lines; returns the header and the byte offset just past it (the blank line).
fn parse_header(bytes: &[u8]) -> Result<(Header, usize), LoadErrorKind> {
    let mut h = Header::default();
    let mut pos = 0usize;
    let mut first = true;
    while pos < bytes.len() {
        let end = bytes[pos..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(bytes.len(), |i| pos + i);
        let line =
            std::str::from_utf8(&bytes[pos..end]).map_err(|_| header_err("header is not text"))?;
        let line = line.trim_end_matches('\r');
        pos = (end + 1).min(bytes.len());
        if first {
            if !line.starts_with("NRRD000") {
                return Err(header_err(format!(
                    "not a NRRD file: first line is \"{}\", expected \"NRRD000x\"",
                    line.chars().take(40).collect::<String>()
                )));
            }
            first = false;
            continue;
        }
        if line.is_empty() {
            break;
        }
        if line.starts_with('#') || line.contains(":=") {
            continue;
        }
        let Some((key, value)) = line.split_once(':') else {
            return Err(header_err(format!(
                "header line \"{line}\" is not \"field: value\""
            )));
        };
        let value = value.trim();
        match key.trim() {
            "type" => h.ty = Some(parse_type(value)?),
            "dimension" => {
                h.dimension =
                    Some(value.parse().map_err(|_| {
                        header_err(format!("dimension: \"{value}\" is not a number"))
                    })?)
            }
            // Checked once `dimension` is known, so a 2-D file is told it is 2-D.
            "sizes" => h.sizes = Some(value.to_string()),
            "encoding" => {
                h.gzip = Some(match value {
                    "raw" => false,
                    "gzip" | "gz" => true,
                    other => {
                        return Err(header_err(format!(
                            "encoding \"{other}\" is not supported (raw, gzip)"
                        )))
                    }
                })
            }
            "endian" => {
                h.endian = Some(match value {
                    "little" => Endian::Little,
                    "big" => Endian::Big,
                    other => {
                        return Err(header_err(format!(
                            "endian \"{other}\" is not little or big"
                        )))
                    }
                })
            }
            "spacings" => h.spacing = Some(Vec3::from_array(parse_three("spacings", value)?)),
            "space directions" => h.spacing = Some(parse_space_directions(value)?),
            "data file" | "datafile" => {
                if value.starts_with("LIST") || value.split_whitespace().count() > 1 {
                    return Err(header_err(
                        "data file: lists of data files are not supported",
                    ));
                }
                h.data_file = Some(value.to_string());
            }
            "byte skip" | "byteskip" => {
                h.byte_skip = value
                    .parse()
                    .map_err(|_| header_err(format!("byte skip: \"{value}\" is not a number")))?
            }
            "line skip" | "lineskip" => {
                h.line_skip = value
                    .parse()
                    .map_err(|_| header_err(format!("line skip: \"{value}\" is not a number")))?
            }
            _ => {}
        }
    }
    if first {
        return Err(header_err("empty file: expected a NRRD header"));
    }
    Ok((h, pos))
}

/// What a header says of its samples, checked: the grid, type, byte order and encoding.
struct Samples {
    dims: [u32; 3],
    count: u64,
    ty: FileType,
    endian: Endian,
    spacing: Vec3,
    gzip: bool,
}

/// The samples header `h` (of the file at `path`) describes, with `spacing` overriding its
/// own; an error names the header's field.
fn samples_of(h: &Header, path: &Path, spacing: Option<Vec3>) -> Result<Samples, LoadError> {
    let at = |k| LoadError::new(path, k);
    let ty =
        h.ty.ok_or_else(|| at(header_err("missing field \"type\"")))?;
    match h.dimension {
        Some(3) => {}
        Some(d) => {
            return Err(at(header_err(format!(
                "dimension is {d}; voxcube reads 3-D scalar volumes"
            ))))
        }
        None => return Err(at(header_err("missing field \"dimension\""))),
    }
    let sizes = h
        .sizes
        .as_deref()
        .ok_or_else(|| at(header_err("missing field \"sizes\"")))?;
    let dims: [u32; 3] = parse_three("sizes", sizes).map_err(at)?;
    let count = super::declared_samples(&dims.map(u64::from)).map_err(at)?;
    let gzip = h
        .gzip
        .ok_or_else(|| at(header_err("missing field \"encoding\"")))?;
    let endian = match (h.endian, ty.bytes()) {
        (Some(e), _) => e,
        (None, 1) => Endian::Little,
        (None, _) => {
            return Err(at(header_err(
                "missing field \"endian\" (needed for multi-byte types)",
            )))
        }
    };
    let spacing = spacing.or(h.spacing).unwrap_or(Vec3::ONE);
    // Checked here, so the error names the header that gives the spacing, not a data file.
    if let Some(axis) = (0..3).find(|&a| !(spacing[a].is_finite() && spacing[a] > 0.0)) {
        return Err(at(header_err(format!(
            "spacing {} is {}; spacings must be finite and greater than zero",
            ["x", "y", "z"][axis],
            spacing[axis]
        ))));
    }
    Ok(Samples {
        dims,
        count,
        ty,
        endian,
        spacing,
        gzip,
    })
}

/// Where and how a NRRD file's samples lie when they can be streamed as a raw file
/// (`super::load_window`): raw, at an offset the header gives, attached or in its data file,
/// no line skip.
pub(super) fn streamed(
    path: &Path,
    spacing: Option<Vec3>,
) -> Result<Option<(PathBuf, super::raw::RawLayout)>, LoadError> {
    let (head, whole) = super::head(path)?;
    // A header cut off by the limit, or one that does not parse: the whole read decides.
    let Ok((h, data_start)) = parse_header(&head) else {
        return Ok(None);
    };
    if !whole && data_start >= head.len() {
        return Ok(None);
    }
    let samples = samples_of(&h, path, spacing)?;
    if samples.gzip || h.line_skip != 0 {
        return Ok(None);
    }
    let (data, offset) = match &h.data_file {
        Some(name) => (path.parent().unwrap_or(Path::new(".")).join(name), 0),
        None => (path.to_path_buf(), data_start as u64),
    };
    let need = samples.count.saturating_mul(samples.ty.bytes() as u64);
    let length = || {
        let meta = std::fs::metadata(&data).map_err(|e| LoadError::new(&data, e))?;
        Ok(meta.len())
    };
    let Some(header_bytes) = super::samples_start(offset, h.byte_skip, need, length)? else {
        return Ok(None);
    };
    let layout = super::raw::RawLayout {
        dims: samples.dims,
        ty: samples.ty,
        endian: samples.endian,
        header_bytes,
        spacing: samples.spacing,
        trailing: false,
    };
    Ok(Some((data, layout)))
}

/// Load a NRRD volume (`.nrrd` or `.nhdr`). `spacing` overrides the header's.
pub fn load(path: &Path, spacing: Option<Vec3>) -> Result<Volume, LoadError> {
    let bytes = read(path)?;
    let (h, data_start) = parse_header(&bytes).map_err(|k| LoadError::new(path, k))?;
    let at = |k| LoadError::new(path, k);
    let Samples {
        dims,
        count,
        ty,
        endian,
        spacing,
        gzip,
    } = samples_of(&h, path, spacing)?;
    let (data_path, payload): (PathBuf, Vec<u8>) = match &h.data_file {
        Some(name) => {
            let file = path.parent().unwrap_or(Path::new(".")).join(name);
            let bytes = read(&file)?;
            (file, bytes)
        }
        None => (path.to_path_buf(), bytes[data_start..].to_vec()),
    };
    let data_err = |k| LoadError::new(&data_path, k);
    let mut payload = payload;
    for _ in 0..h.line_skip {
        let Some(i) = payload.iter().position(|&b| b == b'\n') else {
            return Err(data_err(header_err(
                "line skip runs past the end of the data",
            )));
        };
        payload.drain(..=i);
    }
    if let Some(axis) = dims.iter().position(|&d| d == 0) {
        return Err(data_err(
            voxcube_kernel::volume::grid::GridError::ZeroDimension { axis }.into(),
        ));
    }
    let need = count.saturating_mul(ty.bytes() as u64);
    let skip = match h.byte_skip {
        -1 if gzip => {
            return Err(at(header_err(
                "byte skip -1 (the data at the file's end) is for raw encoding only; give the count of bytes to skip",
            )))
        }
        -1 => (payload.len() as u64).saturating_sub(need),
        s if s >= 0 => s as u64,
        s => {
            return Err(data_err(header_err(format!(
                "byte skip {s}: only -1 or a count of bytes is meaningful"
            ))))
        }
    };
    // A gzip stream is decoded no further than the header accounts for: what follows is
    // decoded into nothing, for its CRC-32 and length, and counted.
    let length = if gzip {
        let (kept, length) = super::inflate_at_most(
            flate2::read::MultiGzDecoder::new(&payload[..]),
            skip.saturating_add(need),
        )
        .map_err(|e| data_err(super::corrupt_gzip(e)))?;
        payload = kept;
        length
    } else {
        payload.len() as u64
    };
    check_length(length, skip, count, ty).map_err(data_err)?;
    decode(&payload[skip as usize..], dims, spacing, ty, endian).map_err(data_err)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The formats' read by planes, of a Nrrd file.
    fn load_window(
        path: &Path,
        spacing: Option<Vec3>,
        planes: std::ops::Range<u32>,
    ) -> Result<Volume, LoadError> {
        super::super::load_window(path, super::super::Format::Nrrd, spacing, planes)
    }

    /// Whether the formats' read by planes streams a Nrrd file.
    fn streams(path: &Path, spacing: Option<Vec3>) -> Result<bool, LoadError> {
        super::super::streams(path, super::super::Format::Nrrd, spacing)
    }

    #[test]
    fn header_fields_parse() {
        let text = b"NRRD0004\n# c\ntype: unsigned short\ndimension: 3\nsizes: 2 3 4\nencoding: raw\nendian: big\nspace directions: (2,0,0) (0,3,0) (0,0,4)\nkey:=value\n\nDATA";
        let (h, at) = parse_header(text).unwrap();
        assert_eq!(h.ty, Some(FileType::U16));
        assert_eq!(h.sizes.as_deref(), Some("2 3 4"));
        assert_eq!(h.endian, Some(Endian::Big));
        assert_eq!(h.spacing, Some(Vec3::new(2.0, 3.0, 4.0)));
        assert_eq!(&text[at..], b"DATA");
    }

    #[test]
    fn bad_headers_name_the_field() {
        let e = parse_header(b"NRRD0004\ntype: double\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("type \"double\" is not supported"), "{e}");
        let e = parse_header(b"NRRD0004\nencoding: hex\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("encoding \"hex\""), "{e}");
        let e = parse_header(b"P6 garbage\n").unwrap_err().to_string();
        assert!(e.contains("not a NRRD file"), "{e}");
        let e = parse_three::<u32>("sizes", "1 2").unwrap_err().to_string();
        assert!(e.contains("sizes: expected three numbers"), "{e}");
    }

    /// A NRRD file streamed by X planes is the whole read's planes, bit for bit: attached and
    /// detached raw samples, a byte skip and the samples at the file's end (`-1`), two-byte
    /// big-endian samples; windows at the ends, inside and of no plane. A gzip file and a
    /// line skip are not streamed: they are read whole, and kept whole.
    #[test]
    fn a_streamed_window_is_the_whole_read_s_planes() {
        use super::super::windows::{assert_read_whole, assert_streamed, big_endian_u16};
        let dir = tempfile::tempdir().expect("tempdir");
        let (nx, ny, nz) = (5u32, 3u32, 4u32);
        let samples = big_endian_u16(nx * ny * nz);
        let header = |extra: &str| {
            format!("NRRD0004\ntype: uint16\ndimension: 3\nsizes: {nx} {ny} {nz}\nendian: big\nspacings: 1 2 0.5\n{extra}")
        };
        let write =
            |name: &str, bytes: &[u8]| super::super::windows::write(dir.path(), name, bytes);
        let attached = write(
            "a.nrrd",
            &[
                header("encoding: raw\nbyte skip: 3\n\n").as_bytes(),
                b"xyz",
                &samples,
            ]
            .concat(),
        );
        let at_end = write(
            "e.nrrd",
            &[
                header("encoding: raw\nbyte skip: -1\n\n").as_bytes(),
                b"junk",
                &samples,
            ]
            .concat(),
        );
        write("d.raw", &samples);
        let detached = write(
            "d.nhdr",
            header("encoding: raw\ndata file: d.raw\n").as_bytes(),
        );
        for path in [&attached, &at_end, &detached] {
            assert_streamed(path, super::super::Format::Nrrd, nx);
        }
        let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        std::io::Write::write_all(&mut gz, &samples).expect("compressed");
        let gzip = write(
            "g.nrrd",
            &[
                header("encoding: gzip\n\n").as_bytes(),
                &gz.finish().expect("compressed"),
            ]
            .concat(),
        );
        let skip = write(
            "l.nrrd",
            &[
                header("encoding: raw\nline skip: 1\n\n").as_bytes(),
                b"a line\n",
                &samples,
            ]
            .concat(),
        );
        for path in [&gzip, &skip] {
            assert_read_whole(path, super::super::Format::Nrrd);
        }
        assert_eq!(load(&gzip, None).unwrap(), load(&attached, None).unwrap());
    }

    /// The shared data's neghip (a detached header naming raw bytes) streams, and a window of
    /// it is the whole read's planes.
    #[test]
    fn neghip_streams_by_planes() {
        let nhdr =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/neghip-66x66x66.nhdr");
        if !nhdr.is_file() {
            assert!(
                std::env::var_os("CI").is_none(),
                "CI is set but the shared data is missing"
            );
            return;
        }
        assert!(streams(&nhdr, None).unwrap());
        let whole = load(&nhdr, None).unwrap();
        let window = load_window(&nhdr, None, 20..31).unwrap();
        assert_eq!(Some(window), whole.planes(20..31));
    }
}
