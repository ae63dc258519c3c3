//! Pixel records: the primary-ray descriptors a worker keeps for the pixels whose primary rays
//! it generated (their *home*), while the parts of their ray trees are traced anywhere.
//!
//! A record collects each hit's lighting (a [`HitRecord`]), each shadow ray's visibility, and
//! the chain's length, in whatever order they arrive, then combines them with the one formula
//! of [`crate::trace::tree`]: from the deepest hit outward, `through(alpha, color, behind)`, the
//! background behind the deepest. Invariants: a part arrives once (a second copy is refused);
//! a record is complete only when the chain's length is known and every hit up to it and
//! every shadow visibility those hits asked for have arrived; a complete record never changes.
//!
//! [`Records`] holds a worker's records in fixed slots. A slot is reopened for the next pixel
//! without rewriting the hits the last one used: a record clears a hit's storage when the
//! first part for it arrives, so opening one costs the same for a view of one hit as for
//! the deepest chain a view may ask for, and a worker touches only the hits its view calls for.
//! Slots are written when first needed, not when the worker is built: building a worker then
//! writes none of its 64 records of 1,368 bytes, only ever as many as were open at once.

use crate::node::msg::{HitRecord, Outcome};
use crate::optics::shade::MAX_LIGHTS;
use crate::trace::tree;
use crate::trace::view::MAX_DEPTH;
use core::fmt;
use glam::Vec3;
use heapless::Vec;

/// Most hits in one pixel's chain.
pub const MAX_HITS: usize = MAX_DEPTH as usize + 1;

/// A part that does not fit the record.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RecordError {
    /// Hit index or light out of range.
    OutOfRange,
    /// The part was already received.
    Duplicate,
    /// A part for a different pixel, or of the other mode.
    Mismatch,
}

impl fmt::Display for RecordError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            RecordError::OutOfRange => "part index out of range",
            RecordError::Duplicate => "part received twice",
            RecordError::Mismatch => "part belongs to another pixel or mode",
        })
    }
}

impl core::error::Error for RecordError {}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct HitPart {
    present: bool,
    alpha: f32,
    ambient: Vec3,
    direct: [Vec3; MAX_LIGHTS],
    lights: u8,
    shadow_mask: u8,
    visibility: [f32; MAX_LIGHTS],
    seen: u8,
}

/// One pixel's descriptor. Two records are equal when they hold the same parts of the same
/// pixel, whatever stale hits their storage still holds.
#[derive(Clone, Copy, Debug)]
pub struct PixelRecord {
    pixel: u32,
    /// Hits `fresh..` hold no part of this pixel: whatever they hold is stale, and they are
    /// cleared when a part for one of them arrives.
    fresh: u8,
    hits: [HitPart; MAX_HITS],
    chain: Option<u8>,
    color: Option<Vec3>,
}

impl PixelRecord {
    /// An empty record for `pixel`.
    pub fn new(pixel: u32) -> PixelRecord {
        PixelRecord {
            pixel,
            fresh: 0,
            hits: [HitPart::default(); MAX_HITS],
            chain: None,
            color: None,
        }
    }

    /// Make this an empty record for `pixel`, leaving the stale hits where they are.
    fn reopen(&mut self, pixel: u32) {
        self.pixel = pixel;
        self.fresh = 0;
        self.chain = None;
        self.color = None;
    }

    /// The hits some part of this pixel has reached.
    fn parts(&self) -> &[HitPart] {
        self.hits.get(..usize::from(self.fresh)).unwrap_or(&[])
    }

    /// Hit `index`, cleared first if no part of this pixel has reached it yet.
    fn part_mut(&mut self, index: u8) -> Option<&mut HitPart> {
        let index = usize::from(index);
        let fresh = usize::from(self.fresh);
        if index >= fresh {
            self.hits.get_mut(fresh..=index)?.fill(HitPart::default());
            // `index < MAX_HITS`, which fits in a byte: the slice above would not exist else.
            self.fresh = index as u8 + 1;
        }
        self.hits.get_mut(index)
    }

    /// The pixel.
    pub fn pixel(&self) -> u32 {
        self.pixel
    }

