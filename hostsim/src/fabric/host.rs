//! The host's side of the protocol, one implementation for every fabric: it takes pixel sets
//! and tokens, asks for statistics once it holds every cluster's token, and ends when it
//! holds every node's statistics and every pixel they count.
//!
//! Invariants (each breach is an error naming it): a pixel arrives once and inside the image;
//! a cluster's token arrives once; a node reports once, and only after the host asked. The
//! host ends with every pixel of the image.

use voxcube_kernel::node::msg::Msg;
use voxcube_kernel::node::stats::NodeStats;

/// The host's state in one run.
#[derive(Debug)]
pub struct Host {
    image: Vec<Option<[u8; 4]>>,
    width: u32,
    received: u64,
    tokens: Vec<bool>,
    reports: Vec<Option<NodeStats>>,
    collecting: bool,
}

impl Host {
    /// A host for an image of `pixels` pixels `width` wide, `clusters` clusters, `nodes` nodes.
    pub fn new(pixels: usize, width: u32, clusters: usize, nodes: usize) -> Host {
        Host {
            image: vec![None; pixels],
            width,
            received: 0,
            tokens: vec![false; clusters],
            reports: vec![None; nodes],
            collecting: false,
        }
    }

    /// Take one message. `Ok(true)` means every token is now in: send every node a `Collect`.
    pub fn receive(&mut self, msg: Msg) -> Result<bool, String> {
        match msg {
            Msg::Pixels(set) => {
                for &(pixel, rgba) in set.entries() {
                    match self.image.get_mut(pixel as usize) {
                        Some(slot @ None) => *slot = Some(rgba),
                        Some(Some(_)) => {
                            return Err(format!("pixel {pixel} reached the host twice"))
                        }
                        None => return Err(format!("pixel {pixel} is outside the image")),
                    }
                    self.received += 1;
                }
            }
            Msg::Token { cluster } => match self.tokens.get_mut(usize::from(cluster)) {
                Some(t @ false) => *t = true,
                _ => return Err(format!("a second or unknown token of cluster {cluster}")),
            },
            Msg::Stats(stats) => {
                if !self.collecting {
                    return Err(format!(
                        "node {} reported before the host asked",
                        stats.node
                    ));
                }
                match self.reports.get_mut(usize::from(stats.node)) {
                    Some(r @ None) => *r = Some(stats),
                    _ => {
                        return Err(format!(
                            "a second or unknown report from node {}",
                            stats.node
                        ))
                    }
                }
            }
            other => return Err(format!("the host got an unexpected {:?}", other.kind())),
        }
        if !self.collecting && self.tokens.iter().all(|&t| t) {
            self.collecting = true;
            return Ok(true);
        }
        Ok(false)
    }

    /// Whether the run is over: every report in, and every pixel the reports count.
    pub fn done(&self) -> bool {
        self.reports.iter().all(Option::is_some)
            && self.received >= self.reports.iter().flatten().map(|s| s.pixels_sent).sum()
    }

    /// Pixels received.
    pub fn received(&self) -> u64 {
        self.received
    }

    /// Pixels still missing.
    pub fn missing(&self) -> u64 {
        self.image.len() as u64 - self.received
    }

    /// Tokens received.
    pub fn tokens(&self) -> u32 {
        self.tokens.iter().filter(|&&t| t).count() as u32
    }

    /// Reports received.
    pub fn reports(&self) -> usize {
        self.reports.iter().flatten().count()
    }

    /// Whether node `n` has reported.
    pub fn has_report(&self, n: usize) -> bool {
        self.reports.get(n).is_some_and(Option::is_some)
    }

    /// The rows still missing pixels, summarised.
    pub fn missing_rows(&self) -> String {
        missing_rows(&self.image, self.width)
    }

    /// The image and the reports, in node order; an error if a pixel is missing.
    pub fn finish(self) -> Result<(Vec<[u8; 4]>, Vec<NodeStats>), String> {
        if self.received != self.image.len() as u64 {
            return Err(format!(
                "the host ended with {} of {} pixels",
                self.received,
                self.image.len()
            ));
        }
        let reports = self
            .reports
            .into_iter()
            .map(Option::unwrap_or_default)
            .collect();
        Ok((
            self.image
                .into_iter()
                .map(Option::unwrap_or_default)
                .collect(),
            reports,
        ))
    }
}

/// The image rows with missing pixels, summarised as ranges.
pub fn missing_rows(image: &[Option<[u8; 4]>], width: u32) -> String {
    let width = width.max(1) as usize;
    let rows: Vec<usize> = image
        .chunks(width)
        .enumerate()
        .filter(|(_, r)| r.iter().any(Option::is_none))
        .map(|(i, _)| i)
        .collect();
    let mut out: Vec<String> = Vec::new();
    let mut i = 0;
    while i < rows.len() {
        let start = rows[i];
        while i + 1 < rows.len() && rows[i + 1] == rows[i] + 1 {
            i += 1;
        }
        out.push(if rows[i] == start {
            start.to_string()
        } else {
            format!("{start}-{}", rows[i])
        });
        i += 1;
    }
    if out.len() > 12 {
        let n = out.len();
        out.truncate(12);
        out.push(format!("... ({n} runs in all)"));
    }
    out.join(", ")
}
