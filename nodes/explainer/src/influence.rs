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
use causal_arm_scoring::EdgeClaims;
use causal_arm_trainer::LoadedModel;
use rand::rngs::StdRng;
use rand::seq::index::sample;
use rand::{Rng, SeedableRng};

use crate::{ExplainError, Explainer, Result, forward_inputs};

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
fn discrete_values(data: &Dataset, j: usize) -> Option<Vec<f32>> {
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
    let mut probe = Probe::draw(data, settings)?;
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
    if settings.observations == 0 || settings.resamples < 2 || settings.bootstrap == 0 {
        return bad(format!(
            "influence needs at least 1 observation, 2 resamples and 1 bootstrap draw, got {}, {}, {}",
            settings.observations, settings.resamples, settings.bootstrap
        ));
    }
    if settings.observations > rows {
        return bad(format!(
            "the data has {rows} transitions; {} observations need more",
            settings.observations
        ));
    }
    if !(settings.kappa.is_finite() && settings.kappa >= 0.0) {
        return bad(format!(
            "kappa must be a non-negative number, got {}",
            settings.kappa
        ));
    }
    Ok(())
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

/// Calibrated claims from per-observation `effects` over the observations `members`
/// (indices into `effects.rows`): score = mean effect / error, interval = 95 % bootstrap
/// interval of that ratio, verdict = lower bound > κ.
#[allow(clippy::too_many_arguments)]
pub fn calibrated_claims(
    effects: &Effects,
    members: &[usize],
    error: &[f64],
    settings: &InfluenceSettings,
    context: &str,
    action_names: &[String],
    state_names: &[String],
) -> EdgeClaims {
    let (na, ns) = (effects.n_action, effects.n_state);
    let n = members.len().max(1);
    let ratio = |mean: f64, k: usize| if mean == 0.0 { 0.0 } else { mean / error[k] };
    let interval = bootstrap_interval(effects, members, settings, ratio);
    let mut score = vec![vec![0.0; ns]; na];
    let mut drives = vec![vec![false; ns]; na];
    for a in 0..na {
        for k in 0..ns {
            if members.is_empty() {
                continue;
            }
            let sum: f64 = members.iter().map(|&o| effects.at(o, a, k)).sum();
            score[a][k] = ratio(sum / n as f64, k);
            drives[a][k] = interval[a][k][0] > settings.kappa;
        }
    }
    EdgeClaims {
        method: format!("{}/err", effects.method),
        rule: format!(
            "drives when the 95 % bootstrap lower bound of mean effect / the model's MAE on the feature exceeds {}",
            settings.kappa
        ),
        context: context.to_owned(),
        horizon: 1,
        observations: members.len(),
        action_names: action_names.to_vec(),
        state_names: state_names.to_vec(),
        score,
        interval: Some(interval),
        drives,
    }
}

/// Seed offset of every bootstrap over observations: the SHAP and CAI intervals of one
/// context resample the same observations.
const BOOTSTRAP_SEED: u64 = 0xB007;

/// 95 % bootstrap interval (percentiles 2.5 and 97.5 over `settings.bootstrap` resamples of
/// the observations `members`) of `ratio(mean effect, state feature)` for every edge,
/// `[action][state]`; `[0, 0]` without observations.
pub(crate) fn bootstrap_interval(
    effects: &Effects,
    members: &[usize],
    settings: &InfluenceSettings,
    ratio: impl Fn(f64, usize) -> f64,
) -> Vec<Vec<[f64; 2]>> {
    let (na, ns) = (effects.n_action, effects.n_state);
    let mut interval = vec![vec![[0.0; 2]; ns]; na];
    let n = members.len();
    if n == 0 || settings.bootstrap == 0 {
        return interval;
    }
    let cell = na * ns;
    let mut rng = StdRng::seed_from_u64(settings.seed ^ BOOTSTRAP_SEED);
    // boot[edge * draws + d]: the ratio of bootstrap draw d.
    let draws = settings.bootstrap;
    let mut boot = vec![0.0; cell * draws];
    let mut sums = vec![0.0; cell];
    for d in 0..draws {
        sums.iter_mut().for_each(|s| *s = 0.0);
        for _ in 0..n {
            let o = members[rng.random_range(0..n)];
            let row = &effects.values[o * cell..(o + 1) * cell];
            sums.iter_mut().zip(row).for_each(|(s, v)| *s += v);
        }
        for (edge, s) in sums.iter().enumerate() {
            boot[edge * draws + d] = ratio(s / n as f64, edge % ns);
        }
    }
    for (edge, values) in boot.chunks_exact_mut(draws).enumerate() {
        values.sort_by(f64::total_cmp);
        let q = |p: f64| values[((p * (draws - 1) as f64).round() as usize).min(draws - 1)];
        interval[edge / ns][edge % ns] = [q(0.025), q(0.975)];
    }
    interval
}

/// The model's error on every state feature in every context of the data's experiment
/// ([`feature_error`] over the context's rows of a seeded pool): the floors of
/// [`Rule::ErrorRatio`], measured once however many effects are judged against them.
pub struct ErrorFloors {
    pub(crate) per_context: Vec<Vec<f64>>,
}

impl ErrorFloors {
    /// Measures the floors of `explainer`'s model on up to `settings.error_rows` rows.
    pub fn measure(
        explainer: &Explainer,
        data: &Dataset,
        settings: &InfluenceSettings,
    ) -> Result<Self> {
        let mut rng = StdRng::seed_from_u64(settings.seed ^ 0xE770);
        let pool = sample(&mut rng, data.rows(), settings.error_rows.min(data.rows())).into_vec();
        let reader = ContextReader::new(data.experiment);
        let scale = crate::change_scale(data);
        let per_context = Context::of(data.experiment)
            .iter()
            .map(|context| {
                let rows: Vec<usize> = pool
                    .iter()
                    .copied()
                    .filter(|&r| reader.holds(data, r, context))
                    .collect();
                let predicted = predict_next(explainer.model(), data, &rows)?;
                Ok(error_floor(data, &predicted, &rows, &scale))
            })
            .collect::<Result<_>>()?;
        Ok(Self { per_context })
    }
}

/// How per-observation effects become verdicts.
#[derive(Clone, Copy)]
pub enum Rule<'a> {
    /// Magnitudes (CAI spread, |SHAP|) against κ × the model's error ([`calibrated_claims`]).
    ErrorRatio(&'a ErrorFloors),
    /// Signed agreement of independent models, tested against 0 ([`significance_claims`]).
    Significance,
}

/// Claims of `effects` by `rule` in every context of the data's experiment (`all` first),
/// each context judged on its own observations (and, for [`Rule::ErrorRatio`], against the
/// model's error on that context's rows).
pub fn claims_by_context(
    explainer: &Explainer,
    data: &Dataset,
    effects: &Effects,
    settings: &InfluenceSettings,
    rule: Rule,
) -> Vec<EdgeClaims> {
    // Only the significance rule needs the change scale, a pass over every transition.
    let scale = matches!(rule, Rule::Significance).then(|| crate::change_scale(data));
    let reader = ContextReader::new(data.experiment);
    let (actions, states) = (explainer.action_names(), explainer.state_names());
    Context::of(data.experiment)
        .iter()
        .enumerate()
        .map(|(c, context)| {
            let members = effects.members(data, &reader, context);
            match rule {
                Rule::ErrorRatio(floors) => calibrated_claims(
                    effects,
                    &members,
                    &floors.per_context[c],
                    settings,
                    context.name,
                    actions,
                    states,
                ),
                Rule::Significance => {
                    let scale = scale.as_deref().unwrap_or_default();
                    significance_claims(effects, &members, scale, context.name, actions, states)
                }
            }
        })
        .collect()
}

/// Today's relevance rule on the observations `members`: score = their mean effect / the
/// std of the feature's one-step change (`scale`), verdict = score ≥ `threshold`; no
/// interval (see [`crate::verdicts`] for one).
pub(crate) fn threshold_claims(
    effects: &Effects,
    members: &[usize],
    scale: &[f64],
    threshold: f64,
    context: &str,
    (actions, states): (&[String], &[String]),
) -> EdgeClaims {
    let n = members.len().max(1) as f64;
    let score: Vec<Vec<f64>> = (0..effects.n_action)
        .map(|a| {
            (0..effects.n_state)
                .map(|k| {
                    let mean = members.iter().map(|&o| effects.at(o, a, k)).sum::<f64>() / n;
                    crate::in_change_units(mean, scale[k])
                })
                .collect()
        })
        .collect();
    EdgeClaims {
        method: effects.method.clone(),
        rule: format!("mean |SHAP| >= {threshold} x std of the one-step change"),
        context: context.to_owned(),
        horizon: 1,
        observations: members.len(),
        action_names: actions.to_vec(),
        state_names: states.to_vec(),
        drives: score
            .iter()
            .map(|row| row.iter().map(|&v| v >= threshold).collect())
            .collect(),
        score,
        interval: None,
    }
}

/// One part of a union of claims, with the rule its verdicts followed: evidence ≥
/// `threshold`, the evidence being the interval's lower bound when `lower_bound`, else the
/// score.
pub struct UnionPart<'a> {
    /// The part's claims.
    pub claims: &'a EdgeClaims,
    /// Its verdict threshold.
    pub threshold: f64,
    /// Whether its verdicts compare the interval's lower bound (else the score).
    pub lower_bound: bool,
}

