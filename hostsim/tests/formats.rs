//! Every reader: the same volume written in every format loads to the same samples and
//! renders to the same pixels as the raw file, on one node and on a cluster; bad files get
//! an error that names the file and the field. The tests write every file themselves.

use dicom_core::{DataElement, PrimitiveValue, VR};
use dicom_dictionary_std::{tags, uids};
use dicom_object::{FileMetaTableBuilder, InMemDicomObject};
use std::io::Write;
use std::path::Path;
use std::process::Command;
use voxcube::input::scene::Scene;

const DIMS: [usize; 3] = [24, 20, 16];
const SPACING: [f32; 3] = [1.0, 1.0, 1.5];

/// A CT-like blob: air at -1000, a soft shell and a dense core (exact integers).
fn value(x: usize, y: usize, z: usize) -> i16 {
    let d2 = (x as i32 - 12).pow(2) + (y as i32 - 10).pow(2) + ((z as i32 - 8) * 3 / 2).pow(2);
    match d2 {
        0..=16 => 900 - 10 * d2 as i16,
        17..=64 => 60 + (64 - d2 as i16),
        _ => -1000,
    }
}

/// The samples in file order (X fastest).
fn samples() -> Vec<i16> {
    let [nx, ny, nz] = DIMS;
    let mut v = Vec::with_capacity(nx * ny * nz);
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                v.push(value(x, y, z));
            }
        }
    }
    v
}

fn le(v: &[i16]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn be(v: &[i16]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_be_bytes()).collect()
}

/// A NIfTI-1 single file: the 348-byte header (the fields the standard requires), four
/// bytes of extension flag, then the samples.
fn nifti(datatype: i16, bitpix: i16, slope: f32, inter: f32, data: &[u8]) -> Vec<u8> {
    let mut h = vec![0u8; 352];
    h[0..4].copy_from_slice(&348i32.to_le_bytes());
    let dim: [i16; 8] = [
        3,
        DIMS[0] as i16,
        DIMS[1] as i16,
        DIMS[2] as i16,
        1,
        1,
        1,
        1,
    ];
    for (i, d) in dim.iter().enumerate() {
        h[40 + 2 * i..42 + 2 * i].copy_from_slice(&d.to_le_bytes());
    }
    h[70..72].copy_from_slice(&datatype.to_le_bytes());
    h[72..74].copy_from_slice(&bitpix.to_le_bytes());
    let pixdim = [
        1.0f32, SPACING[0], SPACING[1], SPACING[2], 1.0, 1.0, 1.0, 1.0,
    ];
    for (i, p) in pixdim.iter().enumerate() {
        h[76 + 4 * i..80 + 4 * i].copy_from_slice(&p.to_le_bytes());
    }
    h[108..112].copy_from_slice(&352f32.to_le_bytes());
    h[112..116].copy_from_slice(&slope.to_le_bytes());
    h[116..120].copy_from_slice(&inter.to_le_bytes());
    h[344..348].copy_from_slice(b"n+1\0");
    h.extend_from_slice(data);
    h
}

/// A whole number below 2048 in magnitude as IEEE half-precision bits (exact).
fn half(v: i16) -> u16 {
    if v == 0 {
        return 0;
    }
    let (sign, m) = (u16::from(v < 0) << 15, v.unsigned_abs());
    let e = 15 - m.leading_zeros() as u16; // floor(log2 m)
    let fraction = ((u32::from(m) << 10 >> e) & 0x3ff) as u16;
    sign | ((e + 15) << 10) | fraction
}

/// A CCP4/MRC map of the samples (X fastest) in `mode` (1: i16, 2: f32, 12: f16), its columns,
/// rows and sections along the axes `order` (MAPC, MAPR, MAPS: 1 X, 2 Y, 3 Z), big-endian or
/// not, with `extended` bytes of extended header.
fn mrc(v: &[i16], mode: i32, order: [i32; 3], big: bool, extended: usize) -> Vec<u8> {
    let axes = order.map(|a| (a - 1) as usize);
    let counts = axes.map(|a| DIMS[a]);
    let int = |n: i32| {
        if big {
            n.to_be_bytes()
        } else {
            n.to_le_bytes()
        }
    };
    let float = |f: f32| int(f.to_bits() as i32);
    let mut h = vec![0u8; 1024];
    let mut put = |i: usize, w: [u8; 4]| h[4 * i..4 * i + 4].copy_from_slice(&w);
    for slot in 0..3 {
        put(slot, int(counts[slot] as i32));
        put(7 + slot, int(DIMS[slot] as i32));
        put(10 + slot, float(DIMS[slot] as f32 * SPACING[slot]));
        put(13 + slot, float(90.0));
        put(16 + slot, int(order[slot]));
    }
    put(3, int(mode));
    put(23, int(extended as i32));
    h[208..212].copy_from_slice(b"MAP ");
    h[212..214].copy_from_slice(if big { &[0x11, 0x11] } else { &[0x44, 0x44] });
    h.extend(std::iter::repeat_n(0xee, extended));
    for s in 0..counts[2] {
        for r in 0..counts[1] {
            for c in 0..counts[0] {
                let mut p = [0; 3];
                (p[axes[0]], p[axes[1]], p[axes[2]]) = (c, r, s);
                let x = v[p[0] + DIMS[0] * (p[1] + DIMS[1] * p[2])];
                let bytes: Vec<u8> = match (mode, big) {
                    (1, false) => x.to_le_bytes().into(),
                    (1, true) => x.to_be_bytes().into(),
                    (2, false) => f32::from(x).to_le_bytes().into(),
                    (2, true) => f32::from(x).to_be_bytes().into(),
                    (12, false) => half(x).to_le_bytes().into(),
                    (12, true) => half(x).to_be_bytes().into(),
                    _ => unreachable!("a mode the test writes"),
                };
                h.extend(bytes);
            }
        }
    }
    h
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(bytes).expect("gzip");
    e.finish().expect("gzip")
}

fn zlib(bytes: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(bytes).expect("zlib");
    e.finish().expect("zlib")
}

fn mhd_header(extra: &str, data_file: &str) -> String {
    format!(
        "ObjectType = Image\nNDims = 3\nDimSize = {} {} {}\nElementType = MET_SHORT\nElementSpacing = {} {} {}\nBinaryDataByteOrderMSB = False\n{extra}ElementDataFile = {data_file}\n",
        DIMS[0], DIMS[1], DIMS[2], SPACING[0], SPACING[1], SPACING[2]
    )
}

fn vtk_legacy(v: &[i16]) -> Vec<u8> {
    let mut out = format!(
        "# vtk DataFile Version 3.0\nblob\nBINARY\nDATASET STRUCTURED_POINTS\nDIMENSIONS {} {} {}\nSPACING {} {} {}\nORIGIN 0 0 0\nPOINT_DATA {}\nSCALARS density short 1\nLOOKUP_TABLE default\n",
        DIMS[0], DIMS[1], DIMS[2], SPACING[0], SPACING[1], SPACING[2], v.len()
    )
    .into_bytes();
    out.extend(be(v));
    out.push(b'\n');
    out
}

fn vti(v: &[i16]) -> String {
    let e = format!("0 {} 0 {} 0 {}", DIMS[0] - 1, DIMS[1] - 1, DIMS[2] - 1);
    let values: Vec<String> = v.iter().map(i16::to_string).collect();
    format!(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"ImageData\" version=\"1.0\" byte_order=\"LittleEndian\">\n<ImageData WholeExtent=\"{e}\" Origin=\"0 0 0\" Spacing=\"{} {} {}\">\n<Piece Extent=\"{e}\">\n<PointData Scalars=\"density\">\n<DataArray type=\"Int16\" Name=\"density\" format=\"ascii\">\n{}\n</DataArray>\n</PointData>\n<CellData>\n</CellData>\n</Piece>\n</ImageData>\n</VTKFile>\n",
        SPACING[0], SPACING[1], SPACING[2], values.join(" ")
    )
}

/// One slice of a CT series: stored `u16` values, rescaled by `intercept`.
fn dicom_slice(z: usize, stored: &[u16], intercept: f64, series: &str) -> InMemDicomObject {
    let instance = format!("1.2.826.0.1.3680043.2.1125.7.{z}");
    let ds = |v: f64| PrimitiveValue::from(format!("{v}"));
    let obj = InMemDicomObject::from_element_iter([
        DataElement::new(
            tags::SOP_CLASS_UID,
            VR::UI,
            PrimitiveValue::from(uids::CT_IMAGE_STORAGE),
        ),
        DataElement::new(
            tags::SOP_INSTANCE_UID,
            VR::UI,
            PrimitiveValue::from(instance),
        ),
        DataElement::new(
            tags::SERIES_INSTANCE_UID,
            VR::UI,
            PrimitiveValue::from(series),
        ),
        DataElement::new(tags::MODALITY, VR::CS, PrimitiveValue::from("CT")),
        DataElement::new(
            tags::INSTANCE_NUMBER,
            VR::IS,
            PrimitiveValue::from(format!("{}", z + 1)),
        ),
        // Patient position runs downward in z: ordering by name or instance would not do.
        DataElement::new(
            tags::IMAGE_POSITION_PATIENT,
            VR::DS,
            PrimitiveValue::from(format!(
                "-10\\-12\\{}",
                40.0 + f64::from(SPACING[2]) * z as f64
            )),
        ),
        DataElement::new(
            tags::IMAGE_ORIENTATION_PATIENT,
            VR::DS,
            PrimitiveValue::from("1\\0\\0\\0\\1\\0"),
        ),
        DataElement::new(
            tags::PIXEL_SPACING,
            VR::DS,
            PrimitiveValue::from(format!("{}\\{}", SPACING[1], SPACING[0])),
        ),
        DataElement::new(tags::SAMPLES_PER_PIXEL, VR::US, PrimitiveValue::from(1u16)),
        DataElement::new(
            tags::PHOTOMETRIC_INTERPRETATION,
            VR::CS,
            PrimitiveValue::from("MONOCHROME2"),
        ),
        DataElement::new(tags::ROWS, VR::US, PrimitiveValue::from(DIMS[1] as u16)),
        DataElement::new(tags::COLUMNS, VR::US, PrimitiveValue::from(DIMS[0] as u16)),
        DataElement::new(tags::BITS_ALLOCATED, VR::US, PrimitiveValue::from(16u16)),
        DataElement::new(tags::BITS_STORED, VR::US, PrimitiveValue::from(16u16)),
        DataElement::new(tags::HIGH_BIT, VR::US, PrimitiveValue::from(15u16)),
        DataElement::new(
            tags::PIXEL_REPRESENTATION,
            VR::US,
            PrimitiveValue::from(0u16),
        ),
        DataElement::new(tags::RESCALE_INTERCEPT, VR::DS, ds(intercept)),
        DataElement::new(tags::RESCALE_SLOPE, VR::DS, ds(1.0)),
        DataElement::new(
            tags::PIXEL_DATA,
            VR::OW,
            PrimitiveValue::U16(stored.iter().copied().collect()),
        ),
    ]);
    obj
}

