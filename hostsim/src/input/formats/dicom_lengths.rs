//! A DICOM file's element headers, walked before dicom-rs reads it: every value length a
//! header declares must fit in the bytes that follow it in the file, so that no header can
//! make the reader allocate more than the file holds.
//!
//! Invariants: only headers are read (tag, VR, length), never a value, so the walk takes
//! constant memory whatever the file declares; it steps into every sequence and item (their
//! elements are checked too), takes every element of undefined length but pixel data for a
//! sequence of data sets whatever its VR, as dicom-rs reads it, and switches to implicit VR inside a sequence of unknown VR
//! (`UN` of undefined length, PS3.5 §6.2.2), restoring the syntax at its delimiter. A data
//! set in a deflated transfer syntax is not walked: its lengths are those of the inflated
//! stream, which dicom-rs does not read here anyway.

use dicom_core::dictionary::{DataDictionary, DataDictionaryEntry, VirtualVr};
use dicom_core::{Tag, VR};
use dicom_dictionary_std::StandardDataDictionary;
use std::io::{BufReader, Read, Seek};
use std::path::Path;

/// A value length meaning "until its delimiter".
const UNDEFINED: u32 = 0xFFFF_FFFF;

/// How the elements being walked are encoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Syntax {
    Implicit,
    Explicit { big_endian: bool },
}

impl Syntax {
    /// The data set's syntax for transfer syntax `uid`; `None` for a deflated one.
    fn of(uid: &str) -> Option<Syntax> {
        match uid.trim_end_matches(['\0', ' ']) {
            "1.2.840.10008.1.2" => Some(Syntax::Implicit),
            "1.2.840.10008.1.2.2" => Some(Syntax::Explicit { big_endian: true }),
            "1.2.840.10008.1.2.1.99" | "1.2.840.10008.1.2.4.95" => None,
            // Every other syntax (native or encapsulated) is explicit VR little endian.
            _ => Some(Syntax::Explicit { big_endian: false }),
        }
    }
}

/// VRs whose explicit header holds a 2-byte length (PS3.5 Table 7.1-2). Every other VR, and
/// a VR that is none (read as `UN`, as dicom-rs reads it), has two reserved bytes and a
/// 4-byte length.
const SHORT_VRS: [VR; 21] = [
    VR::AE,
    VR::AS,
    VR::AT,
    VR::CS,
    VR::DA,
    VR::DS,
    VR::DT,
    VR::FL,
    VR::FD,
    VR::IS,
    VR::LO,
    VR::LT,
    VR::PN,
    VR::SH,
    VR::SL,
    VR::SS,
    VR::ST,
    VR::TM,
    VR::UI,
    VR::UL,
    VR::US,
];

/// Why a file's headers cannot be trusted.
#[derive(Debug, thiserror::Error)]
pub enum LengthError {
    /// Reading the file failed.
    #[error("{0}")]
    Io(#[from] std::io::Error),
    /// A header declares more bytes than the file holds after it.
    #[error(
        "element ({group:04X},{element:04X}) at byte {offset} declares {declared} bytes, but only {left} follow it in the file"
    )]
    TooLong {
        /// The element's tag.
        group: u16,
        /// The element's tag.
        element: u16,
        /// Where its header starts.
        offset: u64,
        /// The length it declares.
        declared: u64,
        /// The bytes after its header.
        left: u64,
    },
    /// A header declares a length that is no whole number of its VR's values: dicom-rs
    /// reads the whole values and counts the rest read, so what follows is read out of step.
    #[error(
        "element ({group:04X},{element:04X}) at byte {offset} declares {declared} bytes of {vr}, no whole number of its {size}-byte values"
    )]
    Misfit {
        /// The element's tag.
        group: u16,
        /// The element's tag.
        element: u16,
        /// Where its header starts.
        offset: u64,
        /// Its VR.
        vr: VR,
        /// The length it declares.
        declared: u32,
        /// The bytes of one value.
        size: u32,
    },
    /// The file ends inside a header.
    #[error("the file ends inside an element header at byte {offset}")]
    CutHeader {
        /// Where the header starts.
        offset: u64,
    },
}

