//! Levoy's `.den` volumes (the format of the UNC data sets of the paper's era, read by
//! VolPack): a 62-byte header of 29 16-bit fields and one 32-bit field, then 8-bit samples,
//! X fastest. Header: version (1), then `orig_min`, `orig_max`, `orig_len`, `extr_min`,
//! `extr_max`, `extr_len`, `map_min`, `map_max`, `map_len` (three each), `map_warps`, and
//! `map_length` (the sample count). The byte order is detected from the version field.

use super::{check_size, decode, read, Endian, FileType, LoadError, LoadErrorKind};
use crate::input::dataset::Volume;
use std::path::Path;
use voxcube_kernel::Vec3;

/// Bytes before the samples.
pub const HEADER_BYTES: usize = 62;

/// Load a `.den` volume. `spacing` defaults to 1.
pub fn load(path: &Path, spacing: Option<Vec3>) -> Result<Volume, LoadError> {
    let bytes = read(path)?;
    parse(&bytes, spacing.unwrap_or(Vec3::ONE)).map_err(|k| LoadError::new(path, k))
}

/// Decode `.den` bytes.
pub fn parse(bytes: &[u8], spacing: Vec3) -> Result<Volume, LoadErrorKind> {
    let err = |m: String| LoadErrorKind::Header(m);
    if bytes.len() < HEADER_BYTES {
        return Err(LoadErrorKind::Truncated {
            expected: HEADER_BYTES as u64,
            actual: bytes.len() as u64,
        });
    }
    let endian = match (bytes[0], bytes[1]) {
        (1, 0) => Endian::Little,
        (0, 1) => Endian::Big,
        (a, b) => {
            return Err(err(format!(
                "not a .den file: version field is bytes {a:#04x} {b:#04x}, expected 1"
            )))
        }
    };
    let short = |i: usize| {
        let b = [bytes[2 * i], bytes[2 * i + 1]];
        match endian {
            Endian::Little => i16::from_le_bytes(b),
            Endian::Big => i16::from_be_bytes(b),
        }
    };
    // Fields 25..28 are map_len; 19..22 map_min; 22..25 map_max.
    let mut dims = [0u32; 3];
    for (axis, dim) in dims.iter_mut().enumerate() {
        let (min, max, len) = (short(19 + axis), short(22 + axis), short(25 + axis));
        if len <= 0 || i32::from(max) - i32::from(min) + 1 != i32::from(len) {
            return Err(err(format!(
                "map_len[{axis}] is {len} but map_min..map_max is {min}..{max}: header is inconsistent"
            )));
        }
        *dim = len as u32;
    }
    super::declared_samples(&dims.map(u64::from))?;
    let l = &bytes[58..62];
    let map_length = match endian {
        Endian::Little => i32::from_le_bytes([l[0], l[1], l[2], l[3]]),
        Endian::Big => i32::from_be_bytes([l[0], l[1], l[2], l[3]]),
    };
    let count = dims.iter().map(|&d| u64::from(d)).product::<u64>();
    if u64::try_from(map_length).ok() != Some(count) {
        return Err(err(format!(
            "map_length is {map_length}, but map_len gives {count} samples"
        )));
    }
    check_size(bytes, HEADER_BYTES as u64, count, FileType::U8)?;
    decode(&bytes[HEADER_BYTES..], dims, spacing, FileType::U8, endian)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(dims: [i16; 3]) -> Vec<u8> {
        let mut shorts = vec![1i16];
        for _ in 0..3 {
            shorts.extend([0, 0, 0]);
            shorts.extend(dims.map(|d| d - 1));
            shorts.extend(dims);
        }
        shorts.push(0);
        let mut b: Vec<u8> = shorts.iter().flat_map(|s| s.to_le_bytes()).collect();
        let n: i32 = dims.iter().map(|&d| i32::from(d)).product();
        b.extend(n.to_le_bytes());
        b
    }

    #[test]
    fn reads_a_small_volume_and_checks_sizes() {
        let mut b = header([2, 1, 1]);
        b.extend([5, 6]);
        let v = parse(&b, Vec3::ONE).unwrap();
        assert_eq!(v.grid.dims(), [2, 1, 1]);
        b.push(0);
        assert!(parse(&b, Vec3::ONE)
            .unwrap_err()
            .to_string()
            .contains("1 trailing bytes"));
        b.truncate(b.len() - 2);
        assert!(parse(&b, Vec3::ONE)
            .unwrap_err()
            .to_string()
            .contains("truncated"));
        let e = parse(&[9; 70], Vec3::ONE).unwrap_err().to_string();
        assert!(e.contains("not a .den file"), "{e}");
    }
}
