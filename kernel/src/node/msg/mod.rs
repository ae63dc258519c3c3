//! Messages between nodes and the host, and their fixed-size little-endian encoding.
//!
//! Each kind has one encoded length ([`MsgKind::encoded_len`]), at most [`MAX_MSG_LEN`]
//! bytes: a tag byte, then the fields in order. Here: the tag and length; each kind's fields,
//! their order and their range checks in its own module (`ray`, `hit`, `resolved`, `pixels`,
//! `planes`, `stats`, `control`), over the little-endian fields of `wire`. Decoding any byte string returns a message or
//! a [`DecodeError`], never panics: lengths, tags and enumerations are checked, counts are
//! bounded, and float fields may hold any bits (the tracer is robust to NaN).
//!
//! Invariant: `decode(encode(m)) == m` for every message, and every encoding is exactly its
//! kind's length.

mod control;
mod hit;
mod pixels;
mod planes;
mod ray;
mod reply;
mod resolved;
mod stats;
mod wire;

pub use crate::node::kind::{MsgKind, KINDS, MAX_MSG_LEN, PIXELS_PER_SET, PLANE_CHUNK};
pub use hit::HitRecord;
pub use pixels::PixelSet;
pub use planes::PlaneChunk;
pub use ray::Travel;
pub use reply::{Reply, NO_HOME, NO_LIGHT};
pub use resolved::{Outcome, Resolved};
pub use wire::DecodeError;

use crate::node::flow::Class;
use crate::node::stats::NodeStats;
use wire::{Reader, Writer};

/// A message.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Msg {
    /// A ray forwarded to the node owning its next sample.
    Ray(Travel),
    /// A hit's contribution, going home.
    Hit(HitRecord),
    /// A resolved descriptor, going home.
    Resolved(Resolved),
    /// Acknowledges `count` messages of credit class `class` read from the receiver of this
    /// ack, by node `from` (flow control).
    Ack {
        /// The acknowledging node.
        from: u16,
        /// Credit class index (see [`crate::node::flow::CREDIT_CLASSES`]).
        class: u8,
        /// Messages acknowledged.
        count: u16,
    },
    /// The termination token of a cluster.
    Token {
        /// The cluster.
        cluster: u16,
    },
    /// Finished pixels, to the host.
    Pixels(PixelSet),
    /// A worker's statistics, to the host.
    Stats(NodeStats),
    /// Slab plane data, between neighbours.
    Planes(PlaneChunk),
    /// The host, after every cluster's token: send your statistics once your acks are in.
    Collect,
}

impl Msg {
    /// The message's kind.
    pub fn kind(&self) -> MsgKind {
        match self {
            Msg::Ray(_) => MsgKind::Ray,
            Msg::Hit(_) => MsgKind::Hit,
            Msg::Resolved(_) => MsgKind::Resolved,
            Msg::Ack { .. } => MsgKind::Ack,
            Msg::Token { .. } => MsgKind::Token,
            Msg::Pixels(_) => MsgKind::Pixels,
            Msg::Stats(_) => MsgKind::Stats,
            Msg::Planes(_) => MsgKind::Planes,
            Msg::Collect => MsgKind::Collect,
        }
    }

    /// The class this message is queued and credited in.
    pub fn class(&self) -> Class {
        match self {
            Msg::Ray(t) => Class::of_ray(t.ray.kind, t.ray.ray.dir.x),
            Msg::Hit(_) | Msg::Resolved(_) => Class::Result,
            Msg::Ack { .. } => Class::Ack,
            Msg::Token { .. } | Msg::Pixels(_) | Msg::Stats(_) | Msg::Planes(_) | Msg::Collect => {
                Class::Control
            }
        }
    }

    /// Encode into `buf`; returns the length (always `self.kind().encoded_len()`).
    pub fn encode(&self, buf: &mut [u8; MAX_MSG_LEN]) -> usize {
        let mut w = Writer::new(buf);
        w.u8(self.kind() as u8);
        match self {
            Msg::Ray(t) => t.emit(&mut w),
            Msg::Hit(h) => h.emit(&mut w),
            Msg::Resolved(r) => r.emit(&mut w),
            Msg::Ack { from, class, count } => control::emit_ack(&mut w, *from, *class, *count),
            Msg::Collect => {}
            Msg::Token { cluster } => control::emit_token(&mut w, *cluster),
            Msg::Pixels(p) => p.emit(&mut w),
            Msg::Stats(s) => stats::emit(s, &mut w),
            Msg::Planes(p) => p.emit(&mut w),
        }
        w.len()
    }

