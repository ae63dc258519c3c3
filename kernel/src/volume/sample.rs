//! Sample types a dataset can hold, and their one conversion to the `f32` the tracer works in.
//!
//! Invariant: the conversion is exact for `u8`, `u16` and `i16` and the identity for `f32`,
//! so a value read on any node is the same bit pattern.

/// The kind of a stored sample, as a scene or file header names it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SampleKind {
    /// Unsigned 8-bit.
    U8,
    /// Unsigned 16-bit.
    U16,
    /// Signed 16-bit (CT's Hounsfield units, for one).
    I16,
    /// IEEE 754 single precision (finite values only: hosts reject NaN and infinities).
    F32,
}

impl SampleKind {
    /// Bytes one sample occupies in storage and in files.
    pub const fn bytes(self) -> usize {
        match self {
            SampleKind::U8 => 1,
            SampleKind::U16 | SampleKind::I16 => 2,
            SampleKind::F32 => 4,
        }
    }

    /// Bytes one node of the fast tier's node field takes for samples of this kind
    /// ([`Sample::Node`]).
    pub const fn node_bytes(self) -> usize {
        match self {
            SampleKind::U8 => size_of::<<u8 as Sample>::Node>(),
            SampleKind::U16 => size_of::<<u16 as Sample>::Node>(),
            SampleKind::I16 => size_of::<<i16 as Sample>::Node>(),
            SampleKind::F32 => size_of::<<f32 as Sample>::Node>(),
        }
    }
}

/// A scalar sample the tracer can read.
pub trait Sample: Copy + Default + Send + Sync + 'static {
    /// Which kind this is.
    const KIND: SampleKind;
    /// The value as `f32`, exactly.
    fn to_f32(self) -> f32;
    /// Write the little-endian bytes into `out`; leaves it untouched unless it is exactly
    /// [`SampleKind::bytes`] long.
    fn write_le(self, out: &mut [u8]);
    /// The sample from little-endian bytes; `None` unless `bytes` is exactly its size.
    fn read_le(bytes: &[u8]) -> Option<Self>;
    /// The lesser of two samples by value: the one whose [`Sample::to_f32`] is the lesser
    /// (that conversion keeps the order), so a least value can be found before converting.
    fn lesser(self, other: Self) -> Self;
    /// The greater of two samples by value, as [`Sample::lesser`].
    fn greater(self, other: Self) -> Self;
    /// How the fast tier's node field stores a node of this kind
    /// ([`crate::volume::lanes`]): a type that holds its value and differences exactly.
    type Node: crate::volume::lanes::Lanes;
    /// The lanes of a node of value `here` whose neighbours are `x`, `y` and `z` (ahead,
    /// behind) along each axis: [`crate::volume::lanes::Lanes::pack`] of the value and the
    /// three differences, each taken in `f32`. A kind may compute them otherwise only where
    /// that gives the same lanes in every bit.
    #[inline(always)]
    fn node_lanes(here: Self, x: [Self; 2], y: [Self; 2], z: [Self; 2]) -> Self::Node {
        use crate::volume::lanes::Lanes;
        let d = |[ahead, behind]: [Self; 2]| ahead.to_f32() - behind.to_f32();
        Self::Node::pack(glam::Vec4::new(here.to_f32(), d(x), d(y), d(z)))
    }
}

/// The sample types differ only in their kind and their order: every conversion is the
/// standard library's own (`f32::from` is exact for `u8`, `u16` and `i16`, the identity for
/// `f32`), and so is every comparison (`Ord` for the integers, `f32::min` and `f32::max`,
/// which the tracer uses on converted values too).
macro_rules! sample {
    ($t:ty, $kind:ident, $lesser:path, $greater:path, $node:ty $(, $lanes:item)?) => {
        impl Sample for $t {
            const KIND: SampleKind = SampleKind::$kind;
            type Node = $node;
            $($lanes)?
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
            #[inline]
            fn lesser(self, other: Self) -> Self {
                $lesser(self, other)
            }
            #[inline]
            fn greater(self, other: Self) -> Self {
                $greater(self, other)
            }
        }
    };
}

// A byte node's value and differences lie in [-255, 255]: exact in i16, half the bytes of f32.
// A 16-bit node's differences need 17 bits, and f32's are f32: they keep four f32 lanes.
sample!(
    u8,
    U8,
    core::cmp::min,
    core::cmp::max,
    [i16; 4],
    // In whole numbers: a byte's value and differences are exact in f32 and in i16 alike, so
    // these are the lanes the default computes, without a conversion per neighbour.
    #[inline(always)]
    fn node_lanes(here: u8, x: [u8; 2], y: [u8; 2], z: [u8; 2]) -> [i16; 4] {
        let d = |[ahead, behind]: [u8; 2]| i16::from(ahead) - i16::from(behind);
        [i16::from(here), d(x), d(y), d(z)]
    }
);
sample!(u16, U16, core::cmp::min, core::cmp::max, [f32; 4]);
sample!(i16, I16, core::cmp::min, core::cmp::max, [f32; 4]);
sample!(f32, F32, f32::min, f32::max, [f32; 4]);

/// The values a field can take over a region (a min/max block's, for skipping).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Range {
    /// Least value.
    pub min: f32,
    /// Greatest value.
    pub max: f32,
}

impl Range {
    /// A range that proves nothing.
    pub const UNKNOWN: Range = Range {
        min: f32::NEG_INFINITY,
        max: f32::INFINITY,
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_byte_node_s_lanes_in_whole_numbers_are_the_default_s_in_every_bit() {
        // The default, spelled out for bytes: each lane through f32 and `pack`.
        let by_floats = |h: u8, x: [u8; 2], y: [u8; 2], z: [u8; 2]| {
            use crate::volume::lanes::Lanes;
            let d = |[a, b]: [u8; 2]| f32::from(a) - f32::from(b);
            <[i16; 4]>::pack(glam::Vec4::new(f32::from(h), d(x), d(y), d(z)))
        };
        // Every pair of neighbours, in each lane in turn, beside every value.
        for a in 0..=255u8 {
            for b in 0..=255u8 {
                let (p, q) = ([a, b], [b, a]);
                for (h, x, y, z) in [(a, p, q, p), (b, q, p, q), (a, [a, a], p, q)] {
                    assert_eq!(u8::node_lanes(h, x, y, z), by_floats(h, x, y, z), "{a} {b}");
                }
            }
        }
    }

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
        (-1024i16).write_le(&mut two);
        assert_eq!(two, [0x00, 0xfc]);
        assert_eq!(i16::read_le(&two), Some(-1024));
        assert_eq!((i16::MIN.to_f32(), i16::MAX.to_f32()), (-32768.0, 32767.0));
    }

    #[test]
    fn the_lesser_and_greater_sample_are_those_of_the_converted_values() {
        fn agree<T: Sample>(a: T, b: T) {
            let (x, y) = (a.to_f32(), b.to_f32());
            assert_eq!(a.lesser(b).to_f32().to_bits(), x.min(y).to_bits());
            assert_eq!(a.greater(b).to_f32().to_bits(), x.max(y).to_bits());
        }
        let mut next = crate::testing::xorshift(0x5a3_91e5);
        for _ in 0..10_000 {
            let (a, b) = (next(), next());
            agree(a as u8, b as u8);
            agree(a as u16, b as u16);
            agree(a as i16, b as i16);
            agree(
                (a % 2001) as f32 * 0.5 - 500.0,
                (b % 2001) as f32 * 0.5 - 500.0,
            );
        }
    }
}
