//! The simulator's network: messages in flight, and each node's receive buffer of a fixed
//! byte capacity and its mailboxes by class.
//!
//! Invariants: a message takes its room in the receiver's buffer when sent and gives it back
//! when read; a send that does not fit is refused and the sender keeps the message; sent =
//! delivered + in flight; the first overflow of any buffer is kept for the checks.

use std::collections::VecDeque;
use voxcube_kernel::node::flow::Class;
use voxcube_kernel::node::msg::{Msg, MsgKind, MAX_MSG_LEN};
use voxcube_kernel::node::port::{Dest, Port};

#[derive(Clone)]
pub(super) struct Envelope {
    pub(super) from: Option<u16>,
    pub(super) to: Dest,
    pub(super) len: usize,
    pub(super) bytes: [u8; MAX_MSG_LEN],
    pub(super) seq: u64,
    /// Virtual arrival time (timed runs).
    pub(super) arrival: f64,
}

/// What delivering an envelope needs of it once its message is decoded.
pub(super) struct Delivered {
    pub(super) from: Option<u16>,
    pub(super) to: Dest,
    pub(super) len: usize,
    pub(super) arrival: f64,
}

#[derive(Clone, Default)]
pub(super) struct Mailbox {
    pub(super) by_class: [VecDeque<(Dest, Msg)>; 7],
}

pub(super) struct SimPort<'n> {
    pub(super) from: u16,
    pub(super) net: &'n mut Network,
    pub(super) mailbox: &'n mut Mailbox,
    pub(super) capacity: usize,
    pub(super) received: u64,
}

/// Messages in flight and what each node's buffer holds.
#[derive(Clone)]
pub(super) struct Network {
    pub(super) inflight: Vec<Envelope>,
    /// Bytes each node's receive buffer holds or has promised (in flight to it, or unread).
    pub(super) used: Vec<usize>,
    pub(super) peak: Vec<usize>,
    /// Bytes a receive buffer may hold.
    pub(super) capacity: usize,
    /// The first node whose buffer was pushed past `capacity`, and the bytes it then held.
    /// Buffers only grow in [`Network::push`], so watching there sees every overflow, at the
    /// cost of one comparison a message instead of a scan of every node each event.
    pub(super) overflow: Option<(u16, usize)>,
    pub(super) sent: u64,
    pub(super) delivered: u64,
    pub(super) seq: u64,
    pub(super) refused: Option<(u16, u16, MsgKind)>,
}

impl Network {
    /// An empty network of `nodes` receive buffers of `capacity` bytes each.
    pub(super) fn new(nodes: usize, capacity: usize) -> Network {
        Network {
            inflight: Vec::new(),
            used: vec![0; nodes],
            peak: vec![0; nodes],
            capacity,
            overflow: None,
            sent: 0,
            delivered: 0,
            seq: 0,
            refused: None,
        }
    }

    /// Send `msg` from `from` (`None`: the host) to `to`: it takes its room in the
    /// receiver's buffer now, and gives it back when read.
    pub(super) fn push(&mut self, from: Option<u16>, to: Dest, msg: &Msg) {
        self.seq += 1;
        self.sent += 1;
        // Encoded where it waits: encoding on the stack cost a copy of the envelope.
        self.inflight.push(Envelope {
            from,
            to,
            len: 0,
            bytes: [0u8; MAX_MSG_LEN],
            seq: self.seq,
            arrival: f64::NAN,
        });
        let Some(env) = self.inflight.last_mut() else {
            return;
        };
        env.len = msg.encode(&mut env.bytes);
        let len = env.len;
        if let Dest::Node(n) = to {
            if let Some(u) = self.used.get_mut(usize::from(n)) {
                *u += len;
                self.peak[usize::from(n)] = self.peak[usize::from(n)].max(*u);
                if *u > self.capacity && self.overflow.is_none() {
                    self.overflow = Some((n, *u));
                }
            }
        }
    }
}

impl Port for SimPort<'_> {
    fn try_send(&mut self, to: Dest, msg: Msg) -> Result<(), Msg> {
        if let Dest::Node(n) = to {
            let len = msg.kind().encoded_len();
            if self
                .net
                .used
                .get(usize::from(n))
                .is_none_or(|&u| u + len > self.capacity)
            {
                self.net.refused = Some((self.from, n, msg.kind()));
                return Err(msg);
            }
        }
        self.net.push(Some(self.from), to, &msg);
        Ok(())
    }

    fn peek(&mut self, class: Class) -> Option<&Msg> {
        self.mailbox.by_class[class.index()].front().map(|(_, m)| m)
    }

    fn try_recv(&mut self, class: Class) -> Option<(Dest, Msg)> {
        // Handed on as it left the mailbox: taking it apart and putting it back together
        // cost a copy of the whole message.
        let read = self.mailbox.by_class[class.index()].pop_front();
        if let Some((_, msg)) = &read {
            self.received += 1;
            if let Some(u) = self.net.used.get_mut(usize::from(self.from)) {
                *u = u.saturating_sub(msg.kind().encoded_len());
            }
        }
        read
    }

    fn pending(&self) -> usize {
        self.mailbox.by_class.iter().map(VecDeque::len).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_push_past_capacity_is_an_overflow_even_when_the_buffer_drains_later() {
        let len = Msg::Collect.kind().encoded_len();
        let mut net = Network::new(2, 2 * len);
        for _ in 0..2 {
            net.push(None, Dest::Node(1), &Msg::Collect);
        }
        net.push(None, Dest::Host, &Msg::Collect);
        assert_eq!(net.overflow, None, "full is not over");
        net.push(None, Dest::Node(1), &Msg::Collect);
        net.used[1] = 0;
        net.push(None, Dest::Node(1), &Msg::Collect);
        assert_eq!(
            net.overflow,
            Some((1, 3 * len)),
            "the first overflow is kept"
        );
    }
}
