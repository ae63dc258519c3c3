//! Raw volumes: a fixed-size header to skip, then samples in X-fastest order, with the
//! dimensions, sample type and byte order given by the scene.
//!
//! A file is streamed, a row of X at a time, into the planes kept ([`load_window`]): a
//! window of X planes is a column range of every row, so it is read without holding the
//! file or the other planes, and the whole volume without a second copy of it.
//!
//! Invariant: a window's samples are, bit for bit, those [`parse`] gives the same planes of
//! the whole file (both read through `super::decode_planes`), and the file's length is
//! checked against the layout before a sample is kept.

use super::{check_length, check_size, decode, Endian, FileType, LoadError, LoadErrorKind};
use crate::input::dataset::Volume;
use std::io::{BufReader, Seek, SeekFrom};
use std::ops::Range;
use std::path::Path;
use voxcube_kernel::volume::grid::{Grid, GridError};
use voxcube_kernel::Vec3;

/// How to read a raw file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RawLayout {
    /// Samples along X, Y, Z.
    pub dims: [u32; 3],
    /// Sample type.
    pub ty: FileType,
    /// Byte order.
    pub endian: Endian,
    /// Bytes to skip before the samples.
    pub header_bytes: u64,
    /// Grid spacing.
    pub spacing: Vec3,
    /// Whether bytes may follow the samples: a format's later sections (a legacy VTK file's
    /// line end and further attributes). A raw file's may not: a byte more says its dims,
    /// type or header size are wrong.
    pub trailing: bool,
}

/// Load a raw volume, streamed (every plane of [`load_window`]).
pub fn load(path: &Path, layout: &RawLayout) -> Result<Volume, LoadError> {
    load_window(path, layout, 0..layout.dims[0])
}

/// The grid a raw layout describes.
pub fn grid(layout: &RawLayout) -> Result<Grid, GridError> {
    Grid::new(layout.dims, layout.spacing)
}

/// Of a raw volume, the X planes `planes` alone (all of them, or a node's slab with its
/// ghosts), streamed a row at a time: the file's length is checked against the layout first,
/// and nothing but those planes' samples is kept.
pub fn load_window(
    path: &Path,
    layout: &RawLayout,
    planes: Range<u32>,
) -> Result<Volume, LoadError> {
    let failed = |kind: LoadErrorKind| LoadError::new(path, kind);
    if let Some(axis) = layout.dims.iter().position(|&d| d == 0) {
        return Err(failed(GridError::ZeroDimension { axis }.into()));
    }
    let count = super::declared_samples(&layout.dims.map(u64::from)).map_err(failed)?;
    let grid = grid(layout).map_err(|e| failed(e.into()))?;
    let file = std::fs::File::open(path).map_err(|e| LoadError::new(path, e))?;
    let length = file.metadata().map_err(|e| LoadError::new(path, e))?.len();
    match check_length(length, layout.header_bytes, count, layout.ty) {
        Err(LoadErrorKind::Trailing { .. }) if layout.trailing => {}
        checked => checked.map_err(failed)?,
    }
    let nx = layout.dims[0];
    if planes.start > planes.end || planes.end > nx {
        return Err(failed(LoadErrorKind::Window {
            start: planes.start,
            end: planes.end,
            planes: nx,
        }));
    }
    let mut reader = BufReader::with_capacity(1 << 20, file);
    reader
        .seek(SeekFrom::Start(layout.header_bytes))
        .map_err(|e| LoadError::new(path, e))?;
    let (dims, ty, endian) = (layout.dims, layout.ty, layout.endian);
    let data =
        super::decode_planes(&mut reader, dims, ty, endian, planes.clone()).map_err(failed)?;
    Ok(Volume::window(grid, planes.start, data))
}