/// Write a CT series to `dir`: slice files named in reverse of their position.
fn dicom_series(dir: &Path, v: &[i16], series: &str) {
    std::fs::create_dir_all(dir).expect("mkdir");
    let plane = DIMS[0] * DIMS[1];
    for z in 0..DIMS[2] {
        let stored: Vec<u16> = v[z * plane..(z + 1) * plane]
            .iter()
            .map(|&x| (i32::from(x) + 1024) as u16)
            .collect();
        let file = dicom_slice(z, &stored, -1024.0, series)
            .with_meta(FileMetaTableBuilder::new().transfer_syntax(uids::EXPLICIT_VR_LITTLE_ENDIAN))
            .expect("meta");
        file.write_to_file(dir.join(format!("IM{:04}", DIMS[2] - z)))
            .expect("write dicom");
    }
    std::fs::write(dir.join("README.txt"), "not a slice").expect("write");
}

/// The series compressed with RLE Lossless, as scanners and archives write it: each slice's
/// pixel data one fragment of two PackBits segments (the samples' high bytes, then their low
/// bytes), in literal runs.
fn dicom_rle_series(dir: &Path, v: &[i16]) {
    std::fs::create_dir_all(dir).expect("mkdir");
    let plane = DIMS[0] * DIMS[1];
    let packbits = |bytes: Vec<u8>| -> Vec<u8> {
        let mut out = Vec::new();
        for run in bytes.chunks(128) {
            out.push(run.len() as u8 - 1);
            out.extend_from_slice(run);
        }
        out
    };
    for z in 0..DIMS[2] {
        let stored: Vec<u16> = v[z * plane..(z + 1) * plane]
            .iter()
            .map(|&x| (i32::from(x) + 1024) as u16)
            .collect();
        let high = packbits(stored.iter().map(|s| (s >> 8) as u8).collect());
        let low = packbits(stored.iter().map(|&s| s as u8).collect());
        let mut header = [0u32; 16];
        header[0] = 2;
        header[1] = 64;
        header[2] = 64 + high.len() as u32;
        let mut fragment: Vec<u8> = header.iter().flat_map(|n| n.to_le_bytes()).collect();
        fragment.extend(high);
        fragment.extend(low);
        if fragment.len() % 2 == 1 {
            fragment.push(0);
        }
        let mut slice = dicom_slice(z, &stored, -1024.0, "1.2.826.0.1.3680043.2.1125.10");
        slice.put(DataElement::new(
            tags::PIXEL_DATA,
            VR::OB,
            dicom_core::value::Value::PixelSequence(dicom_core::value::PixelFragmentSequence::new(
                Vec::<u32>::new(),
                vec![fragment],
            )),
        ));
        slice
            .with_meta(FileMetaTableBuilder::new().transfer_syntax(uids::RLE_LOSSLESS))
            .expect("meta")
            .write_to_file(dir.join(format!("IM{:04}", z + 1)))
            .expect("write dicom");
    }
}

/// The series as old files write it: each slice a bare data set in implicit VR little endian,
/// without the Part 10 preamble, `DICM` or a file meta group.
fn dicom_bare_series(dir: &Path, v: &[i16]) {
    std::fs::create_dir_all(dir).expect("mkdir");
    let plane = DIMS[0] * DIMS[1];
    let ts = dicom_transfer_syntax_registry::entries::IMPLICIT_VR_LITTLE_ENDIAN.erased();
    for z in 0..DIMS[2] {
        let stored: Vec<u16> = v[z * plane..(z + 1) * plane]
            .iter()
            .map(|&x| (i32::from(x) + 1024) as u16)
            .collect();
        let file = std::fs::File::create(dir.join(format!("{z}.ima"))).expect("create");
        dicom_slice(z, &stored, -1024.0, "1.2.6")
            .write_dataset_with_ts(file, &ts)
            .expect("write");
    }
}

/// Every format, written into `dir`; returns the scene's dataset tables.
fn write_all(dir: &Path) -> Vec<(&'static str, String)> {
    let v = samples();
    let w = |name: &str, bytes: &[u8]| std::fs::write(dir.join(name), bytes).expect("write");
    w("blob.raw", &le(&v));
    let nrrd = format!(
        "NRRD0004\ntype: short\ndimension: 3\nsizes: {} {} {}\nspacings: {} {} {}\nencoding: raw\nendian: little\n\n",
        DIMS[0], DIMS[1], DIMS[2], SPACING[0], SPACING[1], SPACING[2]
    );
    w("blob.nrrd", &[nrrd.as_bytes(), &le(&v)].concat());
    w("blob.nii", &nifti(4, 16, 1.0, 0.0, &le(&v)));
    // Stored as u16 with an intercept, as scanners write CT.
    let shifted: Vec<u8> = v
        .iter()
        .flat_map(|&x| ((i32::from(x) + 1024) as u16).to_le_bytes())
        .collect();
    w(
        "scaled.nii.gz",
        &gzip(&nifti(512, 16, 1.0, -1024.0, &shifted)),
    );
    // A header and image pair, both gzipped.
    let mut hdr = nifti(4, 16, 1.0, 0.0, &[]);
    hdr.truncate(348);
    hdr[108..112].copy_from_slice(&0f32.to_le_bytes());
    hdr[344..348].copy_from_slice(b"ni1\0");
    w("pair.hdr.gz", &gzip(&hdr));
    w("pair.img.gz", &gzip(&le(&v)));
    w("blob.mhd", mhd_header("", "blob.raw").as_bytes());
    w(
        "blob.mha",
        &[mhd_header("", "LOCAL").as_bytes(), &le(&v)].concat(),
    );
    let packed = zlib(&le(&v));
    let extra = format!(
        "CompressedData = True\nCompressedDataSize = {}\n",
        packed.len()
    );
    w(
        "zipped.mha",
        &[mhd_header(&extra, "LOCAL").as_bytes(), &packed].concat(),
    );
    // Big-endian, said by ITK's other name for the byte order.
    let msb = mhd_header("", "LOCAL").replace(
        "BinaryDataByteOrderMSB = False",
        "ElementByteOrderMSB = True",
    );
    w("msb.mha", &[msb.as_bytes(), &be(&v)].concat());
    // The samples' bytes as zlib blocks, inline and appended (the fuzz pass's checked `.vti`).
    // Blocks of 2,048 bytes: several to a file, the last one partly filled.
    let bytes: Vec<u8> = v.iter().map(|&x| (x / 8).clamp(0, 255) as u8).collect();
    w("zipped.vti", &vti_zlib(DIMS, &bytes, 2048, false));
    w("appended.vti", &vti_zlib(DIMS, &bytes, 2048, true));
    w("binary.vti", &vti_binary(DIMS, &bytes, false));
    w("binary-appended.vti", &vti_binary(DIMS, &bytes, true));
    w("blob.vtk", &vtk_legacy(&v));
    // Density maps: i16 in file order; f32 with columns along Z, rows along X, sections
    // along Y, big-endian, behind an extended header; f16, gzipped.
    w("blob.map", &mrc(&v, 1, [1, 2, 3], false, 0));
    w("turned.mrc", &mrc(&v, 2, [3, 1, 2], true, 80));
    w("half.ccp4.gz", &gzip(&mrc(&v, 12, [2, 3, 1], false, 0)));
    // Blank lines between the header's keyword lines, as VTK's own samples have them.
    let legacy = vtk_legacy(&v);
    let header = legacy.len() - 2 * v.len() - 1;
    let spaced = String::from_utf8_lossy(&legacy[..header])
        .replace("blob\n", "blob\n\n")
        .replace("DIMENSIONS", "\nDIMENSIONS")
        .replace("ORIGIN 0 0 0\n", "ORIGIN 0 0 0\n \n\n");
    w(
        "spaced.vtk",
        &[spaced.as_bytes(), &legacy[header..]].concat(),
    );
    w("blob.vti", vti(&v).as_bytes());
    dicom_series(&dir.join("series"), &v, "1.2.826.0.1.3680043.2.1125.9");
    dicom_bare_series(&dir.join("bare"), &v);
    dicom_rle_series(&dir.join("rle"), &v);
    let raw = format!(
        "path = \"blob.raw\"\ndims = [{}, {}, {}]\ntype = \"i16\"\nendian = \"little\"\nspacing = [{}, {}, {}]",
        DIMS[0], DIMS[1], DIMS[2], SPACING[0], SPACING[1], SPACING[2]
    );
    vec![
        ("raw", raw),
        ("nrrd", "path = \"blob.nrrd\"".into()),
        ("nifti", "path = \"blob.nii\"".into()),
        ("nifti-gz-scaled", "path = \"scaled.nii.gz\"".into()),
        ("nifti-pair-gz", "path = \"pair.hdr.gz\"".into()),
        ("mhd", "path = \"blob.mhd\"".into()),
        ("mha", "path = \"blob.mha\"".into()),
        ("mha-zlib", "path = \"zipped.mha\"".into()),
        ("mha-element-msb", "path = \"msb.mha\"".into()),
        ("vtk", "path = \"blob.vtk\"".into()),
        ("vtk-blank-lines", "path = \"spaced.vtk\"".into()),
        ("mrc-i16", "path = \"blob.map\"".into()),
        ("mrc-f32-turned-big-endian", "path = \"turned.mrc\"".into()),
        ("mrc-f16-gz", "path = \"half.ccp4.gz\"".into()),
        ("vti", "path = \"blob.vti\"".into()),
        ("dicom", "path = \"series\"".into()),
        (
            "dicom-without-preamble",
            "path = \"bare\"\nformat = \"dicom\"".into(),
        ),
        ("dicom-rle", "path = \"rle\"".into()),
    ]
}

