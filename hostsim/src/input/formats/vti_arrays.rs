//! The base64 data arrays of a VTK XML image-data file, checked before `vtkio` decodes them.
//! `vtkio` allocates what a compressed array's block header declares, slices the text by the
//! sizes it claims, and reads no zlib block's Adler-32; so each array is walked here first:
//! its header against the extent it belongs to and against the text that holds it, each zlib
//! block inflated and checked (its Adler-32, its declared length), and the one field VTK and
//! `vtkio` read differently (a full last block, which VTK writes as size 0) mended in place.
//!
//! Invariant: a file passed on is the same length as the one read, differs from it at most
//! in those mended fields, and every base64 array in it decodes, as `vtkio` slices it, within
//! its text, to the bytes its extent, type and components declare, its zlib blocks to
//! checked streams; anything else is refused, naming the array.

use super::LoadErrorKind;
use base64::Engine;
use std::borrow::Cow;

/// `vtkio`'s own decoding: padded, trailing bits allowed.
const B64: base64::engine::GeneralPurpose = base64::engine::GeneralPurpose::new(
    &base64::alphabet::STANDARD,
    base64::engine::general_purpose::PAD.with_decode_allow_trailing_bits(true),
);

fn header_err(msg: impl Into<String>) -> LoadErrorKind {
    LoadErrorKind::Header(msg.into())
}

/// Characters of base64 that encode `n` bytes, as `vtkio` counts them.
fn to_b64(n: usize) -> Option<usize> {
    Some(n.checked_add(2)? / 3 * 4)
}

/// How the file's binary arrays are laid out (`<VTKFile>`'s attributes).
#[derive(Clone, Copy)]
struct Layout {
    /// Bytes of a header number (`header_type`).
    width: usize,
    big: bool,
    compressed: bool,
}

impl Layout {
    /// Header number `i` of `header`, or `None` past its end.
    fn number(&self, header: &[u8], i: usize) -> Option<u64> {
        let word = header.get(i * self.width..(i + 1) * self.width)?;
        let mut full = [0u8; 8];
        Some(if self.big {
            full[8 - self.width..].copy_from_slice(word);
            u64::from_be_bytes(full)
        } else {
            full[..self.width].copy_from_slice(word);
            u64::from_le_bytes(full)
        })
    }

    fn set_number(&self, header: &mut [u8], i: usize, n: u64) {
        let word = &mut header[i * self.width..(i + 1) * self.width];
        if self.big {
            word.copy_from_slice(&n.to_be_bytes()[8 - self.width..]);
        } else {
            word.copy_from_slice(&n.to_le_bytes()[..self.width]);
        }
    }
}

/// The text of a file, searched as the arrays' tags are found.
struct Text<'a>(&'a [u8]);

impl Text<'_> {
    fn find(&self, from: usize, what: &[u8]) -> Option<usize> {
        self.0
            .get(from..)?
            .windows(what.len())
            .position(|w| w == what)
            .map(|i| from + i)
    }

    /// The attribute `name="…"` of the tag that starts at `at`.
    fn attribute(&self, at: usize, name: &str) -> Option<&str> {
        let end = self.find(at, b">")?;
        let tag = std::str::from_utf8(&self.0[at..end]).ok()?;
        let key = format!(" {name}=\"");
        let start = tag.find(&key)? + key.len();
        tag[start..].split('"').next()
    }

    /// The bytes from `start` to the first `end` after it (or the file's end), without the
    /// white space around them: where they start, and how long they are.
    fn trimmed(&self, start: usize, end: &[u8]) -> (usize, usize) {
        let stop = self.find(start, end).unwrap_or(self.0.len());
        let body = &self.0[start.min(stop)..stop];
        let lead = body.len() - body.trim_ascii_start().len();
        (start + lead, body.trim_ascii().len())
    }
}

