//! Causal influence of each action on each next-state feature under the forward model, in
//! the way of CAI (Seitzer et al. 2021, "Causal Influence Detection"): in a state s with
//! action a, resample a_j from its marginal and measure the spread of the predicted
//! s_k(t+1). And the decision rules that turn per-observation effects into verdicts:
//! - error ratio: an edge is claimed when the 95 % bootstrap lower bound of its mean effect
//!   (CAI spread, |SHAP|) exceeds κ × the model's own error on that feature — an effect
//!   smaller than what the model gets wrong cannot be told from the model's mistakes;
//! - significance: signed effects whose mean is tested against 0 with a Bonferroni
//!   correction (agreement of independently trained models; a holdout test with draws of
//!   a_j given the rest).

use causal_arm_dataset::{Context, ContextReader, Dataset, angular_features, wrap_angle};
use causal_arm_models::LoadedModel;
use causal_arm_params::{ExplainerParams, explainer};
use causal_arm_scoring::EdgeClaims;
use rand::rngs::StdRng;
use rand::seq::index::sample;
use rand::{Rng, SeedableRng};

use crate::{ExplainError, Explainer, Result, forward_inputs};

mod rules;
mod significance;
mod switches;

pub use rules::*;
pub use significance::*;
pub use switches::*;

/// How influence is measured and judged.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct InfluenceSettings {
    /// Observations (states with their actions) the influence is averaged over.
    pub observations: usize,
    /// Values of a_j drawn from its marginal per observation.
    pub resamples: usize,
    /// Rows the model's per-feature error (the floor) is measured on.
    pub error_rows: usize,
    /// Bootstrap resamples of the observations for the interval.
    pub bootstrap: usize,
    /// An edge needs its effect's lower bound above κ × the feature's error. 1: an action
    /// must move the prediction by at least the model's own mean error on the feature
    /// (measured: null edges stay at ≤ 0.8 × the error on the paper exp1 FM, the weakest
    /// true edges reach 1.6, docs/RESULTS.md).
    pub kappa: f64,
    /// Seed of every draw.
    pub seed: u64,
}

impl Default for InfluenceSettings {
    fn default() -> Self {
        Self {
            observations: 500,
            resamples: 64,
            error_rows: 20_000,
            bootstrap: 1000,
            kappa: 1.0,
            seed: 0,
        }
    }
}

/// Per-observation effects of every action on every output, `[obs][action][state]`, and
/// what is needed to judge them.
#[derive(Debug, Clone)]
pub struct Effects {
    /// Method name (`cai`, `deep`, `kernel`).
    pub method: String,
    /// Dataset rows of the observations.
    pub rows: Vec<usize>,
    /// Number of actions.
    pub n_action: usize,
    /// Number of state features.
    pub n_state: usize,
    /// `[obs][action][state]`, raw units of the state feature.
    pub values: Vec<f64>,
}

impl Effects {
    /// Indices of the observations whose s(t) is in `context`.
    pub(crate) fn members(
        &self,
        data: &Dataset,
        reader: &ContextReader,
        context: &Context,
    ) -> Vec<usize> {
        (0..self.rows.len())
            .filter(|&o| reader.holds(data, self.rows[o], context))
            .collect()
    }

    fn at(&self, obs: usize, action: usize, state: usize) -> f64 {
        self.values[(obs * self.n_action + action) * self.n_state + state]
    }
}

/// The observations an estimator probes: rows drawn from the data (seeded), their forward
/// inputs `[state ++ action]`, and the generator that continues to draw from.
pub(crate) struct Probe {
    pub(crate) rng: StdRng,
    pub(crate) rows: Vec<usize>,
    pub(crate) base: Vec<f32>,
    pub(crate) ns: usize,
    pub(crate) na: usize,
    pub(crate) width: usize,
}

impl Probe {
    fn draw(data: &Dataset, settings: &InfluenceSettings) -> Result<Self> {
        check(settings, data.rows())?;
        let mut rng = StdRng::seed_from_u64(settings.seed);
        let rows = sample(&mut rng, data.rows(), settings.observations).into_vec();
        Ok(Self::at_rows(data, rows, rng))
    }

