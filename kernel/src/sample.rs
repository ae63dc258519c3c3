//! Sample types a dataset can hold, and their one conversion to the `f32` the tracer works in.
//!
//! Invariant: the conversion is exact for `u8` and `u16` and the identity for `f32`, so a
//! value read on any node is the same bit pattern.

/// The kind of a stored sample, as a scene or file header names it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SampleKind {
    /// Unsigned 8-bit.
    U8,
    /// Unsigned 16-bit.
    U16,
    /// IEEE 754 single precision (finite values only: hosts reject NaN and infinities).
    F32,
}

impl SampleKind {
    /// Bytes one sample occupies in storage and in files.
    pub const fn bytes(self) -> usize {
        match self {
            SampleKind::U8 => 1,
            SampleKind::U16 => 2,
            SampleKind::F32 => 4,
        }
    }
}

/// A scalar sample the tracer can read.
pub trait Sample: Copy + Default + 'static {
    /// Which kind this is.
    const KIND: SampleKind;
    /// The value as `f32`, exactly.
    fn to_f32(self) -> f32;
    /// Write the little-endian bytes into `out`; leaves it untouched unless it is exactly
    /// [`SampleKind::bytes`] long.
    fn write_le(self, out: &mut [u8]);
    /// The sample from little-endian bytes; `None` unless `bytes` is exactly its size.
    fn read_le(bytes: &[u8]) -> Option<Self>;
}

impl Sample for u8 {
    const KIND: SampleKind = SampleKind::U8;
    #[inline]
    fn to_f32(self) -> f32 {
        f32::from(self)
    }
    fn write_le(self, out: &mut [u8]) {
        let bytes = self.to_le_bytes();
        if out.len() == bytes.len() {
            out.copy_from_slice(&bytes);
        }
    }
    fn read_le(bytes: &[u8]) -> Option<Self> {
        Some(Self::from_le_bytes(bytes.try_into().ok()?))
    }
}

impl Sample for u16 {
    const KIND: SampleKind = SampleKind::U16;
    #[inline]
    fn to_f32(self) -> f32 {
        f32::from(self)
    }
    fn write_le(self, out: &mut [u8]) {
        let bytes = self.to_le_bytes();
        if out.len() == bytes.len() {
            out.copy_from_slice(&bytes);
        }
    }
    fn read_le(bytes: &[u8]) -> Option<Self> {
        Some(Self::from_le_bytes(bytes.try_into().ok()?))
    }
}

impl Sample for f32 {
    const KIND: SampleKind = SampleKind::F32;
    #[inline]
    fn to_f32(self) -> f32 {
        self
    }
    fn write_le(self, out: &mut [u8]) {
        let bytes = self.to_le_bytes();
        if out.len() == bytes.len() {
            out.copy_from_slice(&bytes);
        }
    }
    fn read_le(bytes: &[u8]) -> Option<Self> {
        Some(Self::from_le_bytes(bytes.try_into().ok()?))
    }
}
