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

/// The three sample types differ only in their kind: every conversion is the standard
/// library's own (`f32::from` is exact for `u8` and `u16`, the identity for `f32`).
macro_rules! sample {
    ($t:ty, $kind:ident) => {
        impl Sample for $t {
            const KIND: SampleKind = SampleKind::$kind;
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
    };
}

sample!(u8, U8);
sample!(u16, U16);
sample!(f32, F32);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bytes_round_trip_and_wrong_lengths_are_refused() {
        let mut b = [0u8; 4];
        1.5f32.write_le(&mut b);
        assert_eq!(f32::read_le(&b), Some(1.5));
        let mut two = [0u8; 2];
        0xbeefu16.write_le(&mut two);
        assert_eq!(two, [0xef, 0xbe]);
        assert_eq!(u16::read_le(&two), Some(0xbeef));
        // A slice of the wrong size is left alone, or read as nothing.
        let mut three = [9u8; 3];
        7u16.write_le(&mut three);
        assert_eq!(three, [9; 3]);
        assert_eq!(u16::read_le(&three), None);
        assert_eq!(u8::read_le(&[]), None);
        assert_eq!((200u8.to_f32(), 65535u16.to_f32()), (200.0, 65535.0));
    }
}
