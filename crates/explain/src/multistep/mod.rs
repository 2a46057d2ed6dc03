//! Multi-step causal influence: CAI through the chained forward model.
//!
//! One-step CAI ([`crate::influence`]) asks which s_k(t+1) an action a_j(t) moves. Some of
//! the paper's findings are effects further on: turning the magnet on is *followed* by
//! lifting the cube, once the arm moves away. Here the forward model is chained as in the
//! mental simulation: from an observed state, a_j(t) is drawn as one-step CAI draws it, the
//! model predicts s(t+1), is fed its own prediction with the *recorded* action a(t+1), and
//! so on up to s(t+K). The effect of a_j(t) on s_k(t+h) is the spread of the predicted
//! s_k(t+h) over the draws. It is judged by the same error-ratio rule as one-step CAI,
//! against the chained model's own h-step error: an effect smaller than what the chained
//! model gets wrong after h steps cannot be told from its mistakes. Verdicts come from the
//! data and the model alone; the simulator's truth at horizon h only scores them.
//!
//! Chains never cross an episode: an observation needs K consecutive transitions of one
//! episode starting at its row, each continuing the one before.

use causal_arm_dataset::{Context, ContextReader, Dataset, angular_features, wrap_angle};
use causal_arm_scoring::EdgeClaims;
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand::seq::index::sample;
use serde::Serialize;

use crate::decide::{ModelEvidence, default_claims, discrete_actions, model_only_claims};
use crate::influence::{
    ActionDraws, Effects, ErrorFloors, InfluenceSettings, Probe, Rule, check, claims_by_context,
    error_floor, error_pool, mean_change_error, switch_evidence,
};
use crate::{ExplainError, Explainer, Result, forward_inputs};

mod figures;
pub use figures::{MAGNET_PAIR, draw_figures};

/// Largest horizon K: the simulator's truths are written up to s(t+10), and a tanh network
/// chained further drifts far from the data it was trained on.
pub const MAX_HORIZON: usize = 10;

/// Refuses a horizon outside 1..=[`MAX_HORIZON`].
pub fn check_horizon(horizon: usize) -> Result<()> {
    if (1..=MAX_HORIZON).contains(&horizon) {
        return Ok(());
    }
    Err(ExplainError::Options(format!(
        "the horizon must be 1 to {MAX_HORIZON} steps of the chained forward model, got {horizon}"
    )))
}

/// Chains the model `horizon` steps: step 1 from the input rows `first` (`[state ++
/// action]`), step h ≥ 2 from the model's prediction with the recorded action a(t+h−1) of
/// the data, where input row i starts at data row `origin(i)`. `visit(h, predicted)` sees
/// the predicted s(t+h) of every row (raw units, offset added, angles wrapped, as the
/// mental simulation feeds them back).
fn roll(
    explainer: &Explainer,
    data: &Dataset,
    first: Vec<f32>,
    origin: impl Fn(usize) -> usize,
    horizon: usize,
    mut visit: impl FnMut(usize, &[f32]) -> Result<()>,
) -> Result<()> {
    let (ns, na) = (data.state_width(), data.action_width());
    let predict = |inputs: &[f32]| {
        explainer
            .model()
            .predict(inputs)
            .map_err(|e| ExplainError::Options(e.to_string()))
    };
    let mut states = predict(&first)?;
    drop(first);
    visit(1, &states)?;
    for h in 2..=horizon {
        let mut inputs = Vec::with_capacity(states.len() / ns * (ns + na));
        for (i, state) in states.chunks_exact(ns).enumerate() {
            inputs.extend_from_slice(state);
            inputs.extend_from_slice(data.action(origin(i) + h - 1));
        }
        states = predict(&inputs)?;
        visit(h, &states)?;
    }
    Ok(())
}

/// Standard deviation of each feature over each group of `draws` consecutive rows of
/// `predicted` (`ns` wide), angles as wrapped differences from the group's first row (a
/// cube turning through ±π is a small spread, not 2π).
fn spreads(predicted: &[f32], draws: usize, ns: usize, angular: &[bool]) -> Vec<f64> {
    let mut out = Vec::with_capacity(predicted.len() / draws);
    let mut d = vec![0.0; draws];
    for group in predicted.chunks_exact(draws * ns) {
        for s in 0..ns {
            let first = group[s] as f64;
            for (i, v) in d.iter_mut().enumerate() {
                let x = group[i * ns + s] as f64 - first;
                *v = if angular[s] { wrap_angle(x) } else { x };
            }
            let mean = d.iter().sum::<f64>() / draws as f64;
            let var = d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / draws as f64;
            out.push(var.sqrt());
        }
    }
    out
}

