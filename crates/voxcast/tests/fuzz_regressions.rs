//! Every input kept in `tests/fuzz-regressions/<target>/` goes through the
//! same entry point as the fuzz target (`voxcast::fuzz_support::run`) and
//! must come back without a panic, within a memory bound and in reasonable
//! time. The inputs are what the fuzzers (`fuzz/`) found bugs with, and
//! hand-made hostile ones (`hostile-*`: headers that claim billions of
//! voxels over a few bytes, decompression bombs).
//!
//! This test binary counts the bytes allocated (a wrapper around the system
//! allocator), so a reader that allocates what a lying header claims fails
//! here: the peak allocation while reading one input must stay under
//! [`PEAK_LIMIT`], and an allocation that would take the live total past
//! [`HARD_LIMIT`] fails at once (the process aborts with "memory allocation
//! of N bytes failed") instead of exhausting the CI machine.

use std::alloc::{GlobalAlloc, Layout, System};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};
use voxcast::fuzz_support::{run, Target};

/// Largest peak of live heap bytes while one input is read.
const PEAK_LIMIT: usize = 256 << 20;
/// Live heap bytes past which allocations fail.
const HARD_LIMIT: usize = 1 << 30;
/// Longest time for one input (debug build).
const TIME_LIMIT: Duration = Duration::from_secs(60);

struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if !reserve(layout.size()) {
            return std::ptr::null_mut();
        }
        let p = unsafe { System.alloc(layout) };
        if p.is_null() {
            LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if !reserve(layout.size()) {
            return std::ptr::null_mut();
        }
        let p = unsafe { System.alloc_zeroed(layout) };
        if p.is_null() {
            LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let old = layout.size();
        if new_size > old && !reserve(new_size - old) {
            return std::ptr::null_mut();
        }
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if p.is_null() {
            if new_size > old {
                LIVE.fetch_sub(new_size - old, Ordering::Relaxed);
            }
        } else if new_size < old {
            LIVE.fetch_sub(old - new_size, Ordering::Relaxed);
        }
        p
    }
}

/// Counts `n` more live bytes unless that passes [`HARD_LIMIT`]. The peak
/// counts refused attempts too: a reader that falls back gracefully when a
/// huge allocation fails has still tried to make it.
fn reserve(n: usize) -> bool {
    let live = LIVE.fetch_add(n, Ordering::Relaxed).saturating_add(n);
    PEAK.fetch_max(live, Ordering::Relaxed);
    if live > HARD_LIMIT {
        LIVE.fetch_sub(n, Ordering::Relaxed);
        return false;
    }
    true
}

#[global_allocator]
static ALLOC: Counting = Counting;

fn regressions_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz-regressions")
}

/// `(target, file)` for every saved input, sorted.
fn inputs() -> Vec<(Target, PathBuf)> {
    let mut out = Vec::new();
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(regressions_dir())
        .expect("tests/fuzz-regressions exists")
        .map(|e| e.expect("readable folder").path())
        .filter(|p| p.is_dir())
        .collect();
    dirs.sort();
    for d in dirs {
        let name = d.file_name().unwrap().to_string_lossy().to_string();
        let target = Target::from_name(&name)
            .unwrap_or_else(|| panic!("{}: not a fuzz target name", d.display()));
        let mut files: Vec<PathBuf> = std::fs::read_dir(&d)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.is_file())
            .collect();
        files.sort();
        out.extend(files.into_iter().map(|f| (target, f)));
    }
    out
}

/// The only test in this binary, so that one input at a time is measured.
#[test]
fn fuzz_regression_inputs_are_read_without_panic_within_bounds() {
    let all = inputs();
    assert!(
        !all.is_empty(),
        "no inputs in {}",
        regressions_dir().display()
    );
    let mut failures = Vec::new();
    for (target, file) in &all {
        let bytes = std::fs::read(file).unwrap();
        let live_before = LIVE.load(Ordering::Relaxed);
        PEAK.store(live_before, Ordering::Relaxed);
        let start = Instant::now();
        let r = std::panic::catch_unwind(|| run(*target, &bytes));
        let took = start.elapsed();
        let peak = PEAK.load(Ordering::Relaxed).saturating_sub(live_before);
        let name = format!(
            "{}/{}",
            target.name(),
            file.file_name().unwrap().to_string_lossy()
        );
        match r {
            Err(_) => failures.push(format!("{name}: panicked")),
            Ok(outcomes) => {
                assert!(
                    !outcomes.is_empty() || *target == Target::Raw,
                    "{name}: no reader ran"
                );
                for o in &outcomes {
                    if let Err(e) = o {
                        // An error must say what is wrong.
                        assert!(!e.to_string().trim().is_empty(), "{name}: empty error");
                    }
                }
            }
        }
        if peak > PEAK_LIMIT {
            failures.push(format!(
                "{name}: peak allocation {peak} bytes > {PEAK_LIMIT}"
            ));
        }
        if took > TIME_LIMIT {
            failures.push(format!("{name}: took {took:?} > {TIME_LIMIT:?}"));
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} fuzz regression inputs failed:\n{}",
        failures.len(),
        all.len(),
        failures.join("\n")
    );
}
