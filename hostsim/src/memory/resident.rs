//! Memory as the operating system counts it: the resident memory a process has measured
//! (what a node's rank (MPI) or the host's process really held, beside the budget's model of
//! it), and the machine's physical memory (what `--machine host` shares among its nodes).
//!
//! Invariant: a figure is the kernel's own (`VmHWM` of `/proc/self/status`, `MemTotal` of
//! `/proc/meminfo`, Linux), never an estimate; where the system gives none the answer is
//! `None`.

/// The most memory this process has held resident so far, bytes.
pub fn peak() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    peak_in(&status)
}

/// This machine's physical memory, bytes.
pub fn physical() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    kib_field(&info, "MemTotal:")
}

/// `VmHWM` of a `/proc/<pid>/status` text, bytes.
fn peak_in(status: &str) -> Option<u64> {
    kib_field(status, "VmHWM:")
}

/// The field `key` of a `/proc` text that gives it in kB (`key:   1234 kB`), bytes.
fn kib_field(text: &str, key: &str) -> Option<u64> {
    let line = text.lines().find_map(|l| l.strip_prefix(key))?;
    let kib = line.trim().strip_suffix("kB")?.trim().parse::<u64>().ok()?;
    kib.checked_mul(1024)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_high_water_mark_is_read_in_bytes() {
        let status = "Name:\tvoxcube\nVmPeak:\t  900 kB\nVmHWM:\t   1234 kB\nVmRSS:\t 1000 kB\n";
        assert_eq!(peak_in(status), Some(1234 * 1024));
        assert_eq!(peak_in("VmRSS:\t 1000 kB\n"), None);
        assert_eq!(peak_in("VmHWM:\t lots kB\n"), None);
    }

    #[test]
    fn the_physical_memory_is_read_in_bytes() {
        let info = "MemTotal:       24570788 kB\nMemFree:        23000000 kB\n";
        assert_eq!(kib_field(info, "MemTotal:"), Some(24_570_788 * 1024));
        assert_eq!(kib_field("MemFree: 1 kB\n", "MemTotal:"), None);
        if let Some(bytes) = physical() {
            // Linux: this process runs in it.
            assert!(bytes >= peak().unwrap_or(0), "{bytes}");
        }
    }

    #[test]
    fn this_process_holds_at_least_what_it_just_touched() {
        let Some(before) = peak() else {
            // Not Linux: nothing to measure.
            return;
        };
        let touched = vec![1u8; 64 << 20];
        let after = peak().unwrap_or(0);
        assert!(after >= before && after >= 64 << 20, "{before} -> {after}");
        assert_eq!(touched.iter().map(|&b| u64::from(b)).sum::<u64>(), 64 << 20);
    }
}
