//! The seed corpus of `tests/corpus/`, and bounded random mutations of it, through every
//! fuzz target: no input may panic or hang. Bounded to about a minute in all
//! (`CAUSAL_ARM_FUZZ_SECONDS` per target, default 8). Findings are saved under
//! `target/fuzz-findings/` to be turned into corpus entries once fixed.

use std::time::Duration;

use causal_arm_fuzz::{Target, corpus_root, exercise};

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
