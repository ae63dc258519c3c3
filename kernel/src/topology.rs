//! Where a node sits: `m` clusters of `cd` nodes, node id ↔ (cluster, ring position), and which
//! image rows a cluster renders.
//!
//! Invariants: `1 ≤ m`, `1 ≤ cd ≤ MAX_CLUSTER`, `m·cd < 2^16 − 1` (one id is reserved as
//! "no node"). Node ids number clusters consecutively: node = cluster·cd + position. Rows are
//! interleaved over clusters: row `r` belongs to cluster `r mod m`, so neighbouring rows of
//! similar cost go to different clusters.

use crate::partition::MAX_CLUSTER;
use core::fmt;

/// Why a layout is impossible.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LayoutError {
    /// Clusters asked for.
    pub clusters: u32,
    /// Nodes per cluster asked for.
    pub size: u32,
}

impl fmt::Display for LayoutError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} clusters of {} nodes: need at least one of each, at most {MAX_CLUSTER} per cluster and 65534 in all",
            self.clusters, self.size
        )
    }
}

impl core::error::Error for LayoutError {}

/// Clusters and their rings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout {
    clusters: u16,
    size: u16,
}

impl Layout {
    /// `clusters` clusters of `size` nodes.
    pub fn new(clusters: u32, size: u32) -> Result<Layout, LayoutError> {
        let err = LayoutError { clusters, size };
        if clusters == 0
            || size == 0
            || size as usize > MAX_CLUSTER
            || u64::from(clusters) * u64::from(size) >= u64::from(u16::MAX)
        {
            return Err(err);
        }
        Ok(Layout {
            clusters: clusters as u16,
            size: size as u16,
        })
    }

    /// Number of clusters, `m`.
    pub fn clusters(&self) -> u16 {
        self.clusters
    }

    /// Nodes per cluster, `cd`.
    pub fn size(&self) -> u16 {
        self.size
    }

    /// All nodes, `m·cd`.
    pub fn nodes(&self) -> u32 {
        u32::from(self.clusters) * u32::from(self.size)
    }

    /// The node at `position` of `cluster`'s ring.
    pub fn node(&self, cluster: u16, position: u16) -> u16 {
        cluster * self.size + position
    }

    /// `(cluster, position)` of a node.
    pub fn place(&self, node: u16) -> (u16, u16) {
        (node / self.size, node % self.size)
    }

    /// Rows of a `height`-row image that `cluster` renders.
    pub fn rows(&self, cluster: u16, height: u32) -> u32 {
        let (c, m) = (u32::from(cluster), u32::from(self.clusters));
        if c >= height {
            0
        } else {
            (height - 1 - c) / m + 1
        }
    }

    /// The image row of `cluster`'s `i`-th row.
    pub fn row(&self, cluster: u16, i: u32) -> u32 {
        u32::from(cluster) + i * u32::from(self.clusters)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_interleave_and_cover_the_image_once() {
        let l = Layout::new(4, 3).unwrap();
        let mut seen = [0u8; 10];
        for c in 0..4 {
            for i in 0..l.rows(c, 10) {
                seen[l.row(c, i) as usize] += 1;
            }
        }
        assert_eq!(seen, [1; 10]);
        assert_eq!(l.rows(3, 2), 0);
        assert_eq!(l.place(l.node(2, 1)), (2, 1));
        assert!(
            Layout::new(0, 1).is_err()
                && Layout::new(1, 2000).is_err()
                && Layout::new(65535, 1).is_err()
        );
    }
}
