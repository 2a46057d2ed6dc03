//! Tests of the parent module.

use super::*;
use causal_arm_dataset::Experiment;
use causal_arm_mlp::{Head, MlpSpec, Regressor, TrainConfig};
use causal_arm_models::fit::FitSettings;
use causal_arm_models::problems::{FmTarget, forward_model};
use causal_arm_models::{LoadedModel, ModelMeta, ProblemInfo};
use safetensors::{Dtype, tensor::TensorView};

const THETA0: usize = 9;
const EF_X: usize = 16;
const O_Z: usize = 2;
const A0: usize = 23;

/// The toy world both the data and the model follow: θ0 += tanh(a0), ef_x += tanh(θ0),
/// nothing else moves. a0 reaches ef_x only through θ0: one step later.
fn step(s: &[f32], a: &[f32]) -> Vec<f32> {
    let mut next = s.to_vec();
    next[THETA0] += a[0].tanh();
    next[EF_X] += s[THETA0].tanh();
    next
}

/// Exp-2 rows in two episodes of 30 steps, the second starting far from where the first
/// ends and missing its step 12 (a dropped message: the state jumps over the hole).
/// `count` episodes of 30 steps, step 12 of episode 1 missing (a hole). The data test's
/// design needs 4 of them at h = 4.
fn episodes(count: u32) -> Dataset {
    let mut data = Dataset::empty(Experiment::Exp2, Default::default());
    for episode in 0..count {
        let mut s = vec![0.0f32; 23];
        s[O_Z] = 0.775;
        s[THETA0] = if episode == 0 { 0.1 } else { 1.5 };
        for t in 0..30u32 {
            let mut a = vec![0.0f32; 8];
            for (j, v) in a.iter_mut().take(7).enumerate() {
                *v = 0.05 * ((t * 7 + j as u32 + 13 * episode) as f32 * 0.77).sin();
            }
            let next = step(&s, &a);
            if !(episode == 1 && t == 12) {
                data.states.extend(&s);
                data.actions.extend(&a);
                data.next_states.extend(&next);
                data.episodes.push(episode);
                data.holding.push(0);
                data.steps.push(t);
                data.stamps_ns.push(t as u64);
            }
            s = next;
        }
    }
    data
}

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// A forward model that is exactly [`step`] (up to the fast tanh): hidden unit 0 =
/// tanh(a0) into Δθ0, unit 1 = tanh(θ0) into Δef_x, no other weight.
fn toy_model(data: &Dataset) -> Explainer {
    let problem = forward_model(data, FmTarget::Delta);
    let spec = MlpSpec {
        inputs: 31,
        hidden: vec![2],
        heads: problem.heads.iter().map(Head::from).collect(),
    };
    let mut w0 = vec![0.0f32; 2 * 31];
    w0[A0] = 1.0;
    w0[31 + THETA0] = 1.0;
    let mut w1 = vec![0.0f32; 23 * 2];
    w1[THETA0 * 2] = 1.0;
    w1[EF_X * 2 + 1] = 1.0;
    let tensors: Vec<(String, Vec<usize>, Vec<u8>)> = vec![
        ("layers.0.weight".into(), vec![2, 31], f32_bytes(&w0)),
        ("layers.0.bias".into(), vec![2], f32_bytes(&[0.0; 2])),
        ("layers.1.weight".into(), vec![23, 2], f32_bytes(&w1)),
        ("layers.1.bias".into(), vec![23], f32_bytes(&[0.0; 23])),
        ("input.mean".into(), vec![31], f32_bytes(&[0.0; 31])),
        ("input.std".into(), vec![31], f32_bytes(&[1.0; 31])),
        ("output.mean".into(), vec![23], f32_bytes(&[0.0; 23])),
        ("output.std".into(), vec![23], f32_bytes(&[1.0; 23])),
    ];
    let views = tensors.iter().map(|(n, shape, bytes)| {
        (
            n.clone(),
            TensorView::new(Dtype::F32, shape.clone(), bytes).unwrap(),
        )
    });
    let path = std::env::temp_dir().join(format!(
        "causal-arm-multistep-{}-{:?}.safetensors",
        std::process::id(),
        std::thread::current().id()
    ));
    safetensors::serialize_to_file(views, None, &path).unwrap();
    let regressor = Regressor::load(spec.clone(), &path).unwrap();
    let _ = std::fs::remove_file(&path);
    let meta = ModelMeta {
        name: "fm".into(),
        experiment: "exp2".into(),
        architecture: spec,
        problem: ProblemInfo::from(&problem),
        input_mean: vec![0.0; 31],
        input_std: vec![1.0; 31],
        output_mean: vec![0.0; 23],
        output_std: vec![1.0; 23],
        training: FitSettings {
            hidden: vec![2],
            train: TrainConfig::default(),
            epochs: 0,
        },
        trained_on: "hand-made".into(),
        sources: vec![],
    };
    Explainer::new(LoadedModel { meta, regressor }).unwrap()
}

