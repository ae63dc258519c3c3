//! CCP4/MRC density maps (`.map`, `.mrc`, `.ccp4`, gzipped too): the electron-density maps
//! of crystallography and cryo-EM, the paper's own kind of data. A 1024-byte header of 4-byte
//! words, an extended header of `NSYMBT` bytes (skipped), then the samples.
//!
//! Read: `NC`, `NR`, `NS` (the grid), `MODE` (0: i8, 1: i16, 2: f32, 6: u16, 12: f16),
//! `MAPC`/`MAPR`/`MAPS` (which axis the columns, rows and sections run along; the samples are
//! reordered to X fastest), the cell's lengths over its sampling `NX`, `NY`, `NZ` (the spacing,
//! in Å), `NSYMBT`, and the machine stamp (byte order; a file without one is read in the order
//! whose header makes sense). Not applied: `NCSTART`/`NRSTART`/`NSSTART` and the origin
//! (index space), the cell's angles (a non-orthogonal cell is drawn as if it were orthogonal).
//! Complex modes (3, 4) and mode 0's unsigned reading of old files are refused or not taken.
//! Only a stream's own bytes are read: every declared size is checked against what the file
//! holds before the samples are taken, and a gzip stream is decoded whole and checked.

use super::{check_size, corrupt_gzip, decode, Endian, FileType, LoadError, LoadErrorKind};
use crate::input::dataset::Volume;
use std::io::Read;
use std::path::Path;
use voxcube_kernel::Vec3;

/// Bytes of the main header.
const HEADER: usize = 1024;

fn header_err(msg: impl Into<String>) -> LoadErrorKind {
    LoadErrorKind::Header(msg.into())
}

/// What the header says.
#[derive(Clone, Debug, PartialEq)]
struct Header {
    endian: Endian,
    /// Samples along the columns, rows and sections (file order).
    counts: [u32; 3],
    mode: i32,
    /// The axis (0: X, 1: Y, 2: Z) the columns, rows and sections run along.
    axes: [usize; 3],
    /// Spacing along X, Y, Z.
    spacing: Vec3,
    /// Bytes of extended header after the main one.
    extended: u64,
}

/// The 4-byte word `i` of the header as an integer and as a float, in `endian`.
fn word(bytes: &[u8], i: usize, endian: Endian) -> (i32, f32) {
    let mut w = [0u8; 4];
    w.copy_from_slice(&bytes[4 * i..4 * i + 4]);
    let n = match endian {
        Endian::Little => i32::from_le_bytes(w),
        Endian::Big => i32::from_be_bytes(w),
    };
    (n, f32::from_bits(n as u32))
}

/// The byte order: the machine stamp's (bytes 212–213: `0x44 0x4?` little, `0x11 0x11` big),
/// else the one whose `MODE` is one the format defines.
fn endian_of(bytes: &[u8]) -> Endian {
    match (bytes[212], bytes[213]) {
        (0x44, _) => Endian::Little,
        (0x11, 0x11) => Endian::Big,
        _ => {
            let plausible = |e| (0..=16).contains(&word(bytes, 3, e).0);
            if !plausible(Endian::Little) && plausible(Endian::Big) {
                Endian::Big
            } else {
                Endian::Little
            }
        }
    }
}

fn parse_header(bytes: &[u8]) -> Result<Header, LoadErrorKind> {
    if bytes.len() < HEADER {
        return Err(LoadErrorKind::Truncated {
            expected: HEADER as u64,
            actual: bytes.len() as u64,
        });
    }
    if &bytes[208..212] != b"MAP " {
        return Err(header_err(
            "not a CCP4/MRC map: bytes 208-211 are not \"MAP \"",
        ));
    }
    let endian = endian_of(bytes);
    let int = |i| word(bytes, i, endian).0;
    let float = |i| word(bytes, i, endian).1;
    let counts = [int(0), int(1), int(2)];
    let [nc, nr, ns] = counts;
    if counts.iter().any(|&n| n < 1) {
        return Err(header_err(format!(
            "NC, NR, NS are {nc}, {nr}, {ns}; expected three counts of at least 1"
        )));
    }
    let mode = int(3);
    let order = [int(16), int(17), int(18)];
    let mut axes = [0usize; 3];
    let mut seen = [false; 3];
    for (slot, &a) in order.iter().enumerate() {
        let Some(axis) = usize::try_from(a - 1).ok().filter(|&x| x < 3 && !seen[x]) else {
            return Err(header_err(format!(
                "MAPC, MAPR, MAPS are {order:?}; expected an order of the axes 1, 2, 3"
            )));
        };
        seen[axis] = true;
        axes[slot] = axis;
    }
    // The spacing along X, Y, Z: the cell's length over its sampling intervals.
    let sampling = [int(7), int(8), int(9)];
    let cell = [float(10), float(11), float(12)];
    let mut spacing = Vec3::ONE;
    for a in 0..3 {
        if sampling[a] > 0 && cell[a].is_finite() && cell[a] > 0.0 {
            spacing[a] = cell[a] / sampling[a] as f32;
        }
    }
    let extended = u64::try_from(int(23)).map_err(|_| {
        header_err(format!(
            "NSYMBT is {}; expected the extended header's bytes, 0 or more",
            int(23)
        ))
    })?;
    Ok(Header {
        endian,
        counts: counts.map(|n| n as u32),
        mode,
        axes,
        spacing,
        extended,
    })
}

