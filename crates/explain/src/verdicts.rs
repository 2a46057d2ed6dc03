//! The causal claims of a SHAP run, assembled in one place so that `causal-arm explain` and
//! the explainer node decide alike. The default, `<method>+cai+data`, is three-valued
//! ([`crate::decide`]): the data's own test first, the model's calibrated evidence where the
//! data is undecided. Beside it: SHAP by today's threshold rule (in any context) united with
//! CAI influence judged against the model's error floor (`<method>+cai`, the verdicts of
//! earlier releases), each part alone, and the data test alone (`data`).

use causal_arm_dataset::{Context, ContextReader, Dataset};
use causal_arm_discovery::{DataTest, GrangerSettings};
use causal_arm_scoring::EdgeClaims;

use crate::decide::{ModelEvidence, default_claims, discrete_actions};
use crate::influence::{
    Effects, ErrorFloors, InfluenceSettings, Rule, UnionPart, bootstrap_interval, cai_effects,
    claims_by_context, error_pool, mean_change_error, switch_evidence, threshold_claims,
    union_claims,
};
use crate::{ExplainError, Explainer, Explanation, Result};

/// Name of the default claims of a SHAP run by `method` (`kernel+cai+data`, …).
pub fn default_method(method: crate::Method) -> String {
    format!("{method}+cai+data")
}

/// Name of the union of SHAP by today's rule and CAI (`kernel+cai`, `deep+cai`): the
/// verdicts of earlier releases, kept beside the default for comparison.
pub fn union_method(method: crate::Method) -> String {
    format!("{method}+cai")
}

/// The data's own test on `data` as the explainer runs it (the default settings), h steps
/// on (1: the one-step change).
pub fn data_test(data: &Dataset, horizon: usize) -> Result<DataTest> {
    DataTest::run_ahead(data, horizon, &GrangerSettings::data_test())
        .map_err(|e| ExplainError::Options(format!("the data test at h = {horizon}: {e}")))
}

/// The claim sets of a SHAP run, the default (`<method>+cai+data`, context `all`, three
/// verdicts) first; then SHAP by today's rule (every context) united with CAI by its error
/// floor, per context (`<method>+cai`; in context `all`, SHAP of any context counts); SHAP
/// by today's rule, SHAP against the model's error, CAI alone, and the data test alone.
/// `explanation` must have been made on `data` (its observations are rows of it).
pub fn shap_and_cai_claims(
    explainer: &Explainer,
    data: &Dataset,
    explanation: &Explanation,
    threshold: f64,
    settings: &InfluenceSettings,
) -> Result<Vec<EdgeClaims>> {
    check_explained_on(explanation, data)?;
    let effects = explanation.effects();
    let shap = shap_claims_by_context(explainer, data, explanation, &effects, threshold, settings);
    let floors = ErrorFloors::measure(explainer, data, settings)?;
    let rule = Rule::ErrorRatio(&floors);
    let shap_err = claims_by_context(explainer, data, &effects, settings, rule);
    let cai_effects = cai_effects(explainer, data, settings)?;
    let cai = claims_by_context(explainer, data, &cai_effects, settings, rule);
    let data_test = data_test(data, 1)?;
    let switches = switch_evidence(explainer, data, settings, &data_test)?;
    let evidence = ModelEvidence {
        parts: vec![&cai[0], &shap_err[0]],
        error: floors.per_context[0].clone(),
        mean_change_error: mean_change_error(data, &error_pool(data, settings, 1)),
        discrete: discrete_actions(data),
        switches: Some(&switches),
    };
    let default = default_claims(
        &default_method(explanation.settings.method),
        &data_test,
        &evidence,
        settings.kappa,
    );
    let name = union_method(explanation.settings.method);
    let part = |c, threshold, lower_bound| UnionPart {
        claims: c,
        threshold,
        lower_bound,
    };
    let mut out = vec![default];
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
    out.push(data_test.claims("data"));
    Ok(out)
}

/// Today's SHAP rule over all of `explanation`'s observations, with bootstrap intervals:
/// score = mean |SHAP| / std of the feature's one-step change, verdict = score ≥
/// `threshold` (the claims of `shap_claims_by_context` in context `all`, from the
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
    with_interval(
        threshold_claims(&effects, &members, scale, threshold, Context::ALL, names),
        &effects,
        &members,
        scale,
        settings,
    )
}

/// Today's SHAP rule in every context of the data's experiment (`all` first), each with the
/// bootstrap interval of its score over that context's observations; the unit is the
/// explanation's change scale (measured on `data` when it was made).
fn shap_claims_by_context(
    explainer: &Explainer,
    data: &Dataset,
    explanation: &Explanation,
    effects: &Effects,
    threshold: f64,
    settings: &InfluenceSettings,
) -> Vec<EdgeClaims> {
    let scale = &explanation.state_scale;
    let reader = ContextReader::new(data.experiment);
    let names = (explainer.action_names(), explainer.state_names());
    Context::of(data.experiment)
        .iter()
        .map(|context| {
            let members = effects.members(data, &reader, context);
            let claims = threshold_claims(effects, &members, scale, threshold, context.name, names);
            with_interval(claims, effects, &members, scale, settings)
        })
        .collect()
}

/// `claims` of today's SHAP rule with the bootstrap interval of their score (mean effect /
/// `scale`) over the observations `members`.
fn with_interval(
    mut claims: EdgeClaims,
    effects: &Effects,
    members: &[usize],
    scale: &[f64],
    settings: &InfluenceSettings,
) -> EdgeClaims {
    let ratio = |mean: f64, k: usize| crate::in_change_units(mean, scale[k]);
    claims.interval = Some(bootstrap_interval(effects, members, settings, ratio));
    claims
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
        let unit = [1.0, 4.0, 0.0];
        let i = bootstrap_interval(&e, &members, &settings, |m, k| {
            crate::in_change_units(m, unit[k])
        });
        let [lo, hi] = i[0][0];
        assert!(lo < 49.5 && 49.5 < hi, "{lo} {hi}");
        // Standard error of the mean of 0..99 is ≈ 2.9: the interval spans about ±1.96 of it.
        assert!((hi - lo - 2.0 * 1.96 * 2.87).abs() < 2.5, "{lo} {hi}");
        assert_eq!(i[0][1], [0.5, 0.5]);
        assert_eq!(i[0][2], [0.0, 0.0]);
        assert_eq!(
            bootstrap_interval(&e, &[], &settings, |m, _| m)[0][0],
            [0.0, 0.0]
        );
    }
}
