//! Cross-validation on real generated bags: figures beat the baseline, files round-trip.

use std::path::PathBuf;

use causal_arm_datagen::{GenerateOptions, generate};
use causal_arm_dataset::{ActionSource, Experiment, action_names, from_bag, state_names};
use causal_arm_models::model_file::describe;
use causal_arm_models::structure::FoundGraph;
use causal_arm_models::{
    ModelKind, Profile, RunRecord, TrainOptions, cross_validate, load_model, save_model,
};
use causal_arm_protocol::RunPlan;

fn dataset(experiment: Experiment, episodes: u64, steps: u64) -> causal_arm_dataset::Dataset {
    // Tests run in parallel threads of one process: each call gets its own directory.
    static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!(
        "causal-arm-trainer-{experiment}-{}-{call}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    let plan = RunPlan {
        episodes,
        steps_per_episode: steps,
    };
    generate(
        &GenerateOptions::new(experiment, plan, 9, dir.join("bag")),
        &mut |_, _| {},
    )
    .unwrap();
    from_bag(&dir.join("bag"), Some(experiment), ActionSource::Realized).unwrap()
}

fn quick(epochs: usize) -> TrainOptions {
    TrainOptions {
        profile: Profile::Quick,
        epochs: Some(epochs),
        folds: 3,
        fm_hidden: vec![64, 64],
        im_hidden: vec![64, 64],
        batch_size: 64,
        ..TrainOptions::default()
    }
}

#[test]
fn exp1_models_beat_the_mean_baseline_and_files_round_trip() {
    let data = dataset(Experiment::Exp1, 1, 1500);
    let fm = cross_validate(&data, ModelKind::Fm, &quick(15), &mut |_| {}).unwrap();
    let keys: Vec<&str> = fm.figures.iter().map(|f| f.key.as_str()).collect();
    assert_eq!(keys, ["fm/theta", "fm/ef"]);
    for f in &fm.figures {
        assert_eq!(f.folds.len(), 3);
        assert!(
            f.mean < 0.5 * f.baseline,
            "{}: {} vs baseline {}",
            f.key,
            f.mean,
            f.baseline
        );
        assert!(f.paper.is_some());
    }
    assert_eq!(fm.runs.len(), 3);

    // Save, load, same predictions; the loaded FM adds s(t) back (delta target).
    let (name, model, problem, settings) = &fm.models[0];
    let dir: PathBuf =
        std::env::temp_dir().join(format!("causal-arm-model-{}", std::process::id()));
    let meta = describe(
        name,
        data.experiment,
        model,
        problem,
        settings,
        "test".into(),
        &data.sources,
    );
    save_model(&dir, model, &meta).unwrap();
    let loaded = load_model(&dir, "fm").unwrap();
    assert_eq!(loaded.meta.problem.input_names.len(), 17);
    let x: Vec<f32> = data
        .state(5)
        .iter()
        .chain(data.action(5))
        .copied()
        .collect();
    let y = loaded.predict(&x).unwrap();
    for (j, (p, t)) in y.iter().zip(data.next_state(5)).enumerate() {
        assert!((p - t).abs() < 0.1, "feature {j}: predicted {p}, true {t}");
    }
    // Mental simulation: errors grow with the chained steps; too few windows is an error.
    let fresh = dataset(Experiment::Exp1, 1, 400);
    let sim = causal_arm_models::mental::mental_simulation(&loaded, &fresh, 30, 10).unwrap();
    assert_eq!((sim.trajectories, sim.steps, sim.curves.len()), (30, 10, 2));
    let theta = &sim.curves[0];
    assert_eq!(theta.group, "theta");
    assert!(
        theta.mean[9] > theta.mean[0],
        "chained errors accumulate: {:?}",
        theta.mean
    );
    let err = causal_arm_models::mental::mental_simulation(&loaded, &fresh, 100, 10)
        .unwrap_err()
        .to_string();
    assert!(err.contains("only 39 windows"), "{err}");

    // A corrupt weights file is a clear error.
    std::fs::write(dir.join("fm.safetensors"), b"not a model").unwrap();
    let err = load_model(&dir, "fm").unwrap_err().to_string();
    assert!(err.contains("fm.safetensors"), "{err}");

    let pre = cross_validate(&data, ModelKind::ImPre, &quick(10), &mut |_| {}).unwrap();
    let keys: Vec<&str> = pre.figures.iter().map(|f| f.key.as_str()).collect();
    assert_eq!(keys, ["im_pre/base", "im_pre/pre", "im_pre/assembly"]);
    let base = &pre.figures[0];
    assert!(
        base.mean < 0.3 * base.baseline,
        "base IM sees θ(t+1): {} vs {}",
        base.mean,
        base.baseline
    );
    let ablation = cross_validate(&data, ModelKind::Ablation, &quick(10), &mut |_| {}).unwrap();
    let zero = &ablation.figures[0];
    assert_eq!(zero.key, "ablation/zero");
    assert!(
        zero.mean > base.mean * 3.0,
        "feeding θ(t+1)=0 must hurt: {} vs {}",
        zero.mean,
        base.mean
    );
}

