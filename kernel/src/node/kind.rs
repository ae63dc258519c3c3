//! The kinds of message and their fixed lengths on the wire: what flow control sizes buffers
//! by and what statistics count traffic by, without the messages themselves.
//!
//! Invariant: every kind has one encoded length, tag included, at most [`MAX_MSG_LEN`].

use crate::counters::Counters;
use crate::optics::shade::MAX_LIGHTS;

/// Pixels one pixel-set message carries.
pub const PIXELS_PER_SET: usize = 32;
/// Sample bytes one slab-planes message carries.
pub const PLANE_CHUNK: usize = 256;

/// The kinds of message.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MsgKind {
    /// [`Msg::Ray`](crate::node::msg::Msg::Ray).
    Ray = 0,
    /// [`Msg::Hit`](crate::node::msg::Msg::Hit).
    Hit = 1,
    /// [`Msg::Resolved`](crate::node::msg::Msg::Resolved).
    Resolved = 2,
    /// [`Msg::Ack`](crate::node::msg::Msg::Ack).
    Ack = 3,
    /// [`Msg::Token`](crate::node::msg::Msg::Token).
    Token = 4,
    /// [`Msg::Pixels`](crate::node::msg::Msg::Pixels).
    Pixels = 5,
    /// [`Msg::Stats`](crate::node::msg::Msg::Stats).
    Stats = 6,
    /// [`Msg::Planes`](crate::node::msg::Msg::Planes).
    Planes = 7,
    /// [`Msg::Collect`](crate::node::msg::Msg::Collect).
    Collect = 8,
}

const RAY_LEN: usize = 1 + 4 + 36 + 16 + 1 + 4 + 4 + 1 + 2 + 1 + 4 + 12 + 6;
const HIT_LEN: usize = 6 + 4 + 4 + 12 + 12 * MAX_LIGHTS + 1 + 1 + 1;
const RESOLVED_LEN: usize = 6 + 4 + 1 + 12;
const PIXELS_LEN: usize = 1 + 8 * PIXELS_PER_SET;
const STATS_LEN: usize = 2 + 8 * Counters::COUNT + 8 * 4 + 8 * KINDS + 8 + 8 * 5;
/// Number of message kinds.
pub const KINDS: usize = 9;
const PLANES_LEN: usize = 4 + 4 + 2 + PLANE_CHUNK;

/// The longest encoded message.
pub const MAX_MSG_LEN: usize = 1 + max(
    max(max(RAY_LEN, HIT_LEN), max(PIXELS_LEN, STATS_LEN)),
    PLANES_LEN,
);

const fn max(a: usize, b: usize) -> usize {
    if a > b {
        a
    } else {
        b
    }
}

impl MsgKind {
    /// Bytes a message of this kind encodes to, tag included.
    pub const fn encoded_len(self) -> usize {
        1 + match self {
            MsgKind::Ray => RAY_LEN,
            MsgKind::Hit => HIT_LEN,
            MsgKind::Resolved => RESOLVED_LEN,
            MsgKind::Ack => 5,
            MsgKind::Token => 2,
            MsgKind::Pixels => PIXELS_LEN,
            MsgKind::Stats => STATS_LEN,
            MsgKind::Planes => PLANES_LEN,
            MsgKind::Collect => 0,
        }
    }

    pub(crate) fn from_tag(tag: u8) -> Option<MsgKind> {
        Some(match tag {
            0 => MsgKind::Ray,
            1 => MsgKind::Hit,
            2 => MsgKind::Resolved,
            3 => MsgKind::Ack,
            4 => MsgKind::Token,
            5 => MsgKind::Pixels,
            6 => MsgKind::Stats,
            7 => MsgKind::Planes,
            8 => MsgKind::Collect,
            _ => return None,
        })
    }
}
