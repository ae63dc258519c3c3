//! The size a compressed DICOM frame's own stream declares, read before dicom-rs decodes it:
//! a JPEG or JPEG 2000 decoder allocates for the width and height in its stream's header,
//! which a few bytes can set to anything, whatever the image's `Rows` and `Columns` say.
//!
//! An RLE Lossless frame is read here too: dicom-rs indexes its decoded segments by the
//! image's size without checking that they hold it, and reads its header without checking
//! its length.
//!
//! Invariant: a fragment that starts a JPEG (SOI, `FF D8`) or JPEG 2000 codestream (SOC and
//! SIZ, `FF 4F FF 51`) is passed only when its header is whole and declares the image's
//! Columns × Rows; an RLE frame only when its header is whole and each segment the image's
//! samples need lies in the fragment and unpacks to at least Columns × Rows bytes. Other
//! fragments (continuations, deflate) are not this module's: their decoders size their
//! output from the image's attributes, which the reader has capped.

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
    /// An RLE frame whose header or segments cannot give the image.
    Rle {
        /// The fragment, counted from 0.
        fragment: usize,
        /// What is wrong with it.
        why: String,
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
            FrameError::Rle { fragment, ref why } => {
                write!(f, "pixel data fragment {fragment}: RLE frame {why}")
            }
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

/// Check every fragment of RLE Lossless pixel data (one a frame) against the image's
/// `columns` × `rows`: its 64-byte header declares at least `segments` segments (one per byte
/// of a sample), and each of the first `segments` lies in the fragment (from its offset to the
/// next, the last to the fragment's end) and unpacks whole, as PackBits, to at least a byte
/// per pixel.
pub fn check_rle<'a>(
    fragments: impl IntoIterator<Item = &'a [u8]>,
    columns: u32,
    rows: u32,
    segments: usize,
) -> Result<(), FrameError> {
    let pixels = u64::from(columns) * u64::from(rows);
    for (fragment, bytes) in fragments.into_iter().enumerate() {
        let refuse = |why: String| Err(FrameError::Rle { fragment, why });
        let word = |i: usize| {
            let w = bytes.get(4 * i..4 * i + 4)?;
            Some(u32::from_le_bytes([w[0], w[1], w[2], w[3]]) as usize)
        };
        let (Some(declared), true) = (word(0), bytes.len() >= 64) else {
            return refuse(format!(
                "of {} bytes, short of its 64-byte header",
                bytes.len()
            ));
        };
        if !(segments..=15).contains(&declared) {
            return refuse(format!(
                "declares {declared} segments; the image's samples need {segments} (at most 15)"
            ));
        }
        for segment in 0..segments {
            let start = word(1 + segment).unwrap_or(0);
            let end = match segment + 1 < declared {
                true => word(2 + segment).unwrap_or(0),
                false => bytes.len(),
            };
            let Some(packed) = bytes.get(start..end).filter(|_| start >= 64) else {
                return refuse(format!(
                    "segment {segment} at bytes {start}..{end}: outside the fragment's {} bytes after its header",
                    bytes.len()
                ));
            };
            match unpacked_len(packed) {
                Some(n) if n >= pixels => {}
                Some(n) => {
                    return refuse(format!(
                    "segment {segment} unpacks to {n} bytes; Columns × Rows are {columns} × {rows}"
                ))
                }
                None => return refuse(format!("segment {segment} breaks off in a run")),
            }
        }
    }
    Ok(())
}

/// The bytes a PackBits segment unpacks to, `None` where a run breaks off at its end: a
/// header `h` of 0 to 127 copies the `h + 1` bytes after it, −127 to −1 repeats the byte after
/// it `1 − h` times, −128 does nothing.
fn unpacked_len(packed: &[u8]) -> Option<u64> {
    let (mut i, mut n) = (0, 0u64);
    while let Some(&h) = packed.get(i) {
        match h as i8 {
            h @ 0.. => {
                let run = h as usize + 1;
                packed.get(i + 1..i + 1 + run)?;
                (i, n) = (i + 1 + run, n + run as u64);
            }
            -128 => i += 1,
            h => {
                packed.get(i + 1)?;
                (i, n) = (i + 2, n + (1 - i64::from(h)) as u64);
            }
        }
    }
    Some(n)
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

    /// An RLE frame of `segments` segments, each `packed`, behind the 64-byte header.
    fn rle(segments: &[Vec<u8>]) -> Vec<u8> {
        let mut header = [0u32; 16];
        header[0] = segments.len() as u32;
        let mut at = 64;
        for (i, s) in segments.iter().enumerate() {
            header[1 + i] = at;
            at += s.len() as u32;
        }
        let mut b: Vec<u8> = header.iter().flat_map(|n| n.to_le_bytes()).collect();
        b.extend(segments.concat());
        b
    }

    #[test]
    fn an_rle_frame_passes_only_where_each_segment_unpacks_to_the_image() {
        // 6 × 4 pixels: 24 bytes a segment, as a literal run of 20 and a repeat of 4.
        let whole = [vec![19], vec![7; 20], vec![0xFD, 9]].concat();
        assert_eq!(unpacked_len(&whole), Some(24));
        let ok = rle(&[whole.clone(), whole.clone()]);
        assert_eq!(check_rle([&ok[..]], 6, 4, 2), Ok(()));
        // A no-op header between runs changes nothing.
        let noop = [vec![0x80], whole.clone()].concat();
        assert_eq!(
            check_rle([&rle(&[whole.clone(), noop])[..]], 6, 4, 2),
            Ok(())
        );
        let refused = |frame: &[u8], segments| match check_rle([frame], 6, 4, segments) {
            Err(FrameError::Rle { fragment: 0, why }) => why,
            other => panic!("{other:?}"),
        };
        // One pixel short: dicom-rs would index past the segment.
        let short = [vec![19], vec![7; 20], vec![0xFE, 9]].concat();
        let why = refused(&rle(&[whole.clone(), short]), 2);
        assert!(why.contains("segment 1 unpacks to 23 bytes"), "{why}");
        // A literal run past the segment's end, a repeat without its byte.
        for broken in [vec![19, 7, 7], vec![0xFD]] {
            let why = refused(&rle(&[whole.clone(), broken]), 2);
            assert!(why.contains("segment 1 breaks off"), "{why}");
        }
        // Fewer segments than the samples' bytes, a header cut short, an offset past the end.
        let why = refused(&rle(std::slice::from_ref(&whole)), 2);
        assert!(why.contains("declares 1 segments"), "{why}");
        let why = refused(&ok[..40], 2);
        assert!(why.contains("short of its 64-byte header"), "{why}");
        let mut past = ok.clone();
        past[8..12].copy_from_slice(&4000u32.to_le_bytes());
        let why = refused(&past, 2);
        // Segment 1's offset ends segment 0.
        assert!(
            why.contains("segment 0 at bytes 64..4000: outside"),
            "{why}"
        );
    }
}