/// The type [`decode`] reads a mode's samples as, and the type whose width they take in the
/// file: the same but for half-precision floats, stored in two bytes (as a `u16` is) and
/// decoded as f32 after [`widen_halves`].
fn file_type(mode: i32) -> Result<(FileType, FileType), LoadErrorKind> {
    Ok(match mode {
        0 => (FileType::I8, FileType::I8),
        1 => (FileType::I16, FileType::I16),
        2 => (FileType::F32, FileType::F32),
        6 => (FileType::U16, FileType::U16),
        12 => (FileType::F32, FileType::U16),
        other => {
            return Err(header_err(format!(
            "MODE is {other}; voxcube reads modes 0 (i8), 1 (i16), 2 (f32), 6 (u16) and 12 (f16)"
        )))
        }
    })
}

/// An IEEE half-precision float as f32, exactly (every half is an f32).
fn half_to_f32(h: u16) -> f32 {
    let sign = if h & 0x8000 != 0 { -1.0 } else { 1.0 };
    let exponent = i32::from((h >> 10) & 0x1f);
    let fraction = f32::from(h & 0x3ff);
    match exponent {
        0 => sign * fraction * (2.0f32).powi(-24),
        31 if fraction == 0.0 => sign * f32::INFINITY,
        31 => f32::NAN,
        e => sign * (1.0 + fraction / 1024.0) * (2.0f32).powi(e - 15),
    }
}

/// Half-precision samples in `endian` as little-endian f32 bytes.
fn widen_halves(samples: &[u8], endian: Endian) -> Vec<u8> {
    samples
        .chunks_exact(2)
        .flat_map(|b| {
            let h = match endian {
                Endian::Little => u16::from_le_bytes([b[0], b[1]]),
                Endian::Big => u16::from_be_bytes([b[0], b[1]]),
            };
            half_to_f32(h).to_le_bytes()
        })
        .collect()
}

/// The samples in file order (columns fastest) reordered so that X runs fastest, then Y.
fn to_xyz<T: Copy>(file: &[T], counts: [u32; 3], axes: [usize; 3]) -> Vec<T> {
    let mut dims = [0usize; 3];
    for slot in 0..3 {
        dims[axes[slot]] = counts[slot] as usize;
    }
    let [nc, nr, ns] = counts.map(|n| n as usize);
    let stride = [1, dims[0], dims[0] * dims[1]];
    let (sc, sr, ss) = (stride[axes[0]], stride[axes[1]], stride[axes[2]]);
    let mut out = file.to_vec();
    let mut i = 0;
    for s in 0..ns {
        for r in 0..nr {
            for c in 0..nc {
                out[c * sc + r * sr + s * ss] = file[i];
                i += 1;
            }
        }
    }
    out
}

/// The bytes of a plain map, or of a gzipped one decoded whole, its CRC-32 and length checked;
/// never more than the header declares plus one byte, so a header that lies cannot make the
/// reader take more memory than the volume it declares.
fn contents(path: &Path) -> Result<Vec<u8>, LoadErrorKind> {
    let gz = path.to_string_lossy().to_ascii_lowercase().ends_with(".gz");
    if !gz {
        return Ok(std::fs::read(path)?);
    }
    let file = std::io::BufReader::new(std::fs::File::open(path)?);
    let mut stream = flate2::read::GzDecoder::new(file);
    let mut bytes = vec![0u8; HEADER];
    stream.read_exact(&mut bytes).map_err(corrupt_gzip)?;
    let h = parse_header(&bytes)?;
    let (_, stored) = file_type(h.mode)?;
    let expected = count(&h)?
        .checked_mul(stored.bytes() as u64)
        .and_then(|b| b.checked_add(HEADER as u64 + h.extended))
        .ok_or_else(|| header_err("NC × NR × NS × the sample size overflows"))?;
    let rest = expected - HEADER as u64;
    (&mut stream)
        .take(rest + 1)
        .read_to_end(&mut bytes)
        .map_err(corrupt_gzip)?;
    // To the end of the stream, so that its trailer is checked.
    std::io::copy(&mut stream, &mut std::io::sink()).map_err(corrupt_gzip)?;
    Ok(bytes)
}

