//! What is built once from one volume's samples, whatever the view: each slab's node field
//! ([`crate::memory::nodes`]) and its value ranges ([`crate::memory::ranges`]), and the
//! least and greatest value of the planes a process holds, kept by the
//! planes they cover and shared by every view, orbit frame and bench repetition that reads them.
//!
//! Invariant: each structure is a pure function of the samples of the planes it is kept
//! by, so one built before serves every later slab with those planes; and holding one or
//! not changes no pixel.

use crate::memory::nodes::NodeField;
use crate::memory::ranges::SlabRanges;
use std::any::Any;
use std::fmt;
use std::ops::Range;
use std::sync::{Arc, Mutex, PoisonError};
use voxcube_kernel::volume::nodes;
use voxcube_kernel::volume::sample::Sample;
use voxcube_kernel::volume::slab::Slab;

/// A built structure, its type erased so that one volume's shelf holds any kind's.
type Erased = Arc<dyn Any + Send + Sync>;

/// Each structure built, with the planes it covers.
type Shelf = Mutex<Vec<(Range<u32>, Erased)>>;

/// The structures built from one volume so far, by the planes they cover. Cloning shares
/// them.
#[derive(Clone, Default)]
pub struct Built {
    shelf: Arc<Shelf>,
}

impl Built {
    /// The node field `slab` (of this volume) reads where its node is to `hold` one
    /// (`crate::memory::storage::holds_node_field`), built on up to `threads` OS threads the first
    /// time; none where it holds none.
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
        self.get_or_build(planes, |_| true, || NodeField::build(slab, threads))
    }

    /// The value ranges of `slab`'s stored planes (of this volume), with its cells' where
    /// `cells` asks for them, built on up to `threads` OS threads the first time they are
    /// asked for.
    pub fn ranges<T: Sample + Sync>(
        &self,
        slab: &Slab<'_, T>,
        cells: bool,
        threads: usize,
    ) -> Arc<SlabRanges<T>> {
        self.get_or_build(
            slab.stored(),
            |built: &SlabRanges<T>| built.holds_cells() || !cells,
            || SlabRanges::build(slab, cells, threads),
        )
    }

    /// A summary of the values of the planes `planes` of this volume (their range):
    /// `summary`'s the first time one of its type is asked for.
    pub fn summary<V: Any + Send + Sync + Copy>(
        &self,
        planes: Range<u32>,
        summary: impl FnOnce() -> V,
    ) -> V {
        *self.get_or_build(planes, |_| true, summary)
    }

    /// The structure of type `V` kept for `planes` that `serves`, else `build`'s, kept in its
    /// place. Built under the lock: the nodes of a machine that want the same planes wait for
    /// one build instead of each building it.
    fn get_or_build<V: Any + Send + Sync>(
        &self,
        planes: Range<u32>,
        serves: impl Fn(&V) -> bool,
        build: impl FnOnce() -> V,
    ) -> Arc<V> {
        let mut shelf = self.shelf.lock().unwrap_or_else(PoisonError::into_inner);
        let mut kept = shelf
            .iter_mut()
            .filter(|(p, _)| *p == planes)
            .find_map(|(_, built)| {
                let typed = Arc::clone(built).downcast::<V>().ok()?;
                Some((built, typed))
            });
        match &mut kept {
            Some((_, typed)) if serves(typed) => return Arc::clone(typed),
            _ => {}
        }
        let built = Arc::new(build());
        match kept {
            Some((place, _)) => *place = Arc::clone(&built) as Erased,
            None => shelf.push((planes, Arc::clone(&built) as Erased)),
        }
        built
    }
}

impl fmt::Debug for Built {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let built = self.shelf.lock().map_or(0, |b| b.len());
        write!(f, "Built({built} structures)")
    }
}

/// Every shelf is equal: what a volume has built says nothing about what it is.
impl PartialEq for Built {
    fn eq(&self, _: &Built) -> bool {
        true
    }
}
