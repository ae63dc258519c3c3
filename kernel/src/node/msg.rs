//! Messages between nodes and the host, and their fixed-size little-endian encoding.
//!
//! Each kind has one encoded length ([`MsgKind::encoded_len`]), at most [`MAX_MSG_LEN`]
//! bytes: a tag byte, then the fields in order. Decoding any byte string returns a message or
//! a [`DecodeError`], never panics: lengths, tags and enumerations are checked, counts are
//! bounded, and float fields may hold any bits (the tracer is robust to NaN).
//!
//! Invariant: `decode(encode(m)) == m` for every message, and every encoding is exactly its
//! kind's length.

use crate::counters::Counters;
use crate::node::flow::Class;
use crate::node::kind::COUNTER_FIELDS;
pub use crate::node::kind::{MsgKind, KINDS, MAX_MSG_LEN, PIXELS_PER_SET, PLANE_CHUNK};
use crate::node::stats::NodeStats;
use crate::optics::shade::MAX_LIGHTS;
use crate::trace::lattice::{Lattice, MAX_SAMPLES};
use crate::trace::ray::{Entry, Ray};
use crate::trace::state::{RayKind, RayState};
use core::fmt;
use glam::Vec3;

/// `Reply::light` of a ray that is not a shadow ray.
pub const NO_LIGHT: u8 = u8::MAX;
/// `Reply::home` of a primary ray not yet adopted by a node (centralized generation).
pub const NO_HOME: u16 = u16::MAX;

/// Where a ray's result goes: the pixel record `slot` on node `home`, part `hit` (and `light`
/// for a shadow ray).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Reply {
    /// The node holding the pixel record.
    pub home: u16,
    /// The record's slot there.
    pub slot: u16,
    /// For primary and transparency rays the index of the next hit; for shadow rays the hit
    /// they light.
    pub hit: u8,
    /// For shadow rays the light; otherwise [`NO_LIGHT`].
    pub light: u8,
}

/// A ray in flight between nodes, with all its state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Travel {
    /// The ray.
    pub ray: RayState,
    /// Where its result goes.
    pub reply: Reply,
}

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

/// A run of sample bytes of one X plane (load balancing moves planes between neighbours).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PlaneChunk {
    /// The plane.
    pub plane: u32,
    /// Byte offset of this chunk in the plane.
    pub offset: u32,
    /// Bytes used in `bytes`.
    pub len: u16,
    /// Sample bytes.
    pub bytes: [u8; PLANE_CHUNK],
}

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

/// Why bytes are not a message.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DecodeError {
    /// No bytes.
    Empty,
    /// The tag names no kind.
    UnknownKind(u8),
    /// The length is not the kind's.
    Length {
        /// The kind.
        kind: MsgKind,
        /// Its length.
        expected: usize,
        /// Bytes given.
        actual: usize,
    },
    /// A field holds a value outside its range.
    Field {
        /// The kind.
        kind: MsgKind,
        /// The field.
        field: &'static str,
    },
}

impl fmt::Display for DecodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            DecodeError::Empty => write!(f, "empty message"),
            DecodeError::UnknownKind(t) => write!(f, "unknown message kind {t}"),
            DecodeError::Length {
                kind,
                expected,
                actual,
            } => {
                write!(f, "{kind:?} message of {actual} bytes; it has {expected}")
            }
            DecodeError::Field { kind, field } => {
                write!(f, "{kind:?} message: field {field} out of range")
            }
        }
    }
}

impl core::error::Error for DecodeError {}

struct Writer<'a> {
    buf: &'a mut [u8; MAX_MSG_LEN],
    at: usize,
}