    /// Decode one message: its tag and length here, its fields by its kind's own parser.
    pub fn decode(bytes: &[u8]) -> Result<Msg, DecodeError> {
        let tag = *bytes.first().ok_or(DecodeError::Empty)?;
        let kind = MsgKind::from_tag(tag).ok_or(DecodeError::UnknownKind(tag))?;
        if bytes.len() != kind.encoded_len() {
            return Err(DecodeError::Length {
                kind,
                expected: kind.encoded_len(),
                actual: bytes.len(),
            });
        }
        let mut r = Reader::new(bytes, kind);
        Ok(match kind {
            MsgKind::Ray => Msg::Ray(Travel::parse(&mut r)?),
            MsgKind::Hit => Msg::Hit(HitRecord::parse(&mut r)?),
            MsgKind::Resolved => Msg::Resolved(Resolved::parse(&mut r)?),
            MsgKind::Ack => {
                let (from, class, count) = control::parse_ack(&mut r)?;
                Msg::Ack { from, class, count }
            }
            MsgKind::Collect => Msg::Collect,
            MsgKind::Token => Msg::Token {
                cluster: control::parse_token(&mut r)?,
            },
            MsgKind::Pixels => Msg::Pixels(PixelSet::parse(&mut r)?),
            MsgKind::Stats => Msg::Stats(stats::parse(&mut r)?),
            MsgKind::Planes => Msg::Planes(PlaneChunk::parse(&mut r)?),
        })
    }
}

#[cfg(test)]
mod fixtures;

#[cfg(test)]
mod tests {
    use super::fixtures::*;
    use super::*;
    use crate::counters::Counters;
    use glam::Vec3;

    /// One message of every kind (and every outcome), as encoded.
    fn every_kind() -> [Msg; 11] {
        [
            ray(),
            hit(),
            resolved(Outcome::ChainEnd { hits: 4 }),
            resolved(Outcome::Shadow { visibility: 0.5 }),
            resolved(Outcome::Color(Vec3::new(0.25, 0.5, 2.0))),
            ACK,
            Msg::Collect,
            Msg::Token { cluster: 1 },
            pixels(),
            Msg::Stats(NodeStats {
                node: 2,
                counters: Counters {
                    samples: 11,
                    slab_misses: 13,
                    ..Counters::default()
                },
                forwarded_next: 9,
                sent: [1; KINDS],
                peak_unacked: 3,
                pixels_sent: 5,
                ..NodeStats::default()
            }),
            planes(),
        ]
    }

    /// The wire format itself: each message's bytes, hashed (FNV-1a, 64 bits), pinned as they
    /// were written before the codec was split by message; a change to any field's order,
    /// width or byte order fails here by kind.
    #[test]
    fn every_kind_encodes_to_the_pinned_bytes() {
        let fnv = |bytes: &[u8]| {
            bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| {
                (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
            })
        };
        let hashes = every_kind().map(|m| {
            let mut buf = [0u8; MAX_MSG_LEN];
            let n = m.encode(&mut buf);
            (m.kind(), fnv(&buf[..n]))
        });
        assert_eq!(hashes, PINNED);
    }

    const PINNED: [(MsgKind, u64); 11] = [
        (MsgKind::Ray, 0x65759077d5858f34),
        (MsgKind::Hit, 0xeed4184d85593334),
        (MsgKind::Resolved, 0x736a6c04a6c87b82),
        (MsgKind::Resolved, 0x6336d3bebad03624),
        (MsgKind::Resolved, 0xafd259f94690fb43),
        (MsgKind::Ack, 0xd5eac3d70302a9fe),
        (MsgKind::Collect, 0xaf63c54c8601c577),
        (MsgKind::Token, 0xb6a3c018586c51e2),
        (MsgKind::Pixels, 0x8aee05cc25d1ca32),
        (MsgKind::Stats, 0x5610d0dac45be93b),
        (MsgKind::Planes, 0x016d19aba1642930),
    ];

    #[test]
    fn malformed_bytes_are_errors() {
        assert_eq!(Msg::decode(&[]), Err(DecodeError::Empty));
        assert_eq!(Msg::decode(&[99]), Err(DecodeError::UnknownKind(99)));
        assert!(matches!(
            Msg::decode(&[4, 0]),
            Err(DecodeError::Length { .. })
        ));
        let mut bad = [0u8; MsgKind::Pixels.encoded_len()];
        bad[0] = MsgKind::Pixels as u8;
        bad[1] = 33;
        assert_eq!(
            Msg::decode(&bad),
            Err(DecodeError::Field {
                kind: MsgKind::Pixels,
                field: "count"
            })
        );
    }
}