fn scene(datasets: &[(&str, String)]) -> String {
    let mut s = String::new();
    for (name, table) in datasets {
        s += &format!(
            "[[datasets]]\nname = \"{name}\"\n{table}\n[[datasets.views]]\nname = \"v\"\nwidth = 48\nheight = 40\n[[datasets.views.surfaces]]\niso = 0.0\ncolor = [0.9, 0.8, 0.7]\ntransparency = 0.5\n[[datasets.views.surfaces]]\niso = 500.0\n[[datasets.views.lights]]\ntype = \"directional\"\ndirection = [0.3, -0.4, 1.0]\nshadows = true\n"
        );
    }
    s
}

#[test]
fn every_format_loads_the_same_samples_as_the_raw_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let datasets = write_all(dir.path());
    let file = dir.path().join("all.toml");
    std::fs::write(&file, scene(&datasets)).expect("write scene");
    let loaded = Scene::from_file(&file)
        .and_then(Scene::load)
        .unwrap_or_else(|e| panic!("{e}"));
    use voxcube::input::dataset::VolumeData;
    let raw = &loaded[0].volume;
    assert!(matches!(raw.data, VolumeData::I16(_)));
    // Every value, whatever kind holds it.
    let values = |data: &VolumeData| -> Vec<f32> {
        match data {
            VolumeData::U8(v) => v.iter().map(|&x| f32::from(x)).collect(),
            VolumeData::U16(v) => v.iter().map(|&x| f32::from(x)).collect(),
            VolumeData::I16(v) => v.iter().map(|&x| f32::from(x)).collect(),
            VolumeData::F32(v) => v.clone(),
        }
    };
    for (d, (name, _)) in loaded.iter().zip(&datasets) {
        assert_eq!(d.volume.grid, raw.grid, "{name}: grid");
        assert_eq!(
            values(&d.volume.data),
            values(&raw.data),
            "{name}: samples differ from the raw file's"
        );
        // Signed 16-bit files stay 16-bit. Float files stay floats, and so does the scaled
        // one: u16 shifted by -1024 could reach 64,511, beyond i16, whatever values it holds.
        let floats = ["-scaled", "-f32", "-f16"].iter().any(|k| name.contains(k));
        assert_eq!(
            matches!(d.volume.data, VolumeData::F32(_)),
            floats,
            "{name}: kind {:?}",
            d.volume.data.kind()
        );
    }
}

fn voxcube(dir: &Path, args: &[&str]) -> serde_json::Value {
    let out = Command::new(env!("CARGO_BIN_EXE_voxcube"))
        .arg("render")
        .args(args)
        .arg("-o")
        .arg(dir)
        .arg("--report")
        .arg(dir.join("r.json"))
        .output()
        .expect("runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&std::fs::read(dir.join("r.json")).expect("report")).expect("json")
}

#[test]
fn every_format_renders_the_raw_file_s_pixels_on_one_node_and_on_a_cluster() {
    let dir = tempfile::tempdir().expect("tempdir");
    let datasets = write_all(dir.path());
    let file = dir.path().join("all.toml");
    std::fs::write(&file, scene(&datasets)).expect("write scene");
    let file = file.to_str().expect("utf-8 path");
    let one = voxcube(dir.path(), &[file]);
    let cluster = voxcube(
        dir.path(),
        &[file, "--nodes", "8", "--clusters", "2", "--fabric", "sim"],
    );
    let hashes = |r: &serde_json::Value| -> Vec<String> {
        r["views"]
            .as_array()
            .expect("views")
            .iter()
            .map(|v| v["pixels_sha256"].as_str().expect("hash").to_string())
            .collect()
    };
    let (one, cluster) = (hashes(&one), hashes(&cluster));
    assert_eq!(one.len(), datasets.len());
    for (i, (name, _)) in datasets.iter().enumerate() {
        assert_eq!(one[i], one[0], "{name} on one node");
        assert_eq!(cluster[i], one[0], "{name} on 8 nodes in 2 clusters");
    }
}

/// A density map read straight from its `.map` file renders the same pixels on one node, on
/// the simulator's 4 nodes in 2 clusters and on 2 threads in 1 cluster.
#[test]
fn a_density_map_renders_alike_on_one_node_the_simulator_and_threads() {
    let dir = tempfile::tempdir().expect("tempdir");
    write_all(dir.path());
    let file = dir.path().join("map.toml");
    let map = [("density", "path = \"blob.map\"".to_string())];
    std::fs::write(&file, scene(&map)).expect("write scene");
    let file = file.to_str().expect("utf-8 path");
    let hash = |r: serde_json::Value| r["views"][0]["pixels_sha256"].as_str().map(String::from);
    let one = hash(voxcube(dir.path(), &[file])).expect("a hash");
    for shape in [
        ["--nodes", "4", "--clusters", "2", "--fabric", "sim"],
        ["--nodes", "2", "--clusters", "1", "--fabric", "threads"],
    ] {
        let args = [&[file][..], &shape[..]].concat();
        assert_eq!(
            hash(voxcube(dir.path(), &args)).as_deref(),
            Some(&one[..]),
            "{shape:?}"
        );
    }
    // `info` gives the mean and σ, and the contour levels a crystallographer starts from.
    let (ok, text, err) = run(&["info".as_ref(), dir.path().join("blob.map").as_os_str()]);
    assert!(ok, "{err}");
    let v: Vec<f64> = samples().into_iter().map(f64::from).collect();
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    let rms = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / v.len() as f64).sqrt();
    for part in [
        format!("mean {mean:.2} rms {rms:.2}"),
        format!("2σ {:.4}", mean + 2.0 * rms),
    ] {
        assert!(text.contains(&part), "info omits {part:?}:\n{text}");
    }
    // Its suggested scene contours the map at mean + 1σ (to three figures), and renders.
    let scene = suggested_scene_renders(dir.path(), &dir.path().join("blob.map"));
    let first: f64 = scene
        .lines()
        .find_map(|l| l.strip_prefix("iso = "))
        .and_then(|v| v.parse().ok())
        .expect("an iso value");
    assert!(
        (first - (mean + rms)).abs() < 0.01 * rms.abs(),
        "{first}: {scene}"
    );
}

// ------------------------------------------------------------------ bad files

/// A density map whose header lies or names what voxcube does not read is refused, naming the
/// file and the field, without taking more memory than the file holds.
#[test]
fn a_density_map_whose_header_lies_is_refused_by_name() {
    let dir = tempfile::tempdir().expect("tempdir");
    let good = mrc(&samples(), 1, [1, 2, 3], false, 0);
    let word = |bytes: &mut Vec<u8>, i: usize, n: i32| {
        bytes[4 * i..4 * i + 4].copy_from_slice(&n.to_le_bytes());
    };
    let cases: Vec<(Vec<u8>, &str)> = vec![
        (
            {
                let mut b = good.clone();
                word(&mut b, 3, 3);
                b
            },
            "MODE is 3",
        ),
        (
            {
                let mut b = good.clone();
                word(&mut b, 17, 1);
                b
            },
            "MAPC, MAPR, MAPS are [1, 1, 3]",
        ),
        (
            {
                let mut b = good.clone();
                word(&mut b, 0, 1 << 30);
                b
            },
            "dimensions 1073741824 × 20 × 16 declare 343597383680 samples",
        ),
        (
            {
                let mut b = good.clone();
                word(&mut b, 2, -4);
                b
            },
            "NC, NR, NS are",
        ),
        (
            {
                let mut b = good.clone();
                word(&mut b, 23, -1);
                b
            },
            "NSYMBT is -1",
        ),
        (good[..good.len() - 10].to_vec(), "truncated: expected"),
        ([&good[..], &[0u8; 6]].concat(), "6 trailing bytes"),
        (good[..600].to_vec(), "truncated: expected 1024 bytes"),
    ];
    for (bytes, expected) in cases {
        let path = dir.path().join("bad.map");
        std::fs::write(&path, &bytes).expect("write");
        let message = voxcube::input::formats::mrc::load(&path, None)
            .expect_err(expected)
            .to_string();
        assert!(
            message.contains("bad.map") && message.contains(expected),
            "{expected}: {message}"
        );
    }
    // A gzipped map that is cut short is corrupt compressed data.
    let packed = gzip(&good);
    let path = dir.path().join("bad.map.gz");
    std::fs::write(&path, &packed[..packed.len() - 9]).expect("write");
    let message = voxcube::input::formats::mrc::load(&path, None)
        .expect_err("cut")
        .to_string();
    assert!(message.contains("corrupt compressed data"), "{message}");
}

fn error_of(dir: &Path, table: &str) -> String {
    let file = dir.join("bad.toml");
    std::fs::write(&file, scene(&[("bad", table.to_string())])).expect("write");
    match Scene::from_file(&file).and_then(Scene::load) {
        Ok(_) => panic!("accepted: {table}"),
        Err(e) => e.to_string(),
    }
}

fn assert_names(msg: &str, parts: &[&str]) {
    for p in parts {
        assert!(msg.contains(p), "error {msg:?} does not mention {p:?}");
    }
}

