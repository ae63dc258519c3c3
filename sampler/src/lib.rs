//! A sampling profiler of the instruction a thread is at, for voxcube's benchmarks. A timer
//! on the process's CPU time (`setitimer(ITIMER_PROF)`) raises `SIGPROF` in a running thread;
//! where that thread has asked to be sampled ([`sampled`]), the handler keeps the address of
//! the instruction it interrupted. The addresses are read back with the functions and source
//! files at each, the inlined ones included ([`Samples::resolved`]). That is what a profiler
//! that keys its samples by function and call chain (pprof's) cannot give: a sample loop the
//! compiler merged into one function, reads and shading and compositing, is one function
//! to it, and one frame's files stand for all of its samples.
//!
//! Only x86-64 Linux reads the interrupted address; elsewhere [`Profiler::start`] says so.
//!
//! Invariants: the handler reads a thread-local flag and the context the kernel hands it and
//! writes atomics, nothing else (so it is safe to run between any two instructions); one
//! profiler runs at a time; once installed, the handler stays (a `SIGPROF` raised just before
//! the timer stopped may still arrive, and the signal's default action ends the process).

use std::cell::Cell;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::OnceLock;
use std::time::Duration;

/// The most addresses a profile keeps; later samples are counted as lost.
pub const CAPACITY: usize = 1 << 16;

static ADDRESSES: [AtomicUsize; CAPACITY] = [const { AtomicUsize::new(0) }; CAPACITY];
static TAKEN: AtomicUsize = AtomicUsize::new(0);
static RUNNING: AtomicBool = AtomicBool::new(false);
/// Whether the handler is installed, decided once: a refused installation is never followed
/// by an armed timer, whose signal would then meet its default action.
static INSTALLED: OnceLock<Result<(), std::io::ErrorKind>> = OnceLock::new();

thread_local! {
    /// Whether this thread's samples are kept. Initialised without code (`const`) and never
    /// dropped, so reading it in the handler is a plain thread-local load.
    static SAMPLED: Cell<bool> = const { Cell::new(false) };
}

/// Run `f` with the current thread sampled by a running profiler (by none, none is taken).
/// What the thread does outside it, however busy, leaves no sample.
pub fn sampled<R>(f: impl FnOnce() -> R) -> R {
    /// Puts the thread's flag back as it was, also when `f` unwinds.
    struct Restore(bool);
    impl Drop for Restore {
        fn drop(&mut self) {
            let _ = SAMPLED.try_with(|s| s.set(self.0));
        }
    }
    let _restore = Restore(SAMPLED.with(|s| s.replace(true)));
    f()
}

/// Why a profiler did not start.
#[derive(Debug)]
pub enum StartError {
    /// Another profiler is running.
    Running,
    /// This system's interrupted context is not read here (only x86-64 Linux's is).
    Unsupported,
    /// The signal handler or the timer was refused.
    System(std::io::Error),
}

impl std::fmt::Display for StartError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            StartError::Running => write!(f, "another profile is being taken"),
            StartError::Unsupported => {
                write!(
                    f,
                    "sampling reads the interrupted instruction on x86-64 Linux only"
                )
            }
            StartError::System(e) => write!(f, "the profiling timer was refused: {e}"),
        }
    }
}

impl std::error::Error for StartError {}

/// A running profile: stopped by [`Profiler::stop`] (or dropped, discarding it).
#[derive(Debug)]
pub struct Profiler {
    stopped: bool,
}

impl Profiler {
    /// Sample the sampled threads every `period` of the process's CPU time. The system's
    /// timer fires at its own tick at the finest (4 ms on a kernel of 250 Hz), for all
    /// threads together.
    pub fn start(period: Duration) -> Result<Profiler, StartError> {
        if !cfg!(all(target_arch = "x86_64", target_os = "linux")) {
            return Err(StartError::Unsupported);
        }
        if RUNNING.swap(true, Ordering::AcqRel) {
            return Err(StartError::Running);
        }
        for a in &ADDRESSES {
            a.store(0, Ordering::Relaxed);
        }
        TAKEN.store(0, Ordering::Release);
        let installed = INSTALLED.get_or_init(|| install().map_err(|e| e.kind()));
        let armed = installed
            .map_err(std::io::Error::from)
            .and_then(|()| arm(period));
        if let Err(e) = armed {
            RUNNING.store(false, Ordering::Release);
            return Err(StartError::System(e));
        }
        Ok(Profiler { stopped: false })
    }

