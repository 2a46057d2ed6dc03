//! `--resume`: a run cut short and resumed writes the very bag an uninterrupted run of the
//! seed writes, at an episode boundary and mid-episode; a bag of another run is refused.

use std::path::{Path, PathBuf};

use causal_arm_bag::BagReader;
use causal_arm_datagen::{
    BagSink, GenerateOptions, StepSink, drive_range, fast_forward, generate, generate_resumed,
    interrupted_dir, resume_point,
};
use causal_arm_protocol::{Experiment, RunPlan};

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("causal-arm-resume-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn options(out: &Path) -> GenerateOptions {
    let plan = RunPlan {
        episodes: 3,
        steps_per_episode: 40,
    };
    GenerateOptions::new(Experiment::Exp2, plan, 5, out)
}

/// Every message of the bag: topic, log time and CDR bytes, in file order.
fn content(dir: &Path) -> Vec<(String, u64, Vec<u8>)> {
    let reader = BagReader::open(dir).unwrap();
    reader
        .messages()
        .map(|m| m.unwrap())
        .map(|m| (m.topic, m.log_time_ns, m.data))
        .collect()
}

/// A run killed after `landed` steps reached closed chunks and `more` further steps and
/// half a step did not: what a SIGKILL leaves behind.
fn killed_run(out: &Path, landed: u64, more: u64) {
    let options = options(out);
    let (mut sim, mut babbler) = fast_forward(&options, 0).unwrap();
    let mut sink = BagSink::create(out, false, &options).unwrap();
    sink.latched(&sim.latched_messages()).unwrap();
    let plan = &options.plan;
    drive_range(
        plan,
        0..landed,
        &mut sim,
        &mut babbler,
        &mut sink,
        &mut |_, _| {},
    )
    .unwrap();
    sink.land().unwrap();
    let cut = landed..landed + more;
    drive_range(plan, cut, &mut sim, &mut babbler, &mut sink, &mut |_, _| {}).unwrap();
    let state = sim.state();
    sink.state(state.stamp_ns, sim.step_messages(&state))
        .unwrap();
    // No finish, no flush: the process is gone.
    std::mem::forget(sink);
}

#[test]
fn a_resumed_run_writes_the_bag_of_an_uninterrupted_one() {
    let dir = temp_dir("equal");
    let whole = dir.join("whole");
    generate(&options(&whole), &mut |_, _| {}).unwrap();
    let want = content(&whole);
    // At an episode boundary (40) and mid-episode (55).
    for landed in [40, 55] {
        let cut = dir.join(format!("cut{landed}"));
        killed_run(&cut, landed, 7);
        assert_eq!(resume_point(&cut, &options(&cut)).unwrap(), landed);
        let summary = generate_resumed(&options(&cut), &mut |_, _| {}).unwrap();
        assert_eq!((summary.resumed_at, summary.steps), (landed, 120));
        assert!(!interrupted_dir(&cut).exists());
        let got = content(&cut);
        assert_eq!(got.len(), want.len(), "resumed at {landed}");
        for (i, (g, w)) in got.iter().zip(&want).enumerate() {
            assert!(
                g == w,
                "resumed at {landed}: message {i} ({} at {}) differs",
                g.0,
                g.1
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn resuming_another_run_or_an_unfinished_resume_is_refused_by_name() {
    let dir = temp_dir("refused");
    let cut = dir.join("cut");
    killed_run(&cut, 20, 3);
    let mut other = options(&cut);
    other.seed = 6;
    let err = generate_resumed(&other, &mut |_, _| {})
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("seed = 5") && err.contains("seed = 6"),
        "{err}"
    );
    std::fs::create_dir_all(interrupted_dir(&cut)).unwrap();
    let err = generate_resumed(&options(&cut), &mut |_, _| {})
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("cut.interrupted") && err.contains("move it back"),
        "{err}"
    );
    std::fs::remove_dir_all(interrupted_dir(&cut)).unwrap();
    let err = BagSink::resume(&cut, &options(&cut), Some(21))
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("holds 20 complete steps"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}
