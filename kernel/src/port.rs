//! The port: the only way a worker talks to the world. A fabric (simulator, threads, MPI, a
//! board's link driver) implements it; the worker never sees a thread, a clock or a socket.
//!
//! Invariants a port keeps: a message handed to `try_send` is delivered exactly once or handed
//! back; `try_recv` returns messages of the asked class only; nothing blocks.

use crate::msg::{Msg, MsgKind};

/// Where a message goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dest {
    /// A node, by its node id.
    Node(u16),
    /// The host.
    Host,
}

/// Classes of received messages, in the worker's reading priority.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Class {
    /// Acknowledgements (flow control).
    Ack,
    /// Hit records and resolved descriptors going home.
    Resolved,
    /// Forwarded rays.
    Ray,
    /// Everything else: tokens, slab planes, host traffic.
    Control,
}

impl MsgKind {
    /// The reading class of this kind.
    pub fn class(self) -> Class {
        match self {
            MsgKind::Ack => Class::Ack,
            MsgKind::Hit | MsgKind::Resolved => Class::Resolved,
            MsgKind::Ray => Class::Ray,
            MsgKind::Token | MsgKind::Pixels | MsgKind::Stats | MsgKind::Planes => Class::Control,
        }
    }
}

/// A node's connection to the others and the host.
pub trait Port {
    /// Send `msg` to `to`, or hand it back when it cannot be taken now.
    #[allow(
        clippy::result_large_err,
        reason = "a full link hands the message back, as heapless does; there is no heap to box it on"
    )]
    fn try_send(&mut self, to: Dest, msg: Msg) -> Result<(), Msg>;
    /// The next received message of `class`, if any.
    fn try_recv(&mut self, class: Class) -> Option<Msg>;
    /// Received messages not yet read, all classes.
    fn pending(&self) -> usize;
}