    /// Stop the timer and read the samples taken.
    pub fn stop(mut self) -> Samples {
        self.disarm();
        let taken = TAKEN.load(Ordering::Acquire);
        let addresses = ADDRESSES[..taken.min(CAPACITY)]
            .iter()
            .map(|a| a.load(Ordering::Relaxed))
            .filter(|&a| a != 0)
            .collect();
        Samples {
            addresses,
            lost: taken.saturating_sub(CAPACITY),
        }
    }

    fn disarm(&mut self) {
        if !self.stopped {
            // A zero timer stops it; this cannot fail with valid arguments, and if it did,
            // the handler below ignores what comes once `RUNNING` is down.
            let _ = set_timer(Duration::ZERO);
            RUNNING.store(false, Ordering::Release);
            self.stopped = true;
        }
    }
}

impl Drop for Profiler {
    fn drop(&mut self) {
        self.disarm();
    }
}

/// The addresses a profile took.
#[derive(Clone, Debug, Default)]
pub struct Samples {
    addresses: Vec<usize>,
    lost: usize,
}

/// One function at a sampled address: its name and, where the binary's line tables say,
/// its source file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Frame {
    /// The function, demangled, without its hash.
    pub function: String,
    /// Its source file.
    pub file: Option<String>,
}

impl Samples {
    /// Samples kept.
    pub fn len(&self) -> usize {
        self.addresses.len()
    }

    /// Whether none was kept.
    pub fn is_empty(&self) -> bool {
        self.addresses.is_empty()
    }

    /// Samples taken beyond [`CAPACITY`], not kept.
    pub fn lost(&self) -> usize {
        self.lost
    }

    /// Each distinct address's count and the functions at it, innermost (inlined) first.
    pub fn resolved(&self) -> Vec<(usize, Vec<Frame>)> {
        let mut counts = std::collections::BTreeMap::<usize, usize>::new();
        for &a in &self.addresses {
            *counts.entry(a).or_default() += 1;
        }
        counts
            .into_iter()
            .map(|(address, n)| {
                let mut frames = Vec::new();
                backtrace::resolve(address as *mut std::ffi::c_void, |symbol| {
                    frames.push(Frame {
                        function: symbol
                            .name()
                            .map_or_else(String::new, |name| format!("{name:#}")),
                        file: symbol.filename().map(|f| f.display().to_string()),
                    });
                });
                (n, frames)
            })
            .collect()
    }
}

/// The handler: keep the interrupted address where this thread is sampled.
extern "C" fn on_signal(_: libc::c_int, _: *mut libc::siginfo_t, context: *mut libc::c_void) {
    if !RUNNING.load(Ordering::Relaxed) || !SAMPLED.try_with(Cell::get).unwrap_or(false) {
        return;
    }
    if let Some(address) = interrupted(context) {
        let i = TAKEN.fetch_add(1, Ordering::Relaxed);
        if let Some(slot) = ADDRESSES.get(i) {
            slot.store(address, Ordering::Relaxed);
        }
    }
}

/// The interrupted instruction's address in the context a `SA_SIGINFO` handler is given.
#[cfg(all(target_arch = "x86_64", target_os = "linux"))]
fn interrupted(context: *mut libc::c_void) -> Option<usize> {
    if context.is_null() {
        return None;
    }
    // SAFETY: the kernel passes a `SA_SIGINFO` handler a pointer to the interrupted
    // `ucontext_t` as its third argument, valid while the handler runs; it is not null
    // (checked) and only one register of it is read.
    let rip =
        unsafe { (*context.cast::<libc::ucontext_t>()).uc_mcontext.gregs[libc::REG_RIP as usize] };
    usize::try_from(rip).ok()
}

#[cfg(not(all(target_arch = "x86_64", target_os = "linux")))]
fn interrupted(_: *mut libc::c_void) -> Option<usize> {
    None
}