#[test]
fn bad_nifti_files_name_the_file_and_the_field() {
    let dir = tempfile::tempdir().expect("tempdir");
    let v = le(&samples());
    let w = |name: &str, bytes: &[u8]| std::fs::write(dir.path().join(name), bytes).expect("write");
    let good = nifti(4, 16, 1.0, 0.0, &v);
    w("short.nii", &good[..good.len() - 10]);
    assert_names(
        &error_of(dir.path(), "path = \"short.nii\""),
        &["short.nii", "truncated"],
    );
    let mut magic = good.clone();
    magic[344..348].copy_from_slice(b"xyz\0");
    w("magic.nii", &magic);
    assert_names(
        &error_of(dir.path(), "path = \"magic.nii\""),
        &["magic.nii", "not a NIfTI-1 file", "magic"],
    );
    w(
        "complex.nii",
        &nifti(
            32,
            64,
            1.0,
            0.0,
            &[v.clone(), v.clone(), v.clone(), v.clone()].concat(),
        ),
    );
    assert_names(
        &error_of(dir.path(), "path = \"complex.nii\""),
        &["complex.nii", "datatype", "not supported"],
    );
    let mut four = good.clone();
    four[40..42].copy_from_slice(&4i16.to_le_bytes());
    four[48..50].copy_from_slice(&2i16.to_le_bytes());
    w("series.nii", &[&four[..], &v].concat());
    assert_names(
        &error_of(dir.path(), "path = \"series.nii\""),
        &["series.nii", "dim", "one 3-D"],
    );
    let mut two = good.clone();
    two[0..4].copy_from_slice(&540i32.to_le_bytes());
    w("two.nii", &two);
    assert_names(
        &error_of(dir.path(), "path = \"two.nii\""),
        &["two.nii", "NIfTI-2"],
    );
    w(
        "zero.nii",
        &nifti(4, 16, 1.0, 0.0, &v)
            .iter()
            .enumerate()
            .map(|(i, &b)| if (80..84).contains(&i) { 0 } else { b })
            .collect::<Vec<u8>>(),
    );
    assert_names(
        &error_of(dir.path(), "path = \"zero.nii\""),
        &["zero.nii", "pixdim"],
    );
}

#[test]
fn bad_metaimage_files_name_the_file_and_the_field() {
    let dir = tempfile::tempdir().expect("tempdir");
    let v = le(&samples());
    let w = |name: &str, bytes: &[u8]| std::fs::write(dir.path().join(name), bytes).expect("write");
    w(
        "short.mha",
        &[mhd_header("", "LOCAL").as_bytes(), &v[..v.len() - 3]].concat(),
    );
    assert_names(
        &error_of(dir.path(), "path = \"short.mha\""),
        &["short.mha", "truncated"],
    );
    w(
        "rgb.mha",
        mhd_header("ElementNumberOfChannels = 3\n", "LOCAL").as_bytes(),
    );
    assert_names(
        &error_of(dir.path(), "path = \"rgb.mha\""),
        &["rgb.mha", "ElementNumberOfChannels is 3"],
    );
    w("gone.mhd", mhd_header("", "missing.raw").as_bytes());
    assert_names(
        &error_of(dir.path(), "path = \"gone.mhd\""),
        &["missing.raw", "cannot read"],
    );
    w(
        "bad.zip.mha",
        &[
            mhd_header("CompressedData = True\n", "LOCAL").as_bytes(),
            &v[..100],
        ]
        .concat(),
    );
    assert_names(
        &error_of(dir.path(), "path = \"bad.zip.mha\""),
        &["bad.zip.mha", "CompressedData", "corrupt"],
    );
    let wrong = mhd_header("", "LOCAL").replace("MET_SHORT", "MET_FLOAT");
    w("wrong.mha", &[wrong.as_bytes(), &v].concat());
    assert_names(
        &error_of(dir.path(), "path = \"wrong.mha\""),
        &["wrong.mha", "truncated"],
    );
}

#[test]
fn bad_vtk_files_name_the_file_and_the_field() {
    let dir = tempfile::tempdir().expect("tempdir");
    let s = samples();
    let w = |name: &str, bytes: &[u8]| std::fs::write(dir.path().join(name), bytes).expect("write");
    let good = vtk_legacy(&s);
    w("short.vtk", &good[..good.len() - 400]);
    assert_names(
        &error_of(dir.path(), "path = \"short.vtk\""),
        &["short.vtk", "truncated"],
    );
    w(
        "poly.vtk",
        b"# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\nPOINTS 1 float\n0 0 0\n",
    );
    assert_names(
        &error_of(dir.path(), "path = \"poly.vtk\""),
        &["poly.vtk", "DATASET POLYDATA", "STRUCTURED_POINTS"],
    );
    let cell_values = vec!["7"; (DIMS[0] - 1) * (DIMS[1] - 1) * (DIMS[2] - 1)].join(" ");
    let cells = vti(&s)
        .replace(
            "<PointData Scalars=\"density\">",
            "<PointData>\n</PointData>\n<CellData Scalars=\"density\">",
        )
        .replace("</PointData>\n<CellData>\n</CellData>", "</CellData>");
    let start = cells.find("format=\"ascii\">\n").expect("array") + 15;
    let end = cells.find("\n</DataArray>").expect("array end");
    let cells = format!("{}{cell_values}{}", &cells[..start], &cells[end..]);
    w("cells.vti", cells.as_bytes());
    let m = error_of(dir.path(), "path = \"cells.vti\"");
    assert_names(&m, &["cells.vti", "cell data only", "POINT_DATA"]);
    w("broken.vti", &vti(&s).as_bytes()[..300]);
    assert_names(
        &error_of(dir.path(), "path = \"broken.vti\""),
        &["broken.vti", "VTK XML"],
    );
}

/// A DICOM header that declares more bytes than its file holds is refused before dicom-rs
/// reads it (which would allocate what it declares): in a series, and in a sequence of
/// unknown VR, whose elements are in implicit VR.
#[test]
fn a_dicom_length_past_the_end_of_its_file_is_refused_naming_the_element() {
    let dir = tempfile::tempdir().expect("tempdir");
    let v = samples();
    let lie = dir.path().join("lie");
    dicom_series(&lie, &v, "1.2.3");
    let f = lie.join("IM0003");
    let mut bytes = std::fs::read(&f).expect("read");
    // A private element after the pixel data, declaring 4 GB.
    bytes.extend_from_slice(&[0xE1, 0x7F, 0x10, 0x00, b'O', b'B', 0, 0]);
    bytes.extend_from_slice(&0xFFFF_FFF0u32.to_le_bytes());
    bytes.extend_from_slice(b"abcd");
    std::fs::write(&f, &bytes).expect("write");
    assert_names(
        &error_of(dir.path(), "path = \"lie\""),
        &[
            "IM0003",
            "(7FE1,0010)",
            "declares 4294967280 bytes",
            "only 4 follow",
        ],
    );
    // The same length on an element inside a sequence of unknown VR.
    let nested = dir.path().join("nested");
    dicom_series(&nested, &v, "1.2.3");
    let f = nested.join("IM0002");
    let mut bytes = std::fs::read(&f).expect("read");
    bytes.extend_from_slice(&[
        0xE1, 0x7F, 0x10, 0x00, b'U', b'N', 0, 0, 0xFF, 0xFF, 0xFF, 0xFF,
    ]);
    bytes.extend_from_slice(&[0xFE, 0xFF, 0x00, 0xE0, 0xFF, 0xFF, 0xFF, 0xFF]);
    bytes.extend_from_slice(&[0xE1, 0x7F, 0x11, 0x00]);
    bytes.extend_from_slice(&0xFFFF_FF00u32.to_le_bytes());
    std::fs::write(&f, &bytes).expect("write");
    assert_names(
        &error_of(dir.path(), "path = \"nested\""),
        &["IM0002", "(7FE1,0011)", "declares 4294967040 bytes"],
    );
}

#[test]
fn bad_dicom_series_name_the_file_and_the_field() {
    let dir = tempfile::tempdir().expect("tempdir");
    let v = samples();
    // A slice missing from the middle.
    let gap = dir.path().join("gap");
    dicom_series(&gap, &v, "1.2.3");
    std::fs::remove_file(gap.join(format!("IM{:04}", DIMS[2] - 5))).expect("rm");
    assert_names(
        &error_of(dir.path(), "path = \"gap\""),
        &["gap", "unevenly spaced", "missing slice"],
    );
    // Only two slices left, the middle one gone: their instance numbers show it.
    let pair = dir.path().join("pair");
    dicom_series(&pair, &v, "1.2.3");
    for z in (0..DIMS[2]).filter(|z| ![0, 2].contains(z)) {
        std::fs::remove_file(pair.join(format!("IM{:04}", DIMS[2] - z))).expect("rm");
    }
    assert_names(
        &error_of(dir.path(), "path = \"pair\""),
        &["pair", "InstanceNumbers", "1 and 3", "missing slice"],
    );
    // A slice turned to another plane (coronal among axial ones).
    let turned = dir.path().join("turned");
    dicom_series(&turned, &v, "1.2.3");
    let f = turned.join("IM0004");
    let mut slice = dicom_object::open_file(&f).expect("read");
    slice.put(DataElement::new(
        tags::IMAGE_ORIENTATION_PATIENT,
        VR::DS,
        PrimitiveValue::from("1\\0\\0\\0\\0\\1"),
    ));
    slice.write_to_file(&f).expect("write");
    assert_names(
        &error_of(dir.path(), "path = \"turned\""),
        &["IM0004", "not parallel", "ImageOrientationPatient"],
    );
    // A palette-colour image: its pixels are indices, not values.
    let palette = dir.path().join("palette");
    dicom_series(&palette, &v, "1.2.3");
    let f = palette.join("IM0002");
    let mut slice = dicom_object::open_file(&f).expect("read");
    slice.put(DataElement::new(
        tags::PHOTOMETRIC_INTERPRETATION,
        VR::CS,
        PrimitiveValue::from("PALETTE COLOR"),
    ));
    slice.write_to_file(&f).expect("write");
    assert_names(
        &error_of(dir.path(), "path = \"palette\""),
        &["IM0002", "PALETTE COLOR", "grey-scale"],
    );
    // Two series in one folder.
    let two = dir.path().join("two");
    dicom_series(&two, &v, "1.2.3");
    let plane = DIMS[0] * DIMS[1];
    let other = dicom_slice(0, &vec![0u16; plane], 0.0, "1.2.4")
        .with_meta(FileMetaTableBuilder::new().transfer_syntax(uids::EXPLICIT_VR_LITTLE_ENDIAN))
        .expect("meta");
    other.write_to_file(two.join("OTHER")).expect("write");
    assert_names(
        &error_of(dir.path(), "path = \"two\""),
        &["SeriesInstanceUID", "more than one series"],
    );
    // A truncated slice.
    let cut = dir.path().join("cut");
    dicom_series(&cut, &v, "1.2.3");
    let f = cut.join("IM0003");
    let bytes = std::fs::read(&f).expect("read");
    std::fs::write(&f, &bytes[..bytes.len() - 100]).expect("write");
    assert_names(
        &error_of(dir.path(), "path = \"cut\""),
        &["IM0003", "truncated or malformed"],
    );
    // A compression this build does not decode (JPEG-LS), its frame header whole and of the
    // image's size, so that it reaches the decoder: the slice is named.
    let packed = dir.path().join("packed");
    std::fs::create_dir(&packed).expect("mkdir");
    let mut slice = dicom_slice(0, &vec![0u16; plane], 0.0, "1.2.5");
    let mut jpeg_ls = vec![0xffu8, 0xd8, 0xff, 0xf7, 0x00, 0x0b, 0x08];
    jpeg_ls.extend((DIMS[1] as u16).to_be_bytes());
    jpeg_ls.extend((DIMS[0] as u16).to_be_bytes());
    jpeg_ls.extend([0x01, 0x01, 0x11, 0x00]);
    slice.put(DataElement::new(
        tags::PIXEL_DATA,
        VR::OB,
        dicom_core::value::Value::from(dicom_core::value::PixelFragmentSequence::new_fragments(
            vec![jpeg_ls],
        )),
    ));
    slice
        .with_meta(FileMetaTableBuilder::new().transfer_syntax("1.2.840.10008.1.2.4.80"))
        .expect("meta")
        .write_to_file(packed.join("IM0001"))
        .expect("write");
    assert_names(
        &error_of(dir.path(), "path = \"packed\""),
        &["IM0001", "pixel data", "Unsupported TransferSyntax"],
    );
    // An empty folder.
    std::fs::create_dir(dir.path().join("empty")).expect("mkdir");
    assert_names(
        &error_of(dir.path(), "path = \"empty\""),
        &["empty", "no DICOM files"],
    );
}

