//! Where a node sits: `m` clusters of `cd` nodes, node id ↔ (cluster, ring position), e-cube
//! routes between nodes, and which image rows a cluster renders.
//!
//! On a hypercube (`P = 2^k` nodes, `m = 2^i` clusters of `cd = 2^(k−i)`) a node id is the
//! cluster's bits above the ring's: `node = cluster·cd + gray(position)`, with `gray` the
//! reflected binary Gray code, which is cyclic — so ring neighbours, the last and first
//! included, differ in one bit: one hypercube hop. Other sizes (simulated rings of any length,
//! for tests) number positions plainly.
//!
//! Invariants: `1 ≤ m`, `1 ≤ cd ≤ MAX_CLUSTER`, `m·cd < 2^16 − 1` (one id is reserved as
//! "no node"); every node has exactly one (cluster, position). Rows are interleaved over
//! clusters: row `r` belongs to cluster `r mod m`, so neighbouring rows of similar cost go to
//! different clusters.

use crate::node::partition::MAX_CLUSTER;
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

/// Clusters and their rings, and the image rows the machine traces (every row, unless it
/// re-traces a lost cluster's: [`Layout::with_rows`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout {
    clusters: u16,
    size: u16,
    rows: Rows,
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
            rows: Rows::ALL,
        })
    }

    /// The same machine tracing only `rows`, dealt among its clusters in turn: how surviving
    /// clusters share the rows of a cluster that lost a node. A pixel's colour does not
    /// depend on which cluster traces it, so the rows come out the same bits.
    pub fn with_rows(self, rows: Rows) -> Layout {
        Layout { rows, ..self }
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

    /// Whether this is a hypercube with Gray-code rings (`m` and `cd` powers of two).
    pub fn is_hypercube(&self) -> bool {
        self.size.is_power_of_two() && self.clusters.is_power_of_two()
    }

    /// The hypercube's dimension `k` (`P = 2^k`), when it is one.
    pub fn dimension(&self) -> Option<u32> {
        self.is_hypercube().then(|| self.nodes().trailing_zeros())
    }

    /// The node at `position` of `cluster`'s ring.
    pub fn node(&self, cluster: u16, position: u16) -> u16 {
        let within = if self.size.is_power_of_two() {
            gray(position)
        } else {
            position
        };
        cluster * self.size + within
    }

    /// `(cluster, position)` of a node.
    pub fn place(&self, node: u16) -> (u16, u16) {
        let within = node % self.size;
        let position = if self.size.is_power_of_two() {
            gray_inverse(within)
        } else {
            within
        };
        (node / self.size, position)
    }

    /// The image rows the machine traces, before they are dealt to its clusters.
    pub fn traced(&self) -> Rows {
        self.rows
    }

    /// The image rows `cluster` renders: the clusters take the machine's rows in turn
    /// ([`Rows::deal`]; with every row, [`Rows::of_cluster`]).
    pub fn cluster_rows(&self, cluster: u16) -> Rows {
        self.rows.deal(cluster, self.clusters)
    }

    /// Rows of a `height`-row image that `cluster` renders.
    pub fn rows(&self, cluster: u16, height: u32) -> u32 {
        self.cluster_rows(cluster).count(height)
    }

    /// The image row of `cluster`'s `i`-th row.
    pub fn row(&self, cluster: u16, i: u32) -> u32 {
        self.cluster_rows(cluster).row(i)
    }
}

/// The image rows one cluster renders ([`Layout::cluster_rows`]): `first`, `first + step`, …
/// below the image's height, `step` the number of clusters. A node's depth bounds
/// ([`crate::skip::depths`]) cover its cluster's rows only.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rows {
    first: u32,
    step: u32,
}

impl Default for Rows {
    fn default() -> Rows {
        Rows::ALL
    }
}

impl Rows {
    /// Every row: the one cluster's of a machine of one.
    pub const ALL: Rows = Rows { first: 0, step: 1 };

    /// The rows of cluster `cluster` of `clusters` (`None` for no clusters): the clusters
    /// take every row in turn ([`Rows::deal`], the one rule that deals rows).
    pub fn of_cluster(cluster: u16, clusters: u16) -> Option<Rows> {
        (clusters > 0).then(|| Rows::ALL.deal(cluster, clusters))
    }

    /// Rows `first`, `first + step`, … (a step of 0 is taken as 1).
    pub fn new(first: u32, step: u32) -> Rows {
        Rows {
            first,
            step: step.max(1),
        }
    }

    /// The first row.
    pub fn first(&self) -> u32 {
        self.first
    }

    /// Rows from one to the next.
    pub fn step(&self) -> u32 {
        self.step
    }

    /// The `part`-th of `parts` who take these rows in turn (all of them for no parts).
    pub fn deal(&self, part: u16, parts: u16) -> Rows {
        match parts {
            0 => *self,
            _ => Rows::new(
                self.first
                    .saturating_add(u32::from(part).saturating_mul(self.step)),
                self.step.saturating_mul(u32::from(parts)),
            ),
        }
    }

