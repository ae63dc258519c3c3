//! Flow control: the classes messages travel in, the ack counters that bound every receive
//! buffer, and the arithmetic linking a buffer's bytes to `i_max`.
//!
//! Invariant: with flow control on, `n_i ≤ i_max` for every destination and class at all
//! times, so no receive buffer holds more than [`buffer_bytes`] and no send is refused.
//!
//! For each destination `i` and each credit class, a worker counts `n_i`: messages sent and
//! not yet acknowledged. It sends only while `n_i < i_max`, and starts a ray only if
//! `n_i + r_imax < i_max` for every `i` and class the ray may reach, so a started ray never
//! waits to send. A receiver acknowledges a message when it reads it. So no receive buffer
//! ever holds more than `i_max` messages per sender and class, and no send is ever refused.
//!
//! Why this cannot deadlock: messages are split into classes whose waits form no cycle.
//! - **Results** (hit records and resolved descriptors going home) are always read: reading
//!   one needs nothing but room to send pixels to the host, which always drains.
//! - **Shadow rays** travelling up (toward higher X) need credit only toward higher
//!   positions, or result credit. Shadow rays travelling down need credit only toward lower
//!   positions. Each chain ends at the last slab in its direction, where the ray must end.
//! - **Primary and transparency rays** travelling up (or down) need credit in their own
//!   class toward higher (lower) positions, result credit, and shadow credit. They also need
//!   room for a continuation in that direction's local queue, which drains along the same
//!   chain.
//!
//! Every wait points along a chain that ends, or to a class that is always read, so some
//! worker can always make progress. Each class has its own receive queue, so one class never
//! blocks another at the head of a queue. Acknowledgements need no credit: acks that needed
//! credit could wait on each other forever (a negative control shows it).

use crate::node::kind::MsgKind;
use crate::trace::state::RayKind;

/// Classes of received messages. The credit classes are also the reading queues. The order
/// is the worker's reading priority: acks, then results, then rays.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Class {
    /// Acknowledgements: always read, no credit.
    Ack,
    /// Hit records and resolved descriptors going home.
    Result,
    /// Shadow rays travelling toward higher X.
    ShadowUp,
    /// Shadow rays travelling toward lower X.
    ShadowDown,
    /// Primary and transparency rays travelling toward higher X.
    RayUp,
    /// Primary and transparency rays travelling toward lower X.
    RayDown,
    /// Tokens, the host's requests, slab planes: no credit.
    Control,
}

/// The classes that carry credit, in the index order of [`Class::credit_index`].
pub const CREDIT_CLASSES: [Class; 5] = [
    Class::Result,
    Class::ShadowUp,
    Class::ShadowDown,
    Class::RayUp,
    Class::RayDown,
];

/// Number of credit classes.
pub const CREDITS: usize = CREDIT_CLASSES.len();

/// Every class, in reading priority.
pub const CLASSES: [Class; 7] = [
    Class::Ack,
    Class::Result,
    Class::ShadowUp,
    Class::ShadowDown,
    Class::RayUp,
    Class::RayDown,
    Class::Control,
];

impl Class {
    /// Index among [`CREDIT_CLASSES`], or `None` for classes without credit.
    pub const fn credit_index(self) -> Option<usize> {
        match self {
            Class::Result => Some(0),
            Class::ShadowUp => Some(1),
            Class::ShadowDown => Some(2),
            Class::RayUp => Some(3),
            Class::RayDown => Some(4),
            Class::Ack | Class::Control => None,
        }
    }

    /// The credit class at `index`.
    pub fn from_credit_index(index: u8) -> Option<Class> {
        CREDIT_CLASSES.get(usize::from(index)).copied()
    }

    /// Index among [`CLASSES`].
    pub const fn index(self) -> usize {
        self as usize
    }

    /// The class of a ray of `kind` whose X direction is `dx`. Rays with `dx = 0` never leave
    /// their slab except for the first hop of centralized generation, which is a leaf of the
    /// wait graph either way.
    pub fn of_ray(kind: RayKind, dx: f32) -> Class {
        let up = !(dx < 0.0);
        match (kind, up) {
            (RayKind::Shadow, true) => Class::ShadowUp,
            (RayKind::Shadow, false) => Class::ShadowDown,
            (_, true) => Class::RayUp,
            (_, false) => Class::RayDown,
        }
    }