/// Check every element header of the DICOM file at `path`: a Part 10 file (preamble, `DICM`,
/// meta group) when `part10`, else a bare data set in implicit VR little endian.
pub fn check(path: &Path, part10: bool) -> Result<(), LengthError> {
    let file = std::fs::File::open(path)?;
    let len = file.metadata()?.len();
    let mut walk = Walk {
        reader: BufReader::new(file),
        pos: 0,
        len,
    };
    if !part10 {
        return walk.elements(Syntax::Implicit, None).map(drop);
    }
    walk.skip(132)?;
    // The meta group is explicit VR little endian, and names the data set's syntax. dicom-rs
    // reads it as its group length (0002,0000) says: whole elements until that many bytes are
    // read, whatever their group; the data set starts after them. Without a group length it
    // refuses the file before reading a value.
    // Its header is read as dicom-rs reads it: the tag and a length of 4, whatever the VR.
    let head = walk.bytes::<8>(132)?;
    let vr = VR::from_binary([head[4], head[5]]).unwrap_or(VR::UN);
    let length = match SHORT_VRS.contains(&vr) {
        true => u32::from(u16::from_le_bytes([head[6], head[7]])),
        false => u32::from_le_bytes(walk.bytes::<4>(132)?),
    };
    if head[..4] != [0x02, 0x00, 0x00, 0x00] || length != 4 {
        return Ok(());
    }
    let group_length = u32::from_le_bytes(walk.bytes::<4>(132)?);
    let meta_end = walk.pos + u64::from(group_length);
    let uid = walk.elements(Syntax::Explicit { big_endian: false }, Some(meta_end))?;
    match Syntax::of(&uid) {
        Some(syntax) => walk.elements(syntax, None).map(drop),
        None => Ok(()),
    }
}

/// An element of undefined length being walked, with the syntax around it.
#[derive(Clone, Copy, Debug)]
enum Open {
    /// A sequence: its items hold elements.
    Sequence(Syntax),
    /// Encapsulated pixel data: its items are fragments of bytes.
    Fragments(Syntax),
}

impl Open {
    fn syntax(self) -> Syntax {
        match self {
            Open::Sequence(s) | Open::Fragments(s) => s,
        }
    }
}

/// A walk over a file's element headers.
struct Walk<R> {
    reader: R,
    /// The byte the reader is at.
    pos: u64,
    /// The file's length.
    len: u64,
}

impl<R: Read + Seek> Walk<R> {
    fn skip(&mut self, n: u64) -> Result<(), LengthError> {
        let step = i64::try_from(n).map_err(|_| std::io::Error::other("skip too far"))?;
        self.reader.seek_relative(step)?;
        self.pos += n;
        Ok(())
    }

    fn bytes<const N: usize>(&mut self, offset: u64) -> Result<[u8; N], LengthError> {
        let mut b = [0u8; N];
        self.reader.read_exact(&mut b).map_err(|e| match e.kind() {
            std::io::ErrorKind::UnexpectedEof => LengthError::CutHeader { offset },
            _ => LengthError::Io(e),
        })?;
        self.pos += N as u64;
        Ok(b)
    }

