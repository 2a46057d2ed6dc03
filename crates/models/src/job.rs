//! One training run end to end: cross-validate the requested models on a dataset, save
//! each kind's fold-1 networks and merge the figures into `metrics.json`. `causal-arm
//! train` and the trainer node both go through here, so they write the same files.

use std::path::{Path, PathBuf};

use causal_arm_dataset::{ActionSource, Dataset};

use crate::fit::Progress;
use crate::model_file::describe;
use crate::{Figure, ModelKind, RunRecord, TrainError, TrainOptions, cross_validate, save_model};

/// What a run wrote and measured.
#[derive(Debug)]
pub struct SavedRun {
    /// Every figure of every model kind, in the order trained.
    pub figures: Vec<Figure>,
    /// Epochs and wall time of each network.
    pub runs: Vec<RunRecord>,
    /// Model files written (`.safetensors` and `.json` pairs).
    pub written: Vec<PathBuf>,
    /// The merged metrics file.
    pub metrics: PathBuf,
}

/// Writes the metrics whole then renames it into place: a crash never leaves half a file.
fn write_metrics(
    path: &Path,
    metrics: &serde_json::Map<String, serde_json::Value>,
) -> Result<(), TrainError> {
    let failed = |problem: String| TrainError::File {
        path: path.to_owned(),
        problem,
    };
    let text = serde_json::to_string_pretty(metrics).map_err(|e| failed(e.to_string()))?;
    let write = || -> std::io::Result<()> {
        use std::io::Write;
        let mut file = atomic_write_file::AtomicWriteFile::open(path)?;
        file.write_all((text + "\n").as_bytes())?;
        file.commit()
    };
    write().map_err(|e| failed(format!("cannot write: {e}")))
}

/// Cross-validates `kinds` on `data` and writes `out/<model>.{safetensors,json}` and
/// `out/metrics.json`. Entries of other model kinds already in `metrics.json` are kept,
/// so models trained in separate runs share one directory. `action` is recorded only.
pub fn train_and_save(
    data: &Dataset,
    kinds: &[ModelKind],
    options: &TrainOptions,
    action: ActionSource,
    out: &Path,
    progress: &mut dyn FnMut(Progress),
) -> Result<SavedRun, TrainError> {
    let file_err = |path: &Path, problem: String| TrainError::File {
        path: path.to_owned(),
        problem,
    };
    std::fs::create_dir_all(out).map_err(|e| file_err(out, format!("cannot create: {e}")))?;
    let metrics_path = out.join("metrics.json");
    let mut metrics: serde_json::Map<String, serde_json::Value> =
        match std::fs::read_to_string(&metrics_path) {
            Ok(text) => serde_json::from_str(&text).map_err(|e| {
                file_err(
                    &metrics_path,
                    format!("exists but is not a metrics file ({e}); move it away or pick another output directory"),
                )
            })?,
            Err(_) => Default::default(),
        };
    metrics.insert("experiment".into(), data.experiment.to_string().into());
    metrics.insert("rows".into(), data.rows().into());
    metrics.insert(
        "sources".into(),
        serde_json::to_value(&data.sources).map_err(|e| file_err(&metrics_path, e.to_string()))?,
    );
    let folds_run = options
        .max_folds
        .unwrap_or(options.folds)
        .min(options.folds);
    let mut saved = SavedRun {
        figures: Vec::new(),
        runs: Vec::new(),
        written: Vec::new(),
        metrics: metrics_path.clone(),
    };
    for &kind in kinds {
        let report = cross_validate(data, kind, options, progress)?;
        for (name, model, problem, settings) in &report.models {
            let meta = describe(
                name,
                data.experiment,
                model,
                problem,
                settings,
                format!(
                    "fold 1 of {} ({} of {} rows)",
                    options.folds,
                    data.rows() - data.rows() / options.folds,
                    data.rows()
                ),
                &data.sources,
            );
            let (weights, json) = save_model(out, model, &meta)?;
            saved.written.extend([weights, json]);
        }
        let models_entry = metrics
            .entry("models")
            .or_insert_with(|| serde_json::Value::Object(Default::default()));
        models_entry[kind.name()] = serde_json::json!({
            "folds": options.folds,
            "folds_run": folds_run,
            "figures": report.figures,
            "runs": report.runs,
            "options": {
                "profile": options.profile,
                "epochs": options.epochs,
                "fm_target": options.fm_target,
                "action": action.to_string(),
                "batch_size": options.batch_size,
                "learning_rate": options.learning_rate,
                "lr_schedule": options.lr_schedule.to_string(),
                "fm_hidden": options.fm_hidden,
                "im_hidden": options.im_hidden,
                "seed": options.seed,
                "graph": options.graph.as_ref().map(|g| g.source.clone()),
                "left_out": options.graph.as_ref().map(|g| g.unaffected()),
                "factored_hidden": (kind == ModelKind::FmFactored).then_some(&options.factored_hidden),
                "factored_auxiliary": (kind == ModelKind::FmFactored).then_some(options.factored_auxiliary.name()),
            },
        });
        saved.runs.extend(report.runs);
        saved.figures.extend(report.figures);
        // After every kind, so a run stopped later still leaves what it finished.
        write_metrics(&metrics_path, &metrics)?;
    }
    Ok(saved)
}