#[test]
fn a_file_of_unknown_kind_asks_for_a_format() {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("blob.bin"), [0u8; 64]).expect("write");
    assert_names(
        &error_of(dir.path(), "path = \"blob.bin\""),
        &[
            "blob.bin",
            "format",
            "cannot tell",
            "nifti",
            "dims and type",
        ],
    );
    // The magic finds a NIfTI file whatever its name.
    std::fs::write(
        dir.path().join("brain.img1"),
        nifti(4, 16, 1.0, 0.0, &le(&samples())),
    )
    .expect("write");
    let file = dir.path().join("ok.toml");
    std::fs::write(&file, scene(&[("b", "path = \"brain.img1\"".into())])).expect("write");
    Scene::from_file(&file)
        .and_then(Scene::load)
        .unwrap_or_else(|e| panic!("{e}"));
}

// ------------------------------------------------------------------ voxcube info

fn run(args: &[&std::ffi::OsStr]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_voxcube"))
        .args(args)
        .output()
        .expect("runs");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).to_string(),
        String::from_utf8_lossy(&out.stderr).to_string(),
    )
}

#[test]
fn info_describes_a_volume_and_its_scene_renders_something_on_the_first_try() {
    let dir = tempfile::tempdir().expect("tempdir");
    write_all(dir.path());
    let nii = dir.path().join("blob.nii");
    let (ok, text, err) = run(&["info".as_ref(), nii.as_os_str()]);
    assert!(ok, "{err}");
    for part in [
        "24 x 20 x 16 samples, spacing 1 x 1 x 1.5",
        "i16",
        "min -1000 max 900",
        "histogram",
        "iso values",
        "transfer",
        "ncube2",
        "modern",
    ] {
        assert!(text.contains(part), "info omits {part:?}:\n{text}");
    }
    // This machine's memory shared by a cluster's nodes, where the system says it (Linux).
    if Path::new("/proc/meminfo").exists() {
        assert!(
            text.contains(" / nodes)"),
            "info omits the host column:\n{text}"
        );
    }
    // The volume's value ranges, each view's skipping structures with their bytes and build
    // time, and the node field: 24 × 20 × 16 samples make 6 × 5 × 4 blocks of 4³ cells,
    // min/max blocks of 8 bytes each (0.9 KiB) and cell masks of 8 bytes each (0.9 KiB), and
    // a node field of 7,680 nodes × 16 bytes (0.12 MiB).
    assert!(
        text.lines()
            .any(|l| l.contains("value ranges: min/max blocks 0.9 KiB")
                && l.contains("cells' ranges")
                && l.contains("ms once per volume")),
        "{text}"
    );
    for view in ["surfaces", "composite"] {
        let line = text
            .lines()
            .find(|l| l.trim_start().starts_with(view) && l.contains("built in"))
            .unwrap_or_else(|| panic!("no structures line for {view}:\n{text}"));
        assert!(
            line.contains("cell masks 0.9 KiB") && line.contains("ms for each new view"),
            "{line}"
        );
    }
    assert!(
        text.contains("node field 0.12 MiB") && text.contains("ms once per volume"),
        "{text}"
    );
    // The DICOM folder reads the same.
    let (ok, series, err) = run(&["info".as_ref(), dir.path().join("series").as_os_str()]);
    assert!(ok && series.contains("min -1000 max 900"), "{err}{series}");
    // A ready scene: it renders with no warning, and shows the blob.
    let (ok, scene, err) = run(&["info".as_ref(), "--scene".as_ref(), nii.as_os_str()]);
    assert!(ok, "{err}");
    let file = dir.path().join("first.toml");
    std::fs::write(&file, &scene).expect("write");
    let out = dir.path().join("out");
    let report = dir.path().join("first.json");
    let (ok, _, err) = run(&[
        "render".as_ref(),
        file.as_os_str(),
        "-o".as_ref(),
        out.as_os_str(),
        "--report".as_ref(),
        report.as_os_str(),
    ]);
    assert!(ok, "{err}\n{scene}");
    assert!(!err.contains("warning"), "{err}");
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&report).expect("report")).expect("json");
    let views = json["views"].as_array().expect("views");
    assert_eq!(views.len(), 2, "{scene}");
    for v in views {
        let png = image::open(v["image"].as_str().expect("image path"))
            .expect("png")
            .to_rgba8();
        let lit = png.pixels().filter(|p| p.0[..3] != [0, 0, 0]).count();
        let share = lit as f64 / f64::from(png.width() * png.height());
        assert!(share > 0.2, "{}: {share:.3} of the image shows", v["view"]);
    }
}

/// A single image (one sample thick): the scene `info --scene` suggests renders, in the
/// voxel model, since the cell model needs two samples along each axis.
#[test]
fn info_suggests_a_scene_that_renders_for_a_one_slice_volume() {
    let dir = tempfile::tempdir().expect("tempdir");
    let header = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 24 20 1\nencoding: raw\n\n";
    let image: Vec<u8> = (0..24 * 20).map(|i| ((i * 7) % 200) as u8).collect();
    let nrrd = dir.path().join("slice.nrrd");
    std::fs::write(&nrrd, [header.as_bytes(), &image].concat()).expect("write");
    let scene = suggested_scene_renders(dir.path(), &nrrd);
    assert!(scene.contains("model = \"voxel\""), "{scene}");
}

/// The scene `info --scene` suggests for `volume`, after checking that it renders (into
/// `dir`).
fn suggested_scene_renders(dir: &Path, volume: &Path) -> String {
    let (ok, scene, err) = run(&["info".as_ref(), "--scene".as_ref(), volume.as_os_str()]);
    assert!(ok, "{err}");
    let file = dir.join("suggested.toml");
    std::fs::write(&file, &scene).expect("write");
    let out = dir.join("suggested");
    let (ok, _, err) = run(&[
        "render".as_ref(),
        file.as_os_str(),
        "-o".as_ref(),
        out.as_os_str(),
    ]);
    assert!(ok, "{err}\n{scene}");
    scene
}

#[test]
fn info_on_a_raw_file_asks_for_a_scene() {
    let dir = tempfile::tempdir().expect("tempdir");
    write_all(dir.path());
    let (ok, _, err) = run(&["info".as_ref(), dir.path().join("blob.raw").as_os_str()]);
    assert!(
        !ok && err.contains("blob.raw") && err.contains("raw file has no header"),
        "{err}"
    );
}

/// A `.nii.gz` with any one byte changed is read to the original samples or refused, never
/// read to other samples: the gzip stream's CRC-32 and length are checked before a sample is
/// taken. A change in the gzip trailer (the CRC-32 and ISIZE) or in the deflate data is
/// refused as corrupt compressed data, naming the file.
#[test]
fn a_corrupt_gzip_nifti_is_refused_never_read_to_other_samples() {
    let dir = tempfile::tempdir().expect("tempdir");
    let original = gzip(&nifti(4, 16, 1.0, 0.0, &le(&samples())));
    let path = dir.path().join("blob.nii.gz");
    std::fs::write(&path, &original).expect("write");
    let reference =
        voxcube::input::formats::nifti::load(&path, None).expect("the intact file reads");
    let (mut refused, mut same) = (0, 0);
    let n = original.len();
    // A spread of offsets through the header, the deflate data, and every trailer byte.
    let offsets = (0..n).step_by((n / 200).max(1)).chain(n - 8..n);
    for offset in offsets {
        let mut bad = original.clone();
        bad[offset] ^= 0xa5;
        std::fs::write(&path, &bad).expect("write");
        match voxcube::input::formats::nifti::load(&path, None) {
            Ok(volume) => {
                assert!(
                    volume.grid == reference.grid && volume.data == reference.data,
                    "byte {offset} of {n} changed: read to other samples"
                );
                same += 1;
            }
            Err(e) => {
                let message = e.to_string();
                assert!(message.contains("blob.nii.gz"), "{message}");
                // Past the 10-byte gzip header, every change is in the stream or trailer.
                if offset >= 10 {
                    assert!(
                        message.contains("corrupt compressed data"),
                        "byte {offset}: {message}"
                    );
                }
                refused += 1;
            }
        }
    }
    assert!(refused > 150, "{refused} refused, {same} read alike");
    // A header and image pair: a corrupt image stream is named as such.
    write_all(dir.path());
    let image = dir.path().join("pair.img.gz");
    let mut bad = std::fs::read(&image).expect("read");
    let last = bad.len() - 1;
    bad[last] ^= 1;
    std::fs::write(&image, &bad).expect("write");
    let message = voxcube::input::formats::nifti::load(&dir.path().join("pair.hdr.gz"), None)
        .expect_err("a corrupt image stream")
        .to_string();
    assert!(
        message.contains("pair.img.gz") && message.contains("corrupt compressed data"),
        "{message}"
    );
}