    /// Take in a hit's lighting.
    pub fn add_hit(&mut self, index: u8, h: &HitRecord) -> Result<(), RecordError> {
        if h.pixel != self.pixel || self.color.is_some() {
            return Err(RecordError::Mismatch);
        }
        if usize::from(h.lights) > MAX_LIGHTS {
            return Err(RecordError::OutOfRange);
        }
        let part = self.part_mut(index).ok_or(RecordError::OutOfRange)?;
        if part.present {
            return Err(RecordError::Duplicate);
        }
        part.present = true;
        part.alpha = h.alpha;
        part.ambient = h.ambient;
        part.direct = h.direct;
        part.lights = h.lights;
        part.shadow_mask = h.shadow_mask;
        if !h.continues {
            self.set_chain(index.saturating_add(1))?;
        }
        Ok(())
    }

    fn set_chain(&mut self, hits: u8) -> Result<(), RecordError> {
        if usize::from(hits) > MAX_HITS {
            return Err(RecordError::OutOfRange);
        }
        match self.chain {
            Some(_) => Err(RecordError::Duplicate),
            None => {
                self.chain = Some(hits);
                Ok(())
            }
        }
    }

    /// Take in a ray's result for this pixel (`hit`, `light` from its reply).
    pub fn add_outcome(
        &mut self,
        pixel: u32,
        hit: u8,
        light: u8,
        outcome: Outcome,
    ) -> Result<(), RecordError> {
        if pixel != self.pixel {
            return Err(RecordError::Mismatch);
        }
        match outcome {
            Outcome::ChainEnd { hits } => self.set_chain(hits),
            Outcome::Color(c) => {
                if self.color.is_some()
                    || self.chain.is_some()
                    || self.parts().iter().any(|h| h.present)
                {
                    return Err(RecordError::Duplicate);
                }
                self.color = Some(c);
                Ok(())
            }
            Outcome::Shadow { visibility } => {
                if usize::from(light) >= MAX_LIGHTS {
                    return Err(RecordError::OutOfRange);
                }
                let part = self.part_mut(hit).ok_or(RecordError::OutOfRange)?;
                let slot = part
                    .visibility
                    .get_mut(usize::from(light))
                    .ok_or(RecordError::OutOfRange)?;
                let bit = 1u8 << light;
                if part.seen & bit != 0 {
                    return Err(RecordError::Duplicate);
                }
                part.seen |= bit;
                *slot = visibility;
                Ok(())
            }
        }
    }

    /// The pixel's colour, once every part has arrived.
    pub fn color(&self, background: Vec3) -> Option<Vec3> {
        self.combine(background, true)
    }

    /// The colour as if every missing shadow ray had returned unshadowed: a fault for negative
    /// controls.
    #[cfg(feature = "mutants")]
    pub fn color_without_waiting_for_shadows(&self, background: Vec3) -> Option<Vec3> {
        self.combine(background, false)
    }

    fn combine(&self, background: Vec3, wait_for_shadows: bool) -> Option<Vec3> {
        if let Some(c) = self.color {
            return Some(c);
        }
        let n = usize::from(self.chain?);
        let hits = self.parts().get(..n)?;
        let complete = |h: &HitPart| {
            h.present && (!wait_for_shadows || h.seen & h.shadow_mask == h.shadow_mask)
        };
        if !hits.iter().all(complete) {
            return None;
        }
        let mut seen = background;
        for h in hits.iter().rev() {
            let mut visibility = [1.0f32; MAX_LIGHTS];
            for (l, v) in visibility.iter_mut().enumerate() {
                if h.shadow_mask & h.seen & (1 << l) != 0 {
                    *v = h.visibility[l];
                }
            }
            let lights = usize::from(h.lights).min(MAX_LIGHTS);
            let color = tree::surface_color(h.ambient, &h.direct[..lights], &visibility[..lights]);
            seen = tree::through(h.alpha, color, seen);
        }
        Some(seen)
    }
}

impl PartialEq for PixelRecord {
    fn eq(&self, other: &PixelRecord) -> bool {
        self.pixel == other.pixel
            && self.chain == other.chain
            && self.color == other.color
            && self.parts() == other.parts()
    }
}

/// A worker's pixel records in `N` fixed slots, each open (holding a pixel in flight) or free.
/// Invariants: `in_use` is the number of open slots; only the first `slots.len()` can be open
/// (the rest have never been written).
#[derive(Clone, Debug)]
pub struct Records<const N: usize> {
    slots: Vec<PixelRecord, N>,
    open: [bool; N],
    in_use: usize,
}

