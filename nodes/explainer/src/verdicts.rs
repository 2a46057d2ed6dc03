//! The default causal claims of a SHAP run, assembled in one place so that `causal-arm
//! explain` and the explainer node decide alike: SHAP by today's threshold rule (in any
//! context) united with CAI influence judged against the model's error floor, named
//! `<method>+cai`. Every claim set carries a 95 % bootstrap interval per edge, so a report
//! can say how sure each verdict is, not only what it is.

use causal_arm_dataset::{Context, ContextReader, Dataset};
use causal_arm_scoring::EdgeClaims;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use crate::influence::{
    Effects, ErrorFloors, InfluenceSettings, Rule, UnionPart, cai_effects, claims_by_context,
    threshold_claims, threshold_claims_by_context, union_claims,
};
use crate::{ExplainError, Explainer, Explanation, Result};

/// Seed offset of the bootstrap draws: the one [`crate::influence::calibrated_claims`] uses,
/// so SHAP and CAI intervals of one context resample the same observations.
const BOOTSTRAP_SEED: u64 = 0xB007;

/// Name of the default claims of a SHAP run by `method` (`kernel+cai`, `deep+cai`).
pub fn default_method(method: crate::Method) -> String {
    format!("{method}+cai")
}

/// The claim sets of a SHAP run, the default first: SHAP by today's rule (every context)
/// united with CAI by its error floor, per context (`<method>+cai`; in context `all`, SHAP of
/// any context counts); then SHAP by today's rule, SHAP against the model's error, and CAI
/// alone. `explanation` must have been made on `data` (its observations are rows of it).
pub fn shap_and_cai_claims(
    explainer: &Explainer,
    data: &Dataset,
    explanation: &Explanation,
    threshold: f64,
    settings: &InfluenceSettings,
) -> Result<Vec<EdgeClaims>> {
    check_explained_on(explanation, data)?;
    let effects = explanation.effects();
    let mut shap = threshold_claims_by_context(explainer, data, &effects, threshold);
    add_threshold_intervals(&mut shap, &effects, data, settings);
    let floors = ErrorFloors::measure(explainer, data, settings)?;
    let rule = Rule::ErrorRatio(&floors);
    let shap_err = claims_by_context(explainer, data, &effects, settings, rule);
    let cai_effects = cai_effects(explainer, data, settings)?;
    let cai = claims_by_context(explainer, data, &cai_effects, settings, rule);
    let name = default_method(explanation.settings.method);
    let part = |c, threshold, lower_bound| UnionPart {
        claims: c,
        threshold,
        lower_bound,
    };
    let mut out = Vec::new();
    for (context, cai_context) in shap.iter().zip(&cai) {
        let mut parts: Vec<UnionPart> = if context.context == Context::ALL {
            shap.iter().map(|c| part(c, threshold, false)).collect()
        } else {
            vec![part(context, threshold, false)]
        };
        parts.push(part(cai_context, settings.kappa, true));
        let scope = match context.context.as_str() {
            Context::ALL => "any context".to_owned(),
            c => format!("context {c}"),
        };
        out.extend(union_claims(&name, &context.context, &parts).map(|mut u| {
            u.rule = format!(
                "drives where {method} SHAP does in {scope} (mean |SHAP| >= {threshold} x std of the one-step change) or CAI does in context {} (95 % bootstrap lower bound of mean effect / the model's MAE on the feature > {})",
                context.context, settings.kappa,
                method = explanation.settings.method,
            );
            u
        }));
    }
    out.extend(shap);
    out.extend(shap_err);
    out.extend(cai);
    Ok(out)
}

/// Today's SHAP rule over all of `explanation`'s observations, with bootstrap intervals:
/// score = mean |SHAP| / std of the feature's one-step change, verdict = score ≥
/// `threshold` (the claims of `threshold_claims_by_context` in context `all`, from the
/// explanation alone, for a report made without CAI).
pub fn shap_claims(
    explanation: &Explanation,
    threshold: f64,
    settings: &InfluenceSettings,
) -> EdgeClaims {
    let effects = explanation.effects();
    let scale = &explanation.state_scale;
    let members: Vec<usize> = (0..effects.rows.len()).collect();
    let names = (explanation.action_names(), explanation.state_names());
    let mut claims = threshold_claims(&effects, &members, scale, threshold, Context::ALL, names);
    claims.interval = Some(bootstrap_interval(&effects, &members, scale, settings));
    claims
}

