//! The relevance report: for every state feature, whether any action can change it, and for
//! every action → state edge, whether the action drives it, how strongly and how surely —
//! the paper's "colour can be removed from the state space" finding as data a program can
//! act on. The verdicts are a claim set's (by default the run's `<method>+cai` claims, see
//! [`crate::verdicts`]); the mean |SHAP| heat map is kept beside them.

use causal_arm_scoring::EdgeClaims;
use serde::{Deserialize, Serialize};

use crate::influence::InfluenceSettings;
use crate::{ExplainError, Explanation, Result};

/// Default threshold: an action drives a state feature when its mean |SHAP| reaches 1 % of
/// the standard deviation of that feature's one-step change over the data.
pub const DEFAULT_THRESHOLD: f64 = 0.01;

/// Verdict on one state feature.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StateVerdict {
    /// State feature.
    pub name: String,
    /// Standard deviation of the feature's one-step change over the data (the threshold's
    /// unit; 0 for a feature that never changes within a transition).
    pub scale: f64,
    /// Largest mean |SHAP| any action has on it, raw units.
    pub max_mean_abs_shap: f64,
    /// The action with that largest effect.
    pub strongest_action: String,
    /// `max_mean_abs_shap / scale` (today's SHAP score).
    pub score: f64,
    /// Some action drives it, by the report's decision ([`Relevance::decision_method`]).
    pub affected: bool,
    /// Actions that drive it by the decision, strongest (by decision score) first.
    pub driven_by: Vec<String>,
    /// Largest decision score any action has on it.
    pub decision_score: f64,
    /// No action drives it, and some edge to it is undecided (three-valued decisions):
    /// it is not known to be unaffected.
    #[serde(default)]
    pub undecided: bool,
}

impl StateVerdict {
    /// The verdict in words, as the CSV and the CLI print it.
    pub fn verdict(&self) -> &'static str {
        match (self.affected, self.undecided) {
            (true, _) => "relevant",
            (false, true) => "undecided",
            (false, false) => "not affected by any action",
        }
    }
}

/// What one action drives.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ActionVerdict {
    /// Action feature.
    pub name: String,
    /// State features it drives by the decision, strongest (by decision score) first.
    pub drives: Vec<String>,
    /// Their decision scores, same order.
    pub scores: Vec<f64>,
    /// Their 95 % bootstrap intervals, same order and units.
    pub intervals: Vec<[f64; 2]>,
}

/// The whole report (`relevance.json`; `relevance.csv` holds the state verdicts).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Relevance {
    /// Experiment of the model.
    pub experiment: String,
    /// Attribution method.
    pub method: String,
    /// Observations averaged over.
    pub observations: usize,
    /// Background rows or centres.
    pub background: usize,
    /// Threshold of today's SHAP rule (the SHAP part of the decision).
    pub threshold: f64,
    /// Today's SHAP rule in words (mean |SHAP| against `threshold` × the change's std).
    pub rule: String,
    /// Action names (rows of `mean_abs_shap`).
    pub action_names: Vec<String>,
    /// State names (columns of `mean_abs_shap`).
    pub state_names: Vec<String>,
    /// `[action][state]` mean |SHAP|, raw units of the state feature.
    pub mean_abs_shap: Vec<Vec<f64>>,
    /// One verdict per state feature, in state order.
    pub states: Vec<StateVerdict>,
    /// One entry per action, in action order.
    pub actions: Vec<ActionVerdict>,
    /// State features no action affects (candidates for removal from the state space); an
    /// undecided one is not among them.
    pub unaffected: Vec<String>,
    /// Claim set the verdicts are (`kernel+cai+data`, the default; `kernel` for today's rule).
    pub decision_method: String,
    /// Its decision rule in words.
    pub decision_rule: String,
    /// `[action][state]` verdict: the action drives the feature.
    pub drives: Vec<Vec<bool>>,
    /// `[action][state]` decision score (for `<method>+cai`: evidence / its threshold, ≥ 1
    /// where claimed).
    pub decision_score: Vec<Vec<f64>>,
    /// `[action][state]` 95 % bootstrap interval of the decision score's evidence, same units.
    pub interval: Vec<Vec<[f64; 2]>>,
    /// `[action][state]` three-valued verdicts with reasons, where the decision method
    /// makes them (the default does).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub decisions: Option<Vec<Vec<causal_arm_scoring::Decision>>>,
}