/// What a NIfTI header declares is checked against what its file holds before the samples are
/// kept: a 400-byte file (plain or gzipped) declaring 1,000³ byte samples (1 GB, within the
/// cap on samples) is refused as truncated, naming the bytes it needed and the bytes it had,
/// not read into memory sized by the header; and a `vox_offset` that is no byte offset is
/// refused naming the field.
#[test]
fn a_nifti_header_declaring_more_than_its_file_holds_is_refused_before_allocating() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut huge = nifti(2, 8, 1.0, 0.0, &[7u8; 48]);
    for axis in 1..4 {
        huge[40 + 2 * axis..42 + 2 * axis].copy_from_slice(&1_000i16.to_le_bytes());
    }
    let expected = 352 + 1_000u64.pow(3);
    let plain = dir.path().join("huge.nii");
    std::fs::write(&plain, &huge).expect("write");
    let message = voxcube::input::formats::nifti::load(&plain, None)
        .expect_err("a 400-byte file cannot hold 1 GB")
        .to_string();
    assert!(
        message.contains("huge.nii")
            && message.contains(&format!("truncated: expected {expected} bytes, found 400")),
        "{message}"
    );
    let packed = dir.path().join("huge.nii.gz");
    std::fs::write(&packed, gzip(&huge)).expect("write");
    let message = voxcube::input::formats::nifti::load(&packed, None)
        .expect_err("nor its gzipped copy")
        .to_string();
    assert!(
        message.contains("huge.nii.gz")
            && message.contains(&format!("truncated: expected {expected} bytes, found 400")),
        "{message}"
    );
    let mut offset = nifti(4, 16, 1.0, 0.0, &le(&samples()));
    offset[108..112].copy_from_slice(&352.5f32.to_le_bytes());
    let odd = dir.path().join("odd.nii");
    std::fs::write(&odd, &offset).expect("write");
    let message = voxcube::input::formats::nifti::load(&odd, None)
        .expect_err("half a byte")
        .to_string();
    assert!(
        message.contains("odd.nii") && message.contains("vox_offset is 352.5"),
        "{message}"
    );
}

/// A compressed stream holding far more than its header declares is decoded no further than
/// the header accounts for, the rest counted and checked but not kept: a gzip NRRD and a zlib
/// MetaImage declaring 4×4×4 bytes whose streams hold 8 MiB are refused naming both lengths.
#[test]
fn a_compressed_stream_longer_than_its_header_declares_is_refused_not_kept() {
    let dir = tempfile::tempdir().expect("tempdir");
    let flood = vec![9u8; 8 << 20];
    let nrrd = dir.path().join("flood.nrrd");
    std::fs::write(
        &nrrd,
        [
            &b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 4 4\nencoding: gzip\n\n"[..],
            &gzip(&flood),
        ]
        .concat(),
    )
    .expect("write");
    let message = voxcube::input::formats::nrrd::load(&nrrd, None)
        .expect_err("8 MiB where 64 bytes are declared")
        .to_string();
    assert!(
        message.contains("flood.nrrd")
            && message.contains(&format!("expected 64 bytes, found {}", 8 << 20)),
        "{message}"
    );
    let mhd = dir.path().join("flood.mhd");
    let header = "ObjectType = Image\nNDims = 3\nDimSize = 4 4 4\nElementType = MET_UCHAR\nCompressedData = True\nElementDataFile = LOCAL\n";
    std::fs::write(&mhd, [header.as_bytes(), &zlib(&flood)].concat()).expect("write");
    let message = voxcube::input::formats::metaimage::load(&mhd, None)
        .expect_err("the same in zlib")
        .to_string();
    assert!(
        message.contains("flood.mhd")
            && message.contains(&format!("expected 64 bytes, found {}", 8 << 20)),
        "{message}"
    );
    // A gzip NRRD cannot put its samples at the end of a stream it has not decoded.
    let skip = dir.path().join("skip.nrrd");
    std::fs::write(
        &skip,
        [
            &b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 4 4\nencoding: gzip\nbyte skip: -1\n\n"[..],
            &gzip(&[1u8; 64]),
        ]
        .concat(),
    )
    .expect("write");
    let message = voxcube::input::formats::nrrd::load(&skip, None)
        .expect_err("byte skip -1 with gzip")
        .to_string();
    assert!(message.contains("byte skip -1"), "{message}");
}

/// A header may declare at most `--max-samples` samples (2^32 unless told): a 2,048³ volume
/// declared by a few hundred bytes of gzipped NIfTI, and a DICOM image declaring 10^8 frames,
/// are refused by the cap before anything is decompressed or decoded for them, naming the
/// dimensions, as is a JPEG frame whose own header declares another size than its image; the
/// command line's flag lowers the cap, and a volume within it reads.
#[test]
fn a_header_declaring_more_samples_than_the_cap_is_refused_before_decompressing() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut huge = nifti(2, 8, 1.0, 0.0, &[0u8; 8]);
    for axis in 1..4 {
        huge[40 + 2 * axis..42 + 2 * axis].copy_from_slice(&2048i16.to_le_bytes());
    }
    let path = dir.path().join("huge.nii.gz");
    std::fs::write(&path, gzip(&huge)).expect("write");
    let message = voxcube::input::formats::nifti::load(&path, None)
        .expect_err("2^33 samples")
        .to_string();
    assert!(
        message.contains("huge.nii.gz")
            && message.contains("dimensions 2048 × 2048 × 2048 declare 8589934592 samples")
            && message.contains("--max-samples"),
        "{message}"
    );
    // A DICOM image whose NumberOfFrames declares 10^8 frames of 24×20: refused before its
    // pixel data is decoded.
    let mut frames = dicom_slice(0, &vec![0u16; DIMS[0] * DIMS[1]], 0.0, "1.2.3");
    frames.put(DataElement::new(
        tags::NUMBER_OF_FRAMES,
        VR::IS,
        PrimitiveValue::from("100000000"),
    ));
    let folder = dir.path().join("frames");
    std::fs::create_dir_all(&folder).expect("mkdir");
    frames
        .with_meta(FileMetaTableBuilder::new().transfer_syntax(uids::EXPLICIT_VR_LITTLE_ENDIAN))
        .expect("meta")
        .write_to_file(folder.join("IM0001"))
        .expect("write dicom");
    let message = voxcube::input::formats::dicom::load(&folder, None)
        .expect_err("4.8e10 samples")
        .to_string();
    assert!(
        message.contains("IM0001")
            && message.contains("dimensions 24 × 20 × 100000000 declare 48000000000 samples"),
        "{message}"
    );
    // A JPEG-compressed image whose stream's frame header declares 30,000 × 30,000 where the
    // image says 24 × 20: refused before its decoder allocates for the stream's size.
    let mut jpeg = vec![0xFF, 0xD8, 0xFF, 0xC0, 0x00, 0x0B, 0x08];
    jpeg.extend(30_000u16.to_be_bytes());
    jpeg.extend(30_000u16.to_be_bytes());
    jpeg.extend([0x01, 0x01, 0x11, 0x00, 0xFF, 0xDA, 0x00, 0x02, 0xFF, 0xD9]);
    let mut compressed = dicom_slice(0, &[0u16; 4], 0.0, "1.2.4");
    compressed.put(DataElement::new(
        tags::PIXEL_DATA,
        VR::OB,
        dicom_core::value::Value::PixelSequence(dicom_core::value::PixelFragmentSequence::new(
            Vec::<u32>::new(),
            vec![jpeg],
        )),
    ));
    let folder = dir.path().join("jpeg");
    std::fs::create_dir_all(&folder).expect("mkdir");
    compressed
        .with_meta(FileMetaTableBuilder::new().transfer_syntax("1.2.840.10008.1.2.4.50"))
        .expect("meta")
        .write_to_file(folder.join("IM0001"))
        .expect("write dicom");
    let message = voxcube::input::formats::dicom::load(&folder, None)
        .expect_err("a 30,000² JPEG frame in a 24 × 20 image")
        .to_string();
    assert!(
        message.contains("IM0001")
            && message.contains("JPEG stream declares 30000 × 30000")
            && message.contains("Columns × Rows are 24 × 20"),
        "{message}"
    );
    // The flag: the test volume has DIMS' samples, refused under a cap one below them.
    let blob = dir.path().join("blob.nii");
    std::fs::write(&blob, nifti(4, 16, 1.0, 0.0, &le(&samples()))).expect("write");
    let n: usize = DIMS.iter().product();
    let cap = (n - 1).to_string();
    let (ok, _, err) = run(&[
        "info".as_ref(),
        blob.as_os_str(),
        "--max-samples".as_ref(),
        cap.as_ref(),
    ]);
    assert!(
        !ok && err.contains("blob.nii") && err.contains(&format!("declare {n} samples")),
        "{err}"
    );
    let (ok, _, err) = run(&[
        "info".as_ref(),
        blob.as_os_str(),
        "--max-samples".as_ref(),
        n.to_string().as_ref(),
    ]);
    assert!(ok, "{err}");
}