/// `mean / unit`, 0 where the unit is 0 (a feature the data never changes).
fn ratio(mean: f64, unit: f64) -> f64 {
    if unit > 0.0 { mean / unit } else { 0.0 }
}

/// Refuses an explanation whose observations are not rows of `data` (another bag, or the
/// other experiment), before any row of it is read.
fn check_explained_on(explanation: &Explanation, data: &Dataset) -> Result<()> {
    if explanation.experiment != data.experiment {
        return Err(ExplainError::Mismatch(format!(
            "the explanation is of {}, the data {}",
            explanation.experiment, data.experiment
        )));
    }
    if let Some(&r) = explanation
        .observation_rows
        .iter()
        .find(|&&r| r >= data.rows())
    {
        return Err(ExplainError::Mismatch(format!(
            "the explanation observes row {r}; the data has {} transitions",
            data.rows()
        )));
    }
    Ok(())
}

/// Gives every threshold claim set (one per context of the data's experiment, in
/// [`Context::of`] order) the bootstrap interval of its score over that context's
/// observations.
fn add_threshold_intervals(
    claims: &mut [EdgeClaims],
    effects: &Effects,
    data: &Dataset,
    settings: &InfluenceSettings,
) {
    let scale = crate::change_scale(data);
    let reader = ContextReader::new(data.experiment);
    for (c, context) in claims.iter_mut().zip(Context::of(data.experiment)) {
        let members: Vec<usize> = (0..effects.rows.len())
            .filter(|&o| reader.holds(data, effects.rows[o], &context))
            .collect();
        c.interval = Some(bootstrap_interval(effects, &members, &scale, settings));
    }
}

/// 95 % bootstrap interval (percentiles 2.5 and 97.5 over `settings.bootstrap` resamples
/// of the observations `members`) of mean effect / `unit[k]` for every edge, `[action][state]`;
/// `[0, 0]` without observations.
fn bootstrap_interval(
    effects: &Effects,
    members: &[usize],
    unit: &[f64],
    settings: &InfluenceSettings,
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
            boot[edge * draws + d] = ratio(s / n as f64, unit[edge % ns]);
        }
    }
    for (edge, values) in boot.chunks_exact_mut(draws).enumerate() {
        values.sort_by(f64::total_cmp);
        let q = |p: f64| values[((p * (draws - 1) as f64).round() as usize).min(draws - 1)];
        interval[edge / ns][edge % ns] = [q(0.025), q(0.975)];
    }
    interval
}

#[cfg(test)]
mod tests {
    use super::*;

    fn effects(values: Vec<f64>, n_state: usize) -> Effects {
        let rows = values.len() / n_state;
        Effects {
            method: "test".into(),
            rows: (0..rows).collect(),
            n_action: 1,
            n_state,
            values,
        }
    }

    #[test]
    fn the_bootstrap_interval_brackets_the_mean_and_narrows_with_constant_effects() {
        // Edge 0: effects 0..99 (mean 49.5, unit 1); edge 1: always 2 (unit 4); edge 2: a
        // feature that never changes (unit 0).
        let values: Vec<f64> = (0..100).flat_map(|i| [i as f64, 2.0, 7.0]).collect();
        let e = effects(values, 3);
        let members: Vec<usize> = (0..100).collect();
        let settings = InfluenceSettings::default();
        let i = bootstrap_interval(&e, &members, &[1.0, 4.0, 0.0], &settings);
        let [lo, hi] = i[0][0];
        assert!(lo < 49.5 && 49.5 < hi, "{lo} {hi}");
        // Standard error of the mean of 0..99 is ≈ 2.9: the interval spans about ±1.96 of it.
        assert!((hi - lo - 2.0 * 1.96 * 2.87).abs() < 2.5, "{lo} {hi}");
        assert_eq!(i[0][1], [0.5, 0.5]);
        assert_eq!(i[0][2], [0.0, 0.0]);
        assert_eq!(
            bootstrap_interval(&e, &[], &[1.0; 3], &settings)[0][0],
            [0.0, 0.0]
        );
    }
}
