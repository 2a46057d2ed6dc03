//! The explainer on a real generated exp2 bag and a forward model trained on it: efficiency,
//! the colour finding, the files, and the service's answers to good and bad requests.

use causal_arm_datagen::{GenerateOptions, generate};
use causal_arm_dataset::{ActionSource, Dataset, Experiment, from_bag};
use causal_arm_explain::output::write_all;
use causal_arm_explain::report::DEFAULT_THRESHOLD;
use causal_arm_explain::serve::{ExplainService, relevance_msg};
use causal_arm_explain::{Explainer, Method, Settings, forward_inputs, relevance};
use causal_arm_models::model_file::describe;
use causal_arm_models::{ModelKind, Profile, TrainOptions, cross_validate, load_model, save_model};
use causal_arm_msgs::srv::Explain_Request;
use causal_arm_protocol::RunPlan;

/// A fresh directory per call: the tests run in parallel threads of one process, so the
/// process id alone would let one test overwrite the other's model while it loads.
fn temp(name: &str) -> std::path::PathBuf {
    static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
    let dir = std::env::temp_dir().join(format!(
        "causal-arm-explainer-{name}-{}-{call}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// A 4-episode exp2 bag and an FM trained on it for a few epochs, loaded from its files.
fn trained() -> (Dataset, Explainer) {
    let dir = temp("data");
    let plan = RunPlan {
        episodes: 4,
        steps_per_episode: 500,
    };
    generate(
        &GenerateOptions::new(Experiment::Exp2, plan, 5, dir.join("bag")),
        &mut |_, _| {},
    )
    .unwrap();
    let data = from_bag(
        &dir.join("bag"),
        Some(Experiment::Exp2),
        ActionSource::Realized,
    )
    .unwrap();
    let options = TrainOptions {
        profile: Profile::Quick,
        epochs: Some(4),
        folds: 2,
        max_folds: Some(1),
        fm_hidden: vec![64, 64],
        batch_size: 64,
        ..TrainOptions::default()
    };
    let fm = cross_validate(&data, ModelKind::Fm, &options, &mut |_| {}).unwrap();
    let (name, model, problem, settings) = &fm.models[0];
    let meta = describe(
        name,
        data.experiment,
        model,
        problem,
        settings,
        "test".into(),
        &data.sources,
    );
    save_model(&dir.join("model"), model, &meta).unwrap();
    let explainer = Explainer::new(load_model(&dir.join("model"), "fm").unwrap()).unwrap();
    (data, explainer)
}

#[test]
fn explanations_are_efficient_find_colour_unaffected_and_are_served() {
    let (data, explainer) = trained();
    assert_eq!(explainer.action_names().last().unwrap(), "a_mgt");

    for method in [Method::Deep, Method::Kernel] {
        let mut settings = Settings::for_method(method);
        settings.samples = if method == Method::Deep { 60 } else { 6 };
        settings.background = 20;
        settings.threads = Some(2);
        let mut calls = vec![];
        let e = explainer
            .explain_dataset(&data, &settings, &mut |done, total| {
                calls.push((done, total))
            })
            .unwrap();
        assert_eq!(calls.last(), Some(&(settings.samples, settings.samples)));
        assert_eq!(e.attributions.n_obs, settings.samples);
        assert_eq!(
            (e.attributions.n_inputs, e.attributions.n_outputs),
            (31, 23)
        );
        // Σ_i φ = f(x) − E f(background), within 1e-5 of the output change.
        assert!(
            e.efficiency_error() < 1e-5,
            "{method}: {}",
            e.efficiency_error()
        );

        let report = relevance(&e, DEFAULT_THRESHOLD);
        // Colour never changes within a transition: no action can affect it.
        for c in ["o_R", "o_G", "o_B"] {
            let v = report.state(c).unwrap();
            assert!(!v.affected && v.scale == 0.0, "{method}: {v:?}");
            assert!(report.unaffected.contains(&c.to_string()));
        }
        // Each joint's action drives that joint's angle, strongest of all actions.
        for j in 0..7 {
            let v = report.state(&format!("theta{j}")).unwrap();
            assert_eq!(v.strongest_action, format!("a{j}"), "{method}: {v:?}");
            assert!(report.drives(&format!("a{j}"), &format!("theta{j}")));
        }
        let csv = report.to_csv();
        assert_eq!(csv.lines().count(), 24);
        assert!(csv.contains("o_R,not affected by any action,"));

        let msg = relevance_msg(&report, Default::default());
        assert_eq!(msg.mean_abs_shap.len(), 8 * 23);
        assert_eq!(msg.affected.len(), 23);

        let out = temp(&format!("out-{method}"));
        let written = write_all(&out, &e, &report, false).unwrap();
        for name in [
            "shap_values.safetensors",
            "explanation.json",
            "relevance.json",
            "relevance.csv",
            "heatmap.png",
            "heatmap.svg",
            "pdp_grid.png",
            "pdp_grid.svg",
        ] {
            assert!(written.files.contains(&out.join(name)), "{name} missing");
            assert!(std::fs::metadata(out.join(name)).unwrap().len() > 100);
        }
        let bytes = std::fs::read(out.join("shap_values.safetensors")).unwrap();
        let tensors = safetensors::SafeTensors::deserialize(&bytes).unwrap();
        assert_eq!(
            tensors.tensor("values").unwrap().shape(),
            [settings.samples, 31, 23]
        );
        assert_eq!(tensors.tensor("background").unwrap().shape()[1], 31);
    }

    // The service: good request answered in the message layout, bad ones refused.
    let pool = pool_rows(&data, 200);
    let mut deep = Settings::for_method(Method::Deep);
    deep.background = 30;
    let mut kernel = Settings::for_method(Method::Kernel);
    kernel.background = 5;
    let service = ExplainService::new(explainer, pool, deep.clone(), kernel);
    let row = 700;
    let good = Explain_Request {
        method: "deep".into(),
        state: data.state(row).iter().map(|&v| v as f64).collect(),
        action: data.action(row).iter().map(|&v| v as f64).collect(),
        rows: 1,
        background: 0,
    };
    let reply = service.explain(&good);
    assert!(reply.success, "{}", reply.message);
    assert_eq!(reply.attributions.len(), 23 * 31);
    assert_eq!(reply.input_names.len(), 31);
    assert_eq!(reply.output_names[2], "o_z_next");
    // Same numbers as the library (reply is rows × outputs × inputs).
    let x: Vec<f32> = data
        .state(row)
        .iter()
        .chain(data.action(row))
        .copied()
        .collect();
    let bg = causal_arm_shap::Background::sample(&pool_rows(&data, 30), 31).unwrap();
    let (a, _) = service.explainer().attribute(&x, &bg, &deep).unwrap();
    for j in 0..23 {
        for i in 0..31 {
            assert_eq!(reply.attributions[j * 31 + i], a.get(0, i, j));
        }
    }
    let kernel_reply = service.explain(&Explain_Request {
        method: "kernel".into(),
        ..good.clone()
    });
    assert!(kernel_reply.success, "{}", kernel_reply.message);

    let bad = |f: &dyn Fn(&mut Explain_Request), expect: &str| {
        let mut req = good.clone();
        f(&mut req);
        let reply = service.explain(&req);
        assert!(!reply.success, "accepted: {expect}");
        assert!(
            reply.message.contains(expect),
            "{:?} lacks {expect:?}",
            reply.message
        );
        assert!(reply.attributions.is_empty() && reply.rows == 0);
    };
    bad(&|r| r.method = "lime".into(), "unknown SHAP method");
    bad(&|r| r.rows = 0, "at least 1");
    bad(
        &|r| r.rows = 2,
        "state has 23 values, expected rows × 23 = 46",
    );
    bad(
        &|r| r.action.pop().map(|_| ()).unwrap(),
        "action has 7 values",
    );
    bad(
        &|r| r.state[4] = f64::NAN,
        "state[4] (row 0, column 4) is NaN",
    );
    bad(&|r| r.action[0] = f64::INFINITY, "action[0]");
    bad(
        &|r| r.state[0] = 1e300,
        "state[0] (row 0, column 0) is 1e300, beyond the float32 range",
    );
    bad(&|r| r.rows = 4_000_000_000, "exceeds the deep SHAP limit");
    bad(&|r| r.background = 5000, "exceeds the 200 rows available");
    bad(
        &|r| {
            r.method = "kernel".into();
            r.rows = 51
        },
        "exceeds the kernel SHAP limit of 50",
    );
    // Still serving.
    assert!(service.explain(&good).success);
}

/// The first `rows` transitions as `[state ++ action]` rows, the service's pool order.
fn pool_rows(data: &Dataset, rows: usize) -> Vec<f32> {
    forward_inputs(data, &(0..rows).collect::<Vec<_>>())
}

#[test]
fn bad_settings_and_mismatched_data_are_errors() {
    let (data, explainer) = trained();
    let error_with = |change: &dyn Fn(&mut Settings)| {
        let mut s = Settings::for_method(Method::Deep);
        change(&mut s);
        explainer
            .explain_dataset(&data, &s, &mut |_, _| {})
            .unwrap_err()
            .to_string()
    };
    assert!(error_with(&|s| s.samples = 0).contains("samples"));
    assert!(
        error_with(&|s| s.background_kind = causal_arm_explain::BackgroundKind::Kmeans)
            .contains("equal weights")
    );
    let err = error_with(&|s| s.samples = data.rows());
    assert!(
        err.contains(&format!("the data has {} transitions", data.rows())),
        "{err}"
    );
}
