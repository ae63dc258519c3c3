//! The control messages without a body of their own: a flow-control acknowledgement (`Ack`)
//! and a cluster's termination token (`Token`); `Collect` has no fields at all.
//!
//! Invariant: decoding refuses an acknowledgement of a class that carries no credit.

use super::wire::{DecodeError, Reader, Writer};
use crate::node::flow::Class;

pub(super) fn emit_ack(w: &mut Writer<'_>, from: u16, class: u8, count: u16) {
    w.u16(from);
    w.u8(class);
    w.u16(count);
}

/// An acknowledgement's node, class and count.
pub(super) fn parse_ack(r: &mut Reader<'_>) -> Result<(u16, u8, u16), DecodeError> {
    let from = r.u16()?;
    let class = r.u8()?;
    if Class::from_credit_index(class).is_none() {
        return Err(r.bad("class"));
    }
    Ok((from, class, r.u16()?))
}

pub(super) fn emit_token(w: &mut Writer<'_>, cluster: u16) {
    w.u16(cluster);
}

/// A token's cluster.
pub(super) fn parse_token(r: &mut Reader<'_>) -> Result<u16, DecodeError> {
    r.u16()
}

#[cfg(test)]
mod tests {
    use super::super::fixtures::*;
    use super::super::Msg;

    #[test]
    fn control_messages_round_trip_and_an_ack_s_class_is_checked() {
        roundtrip(ACK);
        roundtrip(Msg::Collect);
        roundtrip(Msg::Token { cluster: 1 });
        refuses(ACK, 3, crate::node::flow::CREDITS as u8, "class");
    }
}