impl UnionPart<'_> {
    /// Evidence over threshold: ≥ 1 exactly where the part claims the edge.
    fn margin(&self, a: usize, k: usize) -> f64 {
        let evidence = match (&self.claims.interval, self.lower_bound) {
            (Some(interval), true) => interval[a][k][0],
            _ => self.claims.score[a][k],
        };
        evidence / self.threshold
    }

    /// The part's 95 % interval of edge (a, k) in the units of its margin (interval /
    /// threshold), if its claims carry intervals.
    fn margin_interval(&self, a: usize, k: usize) -> Option<[f64; 2]> {
        let [lo, hi] = self.claims.interval.as_ref()?[a][k];
        Some([lo / self.threshold, hi / self.threshold])
    }
}

/// Per edge, the margin interval of the part with the largest margin (the part that decides
/// the union's score); `None` unless every deciding part carries an interval.
fn union_interval(parts: &[UnionPart], na: usize, ns: usize) -> Option<Vec<Vec<[f64; 2]>>> {
    (0..na)
        .map(|a| {
            (0..ns)
                .map(|k| {
                    let best = parts.iter().reduce(|p, q| {
                        if q.margin(a, k) > p.margin(a, k) {
                            q
                        } else {
                            p
                        }
                    })?;
                    best.margin_interval(a, k)
                })
                .collect()
        })
        .collect()
}

