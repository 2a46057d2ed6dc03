//! Significance of signed effects: agreement across independently trained forward models,
//! a holdout test with a_j drawn given the rest of the state (neighbour donors), and the
//! Bonferroni-corrected verdicts on them.

use super::*;

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
        decisions: None,
    }
}

/// Rows whose a_j stands in for draws of a_j given (s(t), a_−j(t)): the nearest rows in
/// standardised Euclidean distance over the state and the other actions, among a seeded pool.
/// Marginal draws put an action where it never occurs (switching on a magnet that is on,
/// or moving while the babbler releases the cube at rest), where a network's output is
/// arbitrary and, worse, correlated with the other inputs; conditional draws keep the test
/// of [`holdout_effects`] unbiased.
pub(super) struct NeighbourDonors {
    pool: Vec<usize>,
    state_weight: Vec<f64>,
    action_weight: Vec<f64>,
}

/// Rows the neighbours are searched among.
const DONOR_POOL: usize = 20_000;

/// 1 / standard deviation of each column over `pool` (0 for a constant column).
pub(super) fn inverse_std(
    pool: &[usize],
    width: usize,
    value: impl Fn(usize, usize) -> f64,
) -> Vec<f64> {
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