/// Builds the report of `explanation` decided by today's SHAP rule alone with `threshold`
/// (see [`DEFAULT_THRESHOLD`]), its intervals bootstrapped over the observations: the
/// report of an explanation made without the data CAI needs.
pub fn relevance(explanation: &Explanation, threshold: f64) -> Relevance {
    let settings = InfluenceSettings {
        seed: explanation.settings.seed,
        ..InfluenceSettings::default()
    };
    let claims = crate::verdicts::shap_claims(explanation, threshold, &settings);
    build(explanation, threshold, &claims)
}

/// Builds the report of `explanation` (the mean |SHAP| heat map and today's SHAP rule
/// with `threshold`) decided by the claims of context `all` in `claims`, the first such set
/// (as [`crate::verdicts::shap_and_cai_claims`] orders them: the calibrated
/// `<method>+cai`). Claims without intervals, of another shape or other names are refused.
pub fn calibrated_relevance(
    explanation: &Explanation,
    threshold: f64,
    claims: &[EdgeClaims],
) -> Result<Relevance> {
    let decision = claims
        .iter()
        .find(|c| c.context == causal_arm_dataset::Context::ALL)
        .ok_or_else(|| ExplainError::Mismatch("no claims of context all to decide by".into()))?;
    decision.check_shape().map_err(ExplainError::Mismatch)?;
    if decision.action_names != explanation.action_names()
        || decision.state_names != explanation.state_names()
    {
        return Err(ExplainError::Mismatch(format!(
            "claims of {} name other features than the explanation",
            decision.method
        )));
    }
    if decision.interval.is_none() {
        return Err(ExplainError::Mismatch(format!(
            "claims of {} carry no intervals",
            decision.method
        )));
    }
    Ok(build(explanation, threshold, decision))
}

/// The report of `explanation` with verdicts, scores and intervals from `decision`, whose
/// shape and names match it.
fn build(explanation: &Explanation, threshold: f64, decision: &EdgeClaims) -> Relevance {
    let actions = explanation.action_names().to_vec();
    let states = explanation.state_names().to_vec();
    let mean_abs = explanation.action_mean_abs();
    let scale = &explanation.state_scale;
    let (drives, decided) = (&decision.drives, &decision.score);
    let interval = decision
        .interval
        .clone()
        .unwrap_or_else(|| vec![vec![[0.0; 2]; states.len()]; actions.len()]);
    // Indices where `is_edge` holds, strongest decision score first.
    let strongest_first = |mut edges: Vec<(usize, usize)>| {
        edges.sort_by(|&(a, k), &(b, l)| decided[b][l].total_cmp(&decided[a][k]));
        edges
    };
    let state_verdicts: Vec<StateVerdict> = states
        .iter()
        .enumerate()
        .map(|(j, name)| {
            let (best, max) = (0..actions.len())
                .map(|a| (a, mean_abs[a][j]))
                .fold((0, f64::NEG_INFINITY), |b, c| if c.1 > b.1 { c } else { b });
            let driven = strongest_first(
                (0..actions.len())
                    .filter(|&a| drives[a][j])
                    .map(|a| (a, j))
                    .collect(),
            );
            StateVerdict {
                name: name.clone(),
                scale: scale[j],
                max_mean_abs_shap: max,
                strongest_action: actions[best].clone(),
                score: crate::in_change_units(max, scale[j]),
                affected: !driven.is_empty(),
                driven_by: driven
                    .into_iter()
                    .map(|(a, _)| actions[a].clone())
                    .collect(),
                decision_score: (0..actions.len())
                    .map(|a| decided[a][j])
                    .fold(f64::NEG_INFINITY, f64::max),
                undecided: (0..actions.len())
                    .any(|a| decision.verdict(a, j) == causal_arm_scoring::Verdict::Undecided),
            }
        })
        .collect();
    let action_verdicts = actions
        .iter()
        .enumerate()
        .map(|(a, name)| {
            let driven = strongest_first(
                (0..states.len())
                    .filter(|&k| drives[a][k])
                    .map(|k| (a, k))
                    .collect(),
            );
            ActionVerdict {
                name: name.clone(),
                drives: driven.iter().map(|&(_, k)| states[k].clone()).collect(),
                scores: driven.iter().map(|&(_, k)| decided[a][k]).collect(),
                intervals: driven.iter().map(|&(_, k)| interval[a][k]).collect(),
            }
        })
        .collect();
    Relevance {
        experiment: explanation.experiment.to_string(),
        method: explanation.settings.method.to_string(),
        observations: explanation.attributions.n_obs,
        background: explanation.background.rows(),
        threshold,
        rule: format!(
            "action a drives state feature s when mean |SHAP(a → s(t+1))| over the observations ≥ {threshold} × std of the one-step change s(t+1) − s(t) over the data; s is not affected when no action drives it (always so when s never changes within a transition)"
        ),
        unaffected: state_verdicts
            .iter()
            .filter(|v| !v.affected && !v.undecided)
            .map(|v| v.name.clone())
            .collect(),
        action_names: actions,
        state_names: states,
        mean_abs_shap: mean_abs,
        states: state_verdicts,
        actions: action_verdicts,
        decision_method: decision.method.clone(),
        decision_rule: decision.rule.clone(),
        drives: drives.clone(),
        decision_score: decided.clone(),
        interval,
        decisions: decision.decisions.clone(),
    }
}

