//! The default verdicts (`<method>+cai+data`) with forward models that know nothing: an
//! untrained network (one epoch at a learning rate of 1e-12) and one with random weights.
//! Their evidence must decide nothing; every verdict left is the data's own. And a placebo
//! action, which changes nothing in the data, is never claimed, whatever the model learned.

use causal_arm_datagen::{GenerateOptions, generate};
use causal_arm_dataset::{ActionSource, Dataset, Experiment, from_bag};
use causal_arm_explain::influence::InfluenceSettings;
use causal_arm_explain::verdicts::shap_and_cai_claims;
use causal_arm_explain::{Explainer, Method, Settings};
use causal_arm_models::job::train_and_save;
use causal_arm_models::{ModelKind, Profile, TrainOptions, load_model};
use causal_arm_protocol::RunPlan;
use causal_arm_scoring::{EdgeClaims, Verdict};
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, Normal};

fn temp(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "causal-arm-default-verdicts-{name}-{}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn exp1_bag(dir: &std::path::Path) -> Dataset {
    let plan = RunPlan {
        episodes: 1,
        steps_per_episode: 3000,
    };
    generate(
        &GenerateOptions::new(Experiment::Exp1, plan, 7, dir.join("bag")),
        &mut |_, _| {},
    )
    .unwrap();
    from_bag(
        &dir.join("bag"),
        Some(Experiment::Exp1),
        ActionSource::Realized,
    )
    .unwrap()
}

/// An FM of `data` trained with `learning_rate` for `epochs`, saved into `dir/model`.
fn train(data: &Dataset, dir: &std::path::Path, epochs: usize, learning_rate: f64) {
    let options = TrainOptions {
        profile: Profile::Quick,
        epochs: Some(epochs),
        learning_rate,
        folds: 2,
        max_folds: Some(1),
        fm_hidden: vec![64, 64],
        batch_size: 64,
        ..TrainOptions::default()
    };
    let out = dir.join("model");
    train_and_save(
        data,
        &[ModelKind::Fm],
        &options,
        ActionSource::Realized,
        &out,
        &mut |_| {},
    )
    .unwrap();
}

/// Replaces every layer's weights and biases in `dir/model/fm.safetensors` by draws of an
/// initialization's scale (1/√fan-in), keeping the input and output standardization.
fn randomize_weights(dir: &std::path::Path) {
    use safetensors::tensor::TensorView;
    let path = dir.join("model").join("fm.safetensors");
    let bytes = std::fs::read(&path).unwrap();
    let file = safetensors::SafeTensors::deserialize(&bytes).unwrap();
    let mut rng = StdRng::seed_from_u64(42);
    let mut tensors: Vec<(String, Vec<usize>, Vec<u8>)> = Vec::new();
    for (name, view) in file.tensors() {
        let shape = view.shape().to_vec();
        let data = if name.starts_with("layers.") {
            let fan_in = *shape.last().unwrap() as f64;
            let normal = Normal::new(0.0, 1.0 / fan_in.sqrt()).unwrap();
            let count = shape.iter().product::<usize>();
            (0..count)
                .flat_map(|_| (normal.sample(&mut rng) as f32).to_le_bytes())
                .collect()
        } else {
            view.data().to_vec()
        };
        tensors.push((name, shape, data));
    }
    let views: Vec<(String, TensorView)> = tensors
        .iter()
        .map(|(n, s, d)| {
            (
                n.clone(),
                TensorView::new(safetensors::Dtype::F32, s.clone(), d).unwrap(),
            )
        })
        .collect();
    safetensors::serialize_to_file(views, None, &path).unwrap();
}

fn default_claims(data: &Dataset, dir: &std::path::Path) -> Vec<EdgeClaims> {
    let explainer = Explainer::new(load_model(&dir.join("model"), "fm").unwrap()).unwrap();
    let mut settings = Settings::for_method(Method::Deep);
    settings.samples = 60;
    settings.background = 30;
    let explanation = explainer
        .explain_dataset(data, &settings, &mut |_, _| {})
        .unwrap();
    let influence = InfluenceSettings {
        observations: 200,
        resamples: 16,
        error_rows: 2000,
        bootstrap: 200,
        ..InfluenceSettings::default()
    };
    shap_and_cai_claims(&explainer, data, &explanation, 0.01, &influence).unwrap()
}

