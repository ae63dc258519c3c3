//! Messages of every kind with every field set, for the codecs' tests, and the two checks
//! each codec's tests make: a message round-trips at its kind's length, and one out-of-range
//! byte is refused naming its field.

use super::*;
use crate::optics::shade::MAX_LIGHTS;
use crate::trace::lattice::Lattice;
use crate::trace::ray::{Entry, Ray};
use crate::trace::state::{RayKind, RayState};
use glam::Vec3;

pub(crate) fn roundtrip(m: Msg) {
    let mut buf = [0u8; MAX_MSG_LEN];
    let n = m.encode(&mut buf);
    assert_eq!(n, m.kind().encoded_len());
    assert_eq!(Msg::decode(&buf[..n]), Ok(m));
    assert!(Msg::decode(&buf[..n - 1]).is_err());
}

pub(crate) fn reply() -> Reply {
    Reply {
        home: 3,
        slot: 9,
        hit: 1,
        light: 2,
    }
}

pub(crate) fn ray() -> Msg {
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

pub(crate) fn hit() -> Msg {
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

pub(crate) fn resolved(outcome: Outcome) -> Msg {
    Msg::Resolved(Resolved {
        reply: reply(),
        pixel: 2,
        outcome,
    })
}

pub(crate) fn pixels() -> Msg {
    let mut set = PixelSet::default();
    set.push(5, [1, 2, 3, 4]).unwrap();
    Msg::Pixels(set)
}

pub(crate) fn planes() -> Msg {
    Msg::Planes(PlaneChunk {
        plane: 3,
        offset: 256,
        len: 10,
        bytes: [7; PLANE_CHUNK],
    })
}

pub(crate) const ACK: Msg = Msg::Ack {
    from: 4,
    class: 2,
    count: 2,
};

/// `m`, valid, with byte `at` (tag included) set to `byte`, is refused naming `field`: with
/// the check dropped, the case decodes and the caller's test fails.
pub(crate) fn refuses(m: Msg, at: usize, byte: u8, field: &'static str) {
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
