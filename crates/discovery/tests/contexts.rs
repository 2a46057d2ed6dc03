//! The data test within contexts, on hand-built exp2-layout transitions: the cube (o_x)
//! moves only while held, by a0 with a gain that depends on θ3 (a0 · θ3, which the design
//! over all rows cannot represent: it has a0 × θ3 and a0 × holding, not their product),
//! and switching the magnet off while holding drops it by 5 mm. Every joint moves by its
//! own delta; the effector wanders by noise of its own.

use causal_arm_dataset::{Dataset, Experiment, action_names, state_names};
use causal_arm_discovery::{DataTest, GrangerSettings};
use causal_arm_scoring::Verdict;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};

const O_X: usize = 0;
const THETA0: usize = 9;
const THETA3: usize = 12;
const MGT: usize = 22;
const A_MGT: usize = 7;
const DROP: f64 = -0.005;

/// `chained`: each row starts where the last ended (one episode), else fresh states.
fn held_cube(rows: usize, seed: u64, chained: bool) -> Dataset {
    let mut rng = StdRng::seed_from_u64(seed);
    let action = Normal::new(0.0, 0.05).unwrap();
    let noise = Normal::new(0.0, 1e-4).unwrap();
    let mut data = Dataset::empty(Experiment::Exp2, Default::default());
    let mut last: Option<Vec<f32>> = None;
    for i in 0..rows {
        let holding = rng.random_bool(0.3);
        let fresh: Vec<f32> = (0..23).map(|_| rng.random_range(-1.0..1.0)).collect();
        let mut state = match (&last, chained) {
            (Some(s), true) => s.clone(),
            _ => fresh,
        };
        state[MGT] = if holding || rng.random_bool(0.5) {
            1.0
        } else {
            0.0
        };
        let mut a: Vec<f32> = (0..7).map(|_| action.sample(&mut rng) as f32).collect();
        let switch: f32 = match rng.random_range(0..100) {
            0..2 => -1.0,
            2..4 => 1.0,
            _ => 0.0,
        };
        a.push(switch);
        let mut next = state.clone();
        for j in 0..7 {
            next[THETA0 + j] = state[THETA0 + j] + a[j];
        }
        for k in 16..22 {
            next[k] = (state[k] as f64 + noise.sample(&mut rng)) as f32;
        }
        if holding {
            let moved = a[0] as f64 * state[THETA3] as f64 + noise.sample(&mut rng);
            let dropped = if switch < 0.0 { DROP } else { 0.0 };
            next[O_X] = (state[O_X] as f64 + moved + dropped) as f32;
        }
        next[MGT] = match switch {
            s if s > 0.0 => 1.0,
            s if s < 0.0 => 0.0,
            _ => state[MGT],
        };
        data.states.extend(&state);
        data.next_states.extend(&next);
        data.actions.extend(&a);
        data.episodes.push(0);
        data.holding.push(u8::from(holding));
        data.steps.push(i as u32);
        data.stamps_ns.push(i as u64);
        last = Some(next);
    }
    data
}

#[test]
fn an_effect_confined_to_a_context_is_found_within_it_and_missed_over_all_rows() {
    let data = held_cube(20_000, 1, false);
    let over_all_rows = GrangerSettings {
        within_contexts: false,
        ..GrangerSettings::data_test()
    };
    let all = DataTest::run(&data, &over_all_rows).unwrap();
    assert_ne!(
        all.decide(A_MGT, O_X).verdict,
        Verdict::Drives,
        "over all rows the drop is buried under the held cube's motion: {:?}",
        all.decide(A_MGT, O_X)
    );
    let test = DataTest::run(&data, &GrangerSettings::data_test()).unwrap();
    let names = state_names(Experiment::Exp2);
    let intermittent: Vec<&str> = names
        .iter()
        .zip(&test.intermittent)
        .filter(|(_, i)| **i)
        .map(|(n, _)| n.as_str())
        .collect();
    assert_eq!(
        intermittent,
        ["o_x", "mgt"],
        "the features that stand still"
    );
    let drop = test.decide(A_MGT, O_X);
    assert_eq!(drop.verdict, Verdict::Drives, "{drop:?}");
    assert!(drop.reason.contains("within context"), "{}", drop.reason);
    let claims = test.claims("data");
    let actions = action_names(Experiment::Exp2);
    for (a, row) in claims.drives.iter().enumerate() {
        for (k, &drives) in row.iter().enumerate() {
            let truth = (a < 7 && k == THETA0 + a)
                || (a == 0 && k == O_X)
                || (a == A_MGT && (k == O_X || k == MGT));
            assert!(
                !drives || truth,
                "false edge {} -> {}: {:?}",
                actions[a],
                names[k],
                test.decide(a, k)
            );
        }
    }
    assert!(claims.drives[0][O_X], "a0 moves the held cube");
    // An undecided edge on an intermittent feature names its strongest context too.
    let placebo = test.decide(1, O_X);
    assert_eq!(placebo.verdict, Verdict::Undecided, "{placebo:?}");
    assert!(
        placebo.reason.contains("within context"),
        "{}",
        placebo.reason
    );
    assert!(
        claims.rule.contains("within each context"),
        "{}",
        claims.rule
    );
}

#[test]
fn contexts_are_not_tested_h_steps_on_or_for_features_that_always_move() {
    let data = held_cube(5_000, 2, true);
    let ahead = DataTest::run_ahead(&data, 2, &GrangerSettings::data_test()).unwrap();
    assert!(ahead.within.is_empty(), "{:?}", ahead.within.len());
    let test = DataTest::run(&data, &GrangerSettings::data_test()).unwrap();
    assert!(!test.intermittent[THETA0], "a joint that always moves");
    for context in &test.within {
        assert_eq!(context.pairs[0][THETA0].dof, 0, "{}", context.context);
    }
}