    /// The observations `rows` (chosen by the caller, e.g. rows that start a chain of
    /// transitions), drawing on with `rng`.
    pub(crate) fn at_rows(data: &Dataset, rows: Vec<usize>, rng: StdRng) -> Self {
        let (ns, na) = (data.state_width(), data.action_width());
        Self {
            base: forward_inputs(data, &rows),
            rng,
            rows,
            ns,
            na,
            width: ns + na,
        }
    }
}

impl Probe {
    /// Input rows probing every action: per observation and action j, `count` copies of the
    /// observation with a_j replaced by draw number `index(j, i)` of [`ActionDraws`].
    pub(crate) fn batch(
        &mut self,
        data: &Dataset,
        draws: &ActionDraws,
        count: usize,
        index: impl Fn(usize, usize) -> usize,
    ) -> Vec<f32> {
        let mut batch = Vec::with_capacity(self.rows.len() * self.na * count * self.width);
        for obs in 0..self.rows.len() {
            let x = &self.base[obs * self.width..(obs + 1) * self.width];
            for j in 0..self.na {
                for i in 0..count {
                    let mut row = x.to_vec();
                    row[self.ns + j] =
                        draws.draw(data, j, index(j, i), &x[..self.ns], &mut self.rng);
                    batch.extend_from_slice(&row);
                }
            }
        }
        batch
    }
}

/// The network's own output for input rows `batch` (`width` wide), in chunks that bound
/// the activations' memory: for a delta model s(t+1) − s(t), whose changes over a_j are
/// those of s(t+1) (s(t) is fixed), without f32 rounding of the offset or angle wrapping.
fn network_outputs(explainer: &Explainer, batch: &[f32], width: usize) -> Result<Vec<f32>> {
    let mut predicted = Vec::new();
    for chunk in batch.chunks(65_536 * width) {
        predicted.extend(
            explainer
                .model()
                .regressor
                .predict(chunk)
                .map_err(|e| ExplainError::Options(e.to_string()))?,
        );
    }
    Ok(predicted)
}

/// Distinct values of action column `j` when it takes at most a few (the magnet command's
/// −1, 0, +1): such an action is probed at every value, as the simulator's truth flips
/// it, rather than at marginal draws that almost never leave its common value.
pub(crate) fn discrete_values(data: &Dataset, j: usize) -> Option<Vec<f32>> {
    distinct_values(data.rows(), |r| data.action(r)[j], 8)
}

/// Draws of action `j` for probing. A continuous action: a random row's value (its
/// marginal). A discrete one (the magnet command): its values in turn, but only those the
/// data shows in states like this one (same values of every discrete state feature, the
/// magnet's on/off): switching on a magnet that is on never occurs, and a network's answer
/// there is arbitrary.
pub(crate) struct ActionDraws {
    discrete: Vec<Option<Vec<f32>>>,
    /// State columns with few distinct values (the context a discrete action's support
    /// depends on).
    discrete_states: Vec<usize>,
    /// Per action: the values seen with each combination of the discrete state features.
    support: Vec<std::collections::BTreeMap<Vec<u32>, Vec<f32>>>,
}

impl ActionDraws {
    pub(crate) fn new(data: &Dataset) -> Self {
        let discrete: Vec<Option<Vec<f32>>> = (0..data.action_width())
            .map(|j| discrete_values(data, j))
            .collect();
        let discrete_states: Vec<usize> = (0..data.state_width())
            .filter(|&k| distinct_values(data.rows(), |r| data.state(r)[k], 8).is_some())
            .collect();
        let mut support = vec![std::collections::BTreeMap::new(); data.action_width()];
        for (j, values) in discrete.iter().enumerate() {
            if values.is_none() {
                continue;
            }
            for r in 0..data.rows() {
                let seen: &mut Vec<f32> = support[j]
                    .entry(Self::key(&discrete_states, data.state(r)))
                    .or_default();
                let v = data.action(r)[j];
                if !seen.contains(&v) {
                    seen.push(v);
                    seen.sort_by(f32::total_cmp);
                }
            }
        }
        Self {
            discrete,
            discrete_states,
            support,
        }
    }