/// `bytes` with every base64 array checked, and mended where VTK wrote a full last block as
/// size 0; an error naming the array where one cannot be decoded as declared.
pub(super) fn checked(bytes: &[u8]) -> Result<Cow<'_, [u8]>, LoadErrorKind> {
    let text = Text(bytes);
    let Some(file) = text.find(0, b"<VTKFile") else {
        return Ok(Cow::Borrowed(bytes));
    };
    match text.attribute(file, "type") {
        Some("ImageData") | None => {}
        Some(other) => {
            return Err(header_err(format!(
                "VTKFile type {other}: voxcube reads image data (ImageData)"
            )))
        }
    }
    let compressed = match text.attribute(file, "compressor") {
        None | Some("") => false,
        Some("vtkZLibDataCompressor") => true,
        Some(other) => {
            return Err(header_err(format!(
                "compressor {other}: voxcube reads arrays compressed with zlib \
                 (vtkZLibDataCompressor) or not compressed"
            )))
        }
    };
    let width = match text.attribute(file, "header_type") {
        None | Some("UInt32") => 4,
        Some("UInt64") => 8,
        Some(other) => {
            return Err(header_err(format!(
                "header_type {other}: expected UInt32 or UInt64"
            )))
        }
    };
    let layout = Layout {
        width,
        big: text.attribute(file, "byte_order") == Some("BigEndian"),
        compressed,
    };
    let counts = Counts::of(&text)?;
    // Appended data in base64 (`vtkio` reads no raw appended data, and says so).
    let appended = text
        .find(0, b"<AppendedData")
        .filter(|&at| text.attribute(at, "encoding") == Some("base64"))
        .and_then(|at| Some(text.find(at, b"_")? + 1))
        .map(|start| text.trimmed(start, b"</AppendedData"));
    let mut out: Option<Vec<u8>> = None;
    let mut at = file;
    let mut index = 0;
    while let Some(array) = text.find(at + 1, b"<DataArray") {
        at = array;
        index += 1;
        let (start, len) = match text.attribute(array, "format") {
            Some("binary") => {
                let Some(open) = text.find(array, b">") else {
                    break;
                };
                text.trimmed(open + 1, b"</DataArray")
            }
            Some("appended") => {
                let Some((base, len)) = appended else {
                    continue;
                };
                let offset = text.attribute(array, "offset").unwrap_or("0");
                let offset = offset
                    .parse::<usize>()
                    .ok()
                    .filter(|&o| o <= len)
                    .ok_or_else(|| {
                        header_err(format!(
                            "{}: offset {offset} is not within the appended data ({len} characters)",
                            name(&text, array, index)
                        ))
                    })?;
                (base + offset, len - offset)
            }
            _ => {
                // ASCII: as many numbers as the extent and components make (`vtkio` drops an
                // array that has not, and the volume would be said to have none).
                let Some(open) = text.find(array, b">") else {
                    break;
                };
                // An array cut off is the XML parser's to report.
                if text.find(open, b"</DataArray").is_none() {
                    break;
                }
                let (start, len) = text.trimmed(open + 1, b"</DataArray");
                let values = bytes[start..start + len]
                    .split(u8::is_ascii_whitespace)
                    .filter(|v| !v.is_empty())
                    .count();
                let named = |e| named(e, &text, array, index);
                let (elements, _) = counts.elements(&text, array).map_err(named)?;
                if values as u64 != elements {
                    return Err(named(header_err(format!(
                        "{values} values; its extent and components make {elements}"
                    ))));
                }
                continue;
            }
        };
        let array_text = &bytes[start..start + len];
        let (elements, size) = counts
            .elements(&text, array)
            .map_err(|e| named(e, &text, array, index))?;
        // Checked by `elements` to fit.
        let expected = elements as usize * size;
        let in_error = |e: ArrayError| match e {
            ArrayError::Corrupt(e) => {
                LoadErrorKind::Corrupt(format!("{}: {e}", name(&text, array, index)))
            }
            ArrayError::Header(e) => header_err(format!("{}: {e}", name(&text, array, index))),
        };
        let inline = text.attribute(array, "format") == Some("binary");
        let mended = match layout.compressed {
            true => blocks(layout, array_text, expected).map_err(in_error)?,
            false => {
                plain(layout, array_text, expected, inline).map_err(in_error)?;
                None
            }
        };
        if let Some(header) = mended {
            let out = out.get_or_insert_with(|| bytes.to_vec());
            out[start..start + header.len()].copy_from_slice(&header);
        }
    }
    Ok(out.map_or(Cow::Borrowed(bytes), Cow::Owned))
}

/// A header error `e` said of the array whose tag starts at `array`.
fn named(e: LoadErrorKind, text: &Text<'_>, array: usize, index: usize) -> LoadErrorKind {
    match e {
        LoadErrorKind::Header(e) => header_err(format!("{}: {e}", name(text, array, index))),
        other => other,
    }
}

