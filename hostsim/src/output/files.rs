//! Writing results: PNG images and reports (a regular file is written to a temporary sibling
//! and renamed, so a failed write never leaves a half file under the final name; a device or
//! FIFO is written into, never replaced; a symlink is followed, never replaced), standard
//! output with its errors reported, and the pixel checksum.

use sha2::{Digest, Sha256};
use std::io::Write;
use std::path::{Path, PathBuf};

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

fn write_error(path: &Path, message: impl ToString) -> WriteError {
    WriteError {
        path: path.display().to_string(),
        message: message.to_string(),
    }
}

/// The file a symlink chain ends at (it may not exist yet), so writing replaces no link.
fn follow(path: &Path) -> Result<PathBuf, WriteError> {
    let mut at = path.to_path_buf();
    for _ in 0..40 {
        match std::fs::symlink_metadata(&at) {
            Ok(m) if m.file_type().is_symlink() => {
                let next = std::fs::read_link(&at).map_err(|e| write_error(path, e))?;
                at = match at.parent() {
                    Some(dir) => dir.join(next),
                    None => next,
                };
            }
            _ => return Ok(at),
        }
    }
    Err(write_error(path, "a chain of more than 40 symlinks"))
}

/// What writing `path` means.
enum Target {
    /// A regular file, existing or not: written through a temporary sibling and a rename.
    File(PathBuf),
    /// A device, FIFO or socket (or a link to one, such as `/dev/stdout`): written in place.
    Special,
}

fn target(path: &Path) -> Result<Target, WriteError> {
    match std::fs::metadata(path) {
        Ok(m) if m.is_dir() => Err(write_error(path, "is a folder, not a file")),
        Ok(m) if !m.is_file() => Ok(Target::Special),
        Ok(_) => Ok(Target::File(follow(path)?)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(Target::File(follow(path)?)),
        Err(e) => Err(write_error(path, e)),
    }
}

/// Check, before any work, that `path` can be written: not a folder, and in a folder that
/// takes a new file (a probe file is created there and removed). A device or FIFO is left
/// unopened: opening a FIFO waits for its reader.
pub fn check_writable(path: &Path) -> Result<(), WriteError> {
    let Target::File(target) = target(path)? else {
        return Ok(());
    };
    let dir = match target.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if !dir.is_dir() {
        return Err(write_error(
            path,
            format!("folder {} does not exist", dir.display()),
        ));
    }
    let probe = dir.join(format!(".voxcube-probe-{}", std::process::id()));
    std::fs::write(&probe, b"")
        .and_then(|()| std::fs::remove_file(&probe))
        .map_err(|e| {
            write_error(
                path,
                format!("folder {} takes no new file ({e})", dir.display()),
            )
        })
}

/// Whether `path` is (or will be) a regular file, which may be written more than once: a
/// device or FIFO takes one write, by its reader's count.
pub fn rewritable(path: &Path) -> bool {
    matches!(target(path), Ok(Target::File(_)))
}

/// Write `bytes` to `path`: a regular file through a temporary sibling and a rename; a
/// device or FIFO in place; through a symlink to its target.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), WriteError> {
    let err = |e: std::io::Error| write_error(path, e);
    let target = match target(path)? {
        Target::File(t) => t,
        Target::Special => {
            let mut f = std::fs::OpenOptions::new()
                .write(true)
                .open(path)
                .map_err(err)?;
            return f.write_all(bytes).and_then(|()| f.flush()).map_err(err);
        }
    };
    let mut name = target.file_name().unwrap_or_default().to_os_string();
    name.push(".partial");
    let tmp = target.with_file_name(name);
    std::fs::write(&tmp, bytes).map_err(err)?;
    std::fs::rename(&tmp, &target).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        err(e)
    })
}

/// Write `text` to standard output and flush it: a failed write (a full disk, a closed pipe)
/// is an error, not a silent loss at exit.
pub fn stdout(text: &str) -> Result<(), WriteError> {
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())
        .and_then(|()| out.flush())
        .map_err(|e| WriteError {
            path: "standard output".into(),
            message: e.to_string(),
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
