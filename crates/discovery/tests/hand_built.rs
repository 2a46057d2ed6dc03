//! The data-level tests on hand-built exp1-layout transitions whose causal graph is known:
//! joint deltas move their own joint exactly, a0 moves ef_y with a constant gain, a1 moves
//! ef_x with a gain that depends on the state (a1 · θ3, zero on average), and a6 is a
//! placebo: it changes nothing (θ6 wanders by noise of its own).

use causal_arm_dataset::{Dataset, Experiment};
use causal_arm_discovery::{DataTest, GrangerSettings, Terms, granger_claims};
use causal_arm_scoring::Verdict;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};

const THETA3: usize = 3;
const EF_X: usize = 7;
const EF_Y: usize = 8;
const EF_Z: usize = 9;

/// Appends step `i` of episode 0 (empty-handed): s(t), s(t+1) and a(t).
fn push_step(data: &mut Dataset, i: usize, state: &[f32], next: &[f32], a: &[f32]) {
    data.states.extend(state);
    data.next_states.extend(next);
    data.actions.extend(a);
    data.episodes.push(0);
    data.holding.push(0);
    data.steps.push(i as u32);
    data.stamps_ns.push(i as u64);
}

fn hand_built(rows: usize, seed: u64) -> Dataset {
    let mut rng = StdRng::seed_from_u64(seed);
    let action = Normal::new(0.0, 0.05).unwrap();
    let noise = Normal::new(0.0, 1e-4).unwrap();
    let mut data = Dataset::empty(Experiment::Exp1, Default::default());
    for i in 0..rows {
        let state: Vec<f32> = (0..10).map(|_| rng.random_range(-1.0..1.0)).collect();
        let a: Vec<f32> = (0..7).map(|_| action.sample(&mut rng) as f32).collect();
        let mut next = state.clone();
        for j in 0..6 {
            next[j] = state[j] + a[j];
        }
        next[6] = state[6] + noise.sample(&mut rng) as f32;
        let theta3 = state[THETA3] as f64;
        next[EF_X] = (state[EF_X] as f64 + a[1] as f64 * theta3 + noise.sample(&mut rng)) as f32;
        next[EF_Y] = (state[EF_Y] as f64 + 0.5 * a[0] as f64 + noise.sample(&mut rng)) as f32;
        next[EF_Z] = (state[EF_Z] as f64 + noise.sample(&mut rng)) as f32;
        push_step(&mut data, i, &state, &next, &a);
    }
    data
}

fn true_edge(a: usize, k: usize) -> bool {
    (a < 6 && a == k) || (a == 1 && k == EF_X) || (a == 0 && k == EF_Y)
}

#[test]
fn the_data_test_finds_a_state_dependent_gain_that_the_linear_test_misses() {
    let data = hand_built(4000, 1);
    let linear = granger_claims(&data, Terms::Linear, "granger").unwrap();
    let full = DataTest::run(&data, &GrangerSettings::data_test()).unwrap();
    let claims = full.claims("data");
    assert!(linear.drives[0][EF_Y], "a constant gain is linear");
    assert!(
        !linear.drives[1][EF_X],
        "a1 · θ3 has no linear part on average"
    );
    assert!(claims.drives[1][EF_X], "{:?}", full.decide(1, EF_X));
    assert!(claims.drives[0][EF_Y]);
    for a in 0..7 {
        for k in 0..10 {
            let v = claims.verdict(a, k);
            if true_edge(a, k) {
                assert_eq!(v, Verdict::Drives, "a{a} -> {}", claims.state_names[k]);
            } else {
                assert_ne!(
                    v,
                    Verdict::Drives,
                    "a{a} -> {}: {:?}",
                    claims.state_names[k],
                    full.decide(a, k)
                );
            }
        }
    }
}

#[test]
fn an_exactly_predicted_feature_is_denied_and_a_noisy_one_left_undecided() {
    let data = hand_built(4000, 2);
    let claims = DataTest::run(&data, &GrangerSettings::data_test())
        .unwrap()
        .claims("data");
    // θ1 is θ1 + a1 to f32 rounding: without a0 it is predicted to its resolution.
    assert_eq!(claims.verdict(0, 1), Verdict::DoesNot);
    // ef_z wanders by noise no action explains: nothing decides that a2 does not move it.
    assert_eq!(claims.verdict(2, EF_Z), Verdict::Undecided);
    let d = &claims.decisions.as_ref().unwrap()[2][EF_Z];
    assert!(
        d.reason.contains("not significant") && !d.to_decide.is_empty(),
        "{d:?}"
    );
}