/// A header declaring 1000³ samples over a body of a few bytes is refused by every reader
/// whose header is text, naming the file and what the header declares against what the file
/// holds, before anything is kept for the samples (NIfTI, MRC, DICOM and the compressed
/// streams have tests of their own above).
#[test]
fn headers_declaring_more_samples_than_their_files_hold_are_refused_by_every_reader() {
    let dir = tempfile::tempdir().expect("tempdir");
    let body = "0123456789";
    let vti_ascii = "<?xml version=\"1.0\"?>\n<VTKFile type=\"ImageData\" version=\"1.0\" byte_order=\"LittleEndian\">\n<ImageData WholeExtent=\"0 999 0 999 0 999\" Origin=\"0 0 0\" Spacing=\"1 1 1\">\n<Piece Extent=\"0 999 0 999 0 999\">\n<PointData Scalars=\"v\">\n<DataArray type=\"Int16\" Name=\"v\" format=\"ascii\">\n1 2 3\n</DataArray>\n</PointData>\n</Piece>\n</ImageData>\n</VTKFile>\n";
    let vti_binary = String::from_utf8(vti_binary([4, 4, 4], &[7; 64], false))
        .expect("text")
        .replace("0 3 0 3 0 3", "0 999 0 999 0 999");
    let vti_zipped = String::from_utf8(vti_zlib([4, 4, 4], &[7; 64], 32, true))
        .expect("text")
        .replace("0 3 0 3 0 3", "0 999 0 999 0 999");
    let files: [(&str, String, &str); 6] = [
        (
            "lies.nrrd",
            format!("NRRD0004\ntype: short\ndimension: 3\nsizes: 1000 1000 1000\nencoding: raw\nendian: little\n\n{body}"),
            "truncated: expected 2000000000 bytes, found 10",
        ),
        (
            "lies.mha",
            format!("ObjectType = Image\nNDims = 3\nDimSize = 1000 1000 1000\nElementType = MET_SHORT\nElementDataFile = LOCAL\n{body}"),
            "truncated: expected 2000000000 bytes, found 10",
        ),
        (
            "lies.vtk",
            format!("# vtk DataFile Version 3.0\nx\nBINARY\nDATASET STRUCTURED_POINTS\nDIMENSIONS 1000 1000 1000\nSPACING 1 1 1\nORIGIN 0 0 0\nPOINT_DATA 1000000000\nSCALARS v short 1\nLOOKUP_TABLE default\n{body}"),
            "truncated: expected 2000000000 bytes, found 10",
        ),
        (
            "lies.vti",
            vti_ascii.to_string(),
            "data array \"v\": 3 values; its extent and components make 1000000000",
        ),
        (
            "binary-lies.vti",
            vti_binary,
            "data array \"v\": its header declares 64 bytes, 64 follow it; its extent, type and components make 1000000000",
        ),
        (
            "zipped-lies.vti",
            vti_zipped,
            "data array \"v\": its blocks hold 64 bytes; its extent, type and components make 1000000000",
        ),
    ];
    for (name, text, expected) in files {
        let path = dir.path().join(name);
        std::fs::write(&path, text).expect("write");
        let format = voxcube::input::formats::Format::from_extension(&path).expect("a format");
        let e = voxcube::input::formats::load(&path, format, None)
            .expect_err(name)
            .to_string();
        assert!(e.contains(name) && e.contains(expected), "{name}: {e}");
    }
}

/// A zlib-compressed `.vti` of byte samples, in blocks of `block` bytes (VTK's default is
/// 32,768) with VTK's header
/// (`[blocks][block size][last block size][compressed sizes…]`, the last block size 0 when the
/// last block is full, as VTK writes it), in base64, inline or appended.
fn vti_zlib(dims: [usize; 3], data: &[u8], block: usize, appended: bool) -> Vec<u8> {
    let blocks: Vec<Vec<u8>> = data.chunks(block).map(zlib).collect();
    let mut header = vec![
        blocks.len() as u32,
        block as u32,
        (data.len() % block) as u32,
    ];
    header.extend(blocks.iter().map(|b| b.len() as u32));
    vti_blocks(dims, &header, &blocks.concat(), appended)
}

/// A `.vti` of one zlib-compressed `UInt8` array: its block `header` and its `packed` blocks,
/// as given.
fn vti_blocks(dims: [usize; 3], header: &[u32], packed: &[u8], appended: bool) -> Vec<u8> {
    use base64::Engine;
    let b64 = base64::engine::general_purpose::STANDARD;
    let header: Vec<u8> = header.iter().flat_map(|n| n.to_le_bytes()).collect();
    let e = format!("0 {} 0 {} 0 {}", dims[0] - 1, dims[1] - 1, dims[2] - 1);
    let open = format!(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"ImageData\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt32\" compressor=\"vtkZLibDataCompressor\">\n<ImageData WholeExtent=\"{e}\" Origin=\"0 0 0\" Spacing=\"1 1 1\">\n<Piece Extent=\"{e}\">\n<PointData Scalars=\"v\">\n"
    );
    let mut out = open.into_bytes();
    if appended {
        out.extend(b"<DataArray type=\"UInt8\" Name=\"v\" format=\"appended\" offset=\"0\"/>\n</PointData>\n</Piece>\n</ImageData>\n<AppendedData encoding=\"base64\">\n_");
        out.extend(b64.encode(&header).as_bytes());
        out.extend(b64.encode(packed).as_bytes());
        out.extend(b"\n</AppendedData>\n</VTKFile>\n");
    } else {
        out.extend(b"<DataArray type=\"UInt8\" Name=\"v\" format=\"binary\">\n  ");
        out.extend(b64.encode(&header).as_bytes());
        out.extend(b64.encode(packed).as_bytes());
        out.extend(b"\n</DataArray>\n</PointData>\n</Piece>\n</ImageData>\n</VTKFile>\n");
    }
    out
}

/// A `.vti` whose zlib blocks lie about their sizes, or whose stream is damaged where it
/// still decodes, is refused before `vtkio` allocates or decodes anything, naming the array:
/// a changed byte of a stored (uncompressed) deflate block reads as other samples unless
/// the block's Adler-32 is checked; a block size of 2^31 would have `vtkio` allocate 4 GiB
/// for 512 samples; no blocks at all would have it count `blocks − 1`; an extent past the
/// cap is refused before any array is looked at.
#[test]
fn a_vti_whose_blocks_lie_or_are_damaged_is_refused_before_decoding() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("lies.vti");
    let dims = [8, 8, 8];
    let data: Vec<u8> = (0..512).map(|i| (i * 7 % 251) as u8).collect();
    let stored = {
        let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::none());
        e.write_all(&data).expect("zlib");
        e.finish().expect("zlib")
    };
    let n = stored.len() as u32;
    let read = |bytes: &[u8]| {
        std::fs::write(&path, bytes).expect("write");
        voxcube::input::formats::vtk::load(&path, None)
    };
    let nrrd = dir.path().join("same.nrrd");
    let header = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 8 8 8\nencoding: raw\n\n";
    std::fs::write(&nrrd, [header.as_bytes(), &data].concat()).expect("write");
    let reference = voxcube::input::formats::nrrd::load(&nrrd, None).expect("the raw samples");
    for appended in [false, true] {
        // The intact file reads its samples: the cases below differ from it only as said.
        let intact =
            read(&vti_blocks(dims, &[1, 512, 0, n], &stored, appended)).expect("the intact file");
        assert!(intact.data == reference.data, "appended {appended}");
        // One sample's byte changed inside the stored block: the stream still inflates.
        let mut damaged = stored.clone();
        let at = damaged.len() - 4 - 100;
        damaged[at] ^= 0x20;
        let cases: [(Vec<u8>, &str); 3] = [
            (
                vti_blocks(dims, &[1, 512, 0, n], &damaged, appended),
                "corrupt compressed data: data array \"v\": block 0",
            ),
            (
                vti_blocks(dims, &[2, 1 << 31, 512, n, n], &[&stored[..], &stored].concat(), appended),
                "data array \"v\": its blocks hold 2147484160 bytes; its extent, type and components make 512",
            ),
            (
                vti_blocks(dims, &[0, 512, 0], &stored, appended),
                "data array \"v\": its header declares 0 blocks",
            ),
        ];
        for (bytes, expected) in cases {
            let e = read(&bytes).expect_err(expected).to_string();
            assert!(e.contains("lies.vti") && e.contains(expected), "{e}");
        }
    }
    // An extent past the cap, refused by its samples before its array is decoded.
    let huge = String::from_utf8(vti_blocks(dims, &[1, 512, 0, n], &stored, false))
        .expect("text")
        .replace("0 7 0 7 0 7", "0 99999 0 99999 0 99999");
    let e = read(huge.as_bytes()).expect_err("too large").to_string();
    assert!(e.contains("100000 × 100000 × 100000"), "{e}");
}

/// An uncompressed `.vti` of byte samples in base64, `[bytes][data]` encoded together, inline
/// or appended.
fn vti_binary(dims: [usize; 3], data: &[u8], appended: bool) -> Vec<u8> {
    use base64::Engine;
    let b64 = base64::engine::general_purpose::STANDARD;
    let text = b64.encode([&(data.len() as u32).to_le_bytes()[..], data].concat());
    let e = format!("0 {} 0 {} 0 {}", dims[0] - 1, dims[1] - 1, dims[2] - 1);
    let open = format!(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"ImageData\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt32\">\n<ImageData WholeExtent=\"{e}\" Origin=\"0 0 0\" Spacing=\"1 1 1\">\n<Piece Extent=\"{e}\">\n<PointData Scalars=\"v\">\n"
    );
    let body = match appended {
        true => format!("<DataArray type=\"UInt8\" Name=\"v\" format=\"appended\" offset=\"0\"/>\n</PointData>\n</Piece>\n</ImageData>\n<AppendedData encoding=\"base64\">\n_{text}\n</AppendedData>\n</VTKFile>\n"),
        false => format!("<DataArray type=\"UInt8\" Name=\"v\" format=\"binary\">\n  {text}\n</DataArray>\n</PointData>\n</Piece>\n</ImageData>\n</VTKFile>\n"),
    };
    [open, body].concat().into_bytes()
}

