//! DICOM volumes, read with dicom-rs (`dicom-object`, `dicom-pixeldata`): a folder of
//! single-frame slices of one series, or one multi-frame file.
//!
//! Slices are ordered by their position along the slice normal (`ImagePositionPatient` ·
//! (row × column direction of `ImageOrientationPatient`)), never by file name; without
//! positions, by `InstanceNumber`. The spacing is `PixelSpacing` in the plane and the
//! distance between consecutive slices across it (which must be even within 1%). Values are
//! `RescaleSlope`·v + `RescaleIntercept`. The orientation itself is not applied (index space).
//! Files that start neither with the `DICM` preamble nor like a bare data set in implicit VR
//! little endian (old files, before Part 10), and `DICOMDIR`, are passed over; two series in one folder
//! is an error, as are colour and palette-colour images, slices that are not parallel, uneven
//! or repeated slices (and two slices whose instance numbers skip one), and differing slice
//! sizes. Every element length a file declares is checked against the file before dicom-rs
//! reads it ([`super::dicom_lengths`]), which would allocate what a header declares; the
//! samples an image declares against `--max-samples`, and a compressed frame's own size
//! against the image's ([`super::dicom_frames`]), before its pixel data is decoded.

use super::{LoadError, LoadErrorKind};
use crate::input::dataset::{to_plane_major, Volume, VolumeData};
use dicom_dictionary_std::tags;
use dicom_object::{open_file, DefaultDicomObject, Tag};
use dicom_pixeldata::{ConvertOptions, ModalityLutOption, PixelDecoder};
use std::path::{Path, PathBuf};
use voxcube_kernel::volume::grid::Grid;
use voxcube_kernel::Vec3;

fn header_err(msg: impl Into<String>) -> LoadErrorKind {
    LoadErrorKind::Header(msg.into())
}

/// One slice file, its header read.
struct Slice {
    path: PathBuf,
    object: DefaultDicomObject,
    series: String,
    rows: u32,
    columns: u32,
    /// NumberOfFrames, 1 where absent.
    frames: u64,
    position: Option<[f64; 3]>,
    normal: Option<[f64; 3]>,
    instance: Option<i64>,
    pixel_spacing: Option<[f64; 2]>,
    rescale: (f64, f64),
}

fn floats(object: &DefaultDicomObject, tag: Tag) -> Option<Vec<f64>> {
    object
        .element_opt(tag)
        .ok()
        .flatten()
        .and_then(|e| e.to_multi_float64().ok())
}

/// Element `tag` as text without its padding; empty where it is missing.
fn text(object: &DefaultDicomObject, tag: Tag) -> String {
    object
        .element_opt(tag)
        .ok()
        .flatten()
        .and_then(|e| e.to_str().ok())
        .map(|s| s.trim_end_matches('\0').trim().to_string())
        .unwrap_or_default()
}