    /// How many of them an image of `height` rows has.
    pub fn count(&self, height: u32) -> u32 {
        match self.first < height {
            true => (height - 1 - self.first) / self.step + 1,
            false => 0,
        }
    }

    /// The image row of the `i`-th of them.
    pub fn row(&self, i: u32) -> u32 {
        self.first + i * self.step
    }

    /// The place of image row `row` among them, if it is one of them.
    #[inline]
    pub fn index(&self, row: u32) -> Option<u32> {
        let offset = row.checked_sub(self.first)?;
        (offset % self.step == 0).then_some(offset / self.step)
    }

    /// The places among them of those in the image rows `span`.
    #[inline]
    pub fn within(&self, span: core::ops::Range<u32>) -> core::ops::Range<u32> {
        if self.step == 1 {
            // Every row from `first` on: the same places without two divisions, which the
            // depth bounds' build asks for every cell it places.
            let (start, end) = (
                span.start.saturating_sub(self.first),
                span.end.saturating_sub(self.first),
            );
            return start..end.max(start);
        }
        let place = |row: u32| row.saturating_sub(self.first).div_ceil(self.step);
        let (start, end) = (place(span.start), place(span.end));
        start..end.max(start)
    }
}

/// The reflected binary Gray code of `j`.
pub const fn gray(j: u16) -> u16 {
    j ^ (j >> 1)
}

/// The `j` whose Gray code is `g`.
pub const fn gray_inverse(g: u16) -> u16 {
    let mut j = g;
    let mut shift = 1;
    while shift < 16 {
        j ^= j >> shift;
        shift <<= 1;
    }
    j
}

/// The e-cube route from `from` to `to` on a hypercube: correct the differing address bits
/// from the lowest up, one hop per bit. Yields each node after `from`, ending with `to`.
pub fn ecube_route(from: u16, to: u16) -> impl Iterator<Item = u16> {
    let mut at = from;
    (0..16).filter_map(move |bit| {
        let mask = 1u16 << bit;
        ((at ^ to) & mask != 0).then(|| {
            at ^= mask;
            at
        })
    })
}

/// Hops between two nodes of a hypercube (their Hamming distance).
pub const fn hops(from: u16, to: u16) -> u32 {
    (from ^ to).count_ones()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Survivors dealing a lost cluster's rows trace each of them once, and nothing else.
    #[test]
    fn survivors_deal_a_lost_cluster_s_rows_each_once() {
        let height = 251;
        for (clusters, lost) in [(2u16, 1u16), (4, 0), (4, 3), (8, 5)] {
            let rows = Rows::of_cluster(lost, clusters).unwrap();
            let survivors = Layout::new(u32::from(clusters) - 1, 4)
                .unwrap()
                .with_rows(rows);
            let mut traced = [0u8; 251];
            for k in 0..survivors.clusters() {
                for i in 0..survivors.rows(k, height) {
                    traced[survivors.row(k, i) as usize] += 1;
                }
            }
            for (row, &n) in traced.iter().enumerate() {
                let wanted = rows.index(row as u32).is_some();
                assert_eq!(
                    n,
                    u8::from(wanted),
                    "row {row}, cluster {lost} of {clusters}"
                );
            }
        }
        // Every row, by the plain layout, as before.
        let plain = Layout::new(3, 2).unwrap();
        assert_eq!(plain.cluster_rows(2), Rows::new(2, 3));
    }

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

    /// The places of the rows in a span are those whose row lies in it, for every span and
    /// every cluster of up to five (one cluster: every row, the short way).
    #[test]
    fn the_places_within_a_span_are_those_of_its_rows() {
        for clusters in 1..=5u16 {
            for cluster in 0..clusters {
                let rows = Rows::of_cluster(cluster, clusters).unwrap();
                for start in 0..12 {
                    for end in 0..12 {
                        let places = rows.within(start..end);
                        let expected: heapless::Vec<u32, 16> = (0..16)
                            .filter(|&i| (start..end).contains(&rows.row(i)))
                            .collect();
                        let got: heapless::Vec<u32, 16> = places.clone().collect();
                        assert_eq!(got, expected, "{cluster}/{clusters}: {start}..{end}");
                        assert!(places.start <= places.end);
                    }
                }
            }
        }
    }

    #[test]
    fn gray_code_inverts_and_e_cube_routes_take_one_hop_per_bit() {
        for j in 0..1024u16 {
            assert_eq!(gray_inverse(gray(j)), j);
            assert_eq!(hops(gray(j), gray(j + 1)), 1);
        }
        let route: [u16; 3] = [0b0001, 0b0011, 0b0111];
        assert!(ecube_route(0, 0b0111).eq(route));
        assert_eq!(ecube_route(5, 5).count(), 0);
        assert_eq!(hops(0b1010, 0b0101), 4);
    }
}