/// An array named for a message: its `Name`, or its place among the file's arrays.
fn name(text: &Text<'_>, array: usize, index: usize) -> String {
    match text.attribute(array, "Name") {
        Some(n) => format!("data array \"{n}\""),
        None => format!("data array {index}"),
    }
}

/// Why an array is refused.
enum ArrayError {
    Header(String),
    Corrupt(String),
}

/// The tuples an array holds, as `vtkio` counts them: the points of its piece's extent (the
/// whole extent where the piece gives none), or for cell data its cells.
struct Counts {
    whole: [u64; 3],
}

impl Counts {
    /// From `<ImageData WholeExtent="x0 x1 y0 y1 z0 z1">`, within the samples a volume may
    /// have, before anything is decoded for them.
    fn of(text: &Text<'_>) -> Result<Counts, LoadErrorKind> {
        let whole = text
            .find(0, b"<ImageData")
            .and_then(|at| text.attribute(at, "WholeExtent"))
            .ok_or_else(|| header_err("no ImageData WholeExtent: voxcube reads image data"))?;
        Ok(Counts {
            whole: extent_dims("WholeExtent", whole)?,
        })
    }

    /// The values the array whose tag starts at `array` holds (its tuples × components), and
    /// its type's size in bytes.
    fn elements(&self, text: &Text<'_>, array: usize) -> Result<(u64, usize), LoadErrorKind> {
        let size = match text.attribute(array, "type") {
            Some("Int8" | "UInt8") => 1,
            Some("Int16" | "UInt16") => 2,
            Some("Int32" | "UInt32" | "Float32") => 4,
            Some("Int64" | "UInt64" | "Float64") => 8,
            other => {
                return Err(header_err(format!(
                    "type {other:?}: expected a VTK scalar type"
                )))
            }
        };
        let components = text.attribute(array, "NumberOfComponents").unwrap_or("1");
        let components = components
            .parse::<u64>()
            .ok()
            .filter(|c| (1..=64).contains(c))
            .ok_or_else(|| {
                header_err(format!("NumberOfComponents {components}: expected 1 to 64"))
            })?;
        let before = &text.0[..array];
        let last = |tag: &[u8]| before.windows(tag.len()).rposition(|w| w == tag);
        let dims = match last(b"<Piece").and_then(|at| text.attribute(at, "Extent")) {
            Some(extent) => extent_dims("Piece Extent", extent)?,
            None => self.whole,
        };
        // Cell data is the last section opened before the array and not closed.
        let open = last(b"<CellData").filter(|&at| {
            // `<CellData/>` opens nothing.
            text.find(at, b">")
                .is_some_and(|end| text.0[end - 1] != b'/')
        });
        let tuples: u64 = match open > last(b"</CellData") {
            true => dims.iter().map(|d| d - 1).product(),
            false => dims.iter().product(),
        };
        let elements = tuples
            .checked_mul(components)
            .filter(|e| {
                e.checked_mul(size)
                    .is_some_and(|b| usize::try_from(b).is_ok())
            })
            .ok_or_else(|| header_err("more bytes than memory can address"))?;
        Ok((elements, size as usize))
    }
}

/// The nodes along each axis of an extent `"x0 x1 y0 y1 z0 z1"` (attribute `what`): six
/// integers as `vtkio` reads them (`i32`), each end at or past its start, its span within
/// `i32` (where `vtkio` counts it), and its samples within the cap.
fn extent_dims(what: &str, extent: &str) -> Result<[u64; 3], LoadErrorKind> {
    let refuse = || {
        header_err(format!(
            "{what} \"{extent}\": expected six integers, each axis's end at or past its start"
        ))
    };
    let e: Vec<i32> = extent
        .split_whitespace()
        .map(str::parse)
        .collect::<Result<_, _>>()
        .map_err(|_| refuse())?;
    let [x0, x1, y0, y1, z0, z1] = e[..] else {
        return Err(refuse());
    };
    let span = |a: i32, b: i32| {
        let n = i64::from(b) - i64::from(a) + 1;
        (1..=i64::from(i32::MAX)).contains(&n).then_some(n as u64)
    };
    let dims = [span(x0, x1), span(y0, y1), span(z0, z1)];
    let [Some(x), Some(y), Some(z)] = dims else {
        return Err(refuse());
    };
    super::declared_samples(&[x, y, z])?;
    Ok([x, y, z])
}