    fn key(columns: &[usize], state: &[f32]) -> Vec<u32> {
        columns.iter().map(|&k| state[k].to_bits()).collect()
    }

    /// Draw number `i` of action `j` for the observation with state `state`.
    fn draw(&self, data: &Dataset, j: usize, i: usize, state: &[f32], rng: &mut StdRng) -> f32 {
        match &self.discrete[j] {
            Some(values) => {
                let seen = self.support[j]
                    .get(&Self::key(&self.discrete_states, state))
                    .unwrap_or(values);
                seen[i % seen.len()]
            }
            None => data.action(rng.random_range(0..data.rows()))[j],
        }
    }
}

/// The distinct values of `value(r)` over `rows` rows, sorted, if there are at most `limit`.
fn distinct_values(rows: usize, value: impl Fn(usize) -> f32, limit: usize) -> Option<Vec<f32>> {
    let mut seen: Vec<f32> = Vec::new();
    for r in 0..rows {
        let v = value(r);
        if !seen.contains(&v) {
            if seen.len() == limit {
                return None;
            }
            seen.push(v);
        }
    }
    seen.sort_by(f32::total_cmp);
    Some(seen)
}

/// CAI influence: for each of `settings.observations` rows drawn from `data`, the standard
/// deviation of the forward model's predicted s_k(t+1) over `resamples` draws of a_j from
/// its marginal, or over its values for a discrete action (the other inputs kept).
pub fn cai_effects(
    explainer: &Explainer,
    data: &Dataset,
    settings: &InfluenceSettings,
) -> Result<Effects> {
    cai_effects_at(explainer, data, settings, Probe::draw(data, settings)?)
}

/// CAI influence at the observations of `probe` (see [`cai_effects`]).
fn cai_effects_at(
    explainer: &Explainer,
    data: &Dataset,
    settings: &InfluenceSettings,
    mut probe: Probe,
) -> Result<Effects> {
    let k = settings.resamples;
    let batch = probe.batch(data, &ActionDraws::new(data), k, |_, i| i);
    let Probe {
        rows,
        ns,
        na,
        width,
        ..
    } = probe;
    let predicted = network_outputs(explainer, &batch, width)?;
    let mut values = vec![0.0; rows.len() * na * ns];
    for (group, out) in predicted
        .chunks_exact(k * ns)
        .zip(values.chunks_exact_mut(ns))
    {
        for (s, v) in out.iter_mut().enumerate() {
            let mean = (0..k).map(|r| group[r * ns + s] as f64).sum::<f64>() / k as f64;
            let var = (0..k)
                .map(|r| (group[r * ns + s] as f64 - mean).powi(2))
                .sum::<f64>()
                / k as f64;
            *v = var.sqrt();
        }
    }
    Ok(Effects {
        method: "cai".into(),
        rows,
        n_action: na,
        n_state: ns,
        values,
    })
}

pub(crate) fn check(settings: &InfluenceSettings, rows: usize) -> Result<()> {
    let bad = |m: String| Err(ExplainError::Options(m));
    if settings.observations > rows {
        return bad(format!(
            "the data has {rows} transitions; {} observations need more",
            settings.observations
        ));
    }
    settings.validate()
}

impl InfluenceSettings {
    /// Checks the settings a user gives (κ within the range the explainer node declares in
    /// launch_scripts/graph.toml): the one check of the CLI, the node and the library.
    pub fn validate(&self) -> Result<()> {
        let (low, high) = (explainer::kappa::spec().ok())
            .and_then(|spec| spec.range)
            .unwrap_or((0.0, f64::MAX));
        if !(self.kappa.is_finite() && self.kappa >= low && self.kappa <= high) {
            return Err(ExplainError::Options(format!(
                "kappa must lie in [{low:e}, {high:e}] (parameter kappa of {} in launch_scripts/graph.toml), got {}",
                ExplainerParams::NODE,
                self.kappa
            )));
        }
        if self.observations == 0 || self.resamples < 2 || self.bootstrap == 0 {
            return Err(ExplainError::Options(format!(
                "influence needs at least 1 observation, 2 resamples and 1 bootstrap draw, got {}, {}, {}",
                self.observations, self.resamples, self.bootstrap
            )));
        }
        Ok(())
    }
}