    /// Whether messages of this class travel toward higher ring positions (`None`: either).
    pub fn upward(self) -> Option<bool> {
        match self {
            Class::ShadowUp | Class::RayUp => Some(true),
            Class::ShadowDown | Class::RayDown => Some(false),
            _ => None,
        }
    }

    /// The longest message of this class.
    pub const fn max_len(self) -> usize {
        match self {
            Class::Ack => MsgKind::Ack.encoded_len(),
            Class::Result => max(MsgKind::Hit.encoded_len(), MsgKind::Resolved.encoded_len()),
            Class::ShadowUp | Class::ShadowDown | Class::RayUp | Class::RayDown => {
                MsgKind::Ray.encoded_len()
            }
            Class::Control => MsgKind::Collect.encoded_len(),
        }
    }
}

const fn max(a: usize, b: usize) -> usize {
    if a > b {
        a
    } else {
        b
    }
}

/// Room kept in a receive buffer for control messages: a token and the host's request.
pub const CONTROL_RESERVE: usize = MsgKind::Token.encoded_len() + MsgKind::Collect.encoded_len();

/// Receive-buffer bytes a node of a ring of `cluster_size` needs so that `i_max` messages per
/// sender and class always fit. A sender below sends only up-travelling rays and results, a
/// sender above only down-travelling rays and results: three classes per sender, each with
/// its acknowledgements.
pub const fn buffer_bytes(cluster_size: usize, i_max: usize) -> usize {
    let per_sender = i_max
        * (Class::Result.max_len()
            + Class::ShadowUp.max_len()
            + Class::RayUp.max_len()
            + 3 * Class::Ack.max_len());
    cluster_size.saturating_sub(1) * per_sender + CONTROL_RESERVE
}

/// The largest `i_max` a receive buffer of `bytes` allows in a ring of `cluster_size`.
pub const fn i_max_for(bytes: usize, cluster_size: usize) -> usize {
    let per_sender = Class::Result.max_len()
        + Class::ShadowUp.max_len()
        + Class::RayUp.max_len()
        + 3 * Class::Ack.max_len();
    let senders = if cluster_size > 1 {
        cluster_size - 1
    } else {
        1
    };
    if bytes < CONTROL_RESERVE {
        return 0;
    }
    (bytes - CONTROL_RESERVE) / (senders * per_sender)
}

/// `r_imax`: the most messages of one class toward one destination that tracing one ray of
/// `kind` on one node can send, with `shadow_lights` shadow-casting lights. A primary or
/// transparency ray sends one ray message, or a hit record plus one result per shadow ray
/// ending here, or up to one shadow ray per light; a shadow ray sends one message.
pub const fn r_imax(kind: RayKind, shadow_lights: u8) -> usize {
    match kind {
        RayKind::Shadow => 1,
        RayKind::Primary | RayKind::Transparency => 1 + shadow_lights as usize,
    }
}

/// Whether the nodes ahead of ring position `me` have room for what a step of a ray of `kind`
/// may send them: `unacked[p][c]` is what this node has sent to position `p` in credit class
/// `c` and not yet had acknowledged (one row per position of the ring). The ray itself goes
/// ahead in its own class `own`, toward every position that way; a ray that may cast shadows
/// sends up to `shadow_lights` shadow rays, which go either way. Results go home, which the
/// caller checks. Each class needs its room below `i_max`, so that `n_i` never reaches it.
pub fn room_ahead(
    unacked: &[[u16; CREDITS]],
    me: usize,
    kind: RayKind,
    own: Class,
    shadow_lights: u8,
    i_max: u16,
) -> bool {
    // Only the classes this step can send are looked at: one, or three for a ray casting
    // shadows; a pass over every class and position was most of a ring's start checks.
    let full = |class: Class, need: u16| {
        let (Some(c), Some(up)) = (class.credit_index(), class.upward()) else {
            return false;
        };
        let ahead = if up {
            unacked.get(me + 1..)
        } else {
            unacked.get(..me)
        };
        ahead
            .unwrap_or_default()
            .iter()
            .any(|row| row.get(c).is_some_and(|&n| n.saturating_add(need) >= i_max))
    };
    if full(own, 1) {
        return false;
    }
    let shadows = u16::from(shadow_lights);
    kind == RayKind::Shadow
        || shadows == 0
        || !(full(Class::ShadowUp, shadows) || full(Class::ShadowDown, shadows))
}