/// Claims an edge wherever some part does; the score is the largest margin (evidence /
/// threshold), so `score ≥ 1` is the verdict, and the interval that part's interval in the
/// same units (for a lower-bound part the score is the interval's lower end). Attributions of the actions as taken (SHAP)
/// miss effects an action has only at values it rarely takes (the magnet's switch-off
/// drops a held cube, yet a_mgt is almost always "keep"); influence under probing (CAI)
/// sees those but misses small contributions its error floor hides: the union keeps both
/// kinds of evidence, each at its own calibrated floor.
pub fn union_claims(method: &str, context: &str, parts: &[UnionPart]) -> Option<EdgeClaims> {
    let first = parts.first()?.claims;
    let (na, ns) = (first.action_names.len(), first.state_names.len());
    let score: Vec<Vec<f64>> = (0..na)
        .map(|a| {
            (0..ns)
                .map(|k| {
                    parts
                        .iter()
                        .map(|p| p.margin(a, k))
                        .fold(f64::NEG_INFINITY, f64::max)
                })
                .collect()
        })
        .collect();
    Some(EdgeClaims {
        method: method.to_owned(),
        rule: format!(
            "drives where any of these does: {}",
            parts
                .iter()
                .map(|p| format!(
                    "{} ({}: {})",
                    p.claims.method, p.claims.context, p.claims.rule
                ))
                .collect::<Vec<_>>()
                .join("; ")
        ),
        context: context.to_owned(),
        horizon: first.horizon,
        observations: parts
            .iter()
            .map(|p| p.claims.observations)
            .max()
            .unwrap_or(0),
        action_names: first.action_names.clone(),
        state_names: first.state_names.clone(),
        drives: (0..na)
            .map(|a| {
                (0..ns)
                    .map(|k| parts.iter().any(|p| p.claims.drives[a][k]))
                    .collect()
            })
            .collect(),
        score,
        interval: union_interval(parts, na, ns),
    })
}

