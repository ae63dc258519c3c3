//! Buffers of plain items that the host builds once per volume and that rays read all over
//! (the node field): held, where they are large, in anonymous memory advised to the kernel's
//! transparent huge pages, so that their first writing faults 2 MiB at a time instead of
//! 4 KiB, and a ray's reads across them miss the address translation's cache less.
//!
//! Invariant: a buffer of `len` items reads `len` zeroed items when made, as `vec![zeroed;
//! len]` does, whichever memory holds it; the advice is a hint, and where the kernel refuses
//! it (or the platform has no such thing) the buffer is the same, in ordinary pages.

use bytemuck::Pod;
use std::fmt;
use std::marker::PhantomData;
use std::ops::{Deref, DerefMut};

/// From how many bytes a buffer is mapped and advised: a huge page's 2 MiB, below which the
/// advice cannot take effect.
pub const HUGE_FROM_BYTES: usize = 2 << 20;

/// `len` items, zeroed.
pub struct HugeBuffer<N> {
    held: Held,
    len: usize,
    items: PhantomData<N>,
}

/// Where a buffer's bytes live.
enum Held {
    /// An anonymous mapping advised to huge pages.
    Mapped(memmap2::MmapMut),
    /// The heap's, for a small buffer or where no mapping was made; kept as `u64`s, so
    /// aligned for every item up to eight bytes' alignment.
    Heap(Vec<u64>),
}

impl<N: Pod> HugeBuffer<N> {
    /// `len` zeroed items; `None` where their bytes overflow `usize`, an item asks more than
    /// eight bytes' alignment, or the memory is not given.
    pub fn zeroed(len: usize) -> Option<HugeBuffer<N>> {
        let bytes = len.checked_mul(size_of::<N>())?;
        // A mapping is page-aligned, more than any item asks; the heap's words suffice for
        // items of up to eight bytes' alignment (a node's lanes ask two or four).
        if align_of::<N>() > align_of::<u64>() {
            return None;
        }
        let held = match bytes >= HUGE_FROM_BYTES {
            true => match memmap2::MmapOptions::new().len(bytes).map_anon() {
                Ok(map) => {
                    advise(&map);
                    Held::Mapped(map)
                }
                Err(_) => heap(bytes)?,
            },
            false => heap(bytes)?,
        };
        Some(HugeBuffer {
            held,
            len,
            items: PhantomData,
        })
    }

    /// Whether its memory is a mapping advised to huge pages.
    pub fn is_mapped(&self) -> bool {
        matches!(self.held, Held::Mapped(_))
    }
}

/// Zeroed heap words for `bytes`, or `None` where they are not given.
fn heap(bytes: usize) -> Option<Held> {
    let words = bytes.div_ceil(size_of::<u64>());
    let mut held = Vec::new();
    held.try_reserve_exact(words).ok()?;
    held.resize(words, 0u64);
    Some(Held::Heap(held))
}

/// Ask for huge pages over `map`. A refusal (no THP in this kernel, or off) leaves the
/// ordinary pages, which hold the same bytes.
fn advise(map: &memmap2::MmapMut) {
    #[cfg(target_os = "linux")]
    {
        let _refused_is_fine = map.advise(memmap2::Advice::HugePage);
    }
    #[cfg(not(target_os = "linux"))]
    let _ = map;
}

impl<N: Pod> Deref for HugeBuffer<N> {
    type Target = [N];
    fn deref(&self) -> &[N] {
        let bytes: &[u8] = match &self.held {
            Held::Mapped(map) => map,
            Held::Heap(words) => bytemuck::cast_slice(words),
        };
        // `zeroed` made at least `len` items' bytes, aligned for them.
        bytemuck::cast_slice(&bytes[..self.len * size_of::<N>()])
    }
}

impl<N: Pod> DerefMut for HugeBuffer<N> {
    fn deref_mut(&mut self) -> &mut [N] {
        let len = self.len * size_of::<N>();
        let bytes: &mut [u8] = match &mut self.held {
            Held::Mapped(map) => map,
            Held::Heap(words) => bytemuck::cast_slice_mut(words),
        };
        bytemuck::cast_slice_mut(&mut bytes[..len])
    }
}

impl<N: Pod> Default for HugeBuffer<N> {
    fn default() -> Self {
        HugeBuffer {
            held: Held::Heap(Vec::new()),
            len: 0,
            items: PhantomData,
        }
    }
}

impl<N: Pod + fmt::Debug> fmt::Debug for HugeBuffer<N> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "HugeBuffer({} items, {})",
            self.len,
            if self.is_mapped() { "mapped" } else { "heap" }
        )
    }
}

impl<N: Pod + PartialEq> PartialEq for HugeBuffer<N> {
    fn eq(&self, other: &Self) -> bool {
        **self == **other
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Small and large buffers alike read zeroed items, hold what is written, and are as
    /// long as asked; a large one is a mapping, a small one the heap's.
    #[test]
    fn buffers_are_zeroed_hold_their_items_and_map_only_when_large() {
        for len in [0usize, 1, 3, 1000, HUGE_FROM_BYTES / 8 + 5] {
            let mut b = HugeBuffer::<[i16; 4]>::zeroed(len).expect("memory");
            assert_eq!(b.len(), len);
            assert!(b.iter().all(|&n| n == [0; 4]));
            assert_eq!(b.is_mapped(), len * 8 >= HUGE_FROM_BYTES, "{len}");
            for (i, n) in b.iter_mut().enumerate() {
                *n = [i as i16, 1, 2, 3];
            }
            assert!(b.iter().enumerate().all(|(i, n)| *n == [i as i16, 1, 2, 3]));
        }
        let f = HugeBuffer::<[f32; 4]>::zeroed(HUGE_FROM_BYTES / 16).expect("memory");
        assert!(f.is_mapped() && f.iter().all(|&n| n == [0.0; 4]));
    }

    /// A length whose bytes overflow is refused, not wrapped.
    #[test]
    fn an_overflowing_length_is_refused() {
        assert!(HugeBuffer::<[f32; 4]>::zeroed(usize::MAX / 8).is_none());
    }
}
