//! cargo-fuzz target `trainer_request` (see `causal_arm_fuzz::Target`); run by `tests/fuzz/run.sh`.
#![no_main]

libfuzzer_sys::fuzz_target!(
    |data: &[u8]| causal_arm_fuzz::Target::from_name("trainer_request")
        .expect("a known target")
        .run(data)
);