impl<const N: usize> Default for Records<N> {
    fn default() -> Self {
        Records {
            slots: Vec::new(),
            open: [false; N],
            in_use: 0,
        }
    }
}

impl<const N: usize> Records<N> {
    /// Open a free slot for `pixel`: its index, or `None` when every slot is open.
    pub fn open(&mut self, pixel: u32) -> Option<u16> {
        let written = self.slots.len();
        let slot = match self.open.get(..written)?.iter().position(|&open| !open) {
            Some(slot) => {
                self.slots.get_mut(slot)?.reopen(pixel);
                slot
            }
            None => {
                self.slots.push(PixelRecord::new(pixel)).ok()?;
                written
            }
        };
        let index = u16::try_from(slot).ok()?;
        *self.open.get_mut(slot)? = true;
        self.in_use += 1;
        Some(index)
    }

    /// The record in `slot`, if it is open.
    pub fn get(&self, slot: usize) -> Option<&PixelRecord> {
        match self.open.get(slot) {
            Some(true) => self.slots.get(slot),
            _ => None,
        }
    }

    /// The record in `slot`, if it is open, to take in parts.
    pub fn get_mut(&mut self, slot: usize) -> Option<&mut PixelRecord> {
        match self.open.get(slot) {
            Some(true) => self.slots.get_mut(slot),
            _ => None,
        }
    }

    /// Free `slot` (nothing happens if it is not open).
    pub fn close(&mut self, slot: usize) {
        if let Some(open) = self.open.get_mut(slot).filter(|open| **open) {
            *open = false;
            self.in_use -= 1;
        }
    }

    /// Open slots.
    pub fn in_use(&self) -> usize {
        self.in_use
    }

