//! Writing results: PNG images (written to a temporary file and renamed, so a failed write
//! never leaves a half image under the final name) and the pixel checksum.

use sha2::{Digest, Sha256};
use std::path::Path;

/// SHA-256 of an RGBA8 pixel buffer, lower-case hex.
pub fn pixels_sha256(rgba: &[u8]) -> String {
    Sha256::digest(rgba)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// Why an output could not be written.
#[derive(Debug, thiserror::Error)]
#[error("{path}: cannot write: {message}")]
pub struct WriteError {
    /// The file.
    pub path: String,
    /// Why.
    pub message: String,
}

/// Write `bytes` to `path` through a temporary sibling and a rename.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), WriteError> {
    let err = |e: std::io::Error| WriteError {
        path: path.display().to_string(),
        message: e.to_string(),
    };
    let tmp = path.with_extension("partial");
    std::fs::write(&tmp, bytes).map_err(err)?;
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        err(e)
    })
}

/// Encode RGBA8 pixels as PNG and write them to `path`.
pub fn write_png(path: &Path, width: u32, height: u32, rgba: &[u8]) -> Result<(), WriteError> {
    let mut png = Vec::new();
    let encoder = image::codecs::png::PngEncoder::new(&mut png);
    image::ImageEncoder::write_image(
        encoder,
        rgba,
        width,
        height,
        image::ExtendedColorType::Rgba8,
    )
    .map_err(|e| WriteError {
        path: path.display().to_string(),
        message: e.to_string(),
    })?;
    write_atomic(path, &png)
}