impl Writer<'_> {
    fn bytes(&mut self, b: &[u8]) {
        // Lengths are constants within MAX_MSG_LEN; `get_mut` keeps even a mistake panic-free.
        if let Some(dst) = self.buf.get_mut(self.at..self.at + b.len()) {
            dst.copy_from_slice(b);
        }
        self.at += b.len();
    }
    fn u8(&mut self, v: u8) {
        self.bytes(&[v]);
    }
    fn u16(&mut self, v: u16) {
        self.bytes(&v.to_le_bytes());
    }
    fn u32(&mut self, v: u32) {
        self.bytes(&v.to_le_bytes());
    }
    fn u64(&mut self, v: u64) {
        self.bytes(&v.to_le_bytes());
    }
    fn f32(&mut self, v: f32) {
        self.bytes(&v.to_le_bytes());
    }
    fn vec3(&mut self, v: Vec3) {
        self.f32(v.x);
        self.f32(v.y);
        self.f32(v.z);
    }
    fn reply(&mut self, r: &Reply) {
        self.u16(r.home);
        self.u16(r.slot);
        self.u8(r.hit);
        self.u8(r.light);
    }
}

struct Reader<'a> {
    buf: &'a [u8],
    at: usize,
    kind: MsgKind,
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> Result<[u8; N], DecodeError> {
        let slice = self
            .buf
            .get(self.at..self.at + N)
            .ok_or(DecodeError::Field {
                kind: self.kind,
                field: "length",
            })?;
        self.at += N;
        let mut out = [0u8; N];
        out.copy_from_slice(slice);
        Ok(out)
    }
    fn u8(&mut self) -> Result<u8, DecodeError> {
        Ok(self.take::<1>()?[0])
    }
    fn u16(&mut self) -> Result<u16, DecodeError> {
        Ok(u16::from_le_bytes(self.take()?))
    }
    fn u32(&mut self) -> Result<u32, DecodeError> {
        Ok(u32::from_le_bytes(self.take()?))
    }
    fn u64(&mut self) -> Result<u64, DecodeError> {
        Ok(u64::from_le_bytes(self.take()?))
    }
    fn f32(&mut self) -> Result<f32, DecodeError> {
        Ok(f32::from_le_bytes(self.take()?))
    }
    fn vec3(&mut self) -> Result<Vec3, DecodeError> {
        Ok(Vec3::new(self.f32()?, self.f32()?, self.f32()?))
    }
    fn bool(&mut self, field: &'static str) -> Result<bool, DecodeError> {
        match self.u8()? {
            0 => Ok(false),
            1 => Ok(true),
            _ => Err(self.bad(field)),
        }
    }
    fn reply(&mut self) -> Result<Reply, DecodeError> {
        Ok(Reply {
            home: self.u16()?,
            slot: self.u16()?,
            hit: self.u8()?,
            light: self.u8()?,
        })
    }
    fn bad(&self, field: &'static str) -> DecodeError {
        DecodeError::Field {
            kind: self.kind,
            field,
        }
    }
}

fn entry_code(e: Entry) -> u8 {
    match e {
        Entry::Face { axis, high } => (axis % 3) * 2 + u8::from(high),
        Entry::Inside => 6,
    }
}

fn counters_fields(c: &Counters) -> [u64; COUNTER_FIELDS] {
    c.fields()
}