#[test]
fn bad_options_and_exp2_only_models_are_refused() {
    let data = dataset(Experiment::Exp2, 2, 40);
    let err = cross_validate(&data, ModelKind::ImPre, &quick(1), &mut |_| {})
        .unwrap_err()
        .to_string();
    assert!(err.contains("exp1 only"), "{err}");
    let err = cross_validate(
        &data,
        ModelKind::Fm,
        &TrainOptions {
            folds: 1,
            ..quick(1)
        },
        &mut |_| {},
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("--folds must be at least 2"), "{err}");
    let im = cross_validate(&data, ModelKind::ImMono, &quick(2), &mut |_| {}).unwrap();
    let keys: Vec<&str> = im.figures.iter().map(|f| f.key.as_str()).collect();
    assert_eq!(keys, ["im_mono/joint", "im_mono/magnet"]);
}

/// exp1's true graph: a_i moves θi, a0..a5 move the effector (a6 turns the flange about
/// the effector's axis).
fn exp1_truth_graph() -> FoundGraph {
    let actions = action_names(Experiment::Exp1);
    let states = state_names(Experiment::Exp1);
    let drives = (0..7)
        .map(|a| {
            states
                .iter()
                .map(|s| *s == format!("theta{a}") || (s.starts_with("ef_") && a < 6))
                .collect()
        })
        .collect();
    FoundGraph {
        source: "exp1 truth".into(),
        action_names: actions,
        state_names: states,
        drives,
    }
}

