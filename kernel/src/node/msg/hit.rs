//! A surface hit's contribution going to its pixel's home, [`HitRecord`], and its encoding.
//!
//! Invariant: decoding refuses more lights than [`MAX_LIGHTS`], a shadow mask naming a light
//! past them, and a `continues` byte other than 0 or 1.

use super::reply::Reply;
use super::wire::{DecodeError, Reader, Writer};
use crate::optics::shade::MAX_LIGHTS;
use glam::Vec3;

/// A surface hit's contribution, going to the pixel's home.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HitRecord {
    /// The pixel record and hit index.
    pub reply: Reply,
    /// The pixel (a check against the record).
    pub pixel: u32,
    /// The surface's opacity.
    pub alpha: f32,
    /// Ambient term (or unlit colour).
    pub ambient: Vec3,
    /// Each light's direct term.
    pub direct: [Vec3; MAX_LIGHTS],
    /// Lights whose shadow rays will report a visibility.
    pub shadow_mask: u8,
    /// Lights that contribute.
    pub lights: u8,
    /// Whether a transparency ray continues past this hit.
    pub continues: bool,
}

impl HitRecord {
    pub(super) fn emit(&self, w: &mut Writer<'_>) {
        w.reply(&self.reply);
        w.u32(self.pixel);
        w.f32(self.alpha);
        w.vec3(self.ambient);
        for d in self.direct {
            w.vec3(d);
        }
        w.u8(self.shadow_mask);
        w.u8(self.lights);
        w.u8(u8::from(self.continues));
    }

    pub(super) fn parse(r: &mut Reader<'_>) -> Result<HitRecord, DecodeError> {
        let reply = r.reply()?;
        let pixel = r.u32()?;
        let alpha = r.f32()?;
        let ambient = r.vec3()?;
        let mut direct = [Vec3::ZERO; MAX_LIGHTS];
        for d in &mut direct {
            *d = r.vec3()?;
        }
        let shadow_mask = r.u8()?;
        let lights = r.u8()?;
        if usize::from(lights) > MAX_LIGHTS || u32::from(shadow_mask) >= 1 << MAX_LIGHTS {
            return Err(r.bad("lights"));
        }
        let continues = r.bool("continues")?;
        Ok(HitRecord {
            reply,
            pixel,
            alpha,
            ambient,
            direct,
            shadow_mask,
            lights,
            continues,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::fixtures::*;
    use crate::optics::shade::MAX_LIGHTS;

    #[test]
    fn a_hit_round_trips_and_each_range_is_checked() {
        roundtrip(hit());
        refuses(hit(), 75, 1 << MAX_LIGHTS, "lights");
        refuses(hit(), 76, MAX_LIGHTS as u8 + 1, "lights");
        refuses(hit(), 77, 2, "continues");
    }
}