fn counters_from(f: [u64; COUNTER_FIELDS]) -> Counters {
    let mut c = Counters::default();
    for (slot, v) in c.fields_mut().into_iter().zip(f) {
        *slot = v;
    }
    c
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
        let mut w = Writer { buf, at: 0 };
        w.u8(self.kind() as u8);
        match self {
            Msg::Ray(t) => {
                let r = &t.ray;
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
                w.reply(&t.reply);
            }
            Msg::Hit(h) => {
                w.reply(&h.reply);
                w.u32(h.pixel);
                w.f32(h.alpha);
                w.vec3(h.ambient);
                for d in h.direct {
                    w.vec3(d);
                }
                w.u8(h.shadow_mask);
                w.u8(h.lights);
                w.u8(u8::from(h.continues));
            }
            Msg::Resolved(r) => {
                w.reply(&r.reply);
                w.u32(r.pixel);
                match r.outcome {
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
            Msg::Ack { from, class, count } => {
                w.u16(*from);
                w.u8(*class);
                w.u16(*count);
            }
            Msg::Collect => {}
            Msg::Token { cluster } => w.u16(*cluster),
            Msg::Pixels(p) => {
                w.u8(p.count);
                for (pixel, rgba) in p.pixels {
                    w.u32(pixel);
                    w.bytes(&rgba);
                }
            }
            Msg::Stats(s) => {
                w.u16(s.node);
                for v in counters_fields(&s.counters) {
                    w.u64(v);
                }
                for v in [
                    s.forwarded_next,
                    s.forwarded_prev,
                    s.forwarded_far,
                    s.returned,
                ] {
                    w.u64(v);
                }
                for v in s.sent {
                    w.u64(v);
                }
                w.u64(s.protocol_errors);
                for v in [
                    s.peak_pending,
                    s.peak_records,
                    s.peak_outbox,
                    s.peak_unacked,
                    s.pixels_sent,
                ] {
                    w.u64(v);
                }
            }
            Msg::Planes(p) => {
                w.u32(p.plane);
                w.u32(p.offset);
                w.u16(p.len);
                w.bytes(&p.bytes);
            }
        }
        w.at
    }

    /// Decode one message.
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
        let mut r = Reader {
            buf: bytes,
            at: 1,
            kind,
        };
        Ok(match kind {
            MsgKind::Ray => {
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
                Msg::Ray(Travel { ray, reply })
            }
            MsgKind::Hit => {
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
                Msg::Hit(HitRecord {
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
            MsgKind::Resolved => {
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
                Msg::Resolved(Resolved {
                    reply,
                    pixel,
                    outcome,
                })
            }
            MsgKind::Ack => {
                let from = r.u16()?;
                let class = r.u8()?;
                if Class::from_credit_index(class).is_none() {
                    return Err(r.bad("class"));
                }
                Msg::Ack {
                    from,
                    class,
                    count: r.u16()?,
                }
            }
            MsgKind::Collect => Msg::Collect,
            MsgKind::Token => Msg::Token { cluster: r.u16()? },
            MsgKind::Pixels => {
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
                Msg::Pixels(set)
            }
            MsgKind::Stats => {
                let node = r.u16()?;
                let mut f = [0u64; COUNTER_FIELDS];
                for v in &mut f {
                    *v = r.u64()?;
                }
                let (forwarded_next, forwarded_prev, forwarded_far, returned) =
                    (r.u64()?, r.u64()?, r.u64()?, r.u64()?);
                let mut sent = [0u64; KINDS];
                for v in &mut sent {
                    *v = r.u64()?;
                }
                let protocol_errors = r.u64()?;
                let (peak_pending, peak_records, peak_outbox, peak_unacked, pixels_sent) =
                    (r.u64()?, r.u64()?, r.u64()?, r.u64()?, r.u64()?);
                Msg::Stats(NodeStats {
                    node,
                    counters: counters_from(f),
                    forwarded_next,
                    forwarded_prev,
                    forwarded_far,
                    returned,
                    sent,
                    protocol_errors,
                    peak_pending,
                    peak_records,
                    peak_outbox,
                    peak_unacked,
                    pixels_sent,
                })
            }
            MsgKind::Planes => {
                let plane = r.u32()?;
                let offset = r.u32()?;
                let len = r.u16()?;
                if usize::from(len) > PLANE_CHUNK {
                    return Err(r.bad("len"));
                }
                Msg::Planes(PlaneChunk {
                    plane,
                    offset,
                    len,
                    bytes: r.take()?,
                })
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn roundtrip(m: Msg) {
        let mut buf = [0u8; MAX_MSG_LEN];
        let n = m.encode(&mut buf);
        assert_eq!(n, m.kind().encoded_len());
        assert_eq!(Msg::decode(&buf[..n]), Ok(m));
        assert!(Msg::decode(&buf[..n - 1]).is_err());
    }

    fn reply() -> Reply {
        Reply {
            home: 3,
            slot: 9,
            hit: 1,
            light: 2,
        }
    }

    fn ray() -> Msg {
        let ray = RayState {
            kind: RayKind::Shadow,
            pixel: 7,
            ray: Ray {
                origin: Vec3::ONE,
                dir: Vec3::X,
                dir_world: Vec3::Y,
            },
            lattice: Lattice {
                t_entry: 1.0,
                t_exit: 9.0,
                dt: 0.5,
                last: 16,
            },
            entry: Entry::Face {
                axis: 2,
                high: true,
            },
            k: 3,
            prev: 4.5,
            primed: true,
            prev_stale: true,
            done_here: 5,
            depth: 2,
            weight: 0.25,
            color: Vec3::new(0.1, 0.2, 0.3),
        };
        Msg::Ray(Travel {
            ray,
            reply: reply(),
        })
    }

    fn hit() -> Msg {
        Msg::Hit(HitRecord {
            reply: reply(),
            pixel: 1,
            alpha: 0.5,
            ambient: Vec3::ONE,
            direct: [Vec3::X; MAX_LIGHTS],
            shadow_mask: 3,
            lights: 2,
            continues: true,
        })
    }

    fn resolved(outcome: Outcome) -> Msg {
        Msg::Resolved(Resolved {
            reply: reply(),
            pixel: 2,
            outcome,
        })
    }

    fn pixels() -> Msg {
        let mut set = PixelSet::default();
        set.push(5, [1, 2, 3, 4]).unwrap();
        Msg::Pixels(set)
    }

    fn planes() -> Msg {
        Msg::Planes(PlaneChunk {
            plane: 3,
            offset: 256,
            len: 10,
            bytes: [7; PLANE_CHUNK],
        })
    }

    const ACK: Msg = Msg::Ack {
        from: 4,
        class: 2,
        count: 2,
    };

    #[test]
    fn every_kind_round_trips() {
        roundtrip(ray());
        roundtrip(hit());
        for outcome in [
            Outcome::ChainEnd { hits: 4 },
            Outcome::Shadow { visibility: 0.5 },
            Outcome::Color(Vec3::ONE),
        ] {
            roundtrip(resolved(outcome));
        }
        roundtrip(ACK);
        roundtrip(Msg::Collect);
        roundtrip(Msg::Token { cluster: 1 });
        roundtrip(pixels());
        roundtrip(Msg::Stats(NodeStats {
            node: 2,
            forwarded_next: 9,
            sent: [1; KINDS],
            peak_unacked: 3,
            ..NodeStats::default()
        }));
        roundtrip(planes());
    }

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

    /// Every range check of decoding, each shown by one out-of-range byte in an otherwise
    /// valid message: with a check dropped, its case decodes and this test fails.
    #[test]
    fn every_range_check_refuses_its_field_by_name() {
        // (message, byte offset of the field, tag included, out-of-range byte, field)
        let cases: [(Msg, usize, u8, &str); 11] = [
            (ray(), 1, 3, "kind"),
            // `last`, little-endian at 54..58: its top byte makes it exceed MAX_SAMPLES.
            (ray(), 57, 0xff, "last"),
            (ray(), 58, 7, "entry"),
            (ray(), 67, 4, "flags"),
            (hit(), 75, 1 << MAX_LIGHTS, "lights"),
            (hit(), 76, MAX_LIGHTS as u8 + 1, "lights"),
            (hit(), 77, 2, "continues"),
            (resolved(Outcome::Color(Vec3::ONE)), 11, 3, "outcome"),
            (ACK, 3, crate::node::flow::CREDITS as u8, "class"),
            (pixels(), 1, PIXELS_PER_SET as u8 + 1, "count"),
            // `len`, little-endian at 9..11: its top byte makes it exceed PLANE_CHUNK.
            (planes(), 10, 1, "len"),
        ];
        for (m, at, byte, field) in cases {
            let mut buf = [0u8; MAX_MSG_LEN];
            let n = m.encode(&mut buf);
            assert_eq!(Msg::decode(&buf[..n]), Ok(m), "{field}: the valid message");
            buf[at] = byte;
            assert_eq!(
                Msg::decode(&buf[..n]),
                Err(DecodeError::Field {
                    kind: m.kind(),
                    field
                }),
                "{field}: byte {at} set to {byte}"
            );
        }
    }

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
