//! The factored forward model of one fold: per FM head, a network fed only the head's
//! parents in the found graph. With `--factored-auxiliary auto` each head's candidate
//! networks are compared on validation rows (the tail of the training rows), among
//! themselves and against the full FM, whose own head is kept unless the best candidate
//! is significantly better: the factored FM is then never worse than the full one by
//! chance of selection.

use causal_arm_mlp::Regressor;

use super::{CrossValidation, Fold, held_out_prediction};
use crate::fit::{FitSettings, head_row_errors};
use crate::problems::{self, Problem};
use crate::structure::{self, Auxiliary, FoundGraph, HeadNet};
use crate::{FullFmComparison, Selection, TrainError};

/// File stem of the full FM when some head of a factored FM keeps it.
const FULL_FM_STEM: &str = "fm-factored-full-fm";

/// The full FM beside a factored one (`auto` only): its row errors per head on the
/// validation rows, from a fit on the other training rows; and, once a head keeps it, its
/// fit on all training rows, which is the `--model fm` network itself (same problem,
/// rows, settings and seed).
struct FullFm {
    problem: Problem,
    settings: FitSettings,
    /// Per head of `problem`, each validation row's error.
    validation_errors: Vec<Vec<f64>>,
    refitted: Option<Regressor>,
}

impl FullFm {
    fn head_index(&self, head: &str) -> Result<usize, TrainError> {
        self.problem
            .heads
            .iter()
            .position(|h| h.name == head)
            .ok_or_else(|| TrainError::Options(format!("the full FM has no head {head}")))
    }
}

