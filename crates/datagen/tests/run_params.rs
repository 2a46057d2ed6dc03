//! The run parameters and the options `generate` runs with map onto each other, so a node
//! given `options.run_params().to_ros_args()` runs `options`.

use causal_arm_datagen::{GenerateOptions, Shard};
use causal_arm_params::RunParams;
use causal_arm_protocol::{Experiment, RunPlan};

#[test]
fn options_survive_the_trip_through_run_parameters() {
    let plan = RunPlan {
        episodes: 7,
        steps_per_episode: 500,
    };
    let mut options = GenerateOptions::new(Experiment::Exp2, plan, 42, "bags/x");
    options.exp1.sigma = 0.2;
    options.sim.velocity_scale = 2.5;
    options.exp2.move_while_switching = false;
    options.start_step = 1000;
    options.shard = Some(Shard {
        index: 1,
        count: 3,
        set_seed: 9,
    });
    let back = GenerateOptions::from_run_params(&options.run_params(), "bags/x").unwrap();
    assert_eq!(back.run_params(), options.run_params());
    assert_eq!(
        (
            back.experiment,
            back.plan,
            back.seed,
            back.start_step,
            back.shard
        ),
        (
            options.experiment,
            options.plan,
            options.seed,
            options.start_step,
            options.shard
        )
    );
    assert_eq!(
        (
            back.exp1.sigma,
            back.sim.velocity_scale,
            back.exp2.move_while_switching
        ),
        (0.2, 2.5, false)
    );
}

#[test]
fn the_profile_decides_only_what_the_parameters_leave_at_zero() {
    let run = RunParams {
        experiment: "exp1".into(),
        profile: "paper".into(),
        ..RunParams::default()
    };
    let options = GenerateOptions::from_run_params(&run, "x").unwrap();
    assert_eq!(options.plan.total_steps(), 500_000);
    let run = RunParams { steps: 10, ..run };
    assert_eq!(
        GenerateOptions::from_run_params(&run, "x")
            .unwrap()
            .plan
            .total_steps(),
        10
    );
}

#[test]
fn a_run_parameter_set_that_names_no_run_is_refused_naming_it() {
    let error = |run: RunParams| {
        GenerateOptions::from_run_params(&run, "x")
            .unwrap_err()
            .to_string()
    };
    let shard = RunParams {
        shard_count: 2,
        shard_index: 2,
        ..RunParams::default()
    };
    assert_eq!(error(shard), "shard_index 2 is not a shard of a set of 2");
    let late = RunParams {
        steps: 10,
        start_step: 10,
        ..RunParams::default()
    };
    assert_eq!(
        error(late),
        "start_step 10 is not a step of the run (it has 10 steps)"
    );
    let arm = RunParams {
        arm: "hydraulic".into(),
        ..RunParams::default()
    };
    assert!(error(arm).contains("hydraulic"));
}