/// The samples a map with header `h` holds, NC × NR × NS.
fn count(h: &Header) -> Result<u64, LoadErrorKind> {
    super::declared_samples(&h.counts.map(u64::from))
}

/// Load a CCP4/MRC map. `spacing` overrides the cell's.
pub fn load(path: &Path, spacing: Option<Vec3>) -> Result<Volume, LoadError> {
    let at = |k| LoadError::new(path, k);
    let bytes = contents(path).map_err(at)?;
    let h = parse_header(&bytes).map_err(at)?;
    let (ty, stored) = file_type(h.mode).map_err(at)?;
    let halves = ty != stored;
    check_size(
        &bytes,
        HEADER as u64 + h.extended,
        count(&h).map_err(at)?,
        stored,
    )
    .map_err(at)?;
    let start = HEADER + h.extended as usize;
    let mut dims = [0u32; 3];
    for slot in 0..3 {
        dims[h.axes[slot]] = h.counts[slot];
    }
    let samples: Vec<u8> = match halves {
        true => widen_halves(&bytes[start..], h.endian),
        false => bytes[start..].to_vec(),
    };
    let endian = if halves { Endian::Little } else { h.endian };
    // Reordered as whole samples, so that X runs fastest as `decode` reads them.
    let width = if halves { 4 } else { ty.bytes() };
    let samples: Vec<u8> = match h.axes {
        [0, 1, 2] => samples,
        axes => {
            let items: Vec<&[u8]> = samples.chunks_exact(width).collect();
            to_xyz(&items, h.counts, axes).concat()
        }
    };
    decode(&samples, dims, spacing.unwrap_or(h.spacing), ty, endian).map_err(at)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_half_is_its_value() {
        for h in 0..=u16::MAX {
            let sign = if h & 0x8000 != 0 { -1.0f64 } else { 1.0 };
            let (e, m) = (i32::from((h >> 10) & 0x1f), f64::from(h & 0x3ff));
            let value = match e {
                0 => sign * m * 2f64.powi(-24),
                31 => continue,
                e => sign * (1.0 + m / 1024.0) * 2f64.powi(e - 15),
            };
            assert_eq!(f64::from(half_to_f32(h)), value, "{h:#06x}");
        }
        assert_eq!(half_to_f32(0x7c00), f32::INFINITY);
        assert!(half_to_f32(0x7e00).is_nan());
    }

    #[test]
    fn the_byte_order_is_the_stamp_s_or_else_the_one_whose_mode_makes_sense() {
        let mut h = vec![0u8; HEADER];
        h[12..16].copy_from_slice(&2i32.to_be_bytes());
        assert_eq!(endian_of(&h), Endian::Big, "no stamp, a big-endian mode 2");
        h[12..16].copy_from_slice(&2i32.to_le_bytes());
        assert_eq!(
            endian_of(&h),
            Endian::Little,
            "no stamp, a little-endian mode 2"
        );
        h[212..214].copy_from_slice(&[0x11, 0x11]);
        assert_eq!(endian_of(&h), Endian::Big, "the stamp decides");
        h[212..214].copy_from_slice(&[0x44, 0x41]);
        assert_eq!(endian_of(&h), Endian::Little, "the stamp decides");
    }

    #[test]
    fn samples_are_reordered_so_that_x_runs_fastest() {
        // Columns along Z (2 samples), rows along X (3), sections along Y (2).
        let counts = [2, 3, 2];
        let axes = [2, 0, 1];
        let file: Vec<u32> = (0..12).collect();
        let out = to_xyz(&file, counts, axes);
        // dims X 3, Y 2, Z 2: the sample at (x, y, z) came from column z, row x, section y.
        for z in 0..2 {
            for y in 0..2 {
                for x in 0..3 {
                    assert_eq!(out[x + 3 * y + 6 * z], (z + 2 * x + 6 * y) as u32);
                }
            }
        }
    }
}
