//! Empty-space skipping: the structures that prove samples empty for one view, so the marcher
//! passes over them, and that change no pixel.
//!
//! The marcher's face is [`blocks::Blocks`] (min/max blocks, which carry the view's maps)
//! and [`scan`] (a ray's next samples against the cell masks). The rest are the maps the
//! host builds once per view and node: [`leaps`] (chessboard distances between blocks per
//! octant of ray directions), [`cells`] (each block's cells the view cannot skip, a
//! classification of the [`cell_ranges`] built once per volume), [`cell_leaps`] (distances
//! between those cells, also laid out as the nodes and read through [`node_leaps`]),
//! [`depths`] (each pixel's ray parameter before its first cell that shows, read through
//! [`bounds`]); [`octant`] keys the maps that look ahead of a ray, and [`minmax`] builds the
//! blocks from a slab's samples.
//!
//! Invariant: a structure only ever claims a sample empty when the view's classification of
//! every value the sample could take is empty; skipping is a bound, never an approximation.

pub mod blocks;
pub mod bounds;
pub mod cell_leaps;
pub mod cell_ranges;
pub mod cells;
pub mod depths;
pub mod leaps;
pub mod minmax;
pub mod node_leaps;
pub mod octant;
pub mod scan;