fn settings() -> InfluenceSettings {
    InfluenceSettings {
        observations: 20,
        resamples: 8,
        error_rows: 1000,
        bootstrap: 50,
        ..InfluenceSettings::default()
    }
}

#[test]
fn chains_stay_inside_episodes_and_skip_holes() {
    let data = episodes(2);
    // Episode 0: rows 0..30; episode 1: steps 0..=11 at rows 30..42, 13..=29 at 42..59.
    let reach = data.chain_reach();
    assert_eq!(reach[0], 30);
    assert_eq!(reach[29], 1, "the last row of episode 0 reaches no further");
    assert_eq!((reach[30], reach[41]), (12, 1), "the hole ends the chain");
    assert_eq!((reach[42], reach[58]), (17, 1));
    let rows = data.chainable_rows(5);
    assert!(rows.iter().all(|&r| reach[r] >= 5));
    assert!(!rows.contains(&26) && rows.contains(&25) && !rows.contains(&38));

    // The data follows the model's own dynamics: chained along an episode with the
    // recorded actions, the model is exact at every horizon. One chain across an episode
    // or a hole would cost an error of order 1.
    let explainer = toy_model(&data);
    let floors = chained_error_floors(&explainer, &data, &settings(), 10).unwrap();
    assert_eq!(floors.len(), 10);
    for (h, f) in floors.iter().enumerate() {
        for k in [THETA0, EF_X] {
            assert!(
                f.per_context[0][k] < 1e-5,
                "h={} k={k}: {}",
                h + 1,
                f.per_context[0][k]
            );
        }
    }
    let effects = chained_cai_effects(&explainer, &data, &settings(), 10).unwrap();
    assert!(effects[0].rows.iter().all(|&r| reach[r] >= 10));
}

#[test]
fn an_action_reaches_a_feature_only_through_the_chain_and_never_where_no_path_exists() {
    let data = episodes(4);
    let explainer = toy_model(&data);
    let result = multistep_cai(&explainer, &data, &settings(), 4).unwrap();
    assert_eq!(
        result
            .horizons
            .iter()
            .map(|h| h.horizon)
            .collect::<Vec<_>>(),
        vec![1, 2, 3, 4]
    );
    let effect = |h: usize, a: usize, k: usize| result.horizons[h - 1].mean_effect[0][a][k];
    for h in 1..=4 {
        assert!(effect(h, 0, THETA0) > 1e-3, "a0 → θ0 at h={h}");
        assert_eq!(effect(h, 0, O_Z), 0.0, "a0 → o_z at h={h}");
        for a in 1..8 {
            for k in 0..23 {
                assert_eq!(effect(h, a, k), 0.0, "a{a} → {k} at h={h}");
            }
        }
        let claims = &result.horizons[h - 1].claims[0];
        assert_eq!(claims.horizon, h);
        assert!(claims.drives[0][THETA0] && !claims.drives[0][O_Z]);
        assert_eq!(claims.drives[0][EF_X], h >= 2, "a0 → ef_x at h={h}");
    }
    // a0 moves ef_x only once θ0 has moved: not at h = 1, from h = 2 on.
    assert!(effect(1, 0, EF_X) < 1e-6, "{}", effect(1, 0, EF_X));
    assert!(effect(2, 0, EF_X) > 1e-3);
    let line = result.pair_line("a_mgt", "o_z").unwrap();
    assert!(line.starts_with("a_mgt → o_z (all states): h=1 "), "{line}");
    assert!(
        line.contains("h=4 ") && line.contains("not claimed"),
        "{line}"
    );
}

#[test]
fn horizons_outside_one_to_ten_and_short_data_are_refused() {
    let data = episodes(2);
    let explainer = toy_model(&data);
    for bad in [0, 11] {
        let err = chained_cai_effects(&explainer, &data, &settings(), bad).unwrap_err();
        assert!(err.to_string().contains("1 to 10 steps"), "{err}");
    }
    let many = InfluenceSettings {
        observations: 50,
        ..settings()
    };
    let err = chained_cai_effects(&explainer, &data, &many, 10).unwrap_err();
    assert!(
        err.to_string()
            .contains("start 10 consecutive transitions inside an episode"),
        "{err}"
    );
}
