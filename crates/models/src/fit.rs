//! Fitting a problem on some rows and judging it on others.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use causal_arm_dataset::wrap_angle;
use causal_arm_mlp::{Fitter, Head, Mlp, MlpSpec, Regressor, Standardizer, TrainConfig};
use rand::{SeedableRng, rngs::StdRng, seq::SliceRandom};
use serde::{Deserialize, Serialize};

use crate::TrainError;
use crate::problems::{HeadInfo, Problem};

/// Network size and training schedule of one model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FitSettings {
    /// Widths of the tanh hidden layers.
    pub hidden: Vec<usize>,
    /// Optimizer, learning rate, batch size, shuffle seed.
    pub train: TrainConfig,
    /// Passes over the training rows.
    pub epochs: usize,
}

/// What long work reports as it goes.
#[derive(Debug, Clone)]
pub enum Progress {
    /// A model starts training.
    Start {
        /// Model label (`fm`, `im_pre/pre`, …) and fold.
        label: String,
        /// Epochs planned.
        epochs: usize,
        /// Training rows per epoch.
        rows: usize,
    },
    /// Rows processed in the current epoch.
    Rows(usize),
    /// An epoch finished.
    Epoch {
        /// Epochs done.
        epoch: usize,
        /// Mean training loss (standardised units).
        loss: f64,
    },
}

/// Turns [`Progress`] events into occasional plain-text lines, for logs and pipes where a
/// progress bar cannot draw (the trainer node's `/rosout`, `causal-arm train 2>log`).
/// A line is due at a model's start, at its last epoch, and otherwise at most every
/// `every`; it carries epoch, loss, samples/s and the model's ETA.
#[derive(Debug)]
pub struct ProgressLog {
    every: Duration,
    last: Instant,
    label: String,
    epochs: usize,
    rows: usize,
    started: Instant,
    rows_done: u64,
}

impl ProgressLog {
    /// A log that stays silent for at most `every` between lines.
    pub fn new(every: Duration) -> Self {
        ProgressLog {
            every,
            last: Instant::now(),
            label: String::new(),
            epochs: 0,
            rows: 0,
            started: Instant::now(),
            rows_done: 0,
        }
    }

    /// Feeds one event; returns the line to print when one is due.
    pub fn line(&mut self, event: &Progress) -> Option<String> {
        match event {
            Progress::Start {
                label,
                epochs,
                rows,
            } => {
                (self.label, self.epochs, self.rows) = (label.clone(), *epochs, *rows);
                self.started = Instant::now();
                self.rows_done = 0;
                self.last = self.started;
                Some(format!("training {label}: {epochs} epochs on {rows} rows"))
            }
            Progress::Rows(n) => {
                self.rows_done += *n as u64;
                None
            }
            Progress::Epoch { epoch, loss } => {
                let due = *epoch == self.epochs || self.last.elapsed() >= self.every;
                if !due {
                    return None;
                }
                self.last = Instant::now();
                let elapsed = self.started.elapsed().as_secs_f64();
                let per_s = self.rows_done as f64 / elapsed.max(1e-9);
                let left = (self.epochs.saturating_sub(*epoch) * self.rows) as f64;
                Some(format!(
                    "{}: epoch {epoch}/{}, loss {loss:.5}, {:.0} samples/s, {:.0} s elapsed, ETA {:.0} s",
                    self.label,
                    self.epochs,
                    per_s,
                    elapsed,
                    left / per_s.max(1e-9)
                ))
            }
        }
    }
}

/// Rows `rows` of a row-major matrix.
pub fn take_rows(data: &[f32], width: usize, rows: &[usize]) -> Vec<f32> {
    let mut out = Vec::with_capacity(rows.len() * width);
    for &r in rows {
        out.extend_from_slice(&data[r * width..(r + 1) * width]);
    }
    out
}

/// Test rows of each of `k` folds of a seeded shuffle of `0..n` (the rest is training).
pub fn folds(n: usize, k: usize, seed: u64) -> Vec<Vec<usize>> {
    let mut order: Vec<usize> = (0..n).collect();
    order.shuffle(&mut StdRng::seed_from_u64(seed));
    (0..k)
        .map(|f| order[f * n / k..(f + 1) * n / k].to_vec())
        .collect()
}

