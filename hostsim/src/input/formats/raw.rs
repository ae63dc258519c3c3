//! Raw volumes: a fixed-size header to skip, then samples in X-fastest order, with the
//! dimensions, sample type and byte order given by the scene.

use super::{check_size, decode, read, Endian, FileType, LoadError, LoadErrorKind};
use crate::input::dataset::Volume;
use std::path::Path;
use voxcube_kernel::volume::grid::GridError;
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
}

/// Load a raw volume.
pub fn load(path: &Path, layout: &RawLayout) -> Result<Volume, LoadError> {
    let bytes = read(path)?;
    parse(&bytes, layout).map_err(|kind| LoadError::new(path, kind))
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

    fn layout(dims: [u32; 3], ty: FileType, header_bytes: u64) -> RawLayout {
        RawLayout {
            dims,
            ty,
            endian: Endian::Little,
            header_bytes,
            spacing: Vec3::ONE,
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
        assert_eq!(v.data, crate::input::dataset::VolumeData::U16(vec![256, 2]));
        let v = parse(&[0xff, 0xff], &layout([1, 1, 1], FileType::I16, 0)).unwrap();
        assert_eq!(v.data, crate::input::dataset::VolumeData::F32(vec![-1.0]));
        let nan = f32::NAN.to_le_bytes();
        let bytes = [0.0f32.to_le_bytes(), nan].concat();
        let e = parse(&bytes, &layout([2, 1, 1], FileType::F32, 0))
            .unwrap_err()
            .to_string();
        assert!(e.contains("(x 1, y 0, z 0) is NaN"), "{e}");
    }
}
