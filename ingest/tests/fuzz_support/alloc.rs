//! A counting global allocator for the fuzz test binary: while a case runs on a thread ("armed"), it records the
//! largest single allocation (or reallocation target) that thread makes. Counters are thread-local, so the test
//! harness may run several readers' tests in parallel.
//!
//! An armed request above [`HARD_CAP`] is not attempted: the allocator saves the running case (see
//! [`set_current_case`]) to the regression directory, prints how to replay it and aborts the process, because
//! such a request either fails (and `handle_alloc_error` aborts without a trace) or takes the machine's memory.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::io::Write;
use std::path::PathBuf;

/// Largest single allocation a case may request before the process saves it and aborts. Every reader's bound
/// (see `fuzz_support::alloc_bound`) is far below this; 1 GiB is the size at which the request itself, not the
/// assertion after the case, becomes the danger on a CI machine.
pub const HARD_CAP: usize = 1 << 30;

/// The system allocator with per-thread accounting of the largest request while armed.
#[derive(Debug)]
pub struct CountingAlloc;

/// The running case, for the oversize path: its bytes (valid while armed), where to save them, its id.
#[derive(Clone, Copy)]
struct CurrentCase {
    ptr: *const u8,
    len: usize,
    reader: &'static str,
    seed: u64,
    case: u64,
}

thread_local! {
    static ARMED: Cell<bool> = const { Cell::new(false) };
    static LARGEST: Cell<usize> = const { Cell::new(0) };
    static CURRENT: Cell<Option<CurrentCase>> = const { Cell::new(None) };
}

/// Starts counting on this thread (resets the largest request to 0).
pub fn arm() {
    LARGEST.with(|l| l.set(0));
    ARMED.with(|a| a.set(true));
}

/// Stops counting on this thread; returns the largest single request since [`arm`].
pub fn disarm() -> usize {
    ARMED.with(|a| a.set(false));
    LARGEST.with(Cell::get)
}

/// Registers the case about to run on this thread so that an oversize request can save it. `bytes` must stay
/// alive and unmoved until [`clear_current_case`].
pub fn set_current_case(bytes: &[u8], reader: &'static str, seed: u64, case: u64) {
    CURRENT.with(|c| c.set(Some(CurrentCase { ptr: bytes.as_ptr(), len: bytes.len(), reader, seed, case })));
}

/// Forgets the case registered by [`set_current_case`].
pub fn clear_current_case() {
    CURRENT.with(|c| c.set(None));
}

/// When non-zero, the first armed request above this many bytes prints a backtrace (`IPT_FUZZ_TRACE_ALLOC`, set by
/// the harness): it shows which code allocated out of proportion in a saved case.
pub static TRACE_ABOVE: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

#[inline]
fn record(size: usize) {
    // `try_with`: during thread teardown the thread-locals may be gone; such allocations are not a case's.
    let armed = ARMED.try_with(Cell::get).unwrap_or(false);
    if !armed {
        return;
    }
    let _ = LARGEST.try_with(|l| l.set(l.get().max(size)));
    if size > HARD_CAP {
        oversize(size);
    }
    let trace = TRACE_ABOVE.load(std::sync::atomic::Ordering::Relaxed);
    if trace != 0 && size > trace {
        trace_allocation(size);
    }
}

#[cold]
fn trace_allocation(size: usize) {
    // Disarmed while capturing (the backtrace allocates); traced once.
    ARMED.with(|a| a.set(false));
    TRACE_ABOVE.store(0, std::sync::atomic::Ordering::Relaxed);
    let bt = std::backtrace::Backtrace::force_capture();
    let _ = writeln!(std::io::stderr(), "fuzz: allocation of {size} bytes at\n{bt}");
    ARMED.with(|a| a.set(true));
}

#[cold]
fn oversize(size: usize) -> ! {
    // Disarmed first: saving allocates, and must not recurse into this path.
    ARMED.with(|a| a.set(false));
    let case = CURRENT.with(Cell::get);
    let mut err = std::io::stderr();
    let _ = writeln!(err, "fuzz: a case requested a single allocation of {size} bytes (cap {HARD_CAP})");
    if let Some(c) = case {
        // SAFETY: `set_current_case` requires the bytes to stay alive and unmoved while the case runs, and we are
        // inside the case (armed).
        let bytes = unsafe { std::slice::from_raw_parts(c.ptr, c.len) };
        let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz/regressions").join(c.reader);
        let path = dir.join(format!("{}-{}.bin", c.seed, c.case));
        let saved = std::fs::create_dir_all(&dir).and_then(|()| std::fs::write(&path, bytes));
        let _ = writeln!(
            err,
            "fuzz: reader {} seed {} case {}: saved to {} ({saved:?}); aborting",
            c.reader,
            c.seed,
            c.case,
            path.display()
        );
    }
    std::process::abort();
}

// SAFETY: every method forwards to `System` with the caller's arguments; the accounting touches only
// const-initialised thread-locals without destructors (no allocation, no reentrancy) except on the oversize
// path, which disarms before allocating and never returns.
unsafe impl GlobalAlloc for CountingAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        record(layout.size());
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        record(layout.size());
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        record(new_size);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}