/// The complement of `test` in `0..n`.
pub fn training_rows(n: usize, test: &[usize]) -> Vec<usize> {
    let mut is_test = vec![false; n];
    for &t in test {
        is_test[t] = true;
    }
    (0..n).filter(|&r| !is_test[r]).collect()
}

/// A look at the model every few epochs, e.g. its held-out error for a learning curve.
pub type Checkpoint<'a> = &'a mut dyn FnMut(usize, &Regressor) -> Result<(), TrainError>;

/// Who watches a fit: progress reports, a stop request, and periodic checkpoints.
pub struct FitWatch<'a> {
    /// Progress of the fit.
    pub progress: &'a mut dyn FnMut(Progress),
    /// Once set, the fit ends before its next epoch with [`TrainError::Stopped`].
    pub stop: Option<&'a AtomicBool>,
    /// Called after every `n`-th epoch (and the last) with the epoch and the model so far.
    pub checkpoint: Option<(usize, Checkpoint<'a>)>,
}

/// Trains a network for `problem` on `rows`, standardising inputs and targets with
/// statistics of those rows only.
pub fn fit(
    problem: &Problem,
    rows: &[usize],
    settings: &FitSettings,
    seed: u64,
    label: &str,
    watch: FitWatch<'_>,
) -> Result<Regressor, TrainError> {
    let FitWatch {
        progress,
        stop,
        mut checkpoint,
    } = watch;
    let n_in = problem.input_names.len();
    let n_out = problem.output_names.len();
    let mut x = take_rows(&problem.inputs, n_in, rows);
    let mut y = take_rows(&problem.targets(), n_out, rows);
    let input = Standardizer::fit(&x, n_in);
    let mut output = Standardizer::fit(&y, n_out);
    // A target column that never varies (colour within exp 2's transitions for a delta FM)
    // is predicted exactly: scale the network's residual noise on it down to nothing.
    for j in 0..n_out {
        if (0..rows.len()).all(|r| y[r * n_out + j] == y[j]) {
            output.std[j] = 1e-6 * output.mean[j].abs().max(1e-3);
        }
    }
    input.apply_in_place(&mut x);
    output.apply_in_place(&mut y);
    let spec = MlpSpec {
        inputs: n_in,
        hidden: settings.hidden.clone(),
        heads: problem.heads.iter().map(Head::from).collect(),
    };
    let mut fitter = Fitter::new(Mlp::new(spec, seed)?, settings.train.clone())?;
    fitter.plan_batches(fitter.batches_for(settings.epochs, rows.len()));
    progress(Progress::Start {
        label: label.to_owned(),
        epochs: settings.epochs,
        rows: rows.len(),
    });
    for epoch in 0..settings.epochs {
        if stop.is_some_and(|s| s.load(Ordering::Relaxed)) {
            return Err(TrainError::Stopped {
                label: label.to_owned(),
                epoch,
            });
        }
        let loss = fitter.epoch(&x, &y, |n| progress(Progress::Rows(n)))?;
        if !loss.is_finite() {
            return Err(TrainError::Diverged {
                label: label.to_owned(),
                epoch: epoch + 1,
            });
        }
        progress(Progress::Epoch {
            epoch: epoch + 1,
            loss,
        });
        if let Some((every, look)) = checkpoint.as_mut() {
            let done = epoch + 1;
            if done % (*every).max(1) == 0 || done == settings.epochs {
                look(
                    done,
                    &Regressor {
                        mlp: fitter.mlp().clone(),
                        input: input.clone(),
                        output: output.clone(),
                    },
                )?;
            }
        }
    }
    Ok(Regressor {
        mlp: fitter.into_mlp(),
        input,
        output,
    })
}