/// A compressed `.vti` whose samples fill its last block exactly (64×64×8 bytes: one full
/// block) reads the same samples as a raw NRRD of them, inline or appended; and one that does
/// not (64×64×9) still does.
#[test]
fn a_compressed_vti_whose_last_block_is_full_reads_its_samples() {
    let dir = tempfile::tempdir().expect("tempdir");
    for nz in [8usize, 9, 16] {
        let dims = [64, 64, nz];
        let data: Vec<u8> = (0..64 * 64 * nz).map(|i| (i * 7 % 251) as u8).collect();
        let header =
            format!("NRRD0004\ntype: uchar\ndimension: 3\nsizes: 64 64 {nz}\nencoding: raw\n\n");
        let nrrd = dir.path().join("same.nrrd");
        std::fs::write(&nrrd, [header.as_bytes(), &data].concat()).expect("write");
        let reference = voxcube::input::formats::nrrd::load(&nrrd, None).expect("the raw samples");
        for appended in [false, true] {
            let path = dir.path().join("blocks.vti");
            std::fs::write(&path, vti_zlib(dims, &data, 32_768, appended)).expect("write");
            let volume = voxcube::input::formats::vtk::load(&path, None)
                .unwrap_or_else(|e| panic!("{nz} planes, appended {appended}: {e}"));
            assert!(
                volume.data == reference.data,
                "{nz} planes, appended {appended}: other samples"
            );
        }
    }
}

/// A fuzz pass over every reader: each test file, damaged at random (bytes changed, the file
/// cut short, bytes inserted, a byte changed to a base64 character), is read to a volume or refused with an error naming the file,
/// and never panics; where the format checks a checksum over the samples (gzip, zlib), a
/// volume read is the original one. `VOXCUBE_FUZZ=N` runs N damaged copies of each file (the
/// default, 150, is what CI runs); the seed is printed with any failure.
#[test]
fn damaged_files_of_every_format_are_read_right_or_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    write_all(dir.path());
    let copies: u64 = std::env::var("VOXCUBE_FUZZ")
        .ok()
        .and_then(|n| n.parse().ok())
        .unwrap_or(150);
    let files = [
        ("blob.nrrd", false),
        ("blob.nii", false),
        ("scaled.nii.gz", true),
        ("blob.mha", false),
        ("zipped.mha", true),
        ("blob.vtk", false),
        ("blob.vti", false),
        ("zipped.vti", true),
        ("appended.vti", true),
        ("binary.vti", false),
        ("binary-appended.vti", false),
        ("blob.map", false),
        ("half.ccp4.gz", true),
        ("slice.dcm", false),
        ("bare.dcm", false),
        ("rle.dcm", false),
    ];
    // One slice of each DICOM series, as a file of its own.
    for (series, name) in [
        ("series", "slice.dcm"),
        ("bare", "bare.dcm"),
        ("rle", "rle.dcm"),
    ] {
        let slice = std::fs::read_dir(dir.path().join(series))
            .expect("the series")
            .filter_map(|e| e.ok().map(|e| e.path()))
            .find(|p| p.extension().is_none_or(|e| e != "txt"))
            .expect("a slice");
        std::fs::copy(slice, dir.path().join(name)).expect("copy");
    }
    // The intact files are the coverage-guided fuzzer's seeds (`fuzz/run.sh`), each in the
    // corpus of its reader's target.
    if let Some(seeds) = std::env::var_os("VOXCUBE_FUZZ_SEEDS") {
        for (name, _) in files {
            let target = match name.split_once('.').map_or("", |(_, ext)| ext) {
                "nrrd" => "nrrd",
                "nii" => "nifti",
                "nii.gz" => "nifti_gz",
                "mha" => "metaimage",
                "vtk" => "vtk",
                "vti" => "vti",
                "map" => "mrc",
                "ccp4.gz" => "mrc_gz",
                "dcm" => "dicom",
                other => panic!("{name}: no fuzz target for .{other}"),
            };
            let corpus = Path::new(&seeds).join(target);
            std::fs::create_dir_all(&corpus).expect("mkdir");
            std::fs::copy(dir.path().join(name), corpus.join(name)).expect("copy");
        }
    }
    let damaged = tempfile::tempdir().expect("tempdir");
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    for (name, checked) in files {
        let path = dir.path().join(name);
        let format = voxcube::input::formats::Format::from_extension(&path).expect("a format");
        let original = voxcube::input::formats::load(&path, format, None).expect("the intact file");
        let bytes = std::fs::read(&path).expect("read");
        let target = damaged.path().join(name);
        let (mut read, mut refused) = (0, 0);
        for copy in 0..copies {
            let seed = next();
            let mut bad = bytes.clone();
            let at = (seed >> 8) as usize % bad.len();
            match seed % 4 {
                0 => bad.truncate(at),
                1 => bad.insert(at, (seed >> 40) as u8),
                2 => {
                    for k in 0..1 + (seed >> 60) as usize {
                        let i = (at + k * 997) % bad.len();
                        bad[i] ^= 1 + (seed >> (16 + k)) as u8 % 255;
                    }
                }
                // A text file's byte changed to another character of base64's alphabet, so
                // that the damage reaches what a text reader decodes (an XML file's base64
                // blocks and their headers) rather than stopping at a byte that is no UTF-8.
                _ => {
                    const TEXT: &[u8] =
                        b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
                    bad[at] = TEXT[(seed >> 40) as usize % TEXT.len()];
                }
            }
            std::fs::write(&target, &bad).expect("write");
            let result =
                std::panic::catch_unwind(|| voxcube::input::formats::load(&target, format, None));
            match result {
                Err(_) => panic!("{name}, copy {copy} (seed {seed:#x}): the reader panicked"),
                Ok(Ok(volume)) => {
                    // The header itself carries no checksum: a changed spacing reads as one.
                    if checked {
                        assert!(
                            volume.grid.dims() == original.grid.dims()
                                && volume.data == original.data,
                            "{name}, copy {copy} (seed {seed:#x}): read to other samples"
                        );
                    }
                    read += 1;
                }
                Ok(Err(e)) => {
                    if copy < 3 {
                        eprintln!("{name}: {e}");
                    }
                    assert!(e.to_string().contains(name), "{name}: {e}");
                    refused += 1;
                }
            }
        }
        eprintln!("{name}: {read} read, {refused} refused of {copies} damaged copies");
    }
}

/// A NIfTI-1 file with uncompressed samples streams by X planes as raw files do, so an MPI
/// rank holds only its slab: a window is the whole read's planes bit for bit, for a `.nii`
/// (little-endian i16; u16 scaled by `scl_slope`/`scl_inter` into f32, as CT is stored;
/// big-endian) and a `.hdr`/`.img` pair, at the ends, inside and of no plane. Compressed
/// files, and float samples scaled (whose range no type bounds), are read whole and kept
/// whole.
#[test]
fn a_nifti_window_is_the_whole_read_s_planes() {
    use voxcube::input::formats::{load, load_window, streams, Format};
    let dir = tempfile::tempdir().expect("tempdir");
    let w = |name: &str, bytes: &[u8]| {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).expect("write");
        path
    };
    let v = samples();
    let shifted: Vec<u8> = v
        .iter()
        .flat_map(|&x| ((i32::from(x) + 1024) as u16).to_le_bytes())
        .collect();
    let mut big = nifti(4, 16, 1.0, 0.0, &be(&v));
    // The byte order is the header's own: a big-endian header says so by its sizeof_hdr.
    let shorts = (40..56).step_by(2).chain([70, 72]);
    for (at, len) in shorts.map(|at| (at, 2)).chain([(0, 4)]) {
        big[at..at + len].reverse();
    }
    for at in (76..108).step_by(4).chain([108, 112, 116]) {
        big[at..at + 4].reverse();
    }
    let mut hdr = nifti(4, 16, 1.0, 0.0, &[]);
    hdr.truncate(348);
    hdr[108..112].copy_from_slice(&0f32.to_le_bytes());
    hdr[344..348].copy_from_slice(b"ni1\0");
    w("pair.img", &le(&v));
    let streamed = [
        w("plain.nii", &nifti(4, 16, 1.0, 0.0, &le(&v))),
        w("scaled.nii", &nifti(512, 16, 1.0, -1024.0, &shifted)),
        w("big.nii", &big),
        w("pair.hdr", &hdr),
    ];
    let whole_of = |path: &Path| load(path, Format::Nifti, None).expect("whole read");
    let reference = whole_of(&streamed[0]);
    let nx = DIMS[0] as u32;
    for path in &streamed {
        assert!(
            streams(path, Format::Nifti, None).expect("header"),
            "{}",
            path.display()
        );
        let whole = whole_of(path);
        // Every file holds the same values, the scaled one as f32.
        assert_eq!(
            whole.held_range(),
            reference.held_range(),
            "{}",
            path.display()
        );
        for planes in [0..nx, 0..2, 5..11, nx - 1..nx, 3..3] {
            let window = load_window(path, Format::Nifti, None, planes.clone()).expect("window");
            assert_eq!(window.held(), planes, "{}", path.display());
            assert_eq!(Some(window), whole.planes(planes), "{}", path.display());
        }
    }
    let floats: Vec<u8> = v.iter().flat_map(|&x| f32::from(x).to_le_bytes()).collect();
    let whole_only = [
        w("blob.nii.gz", &gzip(&nifti(4, 16, 1.0, 0.0, &le(&v)))),
        w("floats.nii", &nifti(16, 32, 2.0, 1.0, &floats)),
    ];
    for path in &whole_only {
        assert!(
            !streams(path, Format::Nifti, None).expect("header"),
            "{}",
            path.display()
        );
        let whole = whole_of(path);
        let window = load_window(path, Format::Nifti, None, 1..2).expect("read whole");
        assert_eq!(window, whole, "{}", path.display());
    }
}
