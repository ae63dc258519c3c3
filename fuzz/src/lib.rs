//! What every fuzz target does: one reader given one input, as a file of the name that
//! chooses the reader. A reader may refuse any input; it must not panic, hang, or take
//! memory out of proportion to the file, which libFuzzer catches (`-timeout`,
//! `-malloc_limit_mb`, as `run.sh` sets them).

/// Read `data` as a file named `name` (its extension chooses the reader).
pub fn read_as(name: &str, data: &[u8]) {
    // A folder of this process's own: libFuzzer's workers are processes.
    let dir = std::env::temp_dir().join(format!("voxcube-fuzz-{}", std::process::id()));
    if std::fs::create_dir_all(&dir).is_err() {
        return;
    }
    let path = dir.join(name);
    if std::fs::write(&path, data).is_err() {
        return;
    }
    if let Some(format) = voxcube::input::formats::Format::from_extension(&path) {
        let _ = voxcube::input::formats::load(&path, format, None);
    }
}
