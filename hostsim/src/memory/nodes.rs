//! A node's copy of the fast tier's node field (`voxcube_kernel::volume::nodes`): it depends
//! on the samples of a slab's planes alone, so it is built once per volume and set of planes
//! ([`super::built`]), and shared by every view, orbit frame and repetition that reads one.
//!
//! Invariant: holding the field or not changes no pixel (the kernel computes the same lanes
//! on the fly), so a node that cannot hold it, or whose build fails, renders without it.

use crate::memory::huge::HugeBuffer;
use crate::memory::parts::{even_parts, run_parts, split_sizes, Part};
use std::ops::Range;
use voxcube_kernel::volume::lanes::{Lanes, Nodes};
use voxcube_kernel::volume::nodes;
use voxcube_kernel::volume::sample::Sample;
use voxcube_kernel::volume::slab::Slab;

/// A node field over a slab's planes, or none. Its lanes are held in huge pages where the
/// kernel gives them ([`HugeBuffer`]): rays read a field all over, and at 512³ it is 1 GiB.
#[derive(Debug, Default, PartialEq)]
pub struct NodeField<N: Lanes> {
    planes: Range<u32>,
    lanes: HugeBuffer<N>,
}

impl<N: Lanes> NodeField<N> {
    /// The field of `slab`'s planes ([`nodes::planes_for`]), built on up to `threads` OS
    /// threads in parts of planes (each node reads only the slab, so the parts are the same
    /// bits as one pass); none where the slab does not store the planes its nodes read.
    pub fn build<T: Sample<Node = N> + Sync>(slab: &Slab<'_, T>, threads: usize) -> NodeField<N> {
        let grid = slab.grid();
        let planes = nodes::planes_for(grid, slab.owned());
        let Some(mut lanes) = HugeBuffer::zeroed(nodes::len_for(grid, slab.owned())) else {
            return NodeField::default();
        };
        let parts = even_parts(planes.len() as u32, threads.max(1) as u32);
        let sizes = parts.iter().map(|p| p.len() * grid.plane_len());
        let jobs = split_sizes(&mut lanes, sizes)
            .zip(parts.iter())
            .map(|(out, part)| -> Part<'_> {
                let part = planes.start + part.start..planes.start + part.end;
                Box::new(move || nodes::fill(slab, part, out).is_ok())
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

    /// `slab`, reading this field (unchanged when it holds none or not the slab's planes).
    pub fn apply<'a, T: Sample<Node = N>>(&'a self, slab: Slab<'a, T>) -> Slab<'a, T> {
        if self.lanes.is_empty() || self.planes != nodes::planes_for(slab.grid(), slab.owned()) {
            return slab;
        }
        match Nodes::new(slab.grid(), self.planes.clone(), &self.lanes) {
            Ok(field) => slab.with_nodes(field),
            Err(_) => slab,
        }
    }
}
