//! k-fold cross-validation of one model kind: per fold, fit the kind's networks on the
//! training rows and record each figure on the held-out rows beside the mean baseline.
//! One method per model kind; what they share (a timed fit, a figure, a kept model) is a
//! method of [`CrossValidation`].

use std::ops::Range;
use std::time::{Duration, Instant};

use causal_arm_dataset::{Dataset, Experiment};
use causal_arm_mlp::Regressor;
use rand::{Rng, SeedableRng};

use crate::fit::{
    self, FitSettings, FitWatch, Progress, fit, folds, head_mae, mean_baseline_mae, predict,
    take_rows, training_rows,
};
use crate::problems::{self, Problem};
use crate::report::FigureTable;

mod factored;
use crate::{CurvePoint, KindReport, ModelKind, ProblemInfo, RunRecord, TrainError, TrainOptions};

/// Cross-validates one model kind on `data`.
pub fn cross_validate(
    data: &Dataset,
    kind: ModelKind,
    options: &TrainOptions,
    progress: &mut dyn FnMut(Progress),
) -> Result<KindReport, TrainError> {
    options.validate()?;
    let exp = data.experiment;
    if matches!(kind, ModelKind::ImPre | ModelKind::Ablation) && exp != Experiment::Exp1 {
        return Err(TrainError::Options(format!(
            "{} is defined for exp1 only (the paper's pre-computation study); exp2 has fm and im-mono",
            kind.name()
        )));
    }
    let n = data.rows();
    if n < options.folds * 2 {
        return Err(TrainError::Options(format!(
            "{n} transitions are too few for {} folds",
            options.folds
        )));
    }
    let k = options.folds;
    let run_folds = options.max_folds.unwrap_or(k).clamp(1, k);
    let mut cv = CrossValidation {
        data,
        options,
        progress,
        figures: FigureTable::default(),
        runs: Vec::new(),
        models: Vec::new(),
    };
    for (index, test) in folds(n, k, options.seed).iter().take(run_folds).enumerate() {
        let fold = Fold {
            index,
            train: training_rows(n, test),
            test,
            tag: format!("fold {}/{k}", index + 1),
        };
        match kind {
            ModelKind::Fm => cv.forward_model(&fold)?,
            ModelKind::ImMono => cv.inverse_model(&fold)?,
            ModelKind::FmFactored => {
                let graph = options.graph.as_ref().ok_or_else(|| {
                    TrainError::Options(
                        "fm-factored needs the causal graph found by `causal-arm explain` (--graph CLAIMS_JSON)".into(),
                    )
                })?;
                cv.factored_forward_model(&fold, graph)?
            }
            ModelKind::ImPre => cv.pre_computation(&fold)?,
            ModelKind::Ablation => cv.ablation(&fold)?,
        }
    }
    Ok(KindReport {
        kind,
        figures: cv.figures.summarise(exp),
        runs: cv.runs,
        models: cv.models,
    })
}

/// One fold: its held-out rows and the rest to train on.
struct Fold<'a> {
    index: usize,
    train: Vec<usize>,
    test: &'a [usize],
    /// `fold 2/5`, for labels.
    tag: String,
}

/// What cross-validating one kind accumulates over its folds.
struct CrossValidation<'a> {
    data: &'a Dataset,
    options: &'a TrainOptions,
    progress: &'a mut dyn FnMut(Progress),
    figures: FigureTable,
    runs: Vec<RunRecord>,
    models: Vec<(String, Regressor, ProblemInfo, FitSettings)>,
}

/// The base IM of the pre-computation study, fitted on a fold, with what both its
/// figures (`im_pre`, `ablation`) evaluate it on.
struct BaseIm {
    problem: Problem,
    settings: FitSettings,
    model: Regressor,
    /// a(t) of the held-out rows.
    test_truth: Vec<f32>,
    /// Predict-the-mean MAE of a(t) on the held-out rows.
    baseline: f64,
    pre_problem: Problem,
    /// The pre-network's inputs of the held-out rows.
    test_pre_inputs: Vec<f32>,
}