/// A zlib-compressed array, `[blocks][block size][last block size][compressed sizes…]` and
/// the blocks, each part in base64 of its own, as `vtkio` reads it: checked against the
/// `expected` bytes and the text, each block inflated to its declared length with its
/// Adler-32 checked. The header's text mended where the last block is written as size 0 (a
/// full one), `None` where it needs no mending.
fn blocks(layout: Layout, text: &[u8], expected: usize) -> Result<Option<Vec<u8>>, ArrayError> {
    let header = |m: String| ArrayError::Header(m);
    let short = || header(format!("its data ends early ({} characters)", text.len()));
    let w = layout.width;
    let decode = |t: &[u8]| {
        B64.decode(t)
            .map_err(|e| ArrayError::Corrupt(format!("base64: {e}")))
    };
    let first = text.get(..to_b64(w).ok_or_else(short)?).ok_or_else(short)?;
    let nb = layout.number(&decode(first)?, 0).ok_or_else(short)?;
    // A block has a size in the text: no more blocks than the text has room to size.
    if nb == 0 || nb > (text.len() / w) as u64 {
        return Err(header(format!("its header declares {nb} blocks")));
    }
    let nb = nb as usize;
    let full = (3 + nb) * w;
    let head_chars = to_b64(full).ok_or_else(short)?;
    let mut head = decode(text.get(..head_chars).ok_or_else(short)?)?;
    let number = |i| layout.number(&head, i).ok_or_else(short);
    let (nu, np) = (number(1)?, number(2)?);
    if nu == 0 || np > nu {
        return Err(header(format!(
            "block size {nu} and last block size {np}: expected a block size above 0 and a last block no larger"
        )));
    }
    let last = if np == 0 { nu } else { np };
    let total = (nb as u64 - 1)
        .checked_mul(nu)
        .and_then(|b| b.checked_add(last));
    if total != Some(expected as u64) {
        return Err(header(format!(
            "its blocks hold {} bytes; its extent, type and components make {expected}",
            total.map_or("more than 2^64".to_string(), |t| t.to_string())
        )));
    }
    let sizes = (0..nb)
        .map(|i| number(3 + i))
        .collect::<Result<Vec<_>, _>>()?;
    let packed = sizes
        .iter()
        .try_fold(0u64, |a, &s| a.checked_add(s))
        .and_then(|p| usize::try_from(p).ok())
        .ok_or_else(short)?;
    let data_chars = to_b64(packed).ok_or_else(short)?;
    let data = text
        .get(head_chars..head_chars.checked_add(data_chars).ok_or_else(short)?)
        .ok_or_else(short)?;
    let data = decode(data)?;
    if data.len() < packed {
        return Err(short());
    }
    let mut from = 0;
    for (i, &size) in sizes.iter().enumerate() {
        let block = &data[from..from + size as usize];
        from += size as usize;
        let want = if i + 1 == nb { last } else { nu };
        // One byte more than declared is asked for: a stream that gives exactly the declared
        // bytes has then reached its end, where its Adler-32 is checked.
        let mut stream = std::io::Read::take(flate2::read::ZlibDecoder::new(block), want + 1);
        let got = std::io::copy(&mut stream, &mut std::io::sink())
            .map_err(|e| ArrayError::Corrupt(format!("block {i}: {e}")))?;
        if got != want {
            return Err(ArrayError::Corrupt(format!(
                "block {i} inflates to {}{got} bytes, its header declares {want}",
                if got > want { "more than " } else { "" }
            )));
        }
    }
    if np != 0 {
        return Ok(None);
    }
    layout.set_number(&mut head, 2, nu);
    Ok(Some(B64.encode(&head).into_bytes()))
}

