//! A worker's statistics on their way to the host ([`NodeStats`]), and their encoding: the
//! node, then every counter, forwarding and peak in a fixed order.
//!
//! Invariant: every field is a whole `u64` on the wire (the node a `u16`); any bits decode.

use super::wire::{DecodeError, Reader, Writer};
use crate::counters::Counters;
use crate::node::kind::KINDS;
use crate::node::stats::NodeStats;

pub(super) fn emit(s: &NodeStats, w: &mut Writer<'_>) {
    w.u16(s.node);
    for v in s.counters.fields() {
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

pub(super) fn parse(r: &mut Reader<'_>) -> Result<NodeStats, DecodeError> {
    let node = r.u16()?;
    let mut counters = Counters::default();
    let mut f = [0u64; Counters::COUNT];
    for v in &mut f {
        *v = r.u64()?;
    }
    for (slot, v) in counters.fields_mut().into_iter().zip(f) {
        *slot = v;
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
    Ok(NodeStats {
        node,
        counters,
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

#[cfg(test)]
mod tests {
    use super::super::fixtures::*;
    use super::super::{Msg, KINDS};
    use crate::node::stats::NodeStats;

    #[test]
    fn statistics_round_trip() {
        roundtrip(Msg::Stats(NodeStats {
            node: 2,
            forwarded_next: 9,
            sent: [1; KINDS],
            peak_unacked: 3,
            ..NodeStats::default()
        }));
    }
}
