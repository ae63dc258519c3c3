//! The host's side of the protocol, one implementation for every fabric: it takes pixel sets
//! and tokens, asks for statistics once it holds every cluster's token, and ends when it
//! holds every node's statistics and every pixel they count. A cluster declared lost (one of
//! its nodes stopped answering) is waited for no more: neither its token nor its nodes'
//! statistics.
//!
//! Invariants (each breach is an error naming it): a pixel arrives once and inside the image;
//! a cluster's token arrives once; a node reports once, and only after the host asked. The
//! host ends with every pixel of the image, or, with a cluster lost, hands what it holds to
//! the recovery that completes it.

use voxcube_kernel::node::msg::Msg;
use voxcube_kernel::node::stats::NodeStats;

/// The host's state in one run.
#[derive(Clone, Debug)]
pub struct Host {
    image: Vec<Option<[u8; 4]>>,
    width: u32,
    received: u64,
    tokens: Vec<bool>,
    /// By cluster: declared lost.
    lost: Vec<bool>,
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
            lost: vec![false; clusters],
            reports: vec![None; nodes],
            collecting: false,
        }
    }

    /// The cluster of node `n` (node ids run cluster by cluster).
    fn cluster_of(&self, n: usize) -> usize {
        let size = self.reports.len() / self.tokens.len().max(1);
        n / size.max(1)
    }

    /// Whether the host waits for node `n`'s statistics: it is in a cluster not lost.
    pub fn expects_report(&self, n: usize) -> bool {
        n < self.reports.len() && !self.lost[self.cluster_of(n)]
    }

    /// Wait no more for `cluster`, one of whose nodes stopped answering. `Ok(true)` means
    /// every other token is now in: send every node [`Host::expects_report`] a `Collect`.
    pub fn declare_lost(&mut self, cluster: u16) -> Result<bool, String> {
        match self.lost.get_mut(usize::from(cluster)) {
            Some(lost @ false) => *lost = true,
            _ => return Err(format!("cluster {cluster} is unknown or already lost")),
        }
        Ok(self.start_collecting())
    }

    /// Start collecting once every cluster's token is in or the cluster is lost.
    fn start_collecting(&mut self) -> bool {
        let settled = self.tokens.iter().zip(&self.lost).all(|(&t, &l)| t || l);
        if !self.collecting && settled {
            self.collecting = true;
            return true;
        }
        false
    }

    /// The clusters declared lost.
    pub fn lost_clusters(&self) -> Vec<u16> {
        (0..self.lost.len() as u16)
            .filter(|&c| self.lost[usize::from(c)])
            .collect()
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
        Ok(self.start_collecting())
    }

    /// Whether the run is over: every report the host waits for in, and every pixel the
    /// reports count.
    pub fn done(&self) -> bool {
        (0..self.reports.len()).all(|n| self.has_report(n) || !self.expects_report(n))
            && self.received >= self.reports.iter().flatten().map(|s| s.pixels_sent).sum()
    }

    /// Feed into `h` what steers the host from here on: its pixels, tokens, whether it is
    /// collecting, and which nodes have reported how many pixels (the rest of a report is
    /// history).
    pub fn digest<H: std::hash::Hasher>(&self, h: &mut H) {
        let reports: Vec<Option<u64>> = self
            .reports
            .iter()
            .map(|r| r.as_ref().map(|s| s.pixels_sent))
            .collect();
        h.write(
            format!(
                "{:?}|{:?}|{:?}|{}|{reports:?}",
                self.image, self.tokens, self.lost, self.collecting
            )
            .as_bytes(),
        );
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

    /// What the host holds, pixels and reports, each `None` where it has none.
    pub fn into_parts(self) -> (Vec<Option<[u8; 4]>>, Vec<Option<NodeStats>>) {
        (self.image, self.reports)
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

#[cfg(test)]
mod tests {
    //! The host's rules, each by a direct test of its decision: drop a rule and its
    //! assertion fails.
    use super::*;
    use voxcube_kernel::node::msg::PixelSet;

    fn pixels(list: &[u32]) -> Msg {
        let mut set = PixelSet::default();
        for &p in list {
            assert!(set.push(p, [p as u8, 0, 0, 255]).is_ok());
        }
        Msg::Pixels(set)
    }

    fn stats(node: u16, pixels_sent: u64) -> Msg {
        Msg::Stats(NodeStats {
            node,
            pixels_sent,
            ..NodeStats::default()
        })
    }

    #[test]
    fn a_pixel_arrives_once_and_inside_the_image() {
        let mut host = Host::new(4, 2, 1, 1);
        assert_eq!(host.receive(pixels(&[0, 3])), Ok(false));
        let twice = host.receive(pixels(&[3])).unwrap_err();
        assert!(twice.contains("pixel 3 reached the host twice"), "{twice}");
        let outside = host.receive(pixels(&[4])).unwrap_err();
        assert!(
            outside.contains("pixel 4 is outside the image"),
            "{outside}"
        );
        assert_eq!((host.received(), host.missing()), (2, 2));
    }

    #[test]
    fn collection_starts_once_every_token_is_in_and_each_comes_once() {
        let mut host = Host::new(1, 1, 2, 2);
        assert_eq!(host.receive(Msg::Token { cluster: 1 }), Ok(false));
        assert!(
            host.receive(Msg::Token { cluster: 1 }).is_err(),
            "a second token"
        );
        assert!(
            host.receive(Msg::Token { cluster: 2 }).is_err(),
            "an unknown cluster"
        );
        // Statistics before every token are a protocol breach.
        let early = host.receive(stats(0, 0)).unwrap_err();
        assert!(early.contains("before the host asked"), "{early}");
        assert_eq!(
            host.receive(Msg::Token { cluster: 0 }),
            Ok(true),
            "the last token"
        );
        assert_eq!(host.tokens(), 2);
        assert_eq!(host.receive(stats(0, 0)), Ok(false), "asked only once");
        assert!(host.receive(stats(0, 0)).is_err(), "a second report");
        assert!(host.receive(stats(5, 0)).is_err(), "an unknown node");
        assert!(host.receive(Msg::Collect).is_err(), "not a host's message");
    }

    #[test]
    fn the_host_ends_only_with_every_report_and_every_pixel_they_count() {
        let mut host = Host::new(3, 3, 1, 2);
        assert_eq!(host.receive(pixels(&[0])), Ok(false));
        assert_eq!(host.receive(Msg::Token { cluster: 0 }), Ok(true));
        assert_eq!(host.receive(stats(0, 2)), Ok(false));
        assert!(!host.done(), "a node has not reported");
        assert_eq!(host.receive(stats(1, 1)), Ok(false));
        // The reports count three pixels; one is in, two are still on their way.
        assert!(!host.done(), "pixels the reports count are in flight");
        assert_eq!(host.receive(pixels(&[1, 2])), Ok(false));
        assert!(host.done());
        let (image, reports) = host.finish().unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(image[2], [2, 0, 0, 255]);
        assert_eq!(reports.len(), 2);
        // Ending with a pixel missing is an error, whatever the reports said.
        let mut short = Host::new(2, 2, 1, 1);
        assert_eq!(short.receive(pixels(&[0])), Ok(false));
        assert!(short.finish().unwrap_err().contains("1 of 2 pixels"));
    }

    #[test]
    fn a_lost_cluster_is_waited_for_no_more_and_only_once() {
        // Two clusters of two nodes: nodes 2 and 3 are cluster 1's.
        let mut host = Host::new(4, 2, 2, 4);
        assert_eq!(host.receive(Msg::Token { cluster: 0 }), Ok(false));
        assert_eq!(host.declare_lost(1), Ok(true), "every other token is in");
        assert!(host.declare_lost(1).is_err(), "lost once");
        assert!(host.declare_lost(2).is_err(), "an unknown cluster");
        assert!((host.expects_report(0), host.expects_report(1)) == (true, true));
        assert!(!host.expects_report(2) && !host.expects_report(3));
        assert_eq!(host.receive(stats(0, 0)), Ok(false));
        assert!(!host.done(), "node 1 has not reported");
        assert_eq!(host.receive(stats(1, 0)), Ok(false));
        assert!(host.done(), "the lost cluster's reports are not waited for");
        assert_eq!(host.lost_clusters(), vec![1]);
        // Declared lost before the others' tokens: collection waits for them.
        let mut early = Host::new(4, 2, 2, 4);
        assert_eq!(early.declare_lost(0), Ok(false));
        assert_eq!(early.receive(Msg::Token { cluster: 1 }), Ok(true));
    }
}
