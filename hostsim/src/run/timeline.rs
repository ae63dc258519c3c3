//! A simulated run's timeline as Chrome trace-event JSON (`render --trace`), which Perfetto
//! (ui.perfetto.dev) and chrome://tracing open: one row per node, grouped by cluster, its
//! compute, test, receive, send and idle spans in virtual time, microseconds from the start.
//!
//! A node steps hundreds of thousands of times a frame; a span per step would make a file of
//! hundreds of megabytes. So each node's time is cut into bins (at most [`EVENTS`] spans in
//! the whole file, at least 200 bins a node), and each bin shows how its time divided among
//! the kinds, one span per kind in a fixed order; a kind that fills neighbouring bins (a long
//! wait) stays one span. The shares per bin are exact; the order inside a bin is not.

use crate::fabric::{Span, VirtualTime};
use serde_json::{json, Value};

/// About how many spans the file holds at most.
pub const EVENTS: usize = 100_000;

const KINDS: [&str; 5] = ["compute", "test", "receive", "send", "idle"];

/// `spans` summed into `bins` bins of `width` seconds, laid out kind by kind within each bin,
/// neighbouring spans of one kind merged.
fn binned(spans: &[Span], bins: usize, width: f64) -> Vec<Span> {
    let mut time = vec![[0.0f64; KINDS.len()]; bins];
    for s in spans {
        let k = KINDS.iter().position(|&k| k == s.kind).unwrap_or(0);
        let mut at = s.start;
        let mut b = ((at / width) as usize).min(bins - 1);
        while at < s.end {
            // A boundary rounded just below `at` belongs to the next bin.
            while b + 1 < bins && (b + 1) as f64 * width <= at {
                b += 1;
            }
            let bin_end = if b + 1 == bins {
                s.end
            } else {
                (b + 1) as f64 * width
            };
            let to = s.end.min(bin_end);
            time[b][k] += to - at;
            at = to;
        }
    }
    let mut out: Vec<Span> = Vec::new();
    for (b, parts) in time.iter().enumerate() {
        let mut at = b as f64 * width;
        for (k, &d) in parts.iter().enumerate() {
            if d <= 0.0 {
                continue;
            }
            match out.last_mut() {
                Some(last) if last.kind == KINDS[k] && (last.end - at).abs() <= width * 1e-9 => {
                    last.end = at + d
                }
                _ => out.push(Span {
                    kind: KINDS[k],
                    start: at,
                    end: at + d,
                }),
            }
            at += d;
        }
    }
    out
}

/// `seconds` in microseconds on a grid of 1/1024 µs. Viewers end a span at `ts + dur` in
/// doubles and nest a span that starts before its predecessor's end inside it; on this grid
/// both sums are exact (to 2^43 µs), so a span that starts where another ends starts exactly
/// there, never a rounding error inside it.
fn microseconds(seconds: f64) -> f64 {
    (seconds * 1e6 * 1024.0).round() / 1024.0
}

/// The trace of `time`, a run of clusters of `size` nodes: node `n` is a row of the process
/// of its cluster, `n / size`.
pub fn chrome_trace(time: &VirtualTime, size: u32) -> Value {
    let size = size.max(1) as usize;
    let nodes = time.timeline.len().max(1);
    let end = time
        .timeline
        .iter()
        .filter_map(|s| s.last().map(|s| s.end))
        .fold(time.frame, f64::max)
        .max(f64::MIN_POSITIVE);
    let bins = (EVENTS / (nodes * KINDS.len())).max(200);
    let width = end / bins as f64;
    let mut events = Vec::new();
    for (n, spans) in time.timeline.iter().enumerate() {
        let (pid, tid) = (n / size, n);
        if n % size == 0 {
            events.push(json!({"ph": "M", "name": "process_name", "pid": pid,
                "args": {"name": format!("cluster {pid}")}}));
        }
        events.push(
            json!({"ph": "M", "name": "thread_name", "pid": pid, "tid": tid,
            "args": {"name": format!("node {n}")}}),
        );
        for s in binned(spans, bins, width) {
            let (ts, end) = (microseconds(s.start), microseconds(s.end));
            if end <= ts {
                continue;
            }
            events.push(json!({
                "ph": "X",
                "name": s.kind,
                "cat": s.kind,
                "pid": pid,
                "tid": tid,
                "ts": ts,
                "dur": end - ts,
            }));
        }
    }
    json!({
        "traceEvents": events,
        "displayTimeUnit": "ms",
        "otherData": {
            "clock": "virtual time of the simulated machine, seconds x 1e6",
            "frame_s": time.frame,
            "bin_s": width,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn span(kind: &'static str, start: f64, end: f64) -> Span {
        Span { kind, start, end }
    }

    #[test]
    fn bins_keep_each_kind_s_time_and_merge_long_spans() {
        let spans = [
            span("compute", 0.0, 0.3),
            span("send", 0.3, 0.4),
            span("idle", 0.4, 3.6),
            span("compute", 3.6, 4.0),
        ];
        let out = binned(&spans, 4, 1.0);
        let total = |k: &str| -> f64 {
            out.iter()
                .filter(|s| s.kind == k)
                .map(|s| s.end - s.start)
                .sum()
        };
        assert!((total("compute") - 0.7).abs() < 1e-12);
        assert!((total("send") - 0.1).abs() < 1e-12);
        assert!((total("idle") - 3.2).abs() < 1e-12);
        // The idle stretch across bins 1 and 2 is one span.
        assert!(out
            .iter()
            .any(|s| s.kind == "idle" && s.start <= 1.0 && s.end >= 3.0));
        for w in out.windows(2) {
            assert!(w[0].end <= w[1].start + 1e-12, "{out:?}");
        }
    }

    #[test]
    fn a_span_starting_where_another_ends_starts_exactly_there_in_microseconds() {
        // Negative control: scaled alone, a span from 0.1 s to 0.1 s + 0.2 s ends in a viewer
        // somewhere other than where the next span, starting at 0.1 s + 0.2 s, starts.
        let (start, end) = (0.1f64, 0.1f64 + 0.2);
        assert_ne!(start * 1e6 + (end - start) * 1e6, end * 1e6);
        let (ts, stop) = (microseconds(start), microseconds(end));
        assert_eq!(ts + (stop - ts), stop);
        let mut next = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..100_000 {
            next ^= next << 13;
            next ^= next >> 7;
            next ^= next << 17;
            let start = (next >> 11) as f64 / (1u64 << 53) as f64 * 1e3;
            let d = ((next >> 20) % 1_000_000) as f64 * 1e-9;
            let (ts, stop) = (microseconds(start), microseconds(start + d));
            // What a viewer computes for the span's end, against where the next one starts.
            assert_eq!(ts + (stop - ts), stop, "{start} {d}");
        }
    }
}
