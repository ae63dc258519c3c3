//! The port: the only way a worker talks to the world. A fabric (simulator, threads, MPI, a
//! board's link driver) implements it; the worker never sees a thread, a clock or a socket.
//!
//! Invariants a port keeps: a message handed to `try_send` is delivered exactly once or handed
//! back; received messages are queued by [`Class`], first in first out within a class, and
//! `peek`/`try_recv` look only at the asked class; nothing blocks.

use crate::node::flow::Class;
use crate::node::msg::Msg;

/// Where a message goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dest {
    /// A node, by its node id.
    Node(u16),
    /// The host.
    Host,
}

/// A node's connection to the others and the host.
pub trait Port {
    /// Send `msg` to `to`, or hand it back when it cannot be taken now.
    #[allow(
        clippy::result_large_err,
        reason = "a full link hands the message back, as heapless does; there is no heap to box it on"
    )]
    fn try_send(&mut self, to: Dest, msg: Msg) -> Result<(), Msg>;
    /// The next received message of `class`, without taking it.
    fn peek(&mut self, class: Class) -> Option<&Msg>;
    /// Take the next received message of `class`, with its sender (`Dest::Host` for the host).
    fn try_recv(&mut self, class: Class) -> Option<(Dest, Msg)>;
    /// Received messages not yet read, all classes.
    fn pending(&self) -> usize;
}