/// Counters per ring position and credit class for a ring of at most `RING` positions: a
/// worker keeps one set for `n_i` (messages sent and not yet acknowledged) and one for the
/// reads it owes an acknowledgement.
///
/// Invariants: only the first [`Credits::size`] positions are counted, so a worker built for
/// a small ring holds counters for that ring only; a count saturates at `u16::MAX`, never
/// wraps; classes without credit ([`Class::Ack`], [`Class::Control`]) have no counter and
/// read as zero.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Credits<const RING: usize> {
    counts: [[u16; CREDITS]; RING],
    size: usize,
}

impl<const RING: usize> Credits<RING> {
    /// Zero counters for a ring of `size` positions, or `None` when `size` exceeds `RING`.
    pub const fn new(size: usize) -> Option<Credits<RING>> {
        if size > RING {
            return None;
        }
        Some(Credits {
            counts: [[0; CREDITS]; RING],
            size,
        })
    }

    /// Zero counters for the first `size` positions, at most `RING` of them: for a caller
    /// that has checked the ring against `RING` already ([`Credits::new`] checks).
    pub const fn clamped(size: usize) -> Credits<RING> {
        Credits {
            counts: [[0; CREDITS]; RING],
            size: if size < RING { size } else { RING },
        }
    }

    /// Positions counted: the ring's size.
    pub fn size(&self) -> usize {
        self.size
    }

    /// The count toward ring position `position` in `class` (zero where there is none).
    #[inline]
    pub fn get(&self, position: usize, class: Class) -> u16 {
        self.slot(position, class).map_or(0, |n| *n)
    }

    fn slot(&self, position: usize, class: Class) -> Option<&u16> {
        let c = class.credit_index()?;
        self.counts[..self.size].get(position)?.get(c)
    }

    fn slot_mut(&mut self, position: usize, class: Class) -> Option<&mut u16> {
        let c = class.credit_index()?;
        self.counts[..self.size].get_mut(position)?.get_mut(c)
    }

    /// Add one toward `position` in `class`; the new count, or `None` where there is no
    /// counter (a class without credit, a position outside the ring).
    #[inline]
    pub fn add_one(&mut self, position: usize, class: Class) -> Option<u16> {
        let n = self.slot_mut(position, class)?;
        *n = n.saturating_add(1);
        Some(*n)
    }

    /// Take `count` off the count toward `position` in `class`. `false`, changing nothing,
    /// when it holds less (an acknowledgement of messages never sent: a protocol error).
    pub fn take(&mut self, position: usize, class: Class, count: u16) -> bool {
        match self.slot_mut(position, class) {
            Some(n) if *n >= count => {
                *n -= count;
                true
            }
            _ => false,
        }
    }

    /// Set the count toward `position` in `class` to zero and return what it was.
    pub fn clear(&mut self, position: usize, class: Class) -> u16 {
        self.slot_mut(position, class).map_or(0, core::mem::take)
    }

    /// Whether every count is zero.
    pub fn all_zero(&self) -> bool {
        self.counts[..self.size].iter().flatten().all(|&n| n == 0)
    }

    /// The largest count, over positions and classes.
    pub fn max(&self) -> u16 {
        self.counts[..self.size]
            .iter()
            .flatten()
            .copied()
            .max()
            .unwrap_or(0)
    }

    /// Whether any class toward `position` is one message short of `i_max`.
    pub fn any_full(&self, position: usize, i_max: u16) -> bool {
        self.counts[..self.size]
            .get(position)
            .is_some_and(|row| row.iter().any(|&n| n.saturating_add(1) >= i_max))
    }

    /// [`room_ahead`] over these counters, from ring position `me`.
    #[inline]
    pub fn room_ahead(
        &self,
        me: usize,
        kind: RayKind,
        own: Class,
        shadow_lights: u8,
        i_max: u16,
    ) -> bool {
        room_ahead(
            &self.counts[..self.size],
            me,
            kind,
            own,
            shadow_lights,
            i_max,
        )
    }
}

