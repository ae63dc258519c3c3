//! A ray forwarded to the node that owns its next sample: its whole state and where its result
//! goes, [`Travel`], and its encoding.
//!
//! Invariant: every field a ray needs to continue is on the wire; decoding refuses a kind,
//! entry face or flag byte outside its range and a lattice longer than [`MAX_SAMPLES`].

use super::reply::Reply;
use super::wire::{DecodeError, Reader, Writer};
use crate::trace::lattice::{Lattice, MAX_SAMPLES};
use crate::trace::ray::{Entry, Ray};
use crate::trace::state::{RayKind, RayState};

/// A ray in flight between nodes, with all its state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Travel {
    /// The ray.
    pub ray: RayState,
    /// Where its result goes.
    pub reply: Reply,
}

fn entry_code(e: Entry) -> u8 {
    match e {
        Entry::Face { axis, high } => (axis % 3) * 2 + u8::from(high),
        Entry::Inside => 6,
    }
}

impl Travel {
    pub(super) fn emit(&self, w: &mut Writer<'_>) {
        let r = &self.ray;
        w.u8(r.kind as u8);
        w.u32(r.pixel);
        w.vec3(r.ray.origin);
        w.vec3(r.ray.dir);
        w.vec3(r.ray.dir_world);
        w.f32(r.lattice.t_entry);
        w.f32(r.lattice.t_exit);
        w.f32(r.lattice.dt);
        w.u32(r.lattice.last);
        w.u8(entry_code(r.entry));
        w.u32(r.k);
        w.f32(r.prev);
        w.u8(u8::from(r.primed) | u8::from(r.prev_stale) << 1);
        w.u16(r.done_here);
        w.u8(r.depth);
        w.f32(r.weight);
        w.vec3(r.color);
        w.reply(&self.reply);
    }

    pub(super) fn parse(r: &mut Reader<'_>) -> Result<Travel, DecodeError> {
        let ray_kind = match r.u8()? {
            0 => RayKind::Primary,
            1 => RayKind::Transparency,
            2 => RayKind::Shadow,
            _ => return Err(r.bad("kind")),
        };
        let pixel = r.u32()?;
        let ray = Ray {
            origin: r.vec3()?,
            dir: r.vec3()?,
            dir_world: r.vec3()?,
        };
        let lattice = Lattice {
            t_entry: r.f32()?,
            t_exit: r.f32()?,
            dt: r.f32()?,
            last: r.u32()?,
        };
        if lattice.last > MAX_SAMPLES {
            return Err(r.bad("last"));
        }
        let entry = match r.u8()? {
            6 => Entry::Inside,
            c @ 0..=5 => Entry::Face {
                axis: c / 2,
                high: c % 2 == 1,
            },
            _ => return Err(r.bad("entry")),
        };
        let k = r.u32()?;
        let prev = r.f32()?;
        let flags = r.u8()?;
        if flags > 3 {
            return Err(r.bad("flags"));
        }
        let (primed, prev_stale) = (flags & 1 != 0, flags & 2 != 0);
        let done_here = r.u16()?;
        let depth = r.u8()?;
        let weight = r.f32()?;
        let color = r.vec3()?;
        let reply = r.reply()?;
        let ray = RayState {
            kind: ray_kind,
            pixel,
            ray,
            lattice,
            entry,
            k,
            prev,
            primed,
            prev_stale,
            done_here,
            depth,
            weight,
            color,
        };
        Ok(Travel { ray, reply })
    }
}

#[cfg(test)]
mod tests {
    use super::super::fixtures::*;

    #[test]
    fn a_ray_round_trips_and_each_range_is_checked() {
        roundtrip(ray());
        refuses(ray(), 1, 3, "kind");
        // `last`, little-endian at 54..58: its top byte makes it exceed MAX_SAMPLES.
        refuses(ray(), 57, 0xff, "last");
        refuses(ray(), 58, 7, "entry");
        refuses(ray(), 67, 4, "flags");
    }
}