fn int(object: &DefaultDicomObject, tag: Tag) -> Option<i64> {
    object
        .element_opt(tag)
        .ok()
        .flatten()
        .and_then(|e| e.to_int::<i64>().ok())
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// A DICOM file: Part 10 (a preamble, `DICM` and a file meta group), or an old file of a
/// bare data set in implicit VR little endian, given the meta group that syntax implies.
fn open(path: &Path) -> Result<DefaultDicomObject, String> {
    // dicom-rs allocates what a header declares before it reads the value: every declared
    // length is checked against the file first.
    let part10 = has_preamble(path);
    super::dicom_lengths::check(path, part10).map_err(|e| e.to_string())?;
    if part10 {
        return open_file(path).map_err(|e| e.to_string());
    }
    let ts = dicom_transfer_syntax_registry::entries::IMPLICIT_VR_LITTLE_ENDIAN.erased();
    let file = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let object =
        dicom_object::InMemDicomObject::read_dataset_with_ts(std::io::BufReader::new(file), &ts)
            .map_err(|e| e.to_string())?;
    // An old file may name no SOP class or instance: the meta group needs one of each.
    let meta = dicom_object::FileMetaTableBuilder::new()
        .transfer_syntax(ts.uid())
        .media_storage_sop_class_uid("1.2.840.10008.5.1.4.1.1.7")
        .media_storage_sop_instance_uid("2.25.0");
    object.with_meta(meta).map_err(|e| e.to_string())
}

/// Whether a file without the preamble begins like a bare data set in implicit VR little
/// endian: its first element in group 0x0008 (identification, where every image's data set
/// starts), with a length the file can hold.
fn is_bare_dataset(path: &Path) -> bool {
    use std::io::Read;
    let mut head = [0u8; 8];
    let read = std::fs::File::open(path).and_then(|mut f| f.read_exact(&mut head));
    let size = std::fs::metadata(path).map_or(0, |m| m.len());
    let length = u64::from(u32::from_le_bytes([head[4], head[5], head[6], head[7]]));
    read.is_ok() && head[..2] == [0x08, 0x00] && length + 8 <= size
}

fn read_slice(path: &Path) -> Result<Slice, LoadError> {
    let at = |k| LoadError::new(path, k);
    let object = open(path).map_err(|e| {
        at(header_err(format!(
            "not a readable DICOM file, truncated or malformed ({e})"
        )))
    })?;
    let rows =
        int(&object, tags::ROWS).ok_or_else(|| at(header_err("missing Rows (0028,0010)")))?;
    let columns =
        int(&object, tags::COLUMNS).ok_or_else(|| at(header_err("missing Columns (0028,0011)")))?;
    let photometric = text(&object, tags::PHOTOMETRIC_INTERPRETATION);
    if photometric == "PALETTE COLOR" {
        return Err(at(header_err(
            "PhotometricInterpretation (0028,0004) is PALETTE COLOR: the pixels are indices into a colour table; voxcube reads grey-scale images (MONOCHROME1 or MONOCHROME2)",
        )));
    }
    let spp = int(&object, tags::SAMPLES_PER_PIXEL).unwrap_or(1);
    if spp != 1 {
        return Err(at(header_err(format!(
            "SamplesPerPixel (0028,0002) is {spp}; voxcube reads grey-scale images (1)"
        ))));
    }
    let (rows, columns) = match (u32::try_from(rows), u32::try_from(columns)) {
        (Ok(r), Ok(c)) if r > 0 && c > 0 => (r, c),
        _ => {
            return Err(at(header_err(format!(
                "Rows {rows} × Columns {columns}: expected positive sizes"
            ))))
        }
    };
    // What the pixel data will decode to is checked before it is decoded: a compressed
    // image's few bytes can declare any size.
    let frames = match int(&object, tags::NUMBER_OF_FRAMES).unwrap_or(1) {
        f if f >= 1 => f as u64,
        f => {
            return Err(at(header_err(format!(
                "NumberOfFrames (0028,0008) is {f}; expected at least 1"
            ))))
        }
    };
    super::declared_samples(&[u64::from(columns), u64::from(rows), frames]).map_err(at)?;
    // A compressed frame's own header sizes what its decoder allocates.
    if let Some(fragments) = object
        .element(tags::PIXEL_DATA)
        .ok()
        .and_then(|e| e.value().fragments())
    {
        super::dicom_frames::check(fragments.iter().map(Vec::as_slice), columns, rows)
            .map_err(|e| at(header_err(e.to_string())))?;
        let syntax = object.meta().transfer_syntax().trim_end_matches('\0');
        if syntax == dicom_dictionary_std::uids::RLE_LOSSLESS {
            // A segment per byte of the one sample a pixel holds.
            let bytes = match int(&object, tags::BITS_ALLOCATED) {
                Some(8) => 1,
                _ => 2,
            };
            let fragments = fragments.iter().map(Vec::as_slice);
            super::dicom_frames::check_rle(fragments, columns, rows, bytes)
                .map_err(|e| at(header_err(e.to_string())))?;
        }
    }
    if let Some(bits) = int(&object, tags::BITS_ALLOCATED).filter(|&b| b > 16) {
        return Err(at(header_err(format!(
            "BitsAllocated (0028,0100) is {bits}; voxcube reads 8- and 16-bit images"
        ))));
    }
    let series = text(&object, tags::SERIES_INSTANCE_UID);
    let position =
        floats(&object, tags::IMAGE_POSITION_PATIENT).and_then(|v| <[f64; 3]>::try_from(v).ok());
    let normal = floats(&object, tags::IMAGE_ORIENTATION_PATIENT)
        .and_then(|v| <[f64; 6]>::try_from(v).ok())
        .map(|o| cross([o[0], o[1], o[2]], [o[3], o[4], o[5]]));
    let pixel_spacing =
        floats(&object, tags::PIXEL_SPACING).and_then(|v| <[f64; 2]>::try_from(v).ok());
    let slope = floats(&object, tags::RESCALE_SLOPE)
        .and_then(|v| v.first().copied())
        .unwrap_or(1.0);
    let intercept = floats(&object, tags::RESCALE_INTERCEPT)
        .and_then(|v| v.first().copied())
        .unwrap_or(0.0);
    Ok(Slice {
        path: path.to_path_buf(),
        instance: int(&object, tags::INSTANCE_NUMBER),
        object,
        series,
        rows,
        columns,
        frames,
        position,
        normal,
        pixel_spacing,
        rescale: (slope, intercept),
    })
}

/// Whether a file starts like DICOM Part 10 (a 128-byte preamble, then `DICM`).
fn has_preamble(path: &Path) -> bool {
    use std::io::Read;
    let mut head = [0u8; 132];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok()
        && &head[128..] == b"DICM"
}

/// The slice files of a folder, or the one file.
fn slice_files(path: &Path) -> Result<Vec<PathBuf>, LoadError> {
    if !path.is_dir() {
        return Ok(vec![path.to_path_buf()]);
    }
    let entries = std::fs::read_dir(path).map_err(|e| LoadError::new(path, e))?;
    let mut files = Vec::new();
    for entry in entries {
        let entry = entry.map_err(|e| LoadError::new(path, e))?;
        let p = entry.path();
        let name = entry.file_name().to_string_lossy().to_string();
        let dicom = has_preamble(&p) || is_bare_dataset(&p);
        if p.is_file() && !name.starts_with('.') && name != "DICOMDIR" && dicom {
            files.push(p);
        }
    }
    if files.is_empty() {
        return Err(LoadError::new(
            path,
            header_err(
                "the folder holds no DICOM files (none starts with the DICM preamble or a bare data set)",
            ),
        ));
    }
    files.sort();
    Ok(files)
}

/// Order the slices along the normal and find the distance between them.
fn order(slices: &mut [Slice], folder: &Path) -> Result<f64, LoadError> {
    let at = |k| LoadError::new(folder, k);
    if slices.len() == 1 {
        return Ok(0.0);
    }
    let normal = slices.iter().find_map(|s| s.normal);
    let located = normal.filter(|_| slices.iter().all(|s| s.position.is_some()));
    let Some(n) = located else {
        if slices.iter().any(|s| s.instance.is_none()) {
            return Err(at(header_err(
                "slices have neither ImagePositionPatient with ImageOrientationPatient nor InstanceNumber to order them by",
            )));
        }
        slices.sort_by_key(|s| s.instance);
        return Ok(0.0);
    };
    // Every slice in the first one's plane orientation: a sagittal and a coronal image of one
    // series are no volume.
    let unit = |v: [f64; 3]| {
        let length = dot(v, v).sqrt();
        v.map(|c| c / length)
    };
    let first = unit(n);
    if let Some(tilted) = slices.iter().find(|s| {
        s.normal
            .is_some_and(|m| dot(unit(m), first).abs() < 1.0 - 1e-4)
    }) {
        return Err(at(header_err(format!(
            "{} is not parallel to {}: its ImageOrientationPatient (0020,0037) differs; a folder must hold one stack of parallel slices",
            tilted.path.display(),
            slices[0].path.display()
        ))));
    }
    let depth = |s: &Slice| s.position.map_or(0.0, |p| dot(p, n));
    slices.sort_by(|a, b| depth(a).total_cmp(&depth(b)));
    // Two slices show no uneven spacing; their instance numbers show a slice missing between.
    if let [a, b] = &slices[..] {
        if let (Some(i), Some(j)) = (a.instance, b.instance) {
            if (i - j).abs() > 1 {
                return Err(at(header_err(format!(
                    "{} and {} are the only slices but their InstanceNumbers (0020,0013) are {i} and {j}: a missing slice?",
                    a.path.display(),
                    b.path.display()
                ))));
            }
        }
    }
    let gaps: Vec<f64> = slices
        .windows(2)
        .map(|w| depth(&w[1]) - depth(&w[0]))
        .collect();
    let mut sorted = gaps.clone();
    sorted.sort_by(f64::total_cmp);
    let gap = sorted[sorted.len() / 2];
    for (i, g) in gaps.iter().enumerate() {
        if *g <= gap * 1e-3 {
            return Err(at(header_err(format!(
                "{} and {} lie at the same position; a folder must hold one volume",
                slices[i].path.display(),
                slices[i + 1].path.display()
            ))));
        }
        if (g - gap).abs() > 0.01 * gap {
            return Err(at(header_err(format!(
                "slices are unevenly spaced: {} and {} are {g:.4} apart, the others {gap:.4} (a missing slice?)",
                slices[i].path.display(),
                slices[i + 1].path.display()
            ))));
        }
    }
    Ok(gap)
}

/// Load a DICOM series (a folder) or one multi-frame file. `spacing` overrides the files'.
pub fn load(path: &Path, spacing: Option<Vec3>) -> Result<Volume, LoadError> {
    let files = slice_files(path)?;
    let mut slices = files
        .iter()
        .map(|f| read_slice(f))
        .collect::<Result<Vec<_>, _>>()?;
    let first_series = slices[0].series.clone();
    if let Some(other) = slices.iter().find(|s| s.series != first_series) {
        return Err(LoadError::new(
            &other.path,
            header_err(format!(
                "SeriesInstanceUID {} differs from {}'s {first_series}: the folder holds more than one series",
                other.series,
                slices[0].path.display()
            )),
        ));
    }
    let (rows, columns) = (slices[0].rows, slices[0].columns);
    if let Some(s) = slices
        .iter()
        .find(|s| (s.rows, s.columns) != (rows, columns))
    {
        return Err(LoadError::new(
            &s.path,
            header_err(format!(
                "Rows × Columns {} × {} differ from the first slice's {rows} × {columns}",
                s.rows, s.columns
            )),
        ));
    }
    let gap = order(&mut slices, path)?;
    // The whole stack, before any slice is decoded.
    let depth: u64 = slices.iter().map(|s| s.frames).sum();
    super::declared_samples(&[u64::from(columns), u64::from(rows), depth])
        .map_err(|k| LoadError::new(path, k))?;
    // Decode every slice's stored values; rescaling is applied below, once, in f64.
    let raw = ConvertOptions::new().with_modality_lut(ModalityLutOption::None);
    let mut frames: Vec<(Vec<i32>, (f64, f64), bool)> = Vec::with_capacity(slices.len());
    for s in &slices {
        let at = |k| LoadError::new(&s.path, k);
        let pixels = s
            .object
            .decode_pixel_data()
            .map_err(|e| at(header_err(format!("pixel data: {e}"))))?;
        if pixels.bits_allocated() > 16 {
            return Err(at(header_err(format!(
                "BitsAllocated (0028,0100) is {}; voxcube reads 8- and 16-bit images",
                pixels.bits_allocated()
            ))));
        }
        let signed = pixels.pixel_representation() == dicom_pixeldata::PixelRepresentation::Signed;
        let values: Vec<i32> = pixels
            .to_vec_with_options(&raw)
            .map_err(|e| at(header_err(format!("pixel data: {e}"))))?;
        let expected = rows as usize * columns as usize * pixels.number_of_frames() as usize;
        if values.len() != expected {
            return Err(at(LoadErrorKind::Truncated {
                expected: expected as u64,
                actual: values.len() as u64,
            }));
        }
        frames.push((values, s.rescale, signed));
    }
    let depth =
        frames.iter().map(|f| f.0.len()).sum::<usize>() / (rows as usize * columns as usize);
    let dims = [columns, rows, depth as u32];
    let first = &slices[0];
    let at = |k| LoadError::new(path, k);
    let spacing = match spacing {
        Some(s) => s,
        None => {
            let [row, col] = first.pixel_spacing.unwrap_or([1.0, 1.0]);
            let z = if gap > 0.0 {
                gap
            } else {
                floats(&first.object, tags::SPACING_BETWEEN_SLICES)
                    .or_else(|| floats(&first.object, tags::SLICE_THICKNESS))
                    .and_then(|v| v.first().copied())
                    .unwrap_or(1.0)
            };
            Vec3::new(col as f32, row as f32, z as f32)
        }
    };
    if !(spacing.is_finite() && spacing.min_element() > 0.0) {
        return Err(at(header_err(format!(
            "spacing {spacing} (PixelSpacing and the slice distance): expected three spacings > 0"
        ))));
    }
    let grid = Grid::new(dims, spacing).map_err(|e| at(e.into()))?;
    let identity = frames.iter().all(|f| f.1 == (1.0, 0.0) && !f.2);
    let data = if identity {
        let v: Vec<u16> = frames
            .iter()
            .flat_map(|f| f.0.iter().map(|&x| x.clamp(0, 65535) as u16))
            .collect();
        VolumeData::U16(to_plane_major(&v, dims))
    } else {
        let rescaled = || {
            frames.iter().flat_map(|(v, (slope, inter), _)| {
                v.iter().map(move |&x| f64::from(x) * slope + inter)
            })
        };
        // A CT series' Hounsfield units (signed values, or unsigned with an intercept of
        // -1024) are whole numbers a 16-bit signed sample holds: half a float's bytes, the
        // same values.
        if rescaled().all(super::whole_i16) {
            let v: Vec<i16> = rescaled().map(|y| y as i16).collect();
            return Ok(Volume::new(grid, VolumeData::I16(to_plane_major(&v, dims))));
        }
        let v: Vec<f32> = rescaled().map(|y| y as f32).collect();
        if v.iter().any(|x| !x.is_finite()) {
            return Err(at(header_err(
                "RescaleSlope/RescaleIntercept give values beyond 32-bit floats",
            )));
        }
        VolumeData::F32(to_plane_major(&v, dims))
    };
    let data = match data {
        VolumeData::U16(v) if v.iter().all(|&x| x <= 255) && frames_are_8bit(&slices) => {
            VolumeData::U8(v.into_iter().map(|x| x as u8).collect())
        }
        other => other,
    };
    Ok(Volume::new(grid, data))
}

fn frames_are_8bit(slices: &[Slice]) -> bool {
    slices
        .iter()
        .all(|s| int(&s.object, tags::BITS_ALLOCATED) == Some(8))
}
