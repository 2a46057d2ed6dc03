//! cargo-fuzz target `cdr` (see `causal_arm_fuzz::Target`); run by `tests/fuzz/run.sh`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| causal_arm_fuzz::Target::from_name("cdr")
    .expect("a known target")
    .run(data));