/// Observation rows for chains of `horizon` steps: `settings.observations` rows drawn
/// (seeded) from those with that many transitions ahead in their episode.
fn observation_rows(
    data: &Dataset,
    settings: &InfluenceSettings,
    horizon: usize,
) -> Result<(Vec<usize>, StdRng)> {
    let candidates = data.chainable_rows(horizon);
    if candidates.len() < settings.observations {
        return Err(ExplainError::Options(format!(
            "only {} of the data's {} transitions start {horizon} consecutive transitions inside an episode; {} observations need more (lower --samples or --horizon, or give a longer bag)",
            candidates.len(),
            data.rows(),
            settings.observations
        )));
    }
    check(settings, candidates.len())?;
    let mut rng = StdRng::seed_from_u64(settings.seed);
    let rows = sample(&mut rng, candidates.len(), settings.observations)
        .into_iter()
        .map(|i| candidates[i])
        .collect();
    Ok((rows, rng))
}

/// CAI through the chained model: for every horizon h = 1..=`horizon`, the effects
/// `[obs][action][state]` of a_j(t) on s_k(t+h) (the spread of the predicted s_k(t+h) over
/// `settings.resamples` draws of a_j(t), drawn as one-step CAI draws them; the recorded
/// actions follow). The observations are the same at every horizon.
pub fn chained_cai_effects(
    explainer: &Explainer,
    data: &Dataset,
    settings: &InfluenceSettings,
    horizon: usize,
) -> Result<Vec<Effects>> {
    check_horizon(horizon)?;
    let (rows, rng) = observation_rows(data, settings, horizon)?;
    let mut probe = Probe::at_rows(data, rows, rng);
    let k = settings.resamples;
    let batch = probe.batch(data, &ActionDraws::new(data), k, |_, i| i);
    let (rows, ns, na) = (probe.rows, probe.ns, probe.na);
    let angular = angular_features(data.experiment);
    let mut effects = Vec::with_capacity(horizon);
    roll(
        explainer,
        data,
        batch,
        |i| rows[i / (na * k)],
        horizon,
        |_, predicted| {
            effects.push(Effects {
                method: "cai".into(),
                rows: rows.clone(),
                n_action: na,
                n_state: ns,
                values: spreads(predicted, k, ns, &angular),
            });
            Ok(())
        },
    )?;
    Ok(effects)
}

/// The chained model's own error after h steps, for every h = 1..=`horizon` and every
/// context of the data's experiment ([`feature_error`](crate::influence::feature_error)'s
/// floor of the prediction of s(t+h) from s(t) and the recorded actions, as the mental
/// simulation measures it), over up to `settings.error_rows` chainable rows; contexts are
/// judged on s(t).
pub fn chained_error_floors(
    explainer: &Explainer,
    data: &Dataset,
    settings: &InfluenceSettings,
    horizon: usize,
) -> Result<Vec<ErrorFloors>> {
    check_horizon(horizon)?;
    let pool = error_pool(data, settings, horizon);
    let reader = ContextReader::new(data.experiment);
    let members: Vec<Vec<usize>> = Context::of(data.experiment)
        .iter()
        .map(|c| {
            (0..pool.len())
                .filter(|&i| reader.holds(data, pool[i], c))
                .collect()
        })
        .collect();
    let scale = crate::change_scale(data);
    let ns = data.state_width();
    let mut floors = Vec::with_capacity(horizon);
    roll(
        explainer,
        data,
        forward_inputs(data, &pool),
        |i| pool[i],
        horizon,
        |h, predicted| {
            let per_context = members
                .iter()
                .map(|m| {
                    let rows: Vec<f32> = m
                        .iter()
                        .flat_map(|&i| predicted[i * ns..(i + 1) * ns].iter().copied())
                        .collect();
                    let targets: Vec<usize> = m.iter().map(|&i| pool[i] + h - 1).collect();
                    error_floor(data, &rows, &targets, &scale)
                })
                .collect();
            floors.push(ErrorFloors { per_context });
            Ok(())
        },
    )?;
    Ok(floors)
}