impl CrossValidation<'_> {
    /// One network per FM head, fed only the head's parents in `graph`.
    pub(super) fn factored_forward_model(
        &mut self,
        fold: &Fold,
        graph: &FoundGraph,
    ) -> Result<(), TrainError> {
        let full = problems::forward_model(self.data, self.options.fm_target);
        let full = self.options.reduced(full)?;
        let settings =
            self.options
                .settings("fm", self.data.experiment, &self.options.factored_hidden);
        let auxiliary = self.options.factored_auxiliary;
        let mut full_fm = match auxiliary {
            Auxiliary::Auto => Some(self.full_fm_on_fit_rows(fold)?),
            _ => None,
        };
        for head in &full.heads {
            let candidates = structure::head_candidates(&full, head, graph, auxiliary)?;
            let kept =
                self.choose_head_network(fold, candidates, &head.name, &settings, &full_fm)?;
            match (kept, full_fm.as_mut()) {
                (Some((net, model)), _) => {
                    let primary = net.primary;
                    self.evaluate(fold, &net.problem, primary..primary + 1, &model, "fm")?;
                    let stem = format!("fm-factored-{}", head.name);
                    self.keep(fold, stem, model, &net.problem, settings.clone());
                }
                (None, Some(full_fm)) => self.full_fm_head(fold, full_fm, &head.name)?,
                (None, None) => unreachable!("a head keeps the full FM only beside one"),
            }
        }
        if let Some(FullFm {
            problem,
            settings,
            refitted: Some(model),
            ..
        }) = full_fm
        {
            self.keep(fold, FULL_FM_STEM.into(), model, &problem, settings);
        }
        Ok(())
    }

    /// Fits the full FM on the fit rows and records its row errors on the validation rows.
    fn full_fm_on_fit_rows(&mut self, fold: &Fold) -> Result<FullFm, TrainError> {
        let problem = problems::forward_model(self.data, self.options.fm_target);
        let settings = self
            .options
            .settings("fm", self.data.experiment, &self.options.fm_hidden);
        let (fit_rows, select_rows) = selection_split(&fold.train);
        let label = format!("fm-factored full-fm [validation] {}", fold.tag);
        let model = self.fit(&problem, fit_rows, fold.test, &settings, label)?;
        let (prediction, truth) = held_out_prediction(&problem, &model, select_rows)?;
        let validation_errors = problem
            .heads
            .iter()
            .map(|h| head_row_errors(&prediction, &truth, &problem.heads, h))
            .collect();
        Ok(FullFm {
            problem,
            settings,
            validation_errors,
            refitted: None,
        })
    }

    /// Records the full FM's figure for `head`, fitting it on all training rows first if
    /// no head has needed it yet.
    fn full_fm_head(
        &mut self,
        fold: &Fold,
        full_fm: &mut FullFm,
        head: &str,
    ) -> Result<(), TrainError> {
        let index = full_fm.head_index(head)?;
        let model = match full_fm.refitted.take() {
            Some(model) => model,
            None => {
                let label = format!("fm-factored full-fm {}", fold.tag);
                self.fit(
                    &full_fm.problem,
                    &fold.train,
                    fold.test,
                    &full_fm.settings,
                    label,
                )?
            }
        };
        self.evaluate(fold, &full_fm.problem, index..index + 1, &model, "fm")?;
        full_fm.refitted = Some(model);
        Ok(())
    }

    /// Fits a factored head's candidate networks and picks the one with the lowest error
    /// on the head. With several candidates, or a full FM to compare with, they are fitted
    /// on the first 95 % of the training rows and compared on the rest
    /// ([`selection_split`]), so the test fold plays no part in the choice; each run
    /// records its validation error. Beside a full FM the pick is kept only if
    /// significantly better than the full FM's head ([`FullFmComparison`]); `None` means
    /// the head keeps the full FM's.
    fn choose_head_network(
        &mut self,
        fold: &Fold,
        candidates: Vec<HeadNet>,
        head: &str,
        settings: &FitSettings,
        full_fm: &Option<FullFm>,
    ) -> Result<Option<(HeadNet, Regressor)>, TrainError> {
        let compared = candidates.len() > 1 || full_fm.is_some();
        let (fit_rows, select_rows) = match compared {
            true => selection_split(&fold.train),
            false => (&fold.train[..], &[][..]),
        };
        // (run record, validation MAE) of each candidate compared.
        let mut tried: Vec<(usize, f64)> = Vec::new();
        let mut best: Option<(f64, usize, Vec<f64>, HeadNet, Regressor)> = None;
        for net in candidates {
            let label = format!("fm-factored {head} [{}] {}", net.auxiliary.name(), fold.tag);
            let model = self.fit(&net.problem, fit_rows, fold.test, settings, label.clone())?;
            let (prediction, truth) = held_out_prediction(&net.problem, &model, select_rows)?;
            let info = &net.problem.heads[net.primary];
            let errors = head_row_errors(&prediction, &truth, &net.problem.heads, info);
            let score = errors.iter().sum::<f64>() / errors.len().max(1) as f64;
            let run = self.runs.len() - 1;
            if compared {
                tracing::info!("{label}: validation MAE {score:.4e}");
                tried.push((run, score));
            }
            if best.as_ref().is_none_or(|(b, ..)| score < *b) {
                best = Some((score, run, errors, net, model));
            }
        }
        let Some((_, best_run, best_errors, net, model)) = best else {
            return Err(TrainError::Options(format!(
                "head {head} has no candidate network"
            )));
        };
        let comparison = match full_fm {
            Some(full_fm) => {
                let full_errors = &full_fm.validation_errors[full_fm.head_index(head)?];
                let c = FullFmComparison::from_row_errors(&best_errors, full_errors);
                tracing::info!(
                    "fm-factored {head}: best candidate {:+.3e} ± {:.3e} (2 SE) against the full FM's {:.4e}: {}",
                    c.difference,
                    2.0 * c.standard_error,
                    c.full_fm_validation_mae,
                    if c.candidate_better {
                        "kept"
                    } else {
                        "the full FM's head is kept"
                    }
                );
                Some(c)
            }
            None => None,
        };
        let keep_candidate = comparison.is_none_or(|c| c.candidate_better);
        for (run, validation_mae) in tried {
            self.runs[run].selection = Some(Selection {
                validation_mae,
                chosen: keep_candidate && run == best_run,
                against_full_fm: comparison.filter(|_| run == best_run),
            });
        }
        Ok(keep_candidate.then_some((net, model)))
    }
}

/// Splits training rows into rows to fit on and the last twentieth, contiguous in time, on
/// which the candidates of a factored head are compared (so the test fold stays unseen).
fn selection_split(train: &[usize]) -> (&[usize], &[usize]) {
    let select = (train.len() / 20).max(1).min(train.len().saturating_sub(1));
    train.split_at(train.len() - select)
}
