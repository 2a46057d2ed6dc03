//! The simulator's ground truth on small bags of both experiments: deterministic,
//! physically right where physics leaves no doubt, and refusing bad input clearly.

use std::path::PathBuf;

use causal_arm_datagen::{GenerateOptions, generate};
use causal_arm_intervene::intervene;
use causal_arm_protocol::{Experiment, RunPlan};
use causal_arm_scoring::EdgeClaims;
use causal_arm_truth::{Edge, Plan, Truth, load, score_claims, write_all};

fn bag(
    name: &str,
    experiment: Experiment,
    plan: RunPlan,
    edit: fn(&mut GenerateOptions),
) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("causal-arm-truth-{name}-{}", std::process::id()));
    let mut options = GenerateOptions::new(experiment, plan, 4, &dir);
    options.overwrite = true;
    edit(&mut options);
    generate(&options, &mut |_, _| {}).unwrap();
    dir
}

fn exp1_bag(name: &str) -> PathBuf {
    bag(
        name,
        Experiment::Exp1,
        RunPlan {
            episodes: 1,
            steps_per_episode: 400,
        },
        |_| {},
    )
}

fn exp2_bag() -> PathBuf {
    bag(
        "exp2",
        Experiment::Exp2,
        RunPlan {
            episodes: 3,
            steps_per_episode: 500,
        },
        |_| {},
    )
}

fn truth(bag: &std::path::Path, experiment: Experiment, states: usize) -> Truth {
    let plan = Plan {
        states,
        horizon: 3,
        ..Plan::default()
    };
    intervene(bag, experiment, &plan, &mut |_, _| {}).unwrap()
}

fn edge(t: &Truth, context: &str, action: &str, state: &str) -> Edge {
    let m = t.matrix(context, 1).unwrap();
    m.edge(
        t.action_index(action).unwrap(),
        t.state_index(state).unwrap(),
        t.plan.min_fraction,
    )
}

