//! The size a compressed DICOM frame's own stream declares, read before dicom-rs decodes it:
//! a JPEG or JPEG 2000 decoder allocates for the width and height in its stream's header,
//! which a few bytes can set to anything, whatever the image's `Rows` and `Columns` say.
//!
//! Invariant: a fragment that starts a JPEG (SOI, `FF D8`) or JPEG 2000 codestream (SOC and
//! SIZ, `FF 4F FF 51`) is passed only when its header is whole and declares the image's
//! Columns × Rows; other fragments (continuations, RLE, deflate) are not this module's: their
//! decoders size their output from the image's attributes, which the reader has capped.

use std::fmt;

/// Why a frame's stream is refused.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FrameError {
    /// The stream declares another size than the image.
    Size {
        /// The fragment, counted from 0.
        fragment: usize,
        /// Its codec.
        codec: &'static str,
        /// What it declares: columns, rows.
        declared: (u32, u32),
        /// The image's Columns × Rows.
        image: (u32, u32),
    },
    /// The stream ends, or its markers break off, before its size.
    Header {
        /// The fragment, counted from 0.
        fragment: usize,
        /// Its codec.
        codec: &'static str,
    },
}

impl fmt::Display for FrameError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            FrameError::Size {
                fragment,
                codec,
                declared,
                image,
            } => write!(
                f,
                "pixel data fragment {fragment}: its {codec} stream declares {} × {}, the image's Columns × Rows are {} × {}",
                declared.0, declared.1, image.0, image.1
            ),
            FrameError::Header { fragment, codec } => write!(
                f,
                "pixel data fragment {fragment}: its {codec} stream ends or breaks off before its frame header"
            ),
        }
    }
}

impl std::error::Error for FrameError {}

/// Check every fragment of encapsulated pixel data that starts a JPEG or JPEG 2000 stream
/// against the image's `columns` × `rows`.
pub fn check<'a>(
    fragments: impl IntoIterator<Item = &'a [u8]>,
    columns: u32,
    rows: u32,
) -> Result<(), FrameError> {
    for (fragment, bytes) in fragments.into_iter().enumerate() {
        let (codec, size) = match bytes {
            [0xFF, 0xD8, ..] => ("JPEG", jpeg_size(bytes)),
            [0xFF, 0x4F, 0xFF, 0x51, ..] => ("JPEG 2000", j2k_size(bytes)),
            _ => continue,
        };
        match size {
            None => return Err(FrameError::Header { fragment, codec }),
            Some(declared) if declared != (columns, rows) => {
                return Err(FrameError::Size {
                    fragment,
                    codec,
                    declared,
                    image: (columns, rows),
                })
            }
            Some(_) => {}
        }
    }
    Ok(())
}

/// The width and height of a JPEG stream's frame header (any SOF, JPEG-LS's SOF55 too),
/// walking its marker segments from SOI; `None` where the stream ends or a scan starts first.
fn jpeg_size(bytes: &[u8]) -> Option<(u32, u32)> {
    let u16_at = |i: usize| Some(u16::from_be_bytes([*bytes.get(i)?, *bytes.get(i + 1)?]));
    let mut i = 2;
    loop {
        if *bytes.get(i)? != 0xFF {
            return None;
        }
        // Fill bytes before a marker.
        while *bytes.get(i + 1)? == 0xFF {
            i += 1;
        }
        let marker = *bytes.get(i + 1)?;
        match marker {
            // Standalone markers: no length.
            0x01 | 0xD0..=0xD7 => i += 2,
            // A scan or the end before any frame header.
            0xDA | 0xD9 => return None,
            // SOF0–SOF15 but DHT (C4), JPG (C8) and DAC (CC); SOF55 of JPEG-LS.
            0xC0..=0xCF | 0xF7 if !matches!(marker, 0xC4 | 0xC8 | 0xCC) => {
                // Length, precision, then lines (height) and samples per line (width).
                let height = u16_at(i + 5)?;
                let width = u16_at(i + 7)?;
                return Some((u32::from(width), u32::from(height)));
            }
            _ => i += 2 + usize::from(u16_at(i + 2)?),
        }
    }
}

