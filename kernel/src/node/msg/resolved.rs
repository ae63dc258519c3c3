//! A secondary or composited ray's result going to its pixel's home, [`Resolved`] with its
//! [`Outcome`], and its encoding: the outcome's tag, then its fields, padded to one length.
//!
//! Invariant: decoding refuses an outcome tag other than 0, 1 or 2.

use super::reply::Reply;
use super::wire::{DecodeError, Reader, Writer};
use glam::Vec3;

/// What a finished ray reports.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Outcome {
    /// A primary or transparency ray left the volume: the pixel's chain has `hits` hits.
    ChainEnd {
        /// Hits in the chain.
        hits: u8,
    },
    /// A shadow ray's visibility.
    Shadow {
        /// Transmittance toward the light.
        visibility: f32,
    },
    /// A composited primary ray's final colour.
    Color(Vec3),
}

/// A secondary ray's (or a composited ray's) result, going to the pixel's home.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Resolved {
    /// The pixel record and part.
    pub reply: Reply,
    /// The pixel (a check against the record).
    pub pixel: u32,
    /// The result.
    pub outcome: Outcome,
}

impl Resolved {
    pub(super) fn emit(&self, w: &mut Writer<'_>) {
        w.reply(&self.reply);
        w.u32(self.pixel);
        match self.outcome {
            Outcome::ChainEnd { hits } => {
                w.u8(0);
                w.u8(hits);
                w.bytes(&[0; 11]);
            }
            Outcome::Shadow { visibility } => {
                w.u8(1);
                w.f32(visibility);
                w.bytes(&[0; 8]);
            }
            Outcome::Color(c) => {
                w.u8(2);
                w.vec3(c);
            }
        }
    }

    pub(super) fn parse(r: &mut Reader<'_>) -> Result<Resolved, DecodeError> {
        let reply = r.reply()?;
        let pixel = r.u32()?;
        let outcome = match r.u8()? {
            0 => Outcome::ChainEnd { hits: r.u8()? },
            1 => Outcome::Shadow {
                visibility: r.f32()?,
            },
            2 => Outcome::Color(r.vec3()?),
            _ => return Err(r.bad("outcome")),
        };
        Ok(Resolved {
            reply,
            pixel,
            outcome,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::fixtures::*;
    use super::Outcome;
    use glam::Vec3;

    #[test]
    fn every_outcome_round_trips_and_its_tag_is_checked() {
        for outcome in [
            Outcome::ChainEnd { hits: 4 },
            Outcome::Shadow { visibility: 0.5 },
            Outcome::Color(Vec3::ONE),
        ] {
            roundtrip(resolved(outcome));
        }
        refuses(resolved(Outcome::Color(Vec3::ONE)), 11, 3, "outcome");
    }
}