/// The model decides no edge of the default, and every verdict equals the data test's.
fn assert_model_decides_nothing(claims: &[EdgeClaims], what: &str) {
    let default = &claims[0];
    let data = claims.iter().find(|c| c.method == "data").unwrap();
    assert_eq!(default.method, "deep+cai+data");
    let decisions = default.decisions.as_ref().unwrap();
    for (a, row) in decisions.iter().enumerate() {
        for (k, d) in row.iter().enumerate() {
            assert!(
                !d.source.contains("model"),
                "{what}: {} -> {} decided by the model: {d:?}",
                default.action_names[a],
                default.state_names[k]
            );
            assert_eq!(d.verdict, data.verdict(a, k), "{what}: {a} {k}");
            if d.verdict == Verdict::Undecided {
                assert!(d.reason.contains("has not learned"), "{what}: {d:?}");
            }
        }
    }
}

#[test]
fn untrained_and_random_forward_models_decide_nothing() {
    let dir = temp("untrained");
    let data = exp1_bag(&dir);
    // One epoch at a learning rate of 1e-12 (0 is refused): Adam moves no weight by more
    // than 1e-12 per step, so the network stays as initialized, its standardization fitted.
    train(&data, &dir, 1, 1e-12);
    assert_model_decides_nothing(&default_claims(&data, &dir), "untrained FM");
    randomize_weights(&dir);
    assert_model_decides_nothing(&default_claims(&data, &dir), "random FM");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_trained_model_learns_its_features_and_the_data_decides_the_rest() {
    let dir = temp("trained");
    let data = exp1_bag(&dir);
    train(&data, &dir, 15, 1e-3);
    let claims = default_claims(&data, &dir);
    let default = &claims[0];
    let decisions = default.decisions.as_ref().unwrap();
    // θ_j moves with a_j: claimed; a_i never moves θ_j (i ≠ j): denied by the data.
    for (a, row) in decisions.iter().enumerate().take(7) {
        for (k, d) in row.iter().enumerate().take(7) {
            let expected = if a == k {
                Verdict::Drives
            } else {
                Verdict::DoesNot
            };
            assert_eq!(d.verdict, expected, "a{a} -> theta{k}: {d:?}");
        }
    }
    // Every undecided edge says what would decide it.
    for d in decisions.iter().flatten() {
        assert_eq!(
            d.verdict == Verdict::Undecided,
            !d.to_decide.is_empty(),
            "{d:?}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_placebo_action_column_is_never_claimed() {
    use rand::seq::SliceRandom;
    let dir = temp("placebo");
    let mut data = exp1_bag(&dir);
    // a6 replaced by a shuffled copy of itself: its marginal as babbled, its values
    // unrelated to anything that happened (θ6 moved by the original a6).
    let (na, rows) = (data.action_width(), data.rows());
    let mut column: Vec<f32> = (0..rows).map(|r| data.action(r)[6]).collect();
    column.shuffle(&mut StdRng::seed_from_u64(3));
    for (r, v) in column.into_iter().enumerate() {
        data.actions[r * na + 6] = v;
    }
    train(&data, &dir, 15, 1e-3);
    let claims = default_claims(&data, &dir);
    for c in claims
        .iter()
        .filter(|c| c.method.ends_with("+data") || c.method == "data")
    {
        for (k, state) in c.state_names.iter().enumerate() {
            assert_ne!(
                c.verdict(6, k),
                Verdict::Drives,
                "{}: placebo a6 -> {state}",
                c.method
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_discrete_placebo_command_is_never_claimed() {
    let dir = temp("discrete-placebo");
    let mut data = exp1_bag(&dir);
    // a6 replaced by a command like the magnet's: −1 or +1 in 3 % of the rows each, else 0,
    // drawn independently of everything (θ6 moved by the original a6). The model is
    // probed where it switched, against the joints the data rules out for it.
    let (na, rows) = (data.action_width(), data.rows());
    let mut rng = StdRng::seed_from_u64(5);
    for r in 0..rows {
        let u: f64 = rand::Rng::random(&mut rng);
        data.actions[r * na + 6] = if u < 0.03 {
            -1.0
        } else if u < 0.06 {
            1.0
        } else {
            0.0
        };
    }
    train(&data, &dir, 15, 1e-3);
    let claims = default_claims(&data, &dir);
    let default = &claims[0];
    let decisions = default.decisions.as_ref().unwrap();
    let mut judged = 0;
    for (k, d) in decisions[6].iter().enumerate() {
        let state = &default.state_names[k];
        assert_ne!(d.verdict, Verdict::Drives, "placebo a6 -> {state}: {d:?}");
        if d.reason.contains("where the data switched this command") {
            judged += 1;
        }
    }
    assert!(
        judged > 0,
        "the switch evidence was never judged: {:?}",
        decisions[6]
    );
    let _ = std::fs::remove_dir_all(&dir);
}