/// An array without compression, `[bytes][data]` in base64, as `vtkio` reads it: inline, the
/// whole text decoded at once; appended, the characters of the `expected` bytes and the
/// header. Its header's count must be what follows it, and that the `expected` bytes.
fn plain(layout: Layout, text: &[u8], expected: usize, inline: bool) -> Result<(), ArrayError> {
    let w = layout.width;
    let text = match inline {
        true => text,
        false => {
            let chars = expected.checked_add(w).and_then(to_b64);
            chars.and_then(|c| text.get(..c)).ok_or_else(|| {
                ArrayError::Header(format!("its data ends early ({} characters)", text.len()))
            })?
        }
    };
    let bytes = B64
        .decode(text)
        .map_err(|e| ArrayError::Header(format!("its base64 does not decode: {e}")))?;
    let declared = layout.number(&bytes, 0);
    let held = (bytes.len().saturating_sub(w)) as u64;
    // Appended text is decoded in whole groups of four characters: up to two bytes past
    // the data.
    let fits = match inline {
        true => declared == Some(held) && held == expected as u64,
        false => declared == Some(expected as u64) && held >= expected as u64,
    };
    if !fits {
        return Err(ArrayError::Header(format!(
            "its header declares {} bytes, {held} follow it; its extent, type and components make {expected}",
            declared.map_or("no".to_string(), |d| d.to_string())
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::{checked, B64};
    use base64::Engine;
    use std::io::Write;

    /// A file of one compressed array of 32 bytes in two full blocks of 16, its header's
    /// numbers `width` bytes wide in the byte order `big` says, the last block's size as
    /// `last` (VTK writes 0 for a full one).
    fn file(width: usize, big: bool, last: u64) -> (String, usize) {
        let word = |n: u64| -> Vec<u8> {
            match big {
                true => n.to_be_bytes()[8 - width..].to_vec(),
                false => n.to_le_bytes()[..width].to_vec(),
            }
        };
        let block = |b: u8| {
            let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::fast());
            e.write_all(&[b; 16]).expect("zlib");
            e.finish().expect("zlib")
        };
        let (a, b) = (block(1), block(2));
        let numbers = [2, 16, last, a.len() as u64, b.len() as u64];
        let header: Vec<u8> = numbers.into_iter().flat_map(word).collect();
        let text = format!(
            "<VTKFile type=\"ImageData\" byte_order=\"{}\" header_type=\"UInt{}\" compressor=\"vtkZLibDataCompressor\">\n<ImageData WholeExtent=\"0 3 0 3 0 1\">\n<DataArray type=\"UInt8\" format=\"binary\">\n  {}{}\n</DataArray>",
            if big { "BigEndian" } else { "LittleEndian" },
            width * 8,
            B64.encode(&header),
            B64.encode([a, b].concat())
        );
        let start = text.find("  ").expect("the array") + 2;
        (text, start)
    }

    #[test]
    fn an_empty_last_block_is_read_as_full_for_every_header_width_and_byte_order() {
        for (width, big) in [(4usize, false), (4, true), (8, false), (8, true)] {
            let (text, start) = file(width, big, 0);
            let mended = checked(text.as_bytes()).expect("a file VTK writes");
            let header = B64
                .decode(&mended[start..start + 4 * width])
                .expect("base64");
            let (full, _) = file(width, big, 16);
            let expected = B64
                .decode(&full.as_bytes()[start..start + 4 * width])
                .expect("base64");
            assert_eq!(header, expected, "UInt{} big {big}", width * 8);
            // Nothing else moved.
            assert_eq!(mended.len(), text.len());
            // A last block said as full is left as it is.
            assert!(matches!(
                checked(full.as_bytes()),
                Ok(std::borrow::Cow::Borrowed(_))
            ));
        }
    }

    #[test]
    fn a_last_block_larger_than_a_block_or_blocks_short_of_the_extent_are_refused() {
        let (text, _) = file(4, false, 17);
        let e = checked(text.as_bytes()).expect_err("17 > 16").to_string();
        assert!(e.contains("last block size 17"), "{e}");
        // Blocks of 8 said where the extent makes 32 bytes.
        let (text, start) = file(4, false, 0);
        let mut header = B64.decode(&text[start..start + 16]).expect("base64");
        header[4..8].copy_from_slice(&8u32.to_le_bytes());
        header[8..12].copy_from_slice(&8u32.to_le_bytes());
        let lying = [&text[..start], &B64.encode(&header), &text[start + 16..]].concat();
        let e = checked(lying.as_bytes()).expect_err("16 bytes").to_string();
        assert!(e.contains("its blocks hold 16 bytes"), "{e}");
    }
}
