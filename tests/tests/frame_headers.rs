//! A compressed DICOM frame's own header is read from bytes a file can set to anything: any
//! bytes after a JPEG or JPEG 2000 start are a size or an error, never a panic or a hang; and
//! a whole header passes exactly when it declares the image's size.

use proptest::prelude::*;
use voxcube::input::formats::dicom_frames::check;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(4000))]

    #[test]
    fn any_bytes_after_a_codestream_start_are_read_or_refused(
        j2k in any::<bool>(),
        body in prop::collection::vec(any::<u8>(), 0..64),
        columns in 1u32..70_000,
        rows in 1u32..70_000,
    ) {
        let start: &[u8] = if j2k { &[0xFF, 0x4F, 0xFF, 0x51] } else { &[0xFF, 0xD8] };
        let fragment = [start, &body].concat();
        let _ = check([fragment.as_slice()], columns, rows);
    }

    #[test]
    fn a_whole_jpeg_frame_header_passes_exactly_at_the_image_s_size(
        width in 1u16..=u16::MAX,
        height in 1u16..=u16::MAX,
        columns in 1u32..70_000,
        rows in 1u32..70_000,
        sof in prop::sample::select(vec![0xC0u8, 0xC1, 0xC2, 0xC3, 0xF7]),
    ) {
        let mut frame = vec![0xFF, 0xD8, 0xFF, sof, 0x00, 0x0B, 0x08];
        frame.extend(height.to_be_bytes());
        frame.extend(width.to_be_bytes());
        frame.extend([0x01, 0x01, 0x11, 0x00]);
        let same = (u32::from(width), u32::from(height)) == (columns, rows);
        prop_assert_eq!(check([frame.as_slice()], columns, rows).is_ok(), same);
        // At the image's own size it passes.
        prop_assert!(check([frame.as_slice()], u32::from(width), u32::from(height)).is_ok());
    }
}
