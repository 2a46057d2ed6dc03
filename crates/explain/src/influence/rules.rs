//! Decision rules that turn per-observation effects into verdicts: the error-ratio rule
//! with bootstrap intervals, per context and as a union of parts, and the normal quantiles
//! the significance tests share.

use super::*;

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
        decisions: None,
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
        let pool = error_pool(data, settings, 1);
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

/// The seeded rows a model's error is measured on (at most `settings.error_rows`), among
/// those that start `horizon` consecutive transitions (1: every row), so a chained model's
/// h-step error and the mean change it is compared with share them.
pub fn error_pool(data: &Dataset, settings: &InfluenceSettings, horizon: usize) -> Vec<usize> {
    let candidates = data.chainable_rows(horizon);
    let mut rng = StdRng::seed_from_u64(settings.seed ^ 0xE770);
    sample(
        &mut rng,
        candidates.len(),
        settings.error_rows.min(candidates.len()),
    )
    .into_iter()
    .map(|i| candidates[i])
    .collect()
}

/// Per feature, the mean absolute error of predicting each transition's change by the
/// mean change over `rows` (Euler angles wrapped): what a model that learned nothing about
/// the state and action achieves, the yardstick of [`crate::decide::MAX_ERROR_RATIO`].
pub fn mean_change_error(data: &Dataset, rows: &[usize]) -> Vec<f64> {
    let changes: Vec<Vec<f64>> = rows.iter().map(|&r| data.change(r)).collect();
    let n = rows.len().max(1) as f64;
    (0..data.state_width())
        .map(|k| {
            let mean = changes.iter().map(|c| c[k]).sum::<f64>() / n;
            changes.iter().map(|c| (c[k] - mean).abs()).sum::<f64>() / n
        })
        .collect()
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
        decisions: None,
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
pub(super) fn union_interval(
    parts: &[UnionPart],
    na: usize,
    ns: usize,
) -> Option<Vec<Vec<[f64; 2]>>> {
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
        decisions: None,
    })
}

/// Two-sided normal quantile for the Bonferroni-corrected level `alpha / tests` (one-sided
/// upper tail), by bisection on the complementary error function.
pub(super) fn z_critical(alpha: f64, tests: usize) -> f64 {
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