/// Mean absolute error of the forward model on every state feature (angles wrapped), over
/// `rows` of `data`: the floor below which an effect is indistinguishable from error. It is
/// never below the f32 resolution of the feature (2⁻²³ × its mean magnitude): a feature
/// predicted exactly still carries rounding, and a ratio to 0 would mean nothing. A feature
/// that never changes within a transition gets an infinite floor: the data shows no action
/// changing it, whatever a network does with it.
pub fn feature_error(model: &LoadedModel, data: &Dataset, rows: &[usize]) -> Result<Vec<f64>> {
    let predicted = predict_next(model, data, rows)?;
    Ok(error_floor(
        data,
        &predicted,
        rows,
        &crate::change_scale(data),
    ))
}

/// The model's prediction of s(t+1) for the transitions `rows` (raw units).
fn predict_next(model: &LoadedModel, data: &Dataset, rows: &[usize]) -> Result<Vec<f32>> {
    model
        .predict(&forward_inputs(data, rows))
        .map_err(|e| ExplainError::Options(e.to_string()))
}

/// The floor of [`feature_error`] for predictions `predicted` (raw units, one row per entry
/// of `rows`) of the next states of `rows`; `scale` is [`crate::change_scale`] of `data`.
/// Shared with the chained model's h-step floors, whose targets lie h − 1 rows further on.
pub(crate) fn error_floor(
    data: &Dataset,
    predicted: &[f32],
    rows: &[usize],
    scale: &[f64],
) -> Vec<f64> {
    let ns = data.state_width();
    let angular = angular_features(data.experiment);
    let mut error = vec![0.0; ns];
    for (i, &r) in rows.iter().enumerate() {
        for (k, e) in error.iter_mut().enumerate() {
            let d = predicted[i * ns + k] as f64 - data.next_state(r)[k] as f64;
            *e += if angular[k] { wrap_angle(d) } else { d }.abs();
        }
    }
    let n = rows.len().max(1) as f64;
    let magnitude: Vec<f64> = (0..ns)
        .map(|k| {
            rows.iter()
                .map(|&r| (data.next_state(r)[k] as f64).abs())
                .sum::<f64>()
                / n
        })
        .collect();
    (0..ns)
        .map(|k| {
            if scale[k] == 0.0 {
                f64::INFINITY
            } else {
                (error[k] / n).max(magnitude[k] * f32::EPSILON as f64)
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_tail_and_bonferroni_quantiles() {
        assert!((z_critical(0.05, 1) - 1.644_854).abs() < 1e-4);
        // One-sided 0.05 / 184: z = 3.4584 (the exp2 grid of 8 × 23 pairs).
        assert!((z_critical(0.05, 184) - 3.458_36).abs() < 1e-3);
    }

    fn claims(score: f64, lower: f64, drives: bool) -> EdgeClaims {
        EdgeClaims {
            method: "m".into(),
            rule: "r".into(),
            context: "all".into(),
            horizon: 1,
            observations: 10,
            action_names: vec!["a".into()],
            state_names: vec!["s".into()],
            score: vec![vec![score]],
            interval: Some(vec![vec![[lower, lower + 1.0]]]),
            drives: vec![vec![drives]],
            decisions: None,
        }
    }

    #[test]
    fn a_union_claims_what_any_part_claims_and_scores_the_largest_margin() {
        // A threshold part (score 0.005 against 0.01: not claimed) and a lower-bound part
        // (lower bound 3 against κ = 2: claimed).
        let shap = claims(0.005, 0.0, false);
        let cai = claims(5.0, 3.0, true);
        let parts = [
            UnionPart {
                claims: &shap,
                threshold: 0.01,
                lower_bound: false,
            },
            UnionPart {
                claims: &cai,
                threshold: 2.0,
                lower_bound: true,
            },
        ];
        let u = union_claims("m+c", "all", &parts).unwrap();
        assert!(u.drives[0][0]);
        assert!((u.score[0][0] - 1.5).abs() < 1e-12, "{}", u.score[0][0]);
        // The deciding part (CAI, margin 1.5) gives the interval, in margin units.
        assert_eq!(u.interval.as_ref().unwrap()[0][0], [1.5, 2.0]);
        let neither = claims(1.0, 0.5, false);
        let u = union_claims(
            "m+c",
            "all",
            &[UnionPart {
                claims: &neither,
                threshold: 2.0,
                lower_bound: true,
            }],
        )
        .unwrap();
        assert!(!u.drives[0][0] && u.score[0][0] < 1.0);
        assert!(union_claims("m", "all", &[]).is_none());
    }

    /// Exp-2 rows: magnet off with a_mgt ∈ {0, +1}, magnet on with a_mgt ∈ {0, −1}.
    fn magnet_rows() -> Dataset {
        let mut data = Dataset::empty(causal_arm_dataset::Experiment::Exp2, Default::default());
        for (i, (mgt, command)) in [(0.0, 0.0), (0.0, 1.0), (1.0, 0.0), (1.0, -1.0)]
            .into_iter()
            .cycle()
            .take(40)
            .enumerate()
        {
            let mut state = vec![0.1 * i as f32; 23];
            state[22] = mgt;
            data.states.extend(&state);
            data.next_states.extend(&state);
            data.actions.extend([0.01 * i as f32; 7]);
            data.actions.push(command);
            data.episodes.push(0);
            data.holding.push(0);
            data.steps.push(i as u32);
            data.stamps_ns.push(i as u64);
        }
        data
    }

    #[test]
    fn a_discrete_action_is_probed_only_at_values_seen_in_such_states() {
        let data = magnet_rows();
        let draws = ActionDraws::new(&data);
        assert_eq!(draws.discrete[7], Some(vec![-1.0, 0.0, 1.0]));
        assert_eq!(draws.discrete[0], None, "joint deltas are continuous");
        assert_eq!(
            draws.discrete_states,
            vec![22],
            "only mgt is a discrete state feature"
        );
        let mut rng = StdRng::seed_from_u64(0);
        let probe = |mgt: f32, rng: &mut StdRng| -> Vec<f32> {
            let mut state = vec![0.0; 23];
            state[22] = mgt;
            let mut v: Vec<f32> = (0..6)
                .map(|i| draws.draw(&data, 7, i, &state, rng))
                .collect();
            v.sort_by(f32::total_cmp);
            v.dedup();
            v
        };
        assert_eq!(
            probe(0.0, &mut rng),
            vec![0.0, 1.0],
            "magnet off: keep or switch on"
        );
        assert_eq!(
            probe(1.0, &mut rng),
            vec![-1.0, 0.0],
            "magnet on: keep or switch off"
        );
    }

    fn effects(values: Vec<f64>) -> Effects {
        Effects {
            method: "test".into(),
            rows: (0..values.len()).collect(),
            n_action: 1,
            n_state: 1,
            values,
        }
    }

    #[test]
    fn significance_claims_an_effect_only_when_its_mean_clears_the_corrected_bound() {
        let names = |n: &str| vec![n.to_owned()];
        let members: Vec<usize> = (0..400).collect();
        // Noise around 0: no claim. Noise around 1 with spread 1: t = 20, a claim.
        let noise: Vec<f64> = (0..400)
            .map(|i| ((i * 37 % 101) as f64 - 50.0) / 29.0)
            .collect();
        let null = significance_claims(
            &effects(noise.clone()),
            &members,
            &[1.0],
            "all",
            &names("a"),
            &names("s"),
        );
        assert!(!null.drives[0][0], "t = {}", null.score[0][0]);
        let shifted: Vec<f64> = noise.iter().map(|v| v + 1.0).collect();
        let edge = significance_claims(
            &effects(shifted),
            &members,
            &[1.0],
            "all",
            &names("a"),
            &names("s"),
        );
        assert!(edge.drives[0][0] && edge.score[0][0] > 10.0);
        // A feature the data never changes is never claimed.
        let frozen = significance_claims(
            &effects(vec![1.0; 400]),
            &members,
            &[0.0],
            "all",
            &names("a"),
            &names("s"),
        );
        assert!(!frozen.drives[0][0]);
    }
}