/// Decode raw bytes.
pub fn parse(bytes: &[u8], layout: &RawLayout) -> Result<Volume, LoadErrorKind> {
    if let Some(axis) = layout.dims.iter().position(|&d| d == 0) {
        return Err(GridError::ZeroDimension { axis }.into());
    }
    let count = super::declared_samples(&layout.dims.map(u64::from))?;
    check_size(bytes, layout.header_bytes, count, layout.ty)?;
    let start = layout.header_bytes as usize;
    decode(
        &bytes[start..],
        layout.dims,
        layout.spacing,
        layout.ty,
        layout.endian,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::dataset::VolumeData;

    fn layout(dims: [u32; 3], ty: FileType, header_bytes: u64) -> RawLayout {
        RawLayout {
            dims,
            ty,
            endian: Endian::Little,
            header_bytes,
            spacing: Vec3::ONE,
            trailing: false,
        }
    }

    #[test]
    fn sizes_are_checked_exactly() {
        let e = parse(&[0; 7], &layout([2, 2, 2], FileType::U8, 0))
            .unwrap_err()
            .to_string();
        assert!(e.contains("truncated: expected 8 bytes, found 7"), "{e}");
        let e = parse(&[0; 13], &layout([2, 2, 2], FileType::U8, 4))
            .unwrap_err()
            .to_string();
        assert!(e.contains("1 trailing bytes"), "{e}");
        let e = parse(&[0; 8], &layout([2, 0, 2], FileType::U8, 0))
            .unwrap_err()
            .to_string();
        assert!(e.contains("dimension y is zero"), "{e}");
        let e = parse(
            &[0; 8],
            &layout([u32::MAX, u32::MAX, u32::MAX], FileType::U16, 0),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("declare more than 2^64 samples"), "{e}");
    }

    #[test]
    fn types_and_byte_orders_decode() {
        let v = parse(
            &[1, 0, 0, 2],
            &RawLayout {
                endian: Endian::Big,
                ..layout([2, 1, 1], FileType::U16, 0)
            },
        )
        .unwrap();
        assert_eq!(v.data, VolumeData::U16(vec![256, 2]));
        let v = parse(&[0xff, 0xff], &layout([1, 1, 1], FileType::I16, 0)).unwrap();
        assert_eq!(v.data, VolumeData::I16(vec![-1]));
        let nan = f32::NAN.to_le_bytes();
        let bytes = [0.0f32.to_le_bytes(), nan].concat();
        let e = parse(&bytes, &layout([2, 1, 1], FileType::F32, 0))
            .unwrap_err()
            .to_string();
        assert!(e.contains("(x 1, y 0, z 0) is NaN"), "{e}");
    }

    /// A file of `layout` holding `bytes` (after a header of its own size), in `dir`.
    fn file(dir: &Path, bytes: &[u8], layout: &RawLayout) -> std::path::PathBuf {
        let path = dir.join("v.raw");
        let header = vec![7u8; layout.header_bytes as usize];
        std::fs::write(&path, [header.as_slice(), bytes].concat()).expect("written");
        path
    }

    /// The streamed read is the whole-file read: every sample type in both byte orders, on
    /// uneven grids, read whole and by windows of X planes (at the ends, inside, one plane,
    /// none), each the same bits as the same planes of `parse`'s volume; its NaN is named
    /// where `parse` names it.
    #[test]
    fn the_streamed_read_is_the_whole_file_read() {
        let dir = tempfile::tempdir().expect("tempdir");
        let mut next = 0x2545_f491_u64;
        let mut byte = move || {
            next ^= next << 13;
            next ^= next >> 7;
            next ^= next << 17;
            next as u8
        };
        let types = [
            FileType::U8,
            FileType::U16,
            FileType::I8,
            FileType::I16,
            FileType::F32,
            FileType::I32,
            FileType::U32,
            FileType::F64,
        ];
        for (i, ty) in types.into_iter().enumerate() {
            for endian in [Endian::Little, Endian::Big] {
                let dims = [5 + i as u32 % 3, 3, 4];
                let layout = RawLayout {
                    endian,
                    ..layout(dims, ty, (i % 2 * 16) as u64)
                };
                let count = dims.iter().product::<u32>() as usize;
                // Random bytes; floats from small integers, so every one is finite.
                let bytes: Vec<u8> = (0..count)
                    .flat_map(|_| {
                        let v = f64::from(byte() as i8);
                        let mut b = match ty {
                            FileType::F32 => (v as f32).to_le_bytes().to_vec(),
                            FileType::F64 => v.to_le_bytes().to_vec(),
                            _ => (0..ty.bytes()).map(|_| byte()).collect(),
                        };
                        if endian == Endian::Big && matches!(ty, FileType::F32 | FileType::F64) {
                            b.reverse();
                        }
                        b
                    })
                    .collect();
                let path = file(dir.path(), &bytes, &layout);
                let whole = parse(
                    &bytes,
                    &RawLayout {
                        header_bytes: 0,
                        ..layout
                    },
                )
                .unwrap();
                assert_eq!(load(&path, &layout).unwrap(), whole, "{ty:?} {endian:?}");
                let nx = dims[0];
                for planes in [0..nx, 0..2, 1..4, nx - 1..nx, 2..2] {
                    let window = load_window(&path, &layout, planes.clone()).unwrap();
                    assert_eq!(window.held(), planes, "{ty:?} {endian:?}");
                    assert_eq!(Some(window), whole.planes(planes), "{ty:?} {endian:?}");
                }
                let e = load_window(&path, &layout, nx - 1..nx + 1)
                    .unwrap_err()
                    .to_string();
                let says = format!("X planes {}..{} asked of a volume of {nx}", nx - 1, nx + 1);
                assert!(e.contains(&says), "{e}");
            }
        }
        let nan = [1.0f32.to_le_bytes(), f32::NAN.to_le_bytes()].concat();
        let layout = layout([2, 1, 1], FileType::F32, 0);
        let e = load_window(&file(dir.path(), &nan, &layout), &layout, 1..2)
            .unwrap_err()
            .to_string();
        assert!(e.contains("(x 1, y 0, z 0) is NaN"), "{e}");
    }

    /// A file's length is checked against its layout before a sample is read, whatever the
    /// window: truncated and trailing files are refused by size, naming the file.
    #[test]
    fn a_streamed_file_of_the_wrong_length_is_refused_first() {
        let dir = tempfile::tempdir().expect("tempdir");
        let layout = layout([4, 2, 2], FileType::U16, 4);
        let cases = [
            (31, "truncated: expected 36 bytes, found 35"),
            (33, "1 trailing bytes"),
        ];
        for (len, says) in cases {
            let path = file(dir.path(), &vec![0; len], &layout);
            for planes in [0..4, 1..2] {
                let e = load_window(&path, &layout, planes).unwrap_err().to_string();
                assert!(e.contains(says) && e.contains("v.raw"), "{e}");
            }
        }
    }
}
