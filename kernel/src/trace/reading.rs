//! How a composited loop reads a sample: its value, and its gradient where the read gives
//! it, from the node field's lanes or the slab's own values; each way reads a whole cell of
//! the interior ([`Reading::read_cell`]) as it reads anywhere ([`Reading::read`]).
//!
//! Invariant: a way of reading gives, in every bit and counted alike, the same value and
//! gradient at a point whether the general step or a run through the interior reads it.

use crate::counters::Counters;
use crate::trace::view::View;
use crate::volume::cells::Cells;
use crate::volume::field::{self, Site};
use crate::volume::lanes::Lanes as NodeLanes;
use crate::volume::nodes;
use crate::volume::sample::Sample;
use crate::volume::slab::Slab;
use glam::Vec3;

/// How a sample is read: its value, and the gradient where the read gives it.
pub(crate) trait Reading<T: Sample>: Copy {
    /// What the storage the read uses holds per node.
    type Node: Copy;

    /// That storage as whole cells, for the runs through the slab's interior; `None` where
    /// the slab holds none.
    fn cells<'a>(slab: &Slab<'a, T>) -> Option<Cells<'a, Self::Node>>;

    /// The sample at `at`: its index-space point, and the site where it reads the grid.
    fn read(
        self,
        view: &View,
        slab: &Slab<'_, T>,
        at: (Vec3, &Site),
        counters: &mut Counters,
    ) -> (f32, Option<Vec3>);

    /// The sample at fractions `frac` of a cell-model site whose cell's nodes are `cell`, in
    /// the interior: in every bit, and counted alike, what [`Reading::read`] gives there.
    fn read_cell(
        self,
        slab: &Slab<'_, T>,
        cell: [Self::Node; 8],
        frac: Vec3,
        counters: &mut Counters,
    ) -> (f32, Option<Vec3>);
}

/// The node field's lanes: value and gradient in one interpolation.
#[derive(Clone, Copy)]
pub(crate) struct Lanes;

impl<T: Sample> Reading<T> for Lanes {
    type Node = T::Node;

    #[inline(always)]
    fn cells<'a>(slab: &Slab<'a, T>) -> Option<Cells<'a, T::Node>> {
        slab.nodes().map(|nodes| nodes.cells())
    }

    #[inline(always)]
    fn read(
        self,
        _: &View,
        slab: &Slab<'_, T>,
        (_, site): (Vec3, &Site),
        counters: &mut Counters,
    ) -> (f32, Option<Vec3>) {
        // Counted as the value's read; the gradient where the shading takes it.
        counters.interpolations += 1;
        let (v, g) = nodes::lanes_at(slab, site, counters);
        (v, Some(g))
    }

    #[inline(always)]
    fn read_cell(
        self,
        slab: &Slab<'_, T>,
        cell: [T::Node; 8],
        frac: Vec3,
        counters: &mut Counters,
    ) -> (f32, Option<Vec3>) {
        counters.interpolations += 1;
        let (v, g) =
            nodes::lerp_lanes(cell.map(NodeLanes::unpack), frac, slab.grid().inv_spacing());
        (v, Some(g))
    }
}

/// The slab's value; the shading computes a gradient where it needs one.
#[derive(Clone, Copy)]
pub(crate) struct Value;

impl<T: Sample> Reading<T> for Value {
    type Node = T;

    #[inline(always)]
    fn cells<'a>(slab: &Slab<'a, T>) -> Option<Cells<'a, T>> {
        Some(slab.cells())
    }

    #[inline(always)]
    fn read(
        self,
        view: &View,
        slab: &Slab<'_, T>,
        (_, site): (Vec3, &Site),
        counters: &mut Counters,
    ) -> (f32, Option<Vec3>) {
        (
            field::value_at(slab, view.spec().model, site, counters),
            None,
        )
    }

    #[inline(always)]
    fn read_cell(
        self,
        _: &Slab<'_, T>,
        cell: [T; 8],
        frac: Vec3,
        counters: &mut Counters,
    ) -> (f32, Option<Vec3>) {
        counters.interpolations += 1;
        (field::lerp_cell(cell, frac), None)
    }
}

/// The exact tier's reading where the node field is held: at points in the grid
/// ([`nodes::in_grid`]: every point of the interior), the field's lanes, value and gradient in
/// one interpolation, as [`Lanes`]; elsewhere the slab's value, and the shading takes its six
/// reads. The same bits either way (the value lane is the trilinear value, and in the grid the
/// lanes' gradient is the tier's own), but one read of storage, the one a loop asks for
/// ahead, where the value and gradient apart would read the slab and the field.
#[derive(Clone, Copy)]
pub(crate) struct GridLanes;

impl<T: Sample> Reading<T> for GridLanes {
    type Node = T::Node;

    #[inline(always)]
    fn cells<'a>(slab: &Slab<'a, T>) -> Option<Cells<'a, T::Node>> {
        <Lanes as Reading<T>>::cells(slab)
    }

    #[inline(always)]
    fn read(
        self,
        view: &View,
        slab: &Slab<'_, T>,
        at: (Vec3, &Site),
        counters: &mut Counters,
    ) -> (f32, Option<Vec3>) {
        if nodes::in_grid(slab.grid(), at.0) {
            Lanes.read(view, slab, at, counters)
        } else {
            Value.read(view, slab, at, counters)
        }
    }

    #[inline(always)]
    fn read_cell(
        self,
        slab: &Slab<'_, T>,
        cell: [T::Node; 8],
        frac: Vec3,
        counters: &mut Counters,
    ) -> (f32, Option<Vec3>) {
        Lanes.read_cell(slab, cell, frac, counters)
    }
}