/// Install [`on_signal`] for `SIGPROF`.
fn install() -> std::io::Result<()> {
    // SAFETY: `sigaction` is plain data, for which all zeros is a valid value (no handler,
    // empty flags); the fields that matter are set below.
    let mut action: libc::sigaction = unsafe { std::mem::zeroed() };
    action.sa_sigaction = on_signal as *const () as libc::sighandler_t;
    action.sa_flags = libc::SA_SIGINFO | libc::SA_RESTART;
    // SAFETY: both calls are given valid pointers to live values; the handler installed only
    // touches atomics and a thread-local flag (module invariant).
    let status = unsafe {
        libc::sigemptyset(&mut action.sa_mask);
        libc::sigaction(libc::SIGPROF, &action, std::ptr::null_mut())
    };
    if status == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

/// Arm the timer every `period` (at least a microsecond).
fn arm(period: Duration) -> std::io::Result<()> {
    set_timer(period.max(Duration::from_micros(1)))
}

/// Set the process's CPU-time timer to fire every `period` (zero: stop it).
fn set_timer(period: Duration) -> std::io::Result<()> {
    let every = libc::timeval {
        tv_sec: libc::time_t::try_from(period.as_secs()).unwrap_or(libc::time_t::MAX),
        tv_usec: libc::suseconds_t::from(period.subsec_micros() as i32),
    };
    let timer = libc::itimerval {
        it_interval: every,
        it_value: every,
    };
    // SAFETY: a valid pointer to a live `itimerval`, and none for the old value.
    let status = unsafe { libc::setitimer(libc::ITIMER_PROF, &timer, std::ptr::null_mut()) };
    if status == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

#[cfg(all(test, target_arch = "x86_64", target_os = "linux"))]
mod tests {
    use super::*;
    use std::sync::Mutex;
    use std::time::Instant;

    /// One profile at a time in this process: the tests that take one hold this.
    static ONE: Mutex<()> = Mutex::new(());

    /// The process's profiler to this test alone, until the guard is dropped.
    fn alone() -> std::sync::MutexGuard<'static, ()> {
        ONE.lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// Work the compiler cannot remove, for `wall`.
    #[inline(never)]
    fn busy(wall: Duration) -> u64 {
        let start = Instant::now();
        let mut x = 1u64;
        while start.elapsed() < wall {
            for _ in 0..10_000 {
                x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(1));
            }
        }
        x
    }

    #[test]
    fn a_sampled_thread_s_samples_resolve_to_the_code_it_ran_and_an_unsampled_one_leaves_none() {
        let _one = alone();
        let profiler = Profiler::start(Duration::from_millis(1)).expect("the profiler starts");
        sampled(|| busy(Duration::from_millis(400)));
        let samples = profiler.stop();
        assert!(
            !samples.is_empty(),
            "no sample in 0.4 s of a sampled thread's work"
        );
        let resolved = samples.resolved();
        let here = resolved
            .iter()
            .filter(|(_, frames)| {
                frames.iter().any(|f| {
                    f.function.ends_with("tests::busy")
                        && f.file.as_deref().is_some_and(|p| p.ends_with("lib.rs"))
                })
            })
            .map(|(n, _)| n)
            .sum::<usize>();
        assert!(
            2 * here > samples.len(),
            "{here} of {} samples in the busy function: {resolved:?}",
            samples.len()
        );
        // The control: the same work, not sampled.
        let profiler = Profiler::start(Duration::from_millis(1)).expect("the profiler starts");
        busy(Duration::from_millis(200));
        assert!(
            profiler.stop().is_empty(),
            "an unsampled thread left samples"
        );
    }

    #[test]
    fn one_profile_at_a_time() {
        let _one = alone();
        let first = Profiler::start(Duration::from_millis(1)).expect("the profiler starts");
        assert!(matches!(
            Profiler::start(Duration::from_millis(1)),
            Err(StartError::Running)
        ));
        drop(first);
        let again = Profiler::start(Duration::from_millis(1)).expect("it starts once stopped");
        assert_eq!(again.stop().lost(), 0);
    }

    #[test]
    fn the_flag_is_the_thread_s_own_and_comes_back() {
        assert!(!SAMPLED.with(Cell::get));
        sampled(|| {
            assert!(SAMPLED.with(Cell::get));
            std::thread::scope(|s| {
                s.spawn(|| assert!(!SAMPLED.with(Cell::get)));
            });
            sampled(|| ());
            assert!(SAMPLED.with(Cell::get));
        });
        assert!(!SAMPLED.with(Cell::get));
    }
}
