//! Finished pixels on their way to the host, [`PixelSet`], and its encoding.
//!
//! Invariant: a set holds at most [`PIXELS_PER_SET`] pixels, hands back one that does not
//! fit, and decoding refuses a count past it.

use super::wire::{DecodeError, Reader, Writer};
use crate::node::kind::PIXELS_PER_SET;

/// Finished pixels for the host.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelSet {
    /// How many of `pixels` are used.
    pub count: u8,
    /// Pixel index and RGBA8 value.
    pub pixels: [(u32, [u8; 4]); PIXELS_PER_SET],
}

impl Default for PixelSet {
    fn default() -> PixelSet {
        PixelSet {
            count: 0,
            pixels: [(0, [0; 4]); PIXELS_PER_SET],
        }
    }
}

impl PixelSet {
    /// The used entries.
    pub fn entries(&self) -> &[(u32, [u8; 4])] {
        &self.pixels[..usize::from(self.count).min(PIXELS_PER_SET)]
    }

    /// Add a pixel; hands it back when full.
    pub fn push(&mut self, pixel: u32, rgba: [u8; 4]) -> Result<(), (u32, [u8; 4])> {
        let i = usize::from(self.count);
        match self.pixels.get_mut(i) {
            Some(slot) => {
                *slot = (pixel, rgba);
                self.count += 1;
                Ok(())
            }
            None => Err((pixel, rgba)),
        }
    }

    /// Whether no more pixels fit.
    pub fn is_full(&self) -> bool {
        usize::from(self.count) >= PIXELS_PER_SET
    }
}

impl PixelSet {
    pub(super) fn emit(&self, w: &mut Writer<'_>) {
        w.u8(self.count);
        for (pixel, rgba) in self.pixels {
            w.u32(pixel);
            w.bytes(&rgba);
        }
    }

    pub(super) fn parse(r: &mut Reader<'_>) -> Result<PixelSet, DecodeError> {
        let count = r.u8()?;
        if usize::from(count) > PIXELS_PER_SET {
            return Err(r.bad("count"));
        }
        let mut set = PixelSet {
            count,
            ..PixelSet::default()
        };
        for slot in &mut set.pixels {
            *slot = (r.u32()?, r.take::<4>()?);
        }
        Ok(set)
    }
}

#[cfg(test)]
mod tests {
    use super::super::fixtures::*;
    use super::super::PIXELS_PER_SET;

    #[test]
    fn a_pixel_set_round_trips_and_its_count_is_checked() {
        roundtrip(pixels());
        refuses(pixels(), 1, PIXELS_PER_SET as u8 + 1, "count");
    }
}