/// The classical F test on a change recorded to f32 (θ0 + a0) reads rounding as an effect
/// now and then (seed 6 claims a6 → θ0 at p = 4e-4, effect 1.5e-9 rad); the data test
/// denies such edges by the recording's resolution first.
#[test]
fn a_placebo_action_is_never_claimed() {
    for seed in 0..8 {
        let data = hand_built(3000, 100 + seed);
        let test = DataTest::run(&data, &GrangerSettings::data_test()).unwrap();
        let claims = test.claims("data");
        for k in 0..10 {
            assert_ne!(
                claims.verdict(6, k),
                Verdict::Drives,
                "seed {seed}: placebo a6 -> {}: {:?}",
                claims.state_names[k],
                test.decide(6, k)
            );
        }
    }
}

#[test]
fn too_few_rows_leave_every_edge_of_a_changing_feature_undecided_saying_how_many_would_do() {
    let data = hand_built(50, 3);
    let test = DataTest::run(&data, &GrangerSettings::data_test()).unwrap();
    let needed = test
        .rows_needed
        .expect("50 rows are too few for the full design");
    assert!(needed > 50, "{needed}");
    let claims = test.claims("data");
    assert!(claims.rule.contains("not run"), "{}", claims.rule);
    for a in 0..7 {
        for k in 0..10 {
            let d = test.decide(a, k);
            assert_eq!(d.verdict, Verdict::Undecided, "a{a} -> {k}: {d:?}");
            assert!(
                d.reason.contains(&format!("at least {needed} transitions")),
                "{d:?}"
            );
            assert!(
                d.to_decide.starts_with(&format!("{} more", needed - 50)),
                "{d:?}"
            );
        }
    }
    let anchor = granger_claims(&hand_built(10, 3), Terms::Linear, "granger").unwrap();
    assert!(anchor.rule.starts_with("not run"), "{}", anchor.rule);
    assert!(anchor.drives.iter().flatten().all(|d| !d));
    let none = DataTest::run(&hand_built(0, 3), &GrangerSettings::data_test()).unwrap();
    assert!(
        (0..10).all(|k| none.decide(0, k).verdict == Verdict::Undecided),
        "no rows deny nothing"
    );
}

#[test]
fn bad_settings_are_refused_with_the_reason() {
    let mut bad = GrangerSettings::data_test();
    bad.alpha = 0.0;
    let err = DataTest::run(&hand_built(500, 3), &bad).unwrap_err();
    assert!(err.to_string().contains("(0, 1)"), "{err}");
}

/// A change that one action sets exactly (Δs = a, no noise at all): the robust covariance
/// vanishes, and the verdict must still be "drives", with a finite score.
#[test]
fn an_exactly_determined_effect_is_claimed_with_a_finite_score() {
    let mut data = hand_built(2000, 9);
    for r in 0..data.rows() {
        let a0 = data.actions[r * 7];
        data.next_states[r * 10 + EF_Z] = data.states[r * 10 + EF_Z] + a0;
    }
    let test = DataTest::run(&data, &GrangerSettings::data_test()).unwrap();
    let claims = test.claims("data");
    assert_eq!(
        claims.verdict(0, EF_Z),
        Verdict::Drives,
        "{:?}",
        test.decide(0, EF_Z)
    );
    assert!(claims.score.iter().flatten().all(|v| v.is_finite()));
}

/// One episode of an exp1-layout random walk: each joint integrates its own delta (a0..a5)
/// plus drift noise, θ6 wanders on its own and a6 is a placebo; ef holds θ0..θ2's sum.
fn random_walk(rows: usize, seed: u64) -> Dataset {
    let mut rng = StdRng::seed_from_u64(seed);
    let action = Normal::new(0.0, 0.05).unwrap();
    let drift = Normal::new(0.0, 0.05).unwrap();
    let mut data = Dataset::empty(Experiment::Exp1, Default::default());
    let mut state = vec![0.0f32; 10];
    for i in 0..rows {
        let a: Vec<f32> = (0..7).map(|_| action.sample(&mut rng) as f32).collect();
        let mut next = state.clone();
        for j in 0..7 {
            // Mean-reverting, so the walk stays bounded; θ6 moves by drift alone.
            let own = if j < 6 { a[j] } else { 0.0 };
            next[j] = 0.95 * state[j] + own + drift.sample(&mut rng) as f32;
        }
        next[EF_X] = next[0] + next[1] + next[2];
        push_step(&mut data, i, &state, &next, &a);
        state = next;
    }
    data
}