/// The width and height of a JPEG 2000 codestream from its SIZ segment, which follows SOC:
/// the image area's far corner less its offset.
fn j2k_size(bytes: &[u8]) -> Option<(u32, u32)> {
    let u32_at = |i: usize| {
        let b = bytes.get(i..i + 4)?;
        Some(u32::from_be_bytes([b[0], b[1], b[2], b[3]]))
    };
    // SOC (2), SIZ marker (2), Lsiz (2), Rsiz (2), then Xsiz, Ysiz, XOsiz, YOsiz.
    let (x, y, x0, y0) = (u32_at(8)?, u32_at(12)?, u32_at(16)?, u32_at(20)?);
    Some((x.checked_sub(x0)?, y.checked_sub(y0)?))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A JPEG stream's start: SOI, an APP0 segment, a DQT-like segment, then SOF `sof` of
    /// `width` × `height`, one component.
    fn jpeg(sof: u8, width: u16, height: u16) -> Vec<u8> {
        let mut b = vec![0xFF, 0xD8, 0xFF, 0xE0, 0x00, 0x04, 0x4A, 0x46];
        b.extend([0xFF, 0xFF, 0xDB, 0x00, 0x03, 0x00]);
        b.extend([0xFF, sof, 0x00, 0x0B, 0x08]);
        b.extend(height.to_be_bytes());
        b.extend(width.to_be_bytes());
        b.extend([0x01, 0x01, 0x11, 0x00]);
        b.extend([0xFF, 0xDA, 0x00, 0x02, 0xFF, 0xD9]);
        b
    }

    fn j2k(width: u32, height: u32, x0: u32, y0: u32) -> Vec<u8> {
        let mut b = vec![0xFF, 0x4F, 0xFF, 0x51, 0x00, 0x29, 0x00, 0x00];
        for v in [width + x0, height + y0, x0, y0] {
            b.extend(v.to_be_bytes());
        }
        b
    }

    #[test]
    fn a_frame_header_is_read_through_segments_and_fill_bytes() {
        assert_eq!(jpeg_size(&jpeg(0xC0, 24, 20)), Some((24, 20)));
        assert_eq!(
            jpeg_size(&jpeg(0xC3, 512, 300)),
            Some((512, 300)),
            "lossless"
        );
        assert_eq!(jpeg_size(&jpeg(0xF7, 7, 9)), Some((7, 9)), "JPEG-LS");
        // A DHT marker (C4) is a segment, not a frame header.
        let mut with_dht = jpeg(0xC0, 24, 20);
        with_dht.splice(2..2, [0xFF, 0xC4, 0x00, 0x03, 0x00]);
        assert_eq!(jpeg_size(&with_dht), Some((24, 20)));
        assert_eq!(j2k_size(&j2k(24, 20, 3, 5)), Some((24, 20)));
    }

    #[test]
    fn streams_that_end_or_scan_before_their_frame_header_give_no_size() {
        let whole = jpeg(0xC0, 24, 20);
        for cut in 2..17 {
            assert_eq!(jpeg_size(&whole[..cut]), None, "cut at {cut}");
        }
        assert_eq!(jpeg_size(&[0xFF, 0xD8, 0xFF, 0xDA, 0x00, 0x02]), None);
        assert_eq!(jpeg_size(&[0xFF, 0xD8, 0x00]), None);
        assert_eq!(j2k_size(&j2k(24, 20, 0, 0)[..20]), None);
        // An offset past the far corner.
        assert_eq!(
            j2k_size(
                &j2k(24, 20, 3, 5)[..16]
                    .iter()
                    .chain(&[0xFF; 8])
                    .copied()
                    .collect::<Vec<_>>()
            ),
            None
        );
    }

    #[test]
    fn every_jpeg_fragment_must_declare_the_image_s_size() {
        let good = jpeg(0xC0, 24, 20);
        let continuation = [0x12u8, 0x34, 0x56];
        assert_eq!(check([&good[..], &continuation[..]], 24, 20), Ok(()));
        let big = jpeg(0xC0, 30_000, 30_000);
        assert_eq!(
            check([&good[..], &big[..]], 24, 20),
            Err(FrameError::Size {
                fragment: 1,
                codec: "JPEG",
                declared: (30_000, 30_000),
                image: (24, 20),
            })
        );
        let message = check([&big[..]], 24, 20).unwrap_err().to_string();
        assert!(
            message.contains("JPEG stream declares 30000 × 30000")
                && message.contains("Columns × Rows are 24 × 20"),
            "{message}"
        );
        assert_eq!(
            check([&good[..9]], 24, 20),
            Err(FrameError::Header {
                fragment: 0,
                codec: "JPEG"
            })
        );
        assert!(check([&j2k(24, 21, 0, 0)[..]], 24, 20).is_err());
        assert_eq!(check([&j2k(24, 20, 0, 0)[..]], 24, 20), Ok(()));
    }
}