/// What the chained model says at one horizon.
#[derive(Debug, Clone, Serialize)]
pub struct HorizonResult {
    /// h of s(t+h).
    pub horizon: usize,
    /// Mean effect (spread of the predicted s_k(t+h), raw units) per context,
    /// `[context][action][state]`, contexts in the order of [`MultiStep::contexts`].
    pub mean_effect: Vec<Vec<Vec<f64>>>,
    /// The chained model's h-step error per context, `[context][state]` (the floor the
    /// verdicts compare with; `null` for a feature the data never changes).
    pub error_floor: Vec<Vec<f64>>,
    /// The verdicts at this horizon ([`DEFAULT_METHOD`], context `all`, three-valued): at
    /// h = 1 the one-step default (the data's test first, the model's CAI where it is
    /// undecided); beyond, CAI through the chained model ([`model_only_claims`]).
    pub default: EdgeClaims,
    /// The data's own test of a(t) on s(t+h) − s(t) (`data`, context `all`, three-valued),
    /// beside the model's verdicts. Not a verdict of the product: motor babbling draws a(t)
    /// at random, but the state has no joint velocities, so h steps on a(t) also stands for
    /// the motion it shares with what follows (docs/RESULTS.md, "Multi-step edges").
    pub data: EdgeClaims,
    /// CAI verdicts per context (`all` first): score = mean effect / h-step error, interval
    /// its 95 % bootstrap interval, drives = lower bound > κ.
    pub claims: Vec<EdgeClaims>,
}

/// CAI through the chained forward model at every horizon 1..=K (`multistep.json`).
#[derive(Debug, Clone, Serialize)]
pub struct MultiStep {
    /// K, the largest horizon.
    pub horizon: usize,
    /// How effects were measured and judged.
    pub settings: InfluenceSettings,
    /// Observations (the same at every horizon).
    pub observations: usize,
    /// Rows of the data from which K steps can be chained inside an episode.
    pub chainable_rows: usize,
    /// Context names, `all` first.
    pub contexts: Vec<String>,
    /// Action names (rows of every matrix).
    pub action_names: Vec<String>,
    /// State feature names (columns).
    pub state_names: Vec<String>,
    /// Wall time of effects and floors, s.
    pub seconds: f64,
    /// One entry per horizon, h = 1 first.
    pub horizons: Vec<HorizonResult>,
}

/// Mean of `effects` over each context's observations, `[context][action][state]`.
fn context_means(data: &Dataset, effects: &Effects) -> Vec<Vec<Vec<f64>>> {
    let reader = ContextReader::new(data.experiment);
    let (na, ns) = (effects.n_action, effects.n_state);
    Context::of(data.experiment)
        .iter()
        .map(|c| {
            let members: Vec<usize> = (0..effects.rows.len())
                .filter(|&o| reader.holds(data, effects.rows[o], c))
                .collect();
            let n = members.len().max(1) as f64;
            (0..na)
                .map(|a| {
                    (0..ns)
                        .map(|k| {
                            members
                                .iter()
                                .map(|&o| effects.values[(o * na + a) * ns + k])
                                .sum::<f64>()
                                / n
                        })
                        .collect()
                })
                .collect()
        })
        .collect()
}

/// Name of the multi-step verdicts.
pub const DEFAULT_METHOD: &str = "cai+data";

/// CAI through the chained forward model for horizons 1..=`horizon`: effects, the chained
/// model's h-step error floors, the error-ratio verdicts per horizon and context, the
/// three-valued verdicts per horizon, and the data's own h-step test beside them.
pub fn multistep_cai(
    explainer: &Explainer,
    data: &Dataset,
    settings: &InfluenceSettings,
    horizon: usize,
) -> Result<MultiStep> {
    let started = std::time::Instant::now();
    let effects = chained_cai_effects(explainer, data, settings, horizon)?;
    let floors = chained_error_floors(explainer, data, settings, horizon)?;
    let pool = error_pool(data, settings, horizon);
    let mut horizons = Vec::with_capacity(horizon);
    for (i, (effects, floors)) in effects.iter().zip(&floors).enumerate() {
        let h = i + 1;
        let mut claims =
            claims_by_context(explainer, data, effects, settings, Rule::ErrorRatio(floors));
        for c in &mut claims {
            c.horizon = h;
            c.rule = format!(
                "{}, chained {h} step{} (recorded actions after a_j(t))",
                c.rule,
                if h == 1 { "" } else { "s" }
            );
        }
        let data_test = crate::verdicts::data_test(data, h)?;
        let default = if h == 1 {
            let switches = switch_evidence(explainer, data, settings, &data_test)?;
            let evidence = ModelEvidence {
                parts: vec![&claims[0]],
                error: floors.per_context[0].clone(),
                mean_change_error: mean_change_error(data, &pool),
                discrete: discrete_actions(data),
                switches: Some(&switches),
            };
            default_claims(DEFAULT_METHOD, &data_test, &evidence, settings.kappa)
        } else {
            model_only_claims(DEFAULT_METHOD, &claims[0], &data_test)
        };
        horizons.push(HorizonResult {
            horizon: h,
            mean_effect: context_means(data, effects),
            error_floor: floors.per_context.clone(),
            default,
            data: data_test.claims("data"),
            claims,
        });
    }
    Ok(MultiStep {
        horizon,
        settings: settings.clone(),
        observations: effects.first().map_or(0, |e| e.rows.len()),
        chainable_rows: data.chainable_rows(horizon).len(),
        contexts: Context::of(data.experiment)
            .iter()
            .map(|c| c.name.to_owned())
            .collect(),
        action_names: explainer.action_names().to_vec(),
        state_names: explainer.state_names().to_vec(),
        seconds: started.elapsed().as_secs_f64(),
        horizons,
    })
}