impl Relevance {
    /// The state verdicts as CSV (one row per state feature, header first): the verdict and
    /// `driven_by` by the decision, `score` … `scale` today's SHAP columns.
    pub fn to_csv(&self) -> String {
        let mut out = String::from(
            "state,verdict,score,max_mean_abs_shap,strongest_action,scale,driven_by,decision_method,decision_score\n",
        );
        for v in &self.states {
            out.push_str(&format!(
                "{},{},{:.6e},{:.6e},{},{:.6e},{},{},{:.6e}\n",
                v.name,
                v.verdict(),
                v.score,
                v.max_mean_abs_shap,
                v.strongest_action,
                v.scale,
                v.driven_by.join(";"),
                self.decision_method,
                v.decision_score
            ));
        }
        out
    }

    /// Today's SHAP score (mean |SHAP| / scale) of action number `action` on state feature
    /// number `state`: what the heat map and the PDP ranking show.
    pub fn score(&self, action: usize, state: usize) -> f64 {
        crate::in_change_units(self.mean_abs_shap[action][state], self.states[state].scale)
    }

    /// Whether `action` drives `state` by the report's decision.
    pub fn drives(&self, action: &str, state: &str) -> bool {
        self.actions
            .iter()
            .any(|a| a.name == action && a.drives.iter().any(|s| s == state))
    }

    /// The verdict on `state`, if it is a state feature.
    pub fn state(&self, state: &str) -> Option<&StateVerdict> {
        self.states.iter().find(|v| v.name == state)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Method, Settings};
    use causal_arm_shap::{Attributions, Background};

    /// 50 observations of two states (s0, s1) and two actions (a0, a1), unit change scale:
    /// a0 gives s0 |φ| = 0.5 … 1.5, a1 gives s1 |φ| = 0.001 (below today's 0.01), else 0.
    fn explanation() -> Explanation {
        let (n_obs, n_in, n_out) = (50, 4, 2);
        let mut values = vec![0.0; n_obs * n_in * n_out];
        for o in 0..n_obs {
            values[(o * n_in + 2) * n_out] = 0.5 + o as f64 / 49.0;
            values[(o * n_in + 3) * n_out + 1] = -0.001;
        }
        let names = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        Explanation {
            settings: Settings::for_method(Method::Kernel),
            experiment: causal_arm_dataset::Experiment::Exp1,
            input_names: names(&["s0", "s1", "a0", "a1"]),
            output_names: names(&["s0_next", "s1_next"]),
            n_state: 2,
            observation_rows: (0..n_obs).collect(),
            observations: vec![0.0; n_obs * n_in],
            background: Background::sample(&[0.0; 4], 4).unwrap(),
            attributions: Attributions {
                n_obs,
                n_inputs: n_in,
                n_outputs: n_out,
                values,
                expected: vec![0.0; n_out],
                outputs: vec![0.0; n_obs * n_out],
            },
            seconds: 0.0,
            state_scale: vec![1.0, 1.0],
        }
    }