    /// Walk elements in `syntax` to the end of the file; with `meta_end`, the meta group's
    /// (whole elements until the byte `meta_end` is reached), and give the transfer syntax
    /// UID it names (empty where it names none).
    fn elements(
        &mut self,
        mut syntax: Syntax,
        meta_end: Option<u64>,
    ) -> Result<String, LengthError> {
        let meta = meta_end.is_some();
        let mut uid = String::new();
        // What each open element of undefined length holds, and the syntax to restore at
        // its delimiter.
        let mut open: Vec<Open> = Vec::new();
        while self.pos < self.len {
            let offset = self.pos;
            let big = syntax == Syntax::Explicit { big_endian: true };
            let u16_of = |b: [u8; 2]| match big {
                true => u16::from_be_bytes(b),
                false => u16::from_le_bytes(b),
            };
            let u32_of = |b: [u8; 4]| match big {
                true => u32::from_be_bytes(b),
                false => u32::from_le_bytes(b),
            };
            if meta_end.is_some_and(|end| offset >= end) {
                return Ok(uid);
            }
            let head = self.bytes::<8>(offset)?;
            let tag = Tag(u16_of([head[0], head[1]]), u16_of([head[2], head[3]]));
            let rest = [head[4], head[5], head[6], head[7]];
            let (vr, length) = match syntax {
                // Items and delimiters carry a 4-byte length and no VR in every syntax.
                _ if tag.group() == 0xFFFE => (None, u32_of(rest)),
                Syntax::Implicit => (implicit_vr(tag), u32_of(rest)),
                Syntax::Explicit { .. } => {
                    let vr = VR::from_binary([head[4], head[5]]).unwrap_or(VR::UN);
                    match SHORT_VRS.contains(&vr) {
                        true => (Some(vr), u32::from(u16_of([head[6], head[7]]))),
                        false => (Some(vr), u32_of(self.bytes::<4>(offset)?)),
                    }
                }
            };
            if let Some(size) = vr.and_then(value_size) {
                if length != UNDEFINED && length % size != 0 {
                    return Err(LengthError::Misfit {
                        group: tag.group(),
                        element: tag.element(),
                        offset,
                        vr: vr.unwrap_or(VR::UN),
                        declared: length,
                        size,
                    });
                }
            }
            // Every length is checked, a delimiter's too: dicom-rs may take a delimiter's
            // length for a fragment's and allocate it.
            let left = self.len - self.pos;
            if length != UNDEFINED && u64::from(length) > left {
                return Err(LengthError::TooLong {
                    group: tag.group(),
                    element: tag.element(),
                    offset,
                    declared: u64::from(length),
                    left,
                });
            }
            let in_fragments = matches!(open.last(), Some(Open::Fragments(_)));
            match (tag, length) {
                // A sequence's end: its syntax back.
                (Tag(0xFFFE, 0xE0DD), _) => {
                    if let Some(outer) = open.pop() {
                        syntax = outer.syntax();
                    }
                    continue;
                }
                // An item's start or end, a fragment of encapsulated pixel data, or another
                // element of group FFFE.
                (Tag(0xFFFE, _), _) => {}
                // Undefined length: encapsulated pixel data, whose fragments follow; any other
                // element a sequence, whose items follow (in implicit VR where its VR is
                // unknown), whatever its VR, as dicom-rs reads them.
                (_, UNDEFINED) => {
                    open.push(match tag == Tag(0x7FE0, 0x0010) {
                        true => Open::Fragments(syntax),
                        false => Open::Sequence(syntax),
                    });
                    if vr == Some(VR::UN) {
                        syntax = Syntax::Implicit;
                    }
                }
                _ => {}
            }
            if length == UNDEFINED {
                continue;
            }
            let declared = u64::from(length);
            // A sequence's or an item's elements follow its header; a fragment is bytes, and
            // so is the value of any other tag of group FFFE, an element as dicom-rs reads it.
            let item = tag == Tag(0xFFFE, 0xE000) || tag == Tag(0xFFFE, 0xE00D);
            let container = (item && !in_fragments) || vr == Some(VR::SQ);
            // A UID is at most 64 bytes.
            let transfer_syntax = meta && tag == Tag(0x0002, 0x0010) && declared <= 64;
            match (container, transfer_syntax) {
                (true, _) => {}
                (false, true) => {
                    let mut value = [0u8; 64];
                    let value = &mut value[..declared as usize];
                    self.reader.read_exact(value)?;
                    self.pos += declared;
                    uid = String::from_utf8_lossy(value).into_owned();
                }
                (false, false) => self.skip(declared)?,
            }
        }
        Ok(uid)
    }
}