/// One pair's figures at one horizon, in one context.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairPoint {
    /// h of s(t+h).
    pub horizon: usize,
    /// Mean spread of the predicted feature, raw units.
    pub effect: f64,
    /// The chained model's h-step error on the feature.
    pub floor: f64,
    /// Mean effect / floor.
    pub score: f64,
    /// 95 % bootstrap interval of the score.
    pub interval: [f64; 2],
    /// The verdict.
    pub drives: bool,
}

impl MultiStep {
    /// Every claim set, horizon by horizon: the default, CAI's (`all` first), the data
    /// test's.
    pub fn claims(&self) -> impl Iterator<Item = &EdgeClaims> {
        self.horizons.iter().flat_map(|h| {
            std::iter::once(&h.default)
                .chain(&h.claims)
                .chain(std::iter::once(&h.data))
        })
    }

    /// The curve of `action → state` over the horizons in `context`; `None` for unknown
    /// names.
    pub fn pair(&self, context: &str, action: &str, state: &str) -> Option<Vec<PairPoint>> {
        let c = self.contexts.iter().position(|n| n == context)?;
        let a = self.action_names.iter().position(|n| n == action)?;
        let s = self.state_names.iter().position(|n| n == state)?;
        Some(
            self.horizons
                .iter()
                .map(|h| {
                    let claims = &h.claims[c];
                    PairPoint {
                        horizon: h.horizon,
                        effect: h.mean_effect[c][a][s],
                        floor: h.error_floor[c][s],
                        score: claims.score[a][s],
                        interval: claims.interval.as_ref().map_or([0.0; 2], |i| i[a][s]),
                        drives: claims.drives[a][s],
                    }
                })
                .collect(),
        )
    }

    /// The `n` pairs (action, state indices) with the largest score at any horizon over all
    /// states, strongest first.
    pub fn strongest_pairs(&self, n: usize) -> Vec<(usize, usize)> {
        let (na, ns) = (self.action_names.len(), self.state_names.len());
        let best = |a: usize, s: usize| {
            self.horizons
                .iter()
                .map(|h| h.claims[0].score[a][s])
                .filter(|v| v.is_finite())
                .fold(0.0, f64::max)
        };
        let mut pairs: Vec<(f64, usize, usize)> = (0..na)
            .flat_map(|a| (0..ns).map(move |s| (a, s)))
            .map(|(a, s)| (best(a, s), a, s))
            .collect();
        pairs.sort_by(|p, q| q.0.total_cmp(&p.0));
        pairs.into_iter().take(n).map(|(_, a, s)| (a, s)).collect()
    }

    /// A line showing `action → state` over all states at a few horizons (1, 5, 10 and K,
    /// those up to K), e.g. `a_mgt → o_z (all states): h=1 1.2e-3 / error 4.0e-4 = 3.0
    /// (claimed), …`; `None` for unknown names.
    pub fn pair_line(&self, action: &str, state: &str) -> Option<String> {
        let curve = self.pair(Context::ALL, action, state)?;
        let mut shown: Vec<usize> = [1, 5, 10]
            .into_iter()
            .filter(|&h| h <= self.horizon)
            .collect();
        if !shown.contains(&self.horizon) {
            shown.push(self.horizon);
        }
        let parts: Vec<String> = shown
            .iter()
            .map(|&h| {
                let p = &curve[h - 1];
                format!(
                    "h={h} spread {:.2e} / error {:.2e} = {:.2} ({})",
                    p.effect,
                    p.floor,
                    p.score,
                    if p.drives { "claimed" } else { "not claimed" }
                )
            })
            .collect();
        Some(format!(
            "{action} → {state} (all states): {}",
            parts.join(", ")
        ))
    }
}

#[cfg(test)]
mod tests;