/// Two-sided normal quantile for the Bonferroni-corrected level `alpha / tests` (one-sided
/// upper tail), by bisection on the complementary error function.
fn z_critical(alpha: f64, tests: usize) -> f64 {
    let tail = alpha / tests.max(1) as f64;
    let upper_tail = |z: f64| 0.5 * libm::erfc(z / std::f64::consts::SQRT_2);
    let (mut lo, mut hi) = (0.0, 40.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if upper_tail(mid) > tail {
            lo = mid
        } else {
            hi = mid
        }
    }
    0.5 * (lo + hi)
}

/// Reproducible influence across independently trained forward models (seeds or folds):
/// per observation and action, K pairs of values (v, v′) of a_j drawn from its marginal;
/// each model's signed change d = f(a_j = v) − f(a_j = v′) of every output; the effect is
/// the product of two models' changes, averaged over the pairs (and over model pairs). Its
/// mean over observations estimates Var of the true effect plus the covariance of the
/// models' errors — which is 0 where the models' errors are independent, so an effect no
/// model reproduces averages out however large each model's own error is.
pub fn agreement_effects(
    explainers: &[&Explainer],
    data: &Dataset,
    settings: &InfluenceSettings,
) -> Result<Effects> {
    if explainers.len() < 2 {
        return Err(ExplainError::Options(format!(
            "agreement needs at least 2 independently trained models, got {}",
            explainers.len()
        )));
    }
    let mut probe = Probe::draw(data, settings)?;
    let k = settings.resamples;
    let draws = ActionDraws::new(data);
    // Pairs (v, v′) of distinct values for a discrete action: all ordered pairs in turn.
    let batch = probe.batch(data, &draws, 2 * k, |j, i| {
        if draws.discrete[j].is_some() {
            i + i / 2
        } else {
            i
        }
    });
    let Probe {
        rows,
        ns,
        na,
        width,
        ..
    } = probe;
    let mut changes = Vec::new();
    for e in explainers {
        let predicted = network_outputs(e, &batch, width)?;
        // d per pair: row 2p minus row 2p+1.
        let d: Vec<f64> = predicted
            .chunks_exact(2 * ns)
            .flat_map(|pair| (0..ns).map(move |s| pair[s] as f64 - pair[ns + s] as f64))
            .collect();
        changes.push(d);
    }
    let model_pairs: Vec<(usize, usize)> = (0..changes.len())
        .flat_map(|a| (a + 1..changes.len()).map(move |b| (a, b)))
        .collect();
    let mut values = vec![0.0; rows.len() * na * ns];
    for (cell, v) in values.chunks_exact_mut(ns).enumerate() {
        for (s, out) in v.iter_mut().enumerate() {
            let mut sum = 0.0;
            for &(a, b) in &model_pairs {
                for p in 0..k {
                    let i = (cell * k + p) * ns + s;
                    sum += changes[a][i] * changes[b][i];
                }
            }
            *out = sum / (k * model_pairs.len()) as f64;
        }
    }
    Ok(Effects {
        method: "agreement".into(),
        rows,
        n_action: na,
        n_state: ns,
        values,
    })
}

