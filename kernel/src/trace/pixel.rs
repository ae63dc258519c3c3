//! Turning a traced colour into an RGBA8 pixel.
//!
//! Invariant: every input, NaN and infinities included, yields a defined pixel: channels are
//! clamped to `[0, 1]` and NaN maps to 0 (the tracer is built never to produce one; this is the
//! last line of defence, and tests check the tracer's colours before it too).

use glam::Vec3;

/// One channel in `[0, 1]` to `0..=255`, rounding to nearest; NaN to 0.
#[inline]
pub fn channel(v: f32) -> u8 {
    if !(v > 0.0) {
        return 0;
    }
    (v.min(1.0) * 255.0 + 0.5) as u8
}

/// An opaque RGBA8 pixel.
#[inline]
pub fn rgba8(c: Vec3) -> [u8; 4] {
    [channel(c.x), channel(c.y), channel(c.z), 255]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_input_is_a_defined_pixel() {
        assert_eq!(
            rgba8(Vec3::new(f32::NAN, f32::INFINITY, -1.0)),
            [0, 255, 0, 255]
        );
        assert_eq!(rgba8(Vec3::new(0.5, 1.0 / 255.0, 0.0)), [128, 1, 0, 255]);
    }
}