    /// Write what steers the records from here on: each open slot's index and its record's
    /// live parts (a closed slot, and a record's hits past `fresh`, are history).
    pub(crate) fn digest(&self, w: &mut impl fmt::Write) -> fmt::Result {
        for (slot, r) in self.slots.iter().enumerate() {
            if self.open.get(slot) == Some(&true) {
                let live = r.hits.get(..usize::from(r.fresh)).unwrap_or_default();
                write!(
                    w,
                    "{slot}:{}:{}:{live:?}:{:?}:{:?};",
                    r.pixel, r.fresh, r.chain, r.color
                )?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::node::msg::Reply;

    fn hit(pixel: u32, alpha: f32, mask: u8, continues: bool) -> HitRecord {
        HitRecord {
            reply: Reply {
                home: 0,
                slot: 0,
                hit: 0,
                light: 0,
            },
            pixel,
            alpha,
            ambient: Vec3::splat(0.1),
            direct: [Vec3::splat(0.5), Vec3::ZERO, Vec3::ZERO, Vec3::ZERO],
            shadow_mask: mask,
            lights: 1,
            continues,
        }
    }

    #[test]
    fn parts_in_any_order_give_the_same_colour() {
        let bg = Vec3::new(0.0, 0.0, 1.0);
        let mut a = PixelRecord::new(3);
        a.add_hit(0, &hit(3, 0.5, 1, true)).unwrap();
        assert_eq!(a.color(bg), None);
        a.add_outcome(3, 0, 0, Outcome::Shadow { visibility: 0.25 })
            .unwrap();
        a.add_hit(1, &hit(3, 1.0, 0, false)).unwrap();
        let mut b = PixelRecord::new(3);
        b.add_hit(1, &hit(3, 1.0, 0, false)).unwrap();
        b.add_outcome(3, 0, 0, Outcome::Shadow { visibility: 0.25 })
            .unwrap();
        assert_eq!(b.color(bg), None, "hit 0 is missing");
        b.add_hit(0, &hit(3, 0.5, 1, true)).unwrap();
        assert_eq!(a.color(bg), b.color(bg));
        let front = 0.1 + 0.25 * 0.5;
        let back = 0.1 + 0.5;
        let expect = Vec3::splat(front) * 0.5 + Vec3::splat(back) * 0.5;
        assert!((a.color(bg).unwrap() - expect).length() < 1e-6);
    }

    #[test]
    fn duplicates_and_strangers_are_refused() {
        let mut r = PixelRecord::new(1);
        r.add_hit(0, &hit(1, 0.5, 0, true)).unwrap();
        assert_eq!(
            r.add_hit(0, &hit(1, 0.5, 0, true)),
            Err(RecordError::Duplicate)
        );
        assert_eq!(
            r.add_hit(0, &hit(2, 0.5, 0, true)),
            Err(RecordError::Mismatch)
        );
        assert_eq!(
            r.add_hit(99, &hit(1, 0.5, 0, true)),
            Err(RecordError::OutOfRange)
        );
        assert_eq!(
            r.add_outcome(1, 0, 9, Outcome::Shadow { visibility: 1.0 }),
            Err(RecordError::OutOfRange)
        );
        r.add_outcome(1, 0, 0, Outcome::ChainEnd { hits: 1 })
            .unwrap();
        assert_eq!(
            r.add_outcome(1, 0, 0, Outcome::ChainEnd { hits: 1 }),
            Err(RecordError::Duplicate)
        );
        assert_eq!(r.color(Vec3::ZERO).map(|c| c.is_finite()), Some(true));
    }

    #[test]
    fn a_reopened_slot_shows_nothing_of_its_last_pixel() {
        let bg = Vec3::new(0.0, 0.0, 1.0);
        let mut records = Records::<1>::default();
        let slot = records.open(7).unwrap();
        let deep = records.get_mut(usize::from(slot)).unwrap();
        for i in 0..4 {
            deep.add_hit(i, &hit(7, 0.25, 1, i < 3)).unwrap();
            deep.add_outcome(7, i, 0, Outcome::Shadow { visibility: 0.5 })
                .unwrap();
        }
        assert!(deep.color(bg).is_some());
        assert_eq!(records.open(8), None, "the only slot is open");
        records.close(usize::from(slot));
        assert_eq!(records.in_use(), 0);

        // The stale hits 0..4 of pixel 7 are still in the slot's storage: none may count.
        let slot = records.open(8).unwrap();
        let again = records.get_mut(usize::from(slot)).unwrap();
        assert_eq!(again.color(bg), None);
        again
            .add_outcome(8, 0, 0, Outcome::Color(Vec3::ONE))
            .unwrap();
        assert_eq!(again.color(bg), Some(Vec3::ONE));
        records.close(usize::from(slot));

        let slot = usize::from(records.open(9).unwrap());
        let shallow = records.get_mut(slot).unwrap();
        shallow.add_hit(1, &hit(9, 1.0, 0, false)).unwrap();
        assert_eq!(shallow.color(bg), None, "hit 0 of pixel 9 has not arrived");
        shallow.add_hit(0, &hit(9, 0.5, 0, true)).unwrap();
        let mut fresh = PixelRecord::new(9);
        fresh.add_hit(0, &hit(9, 0.5, 0, true)).unwrap();
        fresh.add_hit(1, &hit(9, 1.0, 0, false)).unwrap();
        assert_eq!(records.get(slot).unwrap().color(bg), fresh.color(bg));
        assert_eq!(records.get(slot), Some(&fresh), "stale hits do not count");
    }

    #[test]
    fn only_open_slots_take_parts_and_closing_twice_changes_nothing() {
        let mut records = Records::<2>::default();
        assert!(records.get_mut(0).is_none());
        let a = usize::from(records.open(1).unwrap());
        let b = usize::from(records.open(2).unwrap());
        assert_ne!(a, b);
        records.close(a);
        records.close(a);
        assert_eq!(records.in_use(), 1);
        assert!(records.get(a).is_none() && records.get(b).is_some());
        assert!(records.get(5).is_none());
        assert_eq!(records.open(3).map(usize::from), Some(a));
    }

    #[test]
    fn a_slot_is_written_first_when_every_written_one_is_open() {
        let mut records = Records::<4>::default();
        assert_eq!(records.slots.len(), 0, "building writes no record");
        let slots: [usize; 3] =
            core::array::from_fn(|p| usize::from(records.open(p as u32).unwrap()));
        assert_eq!(slots, [0, 1, 2]);
        records.close(1);
        assert_eq!(
            records.open(10).map(usize::from),
            Some(1),
            "a free written slot first"
        );
        assert_eq!(records.slots.len(), 3);
        assert_eq!(records.open(11).map(usize::from), Some(3));
        assert_eq!(records.open(12), None, "every slot is open");
        assert_eq!((records.in_use(), records.slots.len()), (4, 4));
        assert_eq!(records.get(1).map(|r| r.pixel), Some(10));
    }
}
