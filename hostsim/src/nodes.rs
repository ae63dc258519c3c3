//! A node's copy of the fast tier's node field (`voxcube_kernel::volume::nodes`): built from
//! its slab where its view reads one and the node holds it, and attached to the slab it traces.
//!
//! Invariant: holding the field or not changes no pixel (the kernel computes the same lanes
//! on the fly), so a node that cannot hold it, or whose build fails, renders without it.

use crate::storage::{even_parts, run_parts, split_sizes, Part, SkipMode};
use std::ops::Range;
use voxcube_kernel::counters::Counters;
use voxcube_kernel::trace::view::View;
use voxcube_kernel::volume::nodes::{self, Lanes, Nodes};
use voxcube_kernel::volume::sample::Sample;
use voxcube_kernel::volume::slab::Slab;

/// A node field over a slab's planes, or none.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NodeField<N> {
    planes: Range<u32>,
    lanes: Vec<N>,
}

impl<N: Lanes> NodeField<N> {
    /// The field of `slab` when `view` reads one ([`View::node_gradients`]) and `mode` holds
    /// it, built on up to `threads` OS threads in parts of planes (each node reads only the
    /// slab, so the parts are the same bits as one pass); else none.
    pub fn build<T: Sample<Node = N> + Sync>(
        slab: &Slab<'_, T>,
        view: &View,
        mode: SkipMode,
        threads: usize,
    ) -> NodeField<N> {
        if !(mode.nodes && view.node_gradients()) {
            return NodeField::default();
        }
        let grid = slab.grid();
        let planes = nodes::planes_for(grid, slab.stored());
        let mut lanes = vec![N::default(); nodes::len_for(grid, slab.stored())];
        let parts = even_parts(planes.len() as u32, threads.max(1) as u32);
        let sizes = parts.iter().map(|p| p.len() * grid.plane_len());
        let jobs = split_sizes(&mut lanes, sizes)
            .zip(parts.iter())
            .map(|(out, part)| -> Part<'_> {
                let part = planes.start + part.start..planes.start + part.end;
                Box::new(move || nodes::fill(slab, part, out, &mut Counters::default()).is_ok())
            })
            .collect();
        match run_parts(jobs, threads).into_iter().all(|built| built) {
            true => NodeField { planes, lanes },
            false => NodeField::default(),
        }
    }

    /// Bytes it holds.
    pub fn bytes(&self) -> usize {
        self.lanes.len() * size_of::<N>()
    }

    /// `slab`, reading this field (unchanged when it holds none or does not match).
    pub fn apply<'a, T: Sample<Node = N>>(&'a self, slab: Slab<'a, T>) -> Slab<'a, T> {
        if self.lanes.is_empty() {
            return slab;
        }
        match Nodes::new(slab.grid(), self.planes.clone(), &self.lanes) {
            Ok(field) if self.planes == nodes::planes_for(slab.grid(), slab.stored()) => {
                slab.with_nodes(field)
            }
            _ => slab,
        }
    }
}