    /// Calibrated claims (context `all`) that add a1 → s1, CAI-decided: score 1.5 = the
    /// lower end of its interval [1.5, 2.5].
    fn calibrated(e: &Explanation) -> EdgeClaims {
        EdgeClaims {
            method: "kernel+cai".into(),
            rule: "drives where kernel SHAP does or CAI does".into(),
            context: "all".into(),
            horizon: 1,
            observations: 50,
            action_names: e.action_names().to_vec(),
            state_names: e.state_names().to_vec(),
            score: vec![vec![100.0, 0.0], vec![0.0, 1.5]],
            interval: Some(vec![
                vec![[90.0, 110.0], [0.0, 0.0]],
                vec![[0.0, 0.0], [1.5, 2.5]],
            ]),
            drives: vec![vec![true, false], vec![false, true]],
            decisions: None,
        }
    }

    #[test]
    fn todays_rule_alone_decides_with_bootstrap_intervals() {
        let e = explanation();
        let r = relevance(&e, DEFAULT_THRESHOLD);
        assert_eq!(r.decision_method, "kernel");
        assert_eq!(r.drives, vec![vec![true, false], vec![false, false]]);
        assert!((r.decision_score[0][0] - 1.0).abs() < 1e-12);
        let [lo, hi] = r.interval[0][0];
        assert!(lo < 1.0 && 1.0 < hi && hi - lo < 0.3, "{lo} {hi}");
        let [lo, hi] = r.interval[1][1];
        assert!(
            (lo - 0.001).abs() < 1e-15 && (hi - 0.001).abs() < 1e-15,
            "constant effect"
        );
        assert_eq!(r.unaffected, vec!["s1".to_string()]);
    }

    #[test]
    fn the_report_carries_the_calibrated_verdict_score_and_interval_of_every_edge() {
        let e = explanation();
        let claims = calibrated(&e);
        // The first set of context `all` decides; other contexts are skipped.
        let mut other = claims.clone();
        other.context = "holding".into();
        other.drives = vec![vec![false; 2]; 2];
        let r = calibrated_relevance(&e, DEFAULT_THRESHOLD, &[other, claims]).unwrap();
        assert_eq!(r.decision_method, "kernel+cai");
        assert!(r.drives("a1", "s1") && r.drives("a0", "s0") && !r.drives("a0", "s1"));
        let s1 = r.state("s1").unwrap();
        assert!(s1.affected && s1.driven_by == ["a1"] && s1.decision_score == 1.5);
        // Today's SHAP columns are kept beside the verdicts.
        assert!((s1.score - 0.001).abs() < 1e-12 && s1.strongest_action == "a1");
        assert!((r.mean_abs_shap[1][1] - 0.001).abs() < 1e-12);
        assert_eq!(r.actions[1].intervals, vec![[1.5, 2.5]]);
        assert_eq!(r.interval[0][0], [90.0, 110.0]);
        assert!(r.unaffected.is_empty());
        assert!(
            r.to_csv()
                .lines()
                .nth(2)
                .unwrap()
                .ends_with(",a1,kernel+cai,1.500000e0")
        );
        // On the wire: row-major action × state.
        let msg = crate::serve::relevance_msg(&r, Default::default());
        assert_eq!(msg.decision_method, "kernel+cai");
        assert_eq!(msg.drives, [true, false, false, true]);
        assert_eq!(msg.score, [100.0, 0.0, 0.0, 1.5]);
        assert_eq!(msg.interval_lower, [90.0, 0.0, 0.0, 1.5]);
        assert_eq!(msg.interval_upper, [110.0, 0.0, 0.0, 2.5]);
        assert_eq!(msg.affected, [true, true]);
        assert_eq!(msg.decision_rule, r.decision_rule);
        assert!(msg.rule.contains("mean |SHAP"));
    }

    #[test]
    fn claims_that_cannot_decide_the_report_are_refused() {
        let e = explanation();
        let mut none = calibrated(&e);
        none.interval = None;
        let mut renamed = calibrated(&e);
        renamed.state_names[1] = "s9".into();
        let mut other = calibrated(&e);
        other.context = "holding".into();
        let mut short = calibrated(&e);
        short.drives.pop();
        for (claims, problem) in [
            (none, "no intervals"),
            (renamed, "other features"),
            (other, "no claims of context all"),
            (short, "not 2 actions"),
        ] {
            let err = calibrated_relevance(&e, DEFAULT_THRESHOLD, &[claims]).unwrap_err();
            assert!(err.to_string().contains(problem), "{err}");
        }
    }
}
