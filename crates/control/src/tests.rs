//! Tests of the parent module.

use super::*;

#[test]
fn the_ims_next_state_features_are_found_in_the_state_or_named() {
    let names = |n: &[&str]| n.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    let state = names(&["theta0", "ef_x", "ef_y"]);
    assert_eq!(
        next_state_indices(&state, &names(&["ef_y", "ef_x"])).unwrap(),
        [2, 1]
    );
    let err = next_state_indices(&state, &names(&["ef_z"])).unwrap_err();
    assert!(
        err.to_string().contains("ef_z is not a state feature"),
        "{err}"
    );
    let err = next_state_indices(&state, &[]).unwrap_err();
    assert!(err.to_string().contains("not an inverse model"), "{err}");
}
use causal_arm_sim::SimConfig;

fn sim() -> Simulator {
    Simulator::new(SimConfig::default()).unwrap()
}

fn exp1() -> StateLayout {
    StateLayout::of(Experiment::Exp1, &ArmModel::embedded())
}

#[test]
fn a_jacobian_step_moves_the_effector_by_the_asked_displacement() {
    let model = ArmModel::embedded();
    let q = [0.3, 0.5, -0.2, -1.0, 0.1, 0.7, 0.0];
    let dx = Vector3::new(0.004, -0.003, 0.002);
    let dq = jacobian_step(&model, &q, &dx, 1e-4).unwrap();
    let moved: Vec<f64> = q.iter().zip(dq).map(|(a, b)| a + b).collect();
    let before = model.ef_pose(&q).unwrap().translation.vector;
    let after = model.ef_pose(&moved).unwrap().translation.vector;
    assert!(
        ((after - before) - dx).norm() < 1e-4,
        "{:?}",
        after - before
    );
}

#[test]
fn targets_are_reachable_and_seeded() {
    let model = ArmModel::embedded();
    let a = sample_targets(&model, 5, 0.35, 1).unwrap();
    assert_eq!(a, sample_targets(&model, 5, 0.35, 1).unwrap());
    assert_ne!(a, sample_targets(&model, 5, 0.35, 2).unwrap());
    assert!(sample_targets(&model, 1, -1.0, 1).is_err());
}

/// The exact inverse model of exp 1 (a = θ* − θ), to check the IM controller's plumbing.
struct ExactIm;
impl InverseModel for ExactIm {
    fn action(&self, state: &[f64], next: &[f64]) -> Result<Vec<f64>, String> {
        Ok((0..ARM_DOF).map(|i| next[i] - state[i]).collect())
    }
}

#[test]
fn the_jacobian_and_an_exact_inverse_model_reach_and_babbling_does_not() {
    let model = ArmModel::embedded();
    let targets = sample_targets(&model, 12, 0.35, 7).unwrap();
    let mut sim = sim();
    let mut run = |controller: &mut dyn Controller| {
        let episodes: Vec<Episode> = (targets.iter())
            .map(|t| {
                sim.reset_episode();
                run_episode(&mut sim, controller, t, 300).unwrap()
            })
            .collect();
        summarize(controller.name(), &episodes)
    };
    let jacobian = run(&mut JacobianController::new(model.clone(), 0.02));
    let im = run(&mut ImController::new(model.clone(), exp1(), ExactIm, 0.02));
    let random = run(&mut RandomController::new(&model, 0.35, 3).unwrap());
    assert!(jacobian.success_5mm >= 0.9, "{jacobian:?}");
    assert!(im.success_5mm >= 0.9, "{im:?}");
    assert!(random.success_1cm <= 0.2, "{random:?}");
}

#[test]
fn near_the_target_the_full_step_action_is_scaled_to_the_remaining_distance() {
    let model = ArmModel::embedded();
    let state = sim().state();
    let ef = state.ef_pose.translation.vector;
    let target = ef + Vector3::new(0.01, -0.005, 0.004);
    let mut controller = ImController::new(model.clone(), exp1(), ExactIm, 0.05);
    let (_, goal, scale) = controller.query(&state, &target).unwrap();
    // The IM is asked about a full 5 cm step toward the target …
    let asked = Vector3::new(goal[7], goal[8], goal[9]) - ef;
    assert!((asked.norm() - 0.05).abs() < 1e-9, "{asked:?}");
    assert!(
        (scale - (target - ef).norm() / 0.05).abs() < 1e-12,
        "{scale}"
    );
    // … and its action, scaled down, lands on the target to first order.
    let command = controller.command(&state, &target).unwrap();
    let reached = model
        .ef_pose(&command.joint_targets)
        .unwrap()
        .translation
        .vector;
    assert!((reached - target).norm() < 1e-3, "{:?}", reached - target);
}

#[test]
fn a_stalled_inverse_model_is_shaken_out_by_one_babbled_step() {
    struct Still;
    impl InverseModel for Still {
        fn action(&self, _: &[f64], _: &[f64]) -> Result<Vec<f64>, String> {
            Ok(vec![0.0; ARM_DOF])
        }
    }
    let model = ArmModel::embedded();
    let state = sim().state();
    let target = state.ef_pose.translation.vector + Vector3::new(0.2, 0.0, 0.0);
    let mut controller = ImController::new(model, exp1(), Still, 0.1);
    let moves: Vec<bool> = (0..2 * STALL_STEPS + 2)
        .map(|_| {
            let command = controller.command(&state, &target).unwrap();
            command.joint_targets != state.joint_positions
        })
        .collect();
    // Every STALL_STEPS-th step without progress babbles; the others are the IM's.
    let babbled: Vec<usize> = (0..moves.len()).filter(|&i| moves[i]).collect();
    assert_eq!(babbled, [STALL_STEPS, 2 * STALL_STEPS], "{moves:?}");
}

#[test]
fn unreachable_and_non_finite_targets_are_refused_naming_the_distance() {
    let model = ArmModel::embedded();
    for target in sample_targets(&model, 5, 0.35, 4).unwrap() {
        check_reachable(&model, &target).unwrap();
    }
    let far = check_reachable(&model, &Vector3::new(3.0, 0.0, 1.0)).unwrap_err();
    assert!(far.to_string().contains("out of the arm's reach"), "{far}");
    assert!(far.to_string().contains("m away"), "{far}");
    let nan = check_reachable(&model, &Vector3::new(f64::NAN, 0.0, 1.0)).unwrap_err();
    assert!(nan.to_string().contains("not a finite position"), "{nan}");
}

#[test]
fn a_broken_inverse_model_is_an_error_naming_it() {
    struct Nan;
    impl InverseModel for Nan {
        fn action(&self, _: &[f64], _: &[f64]) -> Result<Vec<f64>, String> {
            Ok(vec![f64::NAN; ARM_DOF])
        }
    }
    let model = ArmModel::embedded();
    let mut sim = sim();
    let target = Vector3::new(0.3, 0.2, 0.8);
    let err = run_episode(
        &mut sim,
        &mut ImController::new(model, exp1(), Nan, 0.02),
        &target,
        5,
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("finite joint deltas"), "{err}");
}