#[test]
fn exp1_truth_is_deterministic_and_kinematically_right() {
    let bag = exp1_bag("exp1");
    let t = truth(&bag, Experiment::Exp1, 200);
    assert_eq!(
        t.noise_floor, 0.0,
        "an identical replay must change nothing"
    );
    assert!(t.resimulated_steps > 200);
    // Realized actions: theta_k(t+1) = theta_k(t) + a_k, so the block is the diagonal.
    for j in 0..7 {
        for k in 0..7 {
            let e = edge(&t, "all", &format!("a{j}"), &format!("theta{k}"));
            let want = if j == k { Edge::Present } else { Edge::Absent };
            assert_eq!(e, want, "a{j} -> theta{k}");
        }
    }
    // Joint 0 turns about the vertical axis and joint 6 about the tool axis the tip lies on.
    assert_eq!(edge(&t, "all", "a0", "ef_z"), Edge::Absent);
    for c in ["ef_x", "ef_y", "ef_z"] {
        assert_eq!(edge(&t, "all", "a6", c), Edge::Absent, "a6 -> {c}");
        assert_eq!(edge(&t, "all", "a3", c), Edge::Present, "a3 -> {c}");
    }
    // Claims that are the truth score perfectly; claims of the other experiment are refused.
    let perfect = claims_from(&t, "all");
    let rows = score_claims(&t, &perfect).unwrap();
    assert_eq!(rows[0].block, "all");
    assert_eq!(rows[0].scores.precision, Some(1.0));
    assert_eq!(rows[0].scores.recall, Some(1.0));
    assert_eq!(rows[0].scores.auroc, Some(1.0));
    assert!(rows.iter().any(|r| r.block == "theta") && rows.iter().any(|r| r.block == "ef"));
    let mut foreign = perfect.clone();
    foreign.state_names = causal_arm_dataset::state_names(Experiment::Exp2);
    let e = score_claims(&t, &foreign).unwrap_err().to_string();
    assert!(e.contains("the truth (exp1) has actions"), "{e}");
    let e = score_claims(&t, &claims_from(&t, "holding"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("no matrix of context \"holding\""), "{e}");
    // The same plan gives the same truth.
    let again = truth(&bag, Experiment::Exp1, 200);
    assert_eq!(again.matrices, t.matrices);
    // Written and read back whole.
    let out = bag.join("truth");
    write_all(&out, &t).unwrap();
    assert_eq!(load(&out).unwrap(), t);
    let csv = std::fs::read_to_string(out.join("truth.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 3 * 7 * 10);
}

#[test]
fn exp2_truth_finds_the_magnet_and_the_cube_per_context() {
    let bag = exp2_bag();
    let t = truth(&bag, Experiment::Exp2, 300);
    assert_eq!(t.noise_floor, 0.0);
    for a in &t.action_names {
        for colour in ["o_R", "o_G", "o_B"] {
            for h in 1..=3 {
                let m = t.matrix("all", h).unwrap();
                let (ai, si) = (t.action_index(a).unwrap(), t.state_index(colour).unwrap());
                assert_eq!(m.max_effect[ai][si], 0.0, "{a} -> {colour} at t+{h}");
            }
        }
        assert_eq!(
            edge(&t, "all", a, "mgt") == Edge::Present,
            a == "a_mgt",
            "{a} -> mgt"
        );
    }
    // The cube moves with the joints only while held; the magnet's switch drops it.
    assert_eq!(edge(&t, "holding", "a1", "o_z"), Edge::Present);
    assert_eq!(edge(&t, "holding", "a_mgt", "o_z"), Edge::Present);
    let table = t.matrix("cube_on_table", 1).unwrap();
    let held = t.matrix("holding", 1).unwrap();
    let (a1, oz) = (t.action_index("a1").unwrap(), t.state_index("o_z").unwrap());
    assert!(table.active_fraction[a1][oz] < 0.2 * held.active_fraction[a1][oz]);
    assert!(held.states > 0 && table.states > 0);
    assert_eq!(
        held.states + t.matrix("not_holding", 1).unwrap().states,
        t.one_step().states
    );
}

#[test]
fn bad_input_is_refused_with_a_clear_error() {
    let bag = exp1_bag("exp1-bad");
    let err = |experiment, plan: Plan| {
        intervene(&bag, experiment, &plan, &mut |_, _| {})
            .unwrap_err()
            .to_string()
    };
    let e = err(
        Experiment::Exp1,
        Plan {
            states: 0,
            ..Plan::default()
        },
    );
    assert!(e.contains("--states must be at least 1"), "{e}");
    let e = err(Experiment::Exp2, Plan::default());
    assert!(
        e.contains("holds exp1 data") && e.contains("expected exp2"),
        "{e}"
    );
    let e = err(
        Experiment::Exp1,
        Plan {
            states: 100_000,
            ..Plan::default()
        },
    );
    assert!(e.contains("--states 100000 asks for more"), "{e}");
    // A bag made with settings it does not record cannot be revisited: refused, not
    // silently explained with other states.
    let other = bag_with_other_servo();
    let e = intervene(&other, Experiment::Exp1, &Plan::default(), &mut |_, _| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("re-simulation left the bag at stamp"), "{e}");
    // A truth file that is not one.
    let file = other.join("truth.json");
    std::fs::write(&file, "{\"format\": \"something else\"}").unwrap();
    let e = load(&file).unwrap_err().to_string();
    assert!(e.contains("not a truth file"), "{e}");
}

fn bag_with_other_servo() -> PathBuf {
    bag(
        "servo",
        Experiment::Exp1,
        RunPlan {
            episodes: 1,
            steps_per_episode: 1100,
        },
        |o| o.sim.servo_gain = 20.0,
    )
}

/// Claims that say exactly what the truth's one-step matrix says (rare edges claimed).
fn claims_from(t: &Truth, context: &str) -> EdgeClaims {
    let m = t.one_step();
    EdgeClaims {
        method: "oracle".into(),
        rule: "the truth itself".into(),
        context: context.into(),
        horizon: 1,
        observations: m.states,
        action_names: t.action_names.clone(),
        state_names: t.state_names.clone(),
        score: m.active_fraction.clone(),
        interval: None,
        drives: m
            .active_fraction
            .iter()
            .map(|r| r.iter().map(|&f| f > 0.0).collect())
            .collect(),
        decisions: None,
    }
}

/// Off-diagonal a_j → theta_k edges present in the one-step matrix.
fn cross_joint_edges(t: &Truth) -> usize {
    (0..7)
        .flat_map(|j| (0..7).map(move |k| (j, k)))
        .filter(|&(j, k)| {
            j != k && edge(t, "all", &format!("a{j}"), &format!("theta{k}")) == Edge::Present
        })
        .count()
}

#[test]
fn an_effect_size_keeps_what_matters_on_the_dynamic_arm() {
    let bag = bag(
        "dynamic",
        Experiment::Exp1,
        RunPlan {
            episodes: 1,
            steps_per_episode: 300,
        },
        |o| o.sim.arm = causal_arm_sim::ArmMode::Dynamic,
    );
    // Every transition of the episode is intervened on.
    let at = |effect_size: f64| {
        let plan = Plan {
            states: 299,
            effect_size,
            ..Plan::default()
        };
        intervene(&bag, Experiment::Exp1, &plan, &mut |_, _| {}).unwrap()
    };
    let exact = at(0.0);
    let sized = at(0.1);
    // The scale is the recorded joints' own one-step spread (the replay is bit-exact).
    let trace = causal_arm_intervene::Trace::read(&bag, Experiment::Exp1).unwrap();
    for k in 0..7 {
        let steps: Vec<f64> = trace
            .steps
            .windows(2)
            .map(|w| w[1].theta[k] - w[0].theta[k])
            .collect();
        let mean = steps.iter().sum::<f64>() / steps.len() as f64;
        let var = steps.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / steps.len() as f64;
        let ours = exact.feature_step_std[exact.state_index(&format!("theta{k}")).unwrap()];
        assert!(
            (ours - var.sqrt()).abs() < 1e-12,
            "theta{k}: {ours} vs {}",
            var.sqrt()
        );
    }
    // A force-limited arm is coupled: exactly, some joints move others.
    let (coupled, kept) = (cross_joint_edges(&exact), cross_joint_edges(&sized));
    assert!(coupled > 0, "the dynamic arm's joints move each other");
    assert!(
        kept < coupled,
        "{kept} of {coupled} couplings kept at 0.1 std"
    );
    // Each joint command still moves its own joint, and no edge appears that was absent.
    let (m0, m1) = (exact.one_step(), sized.one_step());
    for j in 0..7 {
        let e = edge(&sized, "all", &format!("a{j}"), &format!("theta{j}"));
        assert_eq!(e, Edge::Present, "a{j} -> theta{j}");
    }
    for (r0, r1) in m0.active_fraction.iter().zip(&m1.active_fraction) {
        for (f0, f1) in r0.iter().zip(r1) {
            assert!(f1 <= f0);
        }
    }
    let mut bad = Plan {
        effect_size: -1.0,
        ..Plan::default()
    };
    let e = intervene(&bag, Experiment::Exp1, &bad, &mut |_, _| {}).unwrap_err();
    assert!(e.to_string().contains("--effect-size"), "{e}");
    bad.effect_size = f64::NAN;
    assert!(bad.check().is_err());
}