/// Predictions in raw units for rows of `inputs`, with the problem's offset added and
/// angular outputs (Euler angles) wrapped into (−π, π].
pub fn predict(
    model: &Regressor,
    inputs: &[f32],
    offset_columns: Option<&[usize]>,
    heads: &[HeadInfo],
) -> Result<Vec<f32>, TrainError> {
    let angular: Vec<usize> = heads
        .iter()
        .filter(|h| h.angular)
        .flat_map(|h| h.start..h.start + h.len)
        .collect();
    let mut out = Vec::with_capacity(inputs.len());
    let n_in = model.mlp.spec().inputs;
    let n_out = model.mlp.spec().outputs();
    // Batches bound the memory of the activations on paper-size datasets.
    for chunk in inputs.chunks(65_536 * n_in) {
        let mut y = model.predict(chunk)?;
        if let Some(cols) = offset_columns {
            for (row_out, row_in) in y.chunks_exact_mut(n_out).zip(chunk.chunks_exact(n_in)) {
                for (v, &c) in row_out.iter_mut().zip(cols) {
                    *v += row_in[c];
                }
            }
        }
        if !angular.is_empty() {
            for row_out in y.chunks_exact_mut(n_out) {
                for &c in &angular {
                    row_out[c] = wrap_angle(row_out[c] as f64) as f32;
                }
            }
        }
        out.extend(y);
    }
    Ok(out)
}

/// Mean absolute error of each head (angular heads wrapped into (−π, π]).
pub fn head_mae(prediction: &[f32], truth: &[f32], heads: &[HeadInfo]) -> Vec<f64> {
    heads
        .iter()
        .map(|h| {
            let errors = head_row_errors(prediction, truth, heads, h);
            errors.iter().sum::<f64>() / errors.len().max(1) as f64
        })
        .collect()
}

/// Each row's mean absolute error over the columns of `head`, one of `heads` (angles
/// wrapped): the terms of [`head_mae`], kept apart where two models are compared row by
/// row.
pub fn head_row_errors(
    prediction: &[f32],
    truth: &[f32],
    heads: &[HeadInfo],
    head: &HeadInfo,
) -> Vec<f64> {
    let width: usize = heads.iter().map(|h| h.len).sum();
    let rows = truth.len() / width.max(1);
    (0..rows)
        .map(|r| {
            let row_sum: f64 = (head.start..head.start + head.len)
                .map(|c| {
                    let d = prediction[r * width + c] as f64 - truth[r * width + c] as f64;
                    if head.angular {
                        wrap_angle(d).abs()
                    } else {
                        d.abs()
                    }
                })
                .sum();
            row_sum / head.len.max(1) as f64
        })
        .collect()
}

/// MAE of predicting the training rows' mean of each column (the floor any model must beat).
pub fn mean_baseline_mae(
    truth: &[f32],
    heads: &[HeadInfo],
    train: &[usize],
    test: &[usize],
) -> Vec<f64> {
    let width: usize = heads.iter().map(|h| h.len).sum();
    let mut mean = vec![0f64; width];
    for &r in train {
        for (c, m) in mean.iter_mut().enumerate() {
            *m += truth[r * width + c] as f64;
        }
    }
    mean.iter_mut()
        .for_each(|m| *m /= train.len().max(1) as f64);
    let prediction: Vec<f32> = test
        .iter()
        .flat_map(|_| mean.iter().map(|&m| m as f32))
        .collect();
    head_mae(&prediction, &take_rows(truth, width, test), heads)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn start(epochs: usize) -> Progress {
        Progress::Start {
            label: "fm fold 1/5".into(),
            epochs,
            rows: 100,
        }
    }

    #[test]
    fn progress_log_speaks_at_start_and_end_and_stays_quiet_between() {
        let mut log = ProgressLog::new(Duration::from_secs(3600));
        assert_eq!(
            log.line(&start(3)).as_deref(),
            Some("training fm fold 1/5: 3 epochs on 100 rows")
        );
        for epoch in 1..=3 {
            assert!(log.line(&Progress::Rows(100)).is_none());
            let line = log.line(&Progress::Epoch { epoch, loss: 0.5 });
            assert_eq!(line.is_some(), epoch == 3, "epoch {epoch}: {line:?}");
        }
        let last = log
            .line(&Progress::Epoch {
                epoch: 3,
                loss: 0.5,
            })
            .unwrap();
        assert!(
            last.starts_with("fm fold 1/5: epoch 3/3, loss 0.50000,"),
            "{last}"
        );
        assert!(last.ends_with("ETA 0 s"), "{last}");
    }

    #[test]
    fn progress_log_with_no_interval_reports_every_epoch() {
        let mut log = ProgressLog::new(Duration::ZERO);
        log.line(&start(4));
        log.line(&Progress::Rows(100));
        let line = log
            .line(&Progress::Epoch {
                epoch: 1,
                loss: 1.0,
            })
            .unwrap();
        assert!(line.contains("epoch 1/4"), "{line}");
    }
}