/// Verdicts from signed per-observation effects (see [`agreement_effects`]): score = the
/// t statistic of their mean over the observations `members`, interval = mean ± the
/// Bonferroni-corrected critical value × standard error, verdict = the interval's lower
/// bound above 0 (family-wise error 5 % over every pair). Features the data never changes
/// within a transition (`scale` 0) are never claimed.
pub fn significance_claims(
    effects: &Effects,
    members: &[usize],
    scale: &[f64],
    context: &str,
    action_names: &[String],
    state_names: &[String],
) -> EdgeClaims {
    let (na, ns) = (effects.n_action, effects.n_state);
    let z = z_critical(0.05, na * ns);
    let n = members.len();
    let mut score = vec![vec![0.0; ns]; na];
    let mut interval = vec![vec![[0.0; 2]; ns]; na];
    let mut drives = vec![vec![false; ns]; na];
    for a in 0..na {
        for k in 0..ns {
            if n < 2 || scale[k] == 0.0 {
                continue;
            }
            let values = members.iter().map(|&o| effects.at(o, a, k));
            let mean = values.clone().sum::<f64>() / n as f64;
            let var = values.map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
            let se = (var / n as f64).sqrt();
            score[a][k] = if se > 0.0 { mean / se } else { 0.0 };
            interval[a][k] = [mean - z * se, mean + z * se];
            drives[a][k] = se > 0.0 && mean - z * se > 0.0;
        }
    }
    EdgeClaims {
        method: format!("{}/t", effects.method),
        rule: format!(
            "drives when the mean signed effect (a product of changes) is above 0 at family-wise 5 % (z > {z:.2}, Bonferroni over {} pairs)",
            na * ns
        ),
        context: context.to_owned(),
        horizon: 1,
        observations: n,
        action_names: action_names.to_vec(),
        state_names: state_names.to_vec(),
        score,
        interval: Some(interval),
        drives,
    }
}

/// Rows whose a_j stands in for draws of a_j given (s(t), a_−j(t)): the nearest rows in
/// standardised Euclidean distance over the state and the other actions, among a seeded pool.
/// Marginal draws put an action where it never occurs (switching on a magnet that is on,
/// or moving while the babbler releases the cube at rest), where a network's output is
/// arbitrary and, worse, correlated with the other inputs; conditional draws keep the test
/// of [`holdout_effects`] unbiased.
struct NeighbourDonors {
    pool: Vec<usize>,
    state_weight: Vec<f64>,
    action_weight: Vec<f64>,
}

/// Rows the neighbours are searched among.
const DONOR_POOL: usize = 20_000;

/// 1 / standard deviation of each column over `pool` (0 for a constant column).
fn inverse_std(pool: &[usize], width: usize, value: impl Fn(usize, usize) -> f64) -> Vec<f64> {
    let n = pool.len().max(1) as f64;
    (0..width)
        .map(|k| {
            let mean = pool.iter().map(|&r| value(r, k)).sum::<f64>() / n;
            let var = pool
                .iter()
                .map(|&r| (value(r, k) - mean).powi(2))
                .sum::<f64>()
                / n;
            if var > 0.0 { 1.0 / var.sqrt() } else { 0.0 }
        })
        .collect()
}

impl NeighbourDonors {
    fn new(data: &Dataset, seed: u64) -> Self {
        let mut rng = StdRng::seed_from_u64(seed ^ 0xD0_0A);
        let pool = sample(&mut rng, data.rows(), DONOR_POOL.min(data.rows())).into_vec();
        Self {
            state_weight: inverse_std(&pool, data.state_width(), |r, k| data.state(r)[k] as f64),
            action_weight: inverse_std(&pool, data.action_width(), |r, k| data.action(r)[k] as f64),
            pool,
        }
    }