/// The smallest `i_max` with which any ray can start (`r_imax < i_max` from `n_i = 0`).
pub const fn min_i_max(shadow_lights: u8) -> usize {
    r_imax(RayKind::Primary, shadow_lights) + 1
}

/// Flow-control settings of a worker.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FlowControl {
    /// Whether credits limit sends (off only as a debug option, to show what it prevents).
    pub enabled: bool,
    /// Messages per destination and class that may be unacknowledged.
    pub i_max: u16,
    /// Acknowledge after this many reads from one sender in one class (and whenever idle).
    pub ack_batch: u16,
}

impl FlowControl {
    /// Flow control for a receive buffer of `bytes` in a ring of `cluster_size`.
    pub fn for_buffer(bytes: usize, cluster_size: usize) -> FlowControl {
        let i_max = i_max_for(bytes, cluster_size).min(usize::from(u16::MAX)) as u16;
        FlowControl {
            enabled: true,
            i_max,
            ack_batch: (i_max / 2).max(1),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buffer_arithmetic_round_trips() {
        for size in [2usize, 3, 16, 128] {
            for i_max in [2usize, 5, 40] {
                let bytes = buffer_bytes(size, i_max);
                assert_eq!(i_max_for(bytes, size), i_max);
                assert_eq!(i_max_for(bytes - 1, size), i_max - 1);
            }
        }
        assert_eq!(i_max_for(0, 4), 0);
    }

    /// What [`room_ahead`] decides, class by class over every credit class: the check as the
    /// worker first wrote it.
    fn room_ahead_by_every_class(
        unacked: &[[u16; CREDITS]],
        me: usize,
        kind: RayKind,
        own: Class,
        shadow_lights: u8,
        i_max: u16,
    ) -> bool {
        for (c, class) in CREDIT_CLASSES.iter().enumerate().skip(1) {
            let need = match (kind, *class) {
                (_, cl) if cl == own => 1,
                (RayKind::Shadow, _) => continue,
                (_, Class::ShadowUp | Class::ShadowDown) if shadow_lights > 0 => {
                    u16::from(shadow_lights)
                }
                _ => continue,
            };
            let ahead = match class.upward() {
                Some(true) => me + 1..unacked.len(),
                _ => 0..me,
            };
            if ahead
                .clone()
                .any(|i| unacked[i][c].saturating_add(need) >= i_max)
            {
                return false;
            }
        }
        true
    }

    #[test]
    fn room_ahead_looks_at_what_a_step_sends_and_decides_as_every_class_does() {
        let mut next = crate::testing::xorshift(0x5eed_f10e);
        let (mut refused, mut allowed) = (0, 0);
        for _ in 0..20_000 {
            let size = 1 + next() as usize % 6;
            let me = next() as usize % size;
            let i_max = 2 + (next() % 6) as u16;
            let shadow_lights = (next() % 4) as u8;
            let kind =
                [RayKind::Primary, RayKind::Transparency, RayKind::Shadow][next() as usize % 3];
            let own = Class::of_ray(kind, if next() % 2 == 0 { 0.5 } else { -0.5 });
            // Mostly empty rows, so that a single full class decides.
            let mut unacked = [[0u16; CREDITS]; 6];
            for n in unacked.iter_mut().flatten() {
                if next() % 8 == 0 {
                    *n = (next() % u32::from(i_max + 1)) as u16;
                }
            }
            let table = &unacked[..size];
            let expected = room_ahead_by_every_class(table, me, kind, own, shadow_lights, i_max);
            assert_eq!(
                room_ahead(table, me, kind, own, shadow_lights, i_max),
                expected,
                "{kind:?} {own:?} at {me} of {size}, {shadow_lights} lights, i_max {i_max}: {table:?}"
            );
            if expected {
                allowed += 1;
            } else {
                refused += 1;
            }
        }
        assert!(
            refused > 2_000 && allowed > 2_000,
            "{refused} refused, {allowed} allowed"
        );
    }

    /// The start rule on cases worked by hand, each at its boundary: a ring of three, this
    /// node in the middle (position 1), `i_max` 4.
    #[test]
    fn room_ahead_at_the_boundary_of_each_rule_worked_by_hand() {
        let index = |c: Class| c.credit_index().unwrap_or(usize::MAX);
        let with = |entries: &[(usize, Class, u16)]| {
            let mut table = [[0u16; CREDITS]; 3];
            for &(position, class, n) in entries {
                table[position][index(class)] = n;
            }
            table
        };
        let up = |table: &[[u16; CREDITS]; 3], kind: RayKind, lights: u8| {
            room_ahead(table, 1, kind, Class::of_ray(kind, 1.0), lights, 4)
        };
        let primary = RayKind::Primary;
        // A ray going up needs one more of its class toward position 2: 2 + 1 < 4 starts,
        // 3 + 1 does not.
        assert!(up(&with(&[(2, Class::RayUp, 2)]), primary, 0));
        assert!(!up(&with(&[(2, Class::RayUp, 3)]), primary, 0));
        // Behind it, or in the other direction's class, nothing counts.
        assert!(up(&with(&[(0, Class::RayUp, 4)]), primary, 0));
        assert!(up(&with(&[(2, Class::RayDown, 4)]), primary, 0));
        // With two shadow-casting lights its shadow rays may go either way, two of a class:
        // 1 + 2 < 4 toward position 0 starts, 2 + 2 does not; without lights it does not count.
        assert!(up(&with(&[(0, Class::ShadowDown, 1)]), primary, 2));
        assert!(!up(&with(&[(0, Class::ShadowDown, 2)]), primary, 2));
        assert!(up(&with(&[(0, Class::ShadowDown, 2)]), primary, 0));
        assert!(!up(
            &with(&[(2, Class::ShadowUp, 2)]),
            RayKind::Transparency,
            2
        ));
        // A shadow ray sends one message of its own class and casts none.
        assert!(up(&with(&[(2, Class::ShadowUp, 2)]), RayKind::Shadow, 2));
        assert!(!up(&with(&[(2, Class::ShadowUp, 3)]), RayKind::Shadow, 2));
        assert!(up(&with(&[(0, Class::ShadowDown, 3)]), RayKind::Shadow, 2));
        // At the top of the ring nothing is ahead: any table starts an up ray.
        let full = [[4u16; CREDITS]; 3];
        assert!(room_ahead(&full, 2, primary, Class::RayUp, 0, 4));
        assert!(
            !room_ahead(&full, 2, primary, Class::RayUp, 1, 4),
            "shadows go down"
        );
    }

    #[test]
    fn credits_count_the_ring_only_and_name_their_classes() {
        assert!(Credits::<4>::new(5).is_none());
        let mut c = Credits::<4>::new(2).expect("a ring of two fits four positions");
        assert_eq!(c.add_one(1, Class::RayUp), Some(1));
        assert_eq!(c.add_one(1, Class::RayUp), Some(2));
        assert_eq!(
            c.add_one(2, Class::RayUp),
            None,
            "position 2 is outside a ring of two"
        );
        assert_eq!(c.add_one(0, Class::Ack), None, "acks carry no credit");
        assert_eq!(c.get(1, Class::RayUp), 2);
        assert_eq!(c.get(1, Class::RayDown), 0);
        assert_eq!(c.max(), 2);
        assert!(c.any_full(1, 3) && !c.any_full(0, 3));
        assert!(!c.take(1, Class::RayUp, 3), "more than was sent is refused");
        assert_eq!(c.get(1, Class::RayUp), 2, "and changes nothing");
        assert!(c.take(1, Class::RayUp, 2));
        assert!(c.all_zero());
        c.add_one(0, Class::Result);
        assert_eq!(c.clear(0, Class::Result), 1);
        assert!(c.all_zero());
    }

    #[test]
    fn headroom_grows_with_shadow_lights_only() {
        assert_eq!(min_i_max(0), 2);
        assert_eq!(min_i_max(2), 4);
        assert_eq!(r_imax(RayKind::Shadow, 3), 1);
        assert_eq!(Class::of_ray(RayKind::Primary, -0.5), Class::RayDown);
        assert_eq!(Class::of_ray(RayKind::Shadow, 0.0), Class::ShadowUp);
        for (i, c) in CREDIT_CLASSES.iter().enumerate() {
            assert_eq!(c.credit_index(), Some(i));
        }
    }
}