/// The bytes of one value of `vr`, where dicom-rs reads its values as numbers of that size.
fn value_size(vr: VR) -> Option<u32> {
    match vr {
        VR::US | VR::OW | VR::SS => Some(2),
        VR::AT | VR::FL | VR::OF | VR::SL | VR::UL | VR::OL => Some(4),
        VR::FD | VR::OD | VR::SV | VR::UV | VR::OV => Some(8),
        _ => None,
    }
}

/// The VR the standard dictionary gives `tag` (its sequences matter: their elements are
/// walked); `None` for a private or unknown tag, whose value is bytes to dicom-rs.
fn implicit_vr(tag: Tag) -> Option<VR> {
    match StandardDataDictionary.by_tag(tag)?.vr() {
        VirtualVr::Exact(vr) => Some(vr),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An explicit VR little endian Part 10 file holding data set `dataset`.
    fn part10(dataset: &[u8]) -> Vec<u8> {
        let uid = b"1.2.840.10008.1.2.1\0";
        let mut meta = Vec::new();
        meta.extend_from_slice(&[0x02, 0x00, 0x10, 0x00, b'U', b'I']);
        meta.extend_from_slice(&(uid.len() as u16).to_le_bytes());
        meta.extend_from_slice(uid);
        let mut file = vec![0u8; 128];
        file.extend_from_slice(b"DICM");
        file.extend_from_slice(&[0x02, 0x00, 0x00, 0x00, b'U', b'L', 4, 0]);
        file.extend_from_slice(&(meta.len() as u32).to_le_bytes());
        file.extend_from_slice(&meta);
        file.extend_from_slice(dataset);
        file
    }

    fn long(tag: (u16, u16), vr: &[u8; 2], length: u32) -> Vec<u8> {
        let mut h = Vec::new();
        h.extend_from_slice(&tag.0.to_le_bytes());
        h.extend_from_slice(&tag.1.to_le_bytes());
        h.extend_from_slice(vr);
        h.extend_from_slice(&[0, 0]);
        h.extend_from_slice(&length.to_le_bytes());
        h
    }

    /// An explicit VR element header with a 2-byte length.
    fn short(tag: (u16, u16), vr: &[u8; 2], length: u16) -> Vec<u8> {
        let mut h = Vec::new();
        h.extend_from_slice(&tag.0.to_le_bytes());
        h.extend_from_slice(&tag.1.to_le_bytes());
        h.extend_from_slice(vr);
        h.extend_from_slice(&length.to_le_bytes());
        h
    }

    fn item(length: u32) -> Vec<u8> {
        let mut h = vec![0xFE, 0xFF, 0x00, 0xE0];
        h.extend_from_slice(&length.to_le_bytes());
        h
    }

    fn checked(bytes: &[u8]) -> Result<(), LengthError> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.dcm");
        std::fs::write(&path, bytes).unwrap();
        check(&path, true)
    }

    fn too_long(result: Result<(), LengthError>) -> Option<(u16, u16, u64)> {
        match result {
            Err(LengthError::TooLong {
                group,
                element,
                declared,
                ..
            }) => Some((group, element, declared)),
            _ => None,
        }
    }

    #[test]
    fn lengths_that_fit_pass_and_one_that_does_not_is_named() {
        let mut ok = long((0x0010, 0x0010), b"UT", 4);
        ok.extend_from_slice(b"abcd");
        assert!(checked(&part10(&ok)).is_ok());
        let mut lie = long((0x0010, 0x0010), b"UT", 0xFFFF_FFF0);
        lie.extend_from_slice(b"abcd");
        assert_eq!(
            too_long(checked(&part10(&lie))),
            Some((0x0010, 0x0010, 0xFFFF_FFF0))
        );
    }

    #[test]
    fn an_element_inside_a_sequence_of_defined_length_is_checked() {
        let inner = long((0x0010, 0x0021), b"OB", 0xFFFF_FF00);
        let mut items = item(inner.len() as u32);
        items.extend_from_slice(&inner);
        let mut sq = long((0x0008, 0x1140), b"SQ", items.len() as u32);
        sq.extend_from_slice(&items);
        assert_eq!(
            too_long(checked(&part10(&sq))),
            Some((0x0010, 0x0021, 0xFFFF_FF00))
        );
    }

    #[test]
    fn a_sequence_of_unknown_vr_is_walked_in_implicit_vr_to_its_delimiter() {
        // UN of undefined length: an item of undefined length whose element (implicit VR)
        // declares 4 GB.
        let mut un = long((0x0009, 0x1010), b"UN", UNDEFINED);
        un.extend_from_slice(&item(UNDEFINED));
        un.extend_from_slice(&[0x09, 0x00, 0x11, 0x10]);
        un.extend_from_slice(&0xFFFF_FF00u32.to_le_bytes());
        assert_eq!(
            too_long(checked(&part10(&un))),
            Some((0x0009, 0x1011, 0xFFFF_FF00))
        );
        // The same sequence well formed, then an explicit element after its delimiter: the
        // syntax comes back.
        let mut good = long((0x0009, 0x1010), b"UN", UNDEFINED);
        good.extend_from_slice(&item(UNDEFINED));
        good.extend_from_slice(&[0x09, 0x00, 0x11, 0x10, 2, 0, 0, 0, b'a', b'b']);
        good.extend_from_slice(&[0xFE, 0xFF, 0x0D, 0xE0, 0, 0, 0, 0]);
        good.extend_from_slice(&[0xFE, 0xFF, 0xDD, 0xE0, 0, 0, 0, 0]);
        good.extend_from_slice(&[0x10, 0x00, 0x10, 0x00, b'P', b'N', 2, 0, b'a', b'b']);
        assert!(checked(&part10(&good)).is_ok());
        // Negative control: the explicit element after the delimiter lying about its length
        // is found, so the walk did read it in explicit VR.
        let n = good.len();
        good[n - 4] = 200;
        assert_eq!(
            too_long(checked(&part10(&good))),
            Some((0x0010, 0x0010, 200))
        );
    }

    #[test]
    fn fragments_of_encapsulated_pixel_data_are_bytes_not_elements() {
        // A fragment whose bytes would read as an element declaring 4 GB.
        let mut px = long((0x7FE0, 0x0010), b"OB", UNDEFINED);
        px.extend_from_slice(&item(0));
        px.extend_from_slice(&item(8));
        px.extend_from_slice(&[0x10, 0x00, 0x10, 0x00, 0xFF, 0xFF, 0xFF, 0x7F]);
        px.extend_from_slice(&[0xFE, 0xFF, 0xDD, 0xE0, 0, 0, 0, 0]);
        assert!(checked(&part10(&px)).is_ok());
        // A fragment declaring more than the file holds is still found.
        let n = px.len();
        px[n - 17] = 0x7F;
        assert_eq!(
            too_long(checked(&part10(&px))),
            Some((0xFFFE, 0xE000, 0x7F00_0008))
        );
    }

    #[test]
    fn any_other_element_of_undefined_length_is_a_sequence_of_data_sets() {
        // An OB of undefined length that is not pixel data: dicom-rs reads its items as data
        // sets, whose elements (here one declaring 4 GB) it allocates for. The coverage-guided
        // fuzzer found a Part 10 slice whose pixel data tag, damaged, did so with 825 MB.
        let mut ob = long((0x7FE0, 0x00BD), b"OB", UNDEFINED);
        ob.extend_from_slice(&item(12));
        ob.extend_from_slice(&long((0x0010, 0x0010), b"UT", 0xFFFF_FF00));
        ob.extend_from_slice(&[0xFE, 0xFF, 0xDD, 0xE0, 0, 0, 0, 0]);
        assert_eq!(
            too_long(checked(&part10(&ob))),
            Some((0x0010, 0x0010, 0xFFFF_FF00))
        );
        // The same bytes under the pixel data tag are a fragment: bytes, not elements.
        ob[..4].copy_from_slice(&[0xE0, 0x7F, 0x10, 0x00]);
        assert!(checked(&part10(&ob)).is_ok());
    }

    #[test]
    fn a_length_that_is_no_whole_number_of_values_is_refused() {
        // An SL of 2 bytes: dicom-rs reads no value and reads on two bytes early, where a
        // value's text can read as a length (the coverage-guided fuzzer found one read as
        // 540 MB). Four bytes are one value.
        let mut sl = short((0x0028, 0x0102), b"SL", 2);
        sl.extend_from_slice(&[0, 0]);
        assert!(matches!(
            checked(&part10(&sl)),
            Err(LengthError::Misfit {
                group: 0x0028,
                element: 0x0102,
                declared: 2,
                size: 4,
                ..
            })
        ));
        let mut sl = short((0x0028, 0x0102), b"SL", 4);
        sl.extend_from_slice(&[0, 0, 0, 0]);
        assert!(checked(&part10(&sl)).is_ok());
    }

    #[test]
    fn a_tag_of_group_fffe_that_is_no_item_or_delimiter_is_an_element() {
        // A bare data set: (FFFE,59FF) with one byte of value, then an element declaring
        // 4 GB (the coverage-guided fuzzer's 24-byte file, which dicom-rs read for 7 s in
        // 4 GB): read as an item's start, the one byte put the walk out of step.
        let mut bare = vec![0xFE, 0xFF, 0xFF, 0x59, 1, 0, 0, 0, 0];
        bare.extend_from_slice(&[0x00, 0x00, 0x01, 0x00, 0, 0, 0, 0xFE]);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bare");
        std::fs::write(&path, &bare).unwrap();
        assert_eq!(
            too_long(check(&path, false)),
            Some((0x0000, 0x0001, 0xFE00_0000))
        );
    }

    #[test]
    fn a_delimiter_declaring_more_than_the_file_holds_is_refused() {
        // Encapsulated pixel data whose sequence delimiter declares 512 MB (the
        // coverage-guided fuzzer's file, for which dicom-rs allocated that much).
        let mut px = long((0x7FE0, 0x0010), b"OB", UNDEFINED);
        px.extend_from_slice(&item(0));
        px.extend_from_slice(&item(2));
        px.extend_from_slice(&[1, 2]);
        px.extend_from_slice(&[0xFE, 0xFF, 0xDD, 0xE0, 0, 0, 0, 0x20]);
        assert_eq!(
            too_long(checked(&part10(&px))),
            Some((0xFFFE, 0xE0DD, 0x2000_0000))
        );
        let n = px.len();
        px[n - 1] = 0;
        assert!(checked(&part10(&px)).is_ok());
    }

    #[test]
    fn the_meta_group_is_walked_by_its_group_length_whatever_its_vr() {
        // A group length written as FL (dicom-rs reads its 4 bytes all the same), then a
        // meta element of unknown VR declaring 2.9 GB (the coverage-guided fuzzer's 307-byte
        // file, for which dicom-rs allocated that much).
        let mut file = part10(&[]);
        file[136..138].copy_from_slice(b"FL");
        assert!(checked(&file).is_ok());
        let mut lie = vec![0x02, 0x00, 0x13, 0x00, b'U', 0, 0, 0];
        lie.extend_from_slice(&0xAE49_3231u32.to_le_bytes());
        let group = u32::from_le_bytes([file[140], file[141], file[142], file[143]]);
        file[140..144].copy_from_slice(&(group + lie.len() as u32).to_le_bytes());
        file.extend_from_slice(&lie);
        assert_eq!(
            too_long(checked(&file)),
            Some((0x0002, 0x0013, 0xAE49_3231))
        );
    }

    #[test]
    fn a_file_cut_inside_a_header_is_refused() {
        let mut cut = long((0x0010, 0x0010), b"UT", 0);
        cut.truncate(7);
        assert!(matches!(
            checked(&part10(&cut)),
            Err(LengthError::CutHeader { .. })
        ));
    }
}