    /// For every action j, the `k` pool rows nearest to row `row` in (s, a_−j), itself
    /// excluded.
    fn nearest(&self, data: &Dataset, row: usize, k: usize) -> Vec<Vec<usize>> {
        let (x, a) = (data.state(row), data.action(row));
        let na = a.len();
        let weighted = |u: &[f32], v: &[f32], w: &[f64], out: &mut [f64]| {
            for (((o, &p), &q), &w) in out.iter_mut().zip(u).zip(v).zip(w) {
                *o = ((p - q) as f64 * w).powi(2);
            }
        };
        // Per pool row: the state distance, then each action's term.
        let mut state = vec![0.0; self.pool.len()];
        let mut actions = vec![0.0; self.pool.len() * na];
        let mut scratch = vec![0.0; x.len()];
        for (i, &r) in self.pool.iter().enumerate() {
            weighted(data.state(r), x, &self.state_weight, &mut scratch);
            state[i] = if r == row {
                f64::INFINITY
            } else {
                scratch.iter().sum()
            };
            weighted(
                data.action(r),
                a,
                &self.action_weight,
                &mut actions[i * na..(i + 1) * na],
            );
        }
        let total: Vec<f64> = (0..self.pool.len())
            .map(|i| state[i] + actions[i * na..(i + 1) * na].iter().sum::<f64>())
            .collect();
        let k = k.min(self.pool.len().saturating_sub(1)).max(1);
        (0..na)
            .map(|j| {
                let mut scored: Vec<(f64, usize)> = (0..self.pool.len())
                    .map(|i| (total[i] - actions[i * na + j], i))
                    .collect();
                scored.select_nth_unstable_by(k - 1, |p, q| p.0.total_cmp(&q.0));
                scored[..k].iter().map(|&(_, i)| self.pool[i]).collect()
            })
            .collect()
    }
}

/// Holdout test of each edge on one model (in the way of the holdout randomization test,
/// Tansey et al. 2018): per observation, g = f_k(s, a) − f_k^(−j), the part of the
/// prediction a_j explains (f^(−j) averages the prediction over the a_j of the `resamples`
/// nearest rows in (s, a_−j), draws of a_j given the rest), times the part of the observed change the model without a_j leaves
/// unexplained, y_k − f_k^(−j). Where s_k(t+1) does not depend on a_j, that residual
/// carries nothing a_j could explain and the product averages to 0, whatever the network
/// leaks from a_j into output k; where it does, the product estimates the variance of the
/// effect the model captured. Meaningful on rows the model was not trained on.
pub fn holdout_effects(
    explainer: &Explainer,
    data: &Dataset,
    settings: &InfluenceSettings,
) -> Result<Effects> {
    let Probe {
        rng: _,
        rows,
        base,
        ns,
        na,
        width,
    } = Probe::draw(data, settings)?;
    let k = settings.resamples;
    let donors = NeighbourDonors::new(data, settings.seed);
    let mut batch = Vec::with_capacity(rows.len() * (1 + na * k) * width);
    for (obs, &r) in rows.iter().enumerate() {
        let x = &base[obs * width..(obs + 1) * width];
        batch.extend_from_slice(x);
        let near = donors.nearest(data, r, k);
        for (j, donors) in near.iter().enumerate() {
            for &d in donors {
                let mut row = x.to_vec();
                row[ns + j] = data.action(d)[j];
                batch.extend_from_slice(&row);
            }
        }
    }
    let predicted = network_outputs(explainer, &batch, width)?;
    let angular = angular_features(data.experiment);
    let per_obs = (1 + na * k) * ns;
    let mut values = vec![0.0; rows.len() * na * ns];
    for (obs, &r) in rows.iter().enumerate() {
        let p = &predicted[obs * per_obs..(obs + 1) * per_obs];
        for s in 0..ns {
            let d = data.next_state(r)[s] as f64 - data.state(r)[s] as f64;
            let observed = if angular[s] { wrap_angle(d) } else { d };
            let full = p[s] as f64;
            for j in 0..na {
                let start = (1 + j * k) * ns;
                let without = (0..k).map(|i| p[start + i * ns + s] as f64).sum::<f64>() / k as f64;
                values[(obs * na + j) * ns + s] = (full - without) * (observed - without);
            }
        }
    }
    Ok(Effects {
        method: "holdout".into(),
        rows,
        n_action: na,
        n_state: ns,
        values,
    })
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