impl CrossValidation<'_> {
    /// Fits `problem` on `rows`, timing it and (with `eval_every`) tracing its held-out
    /// error on the fold's test rows; the run is recorded.
    fn fit(
        &mut self,
        problem: &Problem,
        rows: &[usize],
        test: &[usize],
        settings: &FitSettings,
        label: String,
    ) -> Result<Regressor, TrainError> {
        let start = Instant::now();
        let mut curve = Vec::new();
        let mut evaluating = Duration::ZERO;
        let mut look = |epoch: usize, model: &Regressor| -> Result<(), TrainError> {
            let trained = start.elapsed() - evaluating;
            let mae = held_out_mae(problem, model, test)?;
            evaluating = start.elapsed() - trained;
            curve.push(CurvePoint {
                epoch,
                wall_s: trained.as_secs_f64(),
                mae,
            });
            Ok(())
        };
        let watch = FitWatch {
            progress: &mut *self.progress,
            stop: self.options.stop.as_deref(),
            checkpoint: self
                .options
                .eval_every
                .map(|every| (every, &mut look as fit::Checkpoint<'_>)),
        };
        let model = fit(problem, rows, settings, self.options.seed, &label, watch)?;
        let wall = start.elapsed() - evaluating;
        self.runs.push(RunRecord {
            label,
            epochs: settings.epochs,
            rows: rows.len(),
            wall_s: wall.as_secs_f64(),
            parameters: model.mlp.spec().parameters(),
            curve,
            selection: None,
        });
        Ok(model)
    }

    /// Records the held-out figures of `heads` of `problem` (auxiliary outputs left out).
    fn evaluate(
        &mut self,
        fold: &Fold,
        problem: &Problem,
        heads: Range<usize>,
        model: &Regressor,
        prefix: &str,
    ) -> Result<(), TrainError> {
        let mae = held_out_mae(problem, model, fold.test)?;
        let baseline = mean_baseline_mae(&problem.truth, &problem.heads, &fold.train, fold.test);
        let infos = &problem.heads[heads.clone()];
        self.figures
            .record(prefix, infos, &mae[heads.clone()], &baseline[heads]);
        Ok(())
    }

    /// Keeps the first fold's network to save as `stem`.
    fn keep(
        &mut self,
        fold: &Fold,
        stem: String,
        model: Regressor,
        problem: &Problem,
        settings: FitSettings,
    ) {
        if fold.index == 0 {
            self.models
                .push((stem, model, ProblemInfo::from(problem), settings));
        }
    }

    /// One network on a whole problem, every head a figure under `prefix`.
    fn whole(
        &mut self,
        fold: &Fold,
        problem: Problem,
        prefix: &str,
        hidden: &[usize],
    ) -> Result<(), TrainError> {
        let settings = self.options.settings(prefix, self.data.experiment, hidden);
        let stem = prefix.replace('_', "-");
        let label = format!("{stem} {}", fold.tag);
        let model = self.fit(&problem, &fold.train, fold.test, &settings, label)?;
        self.evaluate(fold, &problem, 0..problem.heads.len(), &model, prefix)?;
        self.keep(fold, stem, model, &problem, settings);
        Ok(())
    }

    fn forward_model(&mut self, fold: &Fold) -> Result<(), TrainError> {
        let problem = problems::forward_model(self.data, self.options.fm_target);
        let problem = self.options.reduced(problem)?;
        self.whole(fold, problem, "fm", &self.options.fm_hidden.clone())
    }

    fn inverse_model(&mut self, fold: &Fold) -> Result<(), TrainError> {
        let problem = self.options.reduced(problems::inverse_model(self.data))?;
        self.whole(fold, problem, "im_mono", &self.options.im_hidden.clone())
    }

    /// Fits the base IM [s(t), θ(t+1)] → a(t) of the pre-computation study.
    fn base_im(&mut self, fold: &Fold) -> Result<BaseIm, TrainError> {
        let exp = self.data.experiment;
        let problem = problems::base_inverse_model(self.data);
        let settings = self.options.settings("base", exp, &self.options.im_hidden);
        let label = format!("base IM {}", fold.tag);
        let model = self.fit(&problem, &fold.train, fold.test, &settings, label)?;
        let test_truth = take_rows(&problem.truth, 7, fold.test);
        let baseline = mean_baseline_mae(&problem.truth, &problem.heads, &fold.train, fold.test)[0];
        let pre_problem = problems::pre_network(self.data);
        let test_pre_inputs = take_rows(
            &pre_problem.inputs,
            pre_problem.input_names.len(),
            fold.test,
        );
        Ok(BaseIm {
            problem,
            settings,
            model,
            test_truth,
            baseline,
            pre_problem,
            test_pre_inputs,
        })
    }

    /// The base IM's joint MAE on the held-out rows given `inputs`.
    fn base_mae(base: &BaseIm, inputs: &[f32]) -> Result<f64, TrainError> {
        let prediction = predict(&base.model, inputs, None, &[])?;
        Ok(head_mae(&prediction, &base.test_truth, &base.problem.heads)[0])
    }

    /// The paper's pre-computation IM: the base IM, the pre-network s(t), s′(t+1) → θ(t+1),
    /// and the two assembled.
    fn pre_computation(&mut self, fold: &Fold) -> Result<(), TrainError> {
        let exp = self.data.experiment;
        let base = self.base_im(fold)?;
        let width = base.problem.input_names.len();
        let base_inputs = take_rows(&base.problem.inputs, width, fold.test);
        let base_mae = Self::base_mae(&base, &base_inputs)?;
        self.figures
            .single("im_pre/base", "rad", base_mae, base.baseline);
        let pre_problem = &base.pre_problem;
        let pre_settings = self.options.settings("pre", exp, &self.options.im_hidden);
        let label = format!("pre-network {}", fold.tag);
        let pre = self.fit(pre_problem, &fold.train, fold.test, &pre_settings, label)?;
        let theta_hat = predict(&pre, &base.test_pre_inputs, None, &[])?;
        let theta_truth = take_rows(&pre_problem.truth, 7, fold.test);
        let pre_mae = head_mae(&theta_hat, &theta_truth, &pre_problem.heads)[0];
        let pre_baseline = mean_baseline_mae(
            &pre_problem.truth,
            &pre_problem.heads,
            &fold.train,
            fold.test,
        )[0];
        self.figures
            .single("im_pre/pre", "rad", pre_mae, pre_baseline);
        let assembled = problems::base_inputs_from(exp, &base.test_pre_inputs, &theta_hat);
        let assembly_mae = Self::base_mae(&base, &assembled)?;
        self.figures
            .single("im_pre/assembly", "rad", assembly_mae, base.baseline);
        let BaseIm {
            problem,
            settings,
            model,
            pre_problem,
            ..
        } = base;
        self.keep(fold, "im-pre-base".into(), model, &problem, settings);
        self.keep(fold, "im-pre-pre".into(), pre, &pre_problem, pre_settings);
        Ok(())
    }

    /// The base IM fed θ(t+1) = 0, or θi(t+1) drawn per joint from the training rows.
    fn ablation(&mut self, fold: &Fold) -> Result<(), TrainError> {
        let exp = self.data.experiment;
        let base = self.base_im(fold)?;
        let rows = fold.test.len();
        let zeros = vec![0f32; rows * 7];
        let zero_inputs = problems::base_inputs_from(exp, &base.test_pre_inputs, &zeros);
        let zero_mae = Self::base_mae(&base, &zero_inputs)?;
        self.figures
            .single("ablation/zero", "rad", zero_mae, base.baseline);
        let mut rng = rand::rngs::StdRng::seed_from_u64(self.options.seed ^ 0xab1a);
        let sampled: Vec<f32> = (0..rows * 7)
            .map(|i| {
                let r = fold.train[rng.random_range(0..fold.train.len())];
                base.pre_problem.truth[r * 7 + i % 7]
            })
            .collect();
        let sampled_inputs = problems::base_inputs_from(exp, &base.test_pre_inputs, &sampled);
        let sampled_mae = Self::base_mae(&base, &sampled_inputs)?;
        self.figures
            .single("ablation/sampled", "rad", sampled_mae, base.baseline);
        Ok(())
    }
}

/// MAE of each head of `model` on rows `test` of `problem`.
fn held_out_mae(
    problem: &Problem,
    model: &Regressor,
    test: &[usize],
) -> Result<Vec<f64>, TrainError> {
    let (prediction, truth) = held_out_prediction(problem, model, test)?;
    Ok(head_mae(&prediction, &truth, &problem.heads))
}

/// `model`'s prediction of rows `rows` of `problem`, and their truth.
fn held_out_prediction(
    problem: &Problem,
    model: &Regressor,
    rows: &[usize],
) -> Result<(Vec<f32>, Vec<f32>), TrainError> {
    let inputs = take_rows(&problem.inputs, problem.input_names.len(), rows);
    let prediction = predict(
        model,
        &inputs,
        problem.offset_columns.as_deref(),
        &problem.heads,
    )?;
    let truth = take_rows(&problem.truth, problem.output_names.len(), rows);
    Ok((prediction, truth))
}