#[test]
fn factored_auto_compares_each_heads_candidates_on_training_rows_and_with_the_full_fm() {
    let data = dataset(Experiment::Exp1, 1, 1500);
    let options = TrainOptions {
        graph: Some(exp1_truth_graph()),
        factored_hidden: vec![64, 64],
        max_folds: Some(1),
        ..quick(10)
    };
    let report = cross_validate(&data, ModelKind::FmFactored, &options, &mut |_| {}).unwrap();
    let keys: Vec<&str> = report.figures.iter().map(|f| f.key.as_str()).collect();
    assert_eq!(keys, ["fm/theta", "fm/ef"]);
    for f in &report.figures {
        assert!(
            f.mean < 0.5 * f.baseline,
            "{}: {} vs {}",
            f.key,
            f.mean,
            f.baseline
        );
    }
    // The full FM on the fit rows first; then θ: alone, or with ef (driven by a0..a5
    // only); ef: alone, or with θ0..θ5 (upstream and determined give the same outputs, so
    // one network); and the full FM on all training rows if a head keeps its head.
    let labels: Vec<&str> = report.runs.iter().map(|r| r.label.as_str()).collect();
    assert_eq!(
        labels[..5],
        [
            "fm-factored full-fm [validation] fold 1/3",
            "fm-factored theta [none] fold 1/3",
            "fm-factored theta [determined] fold 1/3",
            "fm-factored ef [none] fold 1/3",
            "fm-factored ef [upstream] fold 1/3",
        ]
    );
    let training_rows = data.rows() - data.rows() / 3;
    let mut heads_keeping_the_full_fm = 0;
    for head in report.runs[1..5].chunks(2) {
        let mae = |r: &RunRecord| r.selection.unwrap().validation_mae;
        let best = head
            .iter()
            .min_by(|a, b| mae(a).total_cmp(&mae(b)))
            .unwrap();
        let comparison = best.selection.unwrap().against_full_fm.unwrap();
        assert!(comparison.full_fm_validation_mae > 0.0);
        assert!(
            (comparison.difference - (mae(best) - comparison.full_fm_validation_mae)).abs() < 1e-9
        );
        assert_eq!(best.selection.unwrap().chosen, comparison.candidate_better);
        heads_keeping_the_full_fm += usize::from(!comparison.candidate_better);
        for run in head {
            assert!(run.rows < training_rows && run.rows > training_rows * 9 / 10);
            if !std::ptr::eq(run, best) {
                assert!(!run.selection.unwrap().chosen);
                assert!(run.selection.unwrap().against_full_fm.is_none());
            }
        }
    }
    let saved: Vec<&str> = report.models.iter().map(|m| m.0.as_str()).collect();
    if heads_keeping_the_full_fm == 0 {
        assert_eq!(labels.len(), 5);
        assert_eq!(saved, ["fm-factored-theta", "fm-factored-ef"]);
    } else {
        assert_eq!(labels[5], "fm-factored full-fm fold 1/3");
        assert_eq!(report.runs[5].rows, training_rows);
        assert_eq!(saved.last(), Some(&"fm-factored-full-fm"));
        assert_eq!(saved.len(), 3 - heads_keeping_the_full_fm);
    }
}

/// A head whose graph withholds actions that drive it cannot beat the full FM: it keeps
/// the full FM's own head, the very network and figure of `--model fm`.
#[test]
fn a_factored_head_no_better_than_the_full_fm_keeps_the_full_fms_head_bit_for_bit() {
    let data = dataset(Experiment::Exp1, 1, 1500);
    let mut graph = exp1_truth_graph();
    for (a, row) in graph.drives.iter_mut().enumerate() {
        for (state, drives) in graph.state_names.iter().zip(row.iter_mut()) {
            if state.starts_with("ef_") {
                *drives = a == 0;
            }
        }
    }
    let options = TrainOptions {
        graph: Some(graph),
        fm_hidden: vec![64, 64],
        factored_hidden: vec![64, 64],
        max_folds: Some(1),
        ..quick(10)
    };
    let factored = cross_validate(&data, ModelKind::FmFactored, &options, &mut |_| {}).unwrap();
    let ef_runs: Vec<&RunRecord> = factored
        .runs
        .iter()
        .filter(|r| r.label.starts_with("fm-factored ef "))
        .collect();
    let comparison = ef_runs
        .iter()
        .find_map(|r| r.selection.unwrap().against_full_fm)
        .unwrap();
    assert!(!comparison.candidate_better, "{comparison:?}");
    assert!(comparison.difference > 0.0, "{comparison:?}");
    assert!(ef_runs.iter().all(|r| !r.selection.unwrap().chosen));
    // Nothing is unaffected under this graph, so `--model fm` with it is the full FM.
    let full = cross_validate(&data, ModelKind::Fm, &options, &mut |_| {}).unwrap();
    let figure = |r: &causal_arm_models::KindReport, key: &str| {
        r.figures.iter().find(|f| f.key == key).unwrap().mean
    };
    assert_eq!(figure(&factored, "fm/ef"), figure(&full, "fm/ef"));
    let saved: Vec<&str> = factored.models.iter().map(|m| m.0.as_str()).collect();
    assert!(saved.contains(&"fm-factored-full-fm"), "{saved:?}");
}