#[test]
fn h_steps_on_the_effect_is_found_and_overlapping_windows_claim_no_placebo() {
    for seed in 0..6 {
        let data = random_walk(6000, seed);
        for horizon in [3, 8] {
            let test = DataTest::run_ahead(&data, horizon, &GrangerSettings::data_test()).unwrap();
            assert_eq!(test.horizon, horizon);
            assert!(test.rows > 5000, "every row but the last h−1 chains");
            let claims = test.claims("data");
            assert_eq!(claims.horizon, horizon);
            assert!(claims.rule.contains("cluster-robust"), "{}", claims.rule);
            // a0(t) still moves θ0 (0.95^h of it) and ef_x h steps on.
            assert_eq!(
                claims.verdict(0, 0),
                Verdict::Drives,
                "{:?}",
                test.decide(0, 0)
            );
            assert_eq!(claims.verdict(0, EF_X), Verdict::Drives);
            // The placebo's windows overlap by h − 1 steps: rows are anything but
            // independent, and a test that trusted them would see effects in the noise.
            for k in 0..10 {
                assert_ne!(
                    claims.verdict(6, k),
                    Verdict::Drives,
                    "seed {seed}, h = {horizon}: a6 -> {}: {:?}",
                    claims.state_names[k],
                    test.decide(6, k)
                );
            }
        }
    }
}

#[test]
fn a_horizon_beyond_every_episode_is_a_clear_error() {
    let data = random_walk(30, 0);
    let err = DataTest::run_ahead(&data, 40, &GrangerSettings::data_test()).unwrap_err();
    assert!(err.to_string().contains("transitions"), "{err}");
}

/// Velocity-limited joints: θ0 and θ1 move by their command clipped at a limit, and the
/// commands are correlated the way exp2's phases make them: half the steps move both
/// joints together by a lot (IK), half babble small independent moves. a1 does not move
/// θ0, but a block that fits θ0's saturation badly leaves a misfit that a1 explains. Here
/// the limit lies where 20 % of the commands reach beyond (the dynamic arm's joint 6:
/// 38 %), at one of the hinges' knots, which then fit it: no claim. Without hinges this
/// data claims a1 → θ0 at z = 32; with the limit between two knots (±0.067 rad here) the
/// hinges cut that to z = 14, still a claim: a limit of the design (docs/RESULTS.md).
#[test]
fn a_saturating_joint_does_not_leak_into_a_correlated_action() {
    let mut rng = StdRng::seed_from_u64(11);
    let command = Normal::new(0.0, 0.08).unwrap();
    let spread = Normal::new(0.0, 0.03).unwrap();
    let noise = Normal::new(0.0, 1e-4).unwrap();
    let commands: Vec<(f32, f32)> = (0..5000)
        .map(|_| {
            if rng.random_bool(0.5) {
                let a0 = 2.0 * command.sample(&mut rng) as f32;
                (a0, a0 + spread.sample(&mut rng) as f32)
            } else {
                let a0 = 0.5 * command.sample(&mut rng) as f32;
                (a0, 0.5 * command.sample(&mut rng) as f32)
            }
        })
        .collect();
    let mut sorted: Vec<f32> = commands.iter().map(|c| c.0).collect();
    sorted.sort_by(f32::total_cmp);
    let (low, high) = (
        sorted[(4999.0 * 0.2) as usize],
        sorted[(4999.0 * 0.8) as usize],
    );
    let mut data = Dataset::empty(Experiment::Exp1, Default::default());
    for (i, &(a0, a1)) in commands.iter().enumerate() {
        let state: Vec<f32> = (0..10).map(|_| rng.random_range(-1.0..1.0)).collect();
        let mut a: Vec<f32> = (0..7).map(|_| command.sample(&mut rng) as f32).collect();
        a[0] = a0;
        a[1] = a1;
        let mut next: Vec<f32> = state
            .iter()
            .map(|&s| s + noise.sample(&mut rng) as f32)
            .collect();
        next[0] += a0.clamp(low, high);
        next[1] += a1.clamp(low, high);
        push_step(&mut data, i, &state, &next, &a);
    }
    let test = DataTest::run(&data, &GrangerSettings::data_test()).unwrap();
    assert_eq!(test.decide(0, 0).verdict, Verdict::Drives);
    assert_eq!(test.decide(1, 1).verdict, Verdict::Drives);
    assert_ne!(
        test.decide(1, 0).verdict,
        Verdict::Drives,
        "a1 -> theta0: {:?}",
        test.decide(1, 0)
    );
}
