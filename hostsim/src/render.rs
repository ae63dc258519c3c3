//! Rendering one view of a loaded dataset on one node that holds the whole volume.
//!
//! Invariant: every pixel is traced by the kernel's in-process tracer; a non-finite colour is
//! counted (`nan_pixels`, which tests require to be zero) before it is made a defined pixel.

use crate::dataset::{Volume, VolumeData};
use std::time::{Duration, Instant};
use voxcube_kernel::counters::Counters;
use voxcube_kernel::pixel::rgba8;
use voxcube_kernel::sample::Sample;
use voxcube_kernel::slab::{Slab, SlabError};
use voxcube_kernel::trace::trace_pixel;
use voxcube_kernel::view::View;

/// A rendered image and what it cost.
#[derive(Clone, Debug)]
pub struct Rendered {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// RGBA8, row-major, row 0 at the top.
    pub pixels: Vec<[u8; 4]>,
    /// Work done.
    pub counters: Counters,
    /// Pixels whose traced colour was not finite (must be zero).
    pub nan_pixels: u64,
    /// Wall-clock time of the trace.
    pub wall: Duration,
}

impl Rendered {
    /// The pixels as one RGBA8 byte buffer.
    pub fn bytes(&self) -> Vec<u8> {
        self.pixels.iter().flatten().copied().collect()
    }
}

/// Render `view` of `volume` on one node.
pub fn render(volume: &Volume, view: &View) -> Result<Rendered, SlabError> {
    match &volume.data {
        VolumeData::U8(d) => render_typed(volume, d, view),
        VolumeData::U16(d) => render_typed(volume, d, view),
        VolumeData::F32(d) => render_typed(volume, d, view),
    }
}

fn render_typed<T: Sample>(
    volume: &Volume,
    data: &[T],
    view: &View,
) -> Result<Rendered, SlabError> {
    let slab = Slab::whole(volume.grid, data)?;
    let start = Instant::now();
    let mut counters = Counters::default();
    let mut nan_pixels = 0;
    let n = view.pixel_count();
    let mut pixels = Vec::with_capacity(n as usize);
    for pixel in 0..n {
        let c = trace_pixel(view, &slab, pixel as u32, &mut counters);
        nan_pixels += u64::from(!c.is_finite());
        pixels.push(rgba8(c));
    }
    let spec = view.spec();
    Ok(Rendered {
        width: spec.width,
        height: spec.height,
        pixels,
        counters,
        nan_pixels,
        wall: start.elapsed(),
    })
}
