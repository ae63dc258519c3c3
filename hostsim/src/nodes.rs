//! A node's copy of the fast tier's node field (`voxcube_kernel::volume::nodes`), and the
//! fields built from one volume: a field depends on the samples of a slab's planes alone, so
//! it is built once per volume and set of planes, and shared by every view, orbit frame and
//! repetition that reads one.
//!
//! Invariant: holding the field or not changes no pixel (the kernel computes the same lanes
//! on the fly), so a node that cannot hold it, or whose build fails, renders without it.

use crate::parts::{even_parts, run_parts, split_sizes, Part};
use std::any::Any;
use std::fmt;
use std::ops::Range;
use std::sync::{Arc, Mutex, PoisonError};
use voxcube_kernel::volume::lanes::{Lanes, Nodes};
use voxcube_kernel::volume::nodes;
use voxcube_kernel::volume::sample::Sample;
use voxcube_kernel::volume::slab::Slab;

/// A node field over a slab's planes, or none.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NodeField<N> {
    planes: Range<u32>,
    lanes: Vec<N>,
}

impl<N: Lanes> NodeField<N> {
    /// The field of `slab`'s planes ([`nodes::planes_for`]), built on up to `threads` OS
    /// threads in parts of planes (each node reads only the slab, so the parts are the same
    /// bits as one pass); none where the slab does not store the planes its nodes read.
    pub fn build<T: Sample<Node = N> + Sync>(slab: &Slab<'_, T>, threads: usize) -> NodeField<N> {
        let grid = slab.grid();
        let planes = nodes::planes_for(grid, slab.owned());
        let mut lanes = vec![N::default(); nodes::len_for(grid, slab.owned())];
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

/// A built field, its lane type erased so that one volume's cache holds any sample kind's.
type Built = Arc<dyn Any + Send + Sync>;

/// The fields built so far, each with the planes it holds.
type Shelf = Mutex<Vec<(Range<u32>, Built)>>;

/// The node fields built from one volume, by the planes they hold. Cloning shares them.
#[derive(Clone, Default)]
pub struct Fields {
    built: Arc<Shelf>,
}

impl Fields {
    /// The field `slab` (of this cache's volume) reads where its node is to `hold` one
    /// (`crate::storage::holds_node_field`): the one built for its planes before, else built
    /// now on up to `threads` OS threads and kept; none where it holds none.
    pub fn field<T: Sample + Sync>(
        &self,
        slab: &Slab<'_, T>,
        hold: bool,
        threads: usize,
    ) -> Arc<NodeField<T::Node>> {
        if !hold {
            return Arc::default();
        }
        let planes = nodes::planes_for(slab.grid(), slab.owned());
        // Built under the lock: the nodes of a machine that want the same planes wait for one
        // build instead of each building it.
        let mut built = self.built.lock().unwrap_or_else(PoisonError::into_inner);
        let found = built
            .iter()
            .filter(|(p, _)| *p == planes)
            .find_map(|(_, field)| Arc::clone(field).downcast::<NodeField<T::Node>>().ok());
        if let Some(field) = found {
            return field;
        }
        let field = Arc::new(NodeField::build(slab, threads));
        built.push((planes, Arc::clone(&field) as Built));
        field
    }
}

impl fmt::Debug for Fields {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let built = self.built.lock().map_or(0, |b| b.len());
        write!(f, "Fields({built} built)")
    }
}

/// Every cache is equal: what a volume has built says nothing about what it is.
impl PartialEq for Fields {
    fn eq(&self, _: &Fields) -> bool {
        true
    }
}
