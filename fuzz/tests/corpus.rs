//! The seed corpus of `tests/corpus/`, and bounded random mutations of it, through every
//! fuzz target: no input may panic or hang. Bounded to about a minute in all
//! (`CAUSAL_ARM_FUZZ_SECONDS` per target, default 8). Findings are saved under
//! `target/fuzz-findings/` to be turned into corpus entries once fixed.

use std::alloc::{GlobalAlloc, Layout, System};
use std::time::Duration;

use causal_arm_fuzz::{Target, corpus_root, exercise};

/// Refuses any single allocation over 1 GiB, as libFuzzer's `-malloc_limit_mb` does: a
/// length field taken on trust shows up as "memory allocation of N bytes failed" (an
/// abort that fails the test) instead of passing on a machine with enough memory.
struct Bounded;

const MAX_ALLOCATION: usize = 1 << 30;

unsafe impl GlobalAlloc for Bounded {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        match layout.size() > MAX_ALLOCATION {
            true => std::ptr::null_mut(),
            false => unsafe { System.alloc(layout) },
        }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        match new_size > MAX_ALLOCATION {
            true => std::ptr::null_mut(),
            false => unsafe { System.realloc(ptr, layout, new_size) },
        }
    }
}

#[global_allocator]
static ALLOCATOR: Bounded = Bounded;

#[test]
fn no_corpus_entry_or_mutation_of_one_panics_or_hangs() {
    let seconds: f64 = std::env::var("CAUSAL_ARM_FUZZ_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(8.0);
    let findings_dir =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/fuzz-findings");
    let mut findings = Vec::new();
    for target in Target::ALL {
        let report = exercise(
            target,
            &corpus_root(),
            &findings_dir,
            Duration::from_secs_f64(seconds),
            0x5eed,
        )
        .unwrap_or_else(|e| panic!("corpus of {}: {e}", target.name()));
        println!(
            "{}: {} seeds, {} mutants, {} findings",
            target.name(),
            report.seeds,
            report.mutants,
            report.findings.len()
        );
        assert!(report.seeds > 0, "tests/corpus/{} is empty", target.name());
        findings.extend(report.findings);
    }
    assert!(findings.is_empty(), "findings: {findings:#?}");
}
