//! The relevance report: for every state feature, whether any action can change it, and for
//! every action, which state features it drives — the paper's "colour can be removed from
//! the state space" finding as data a program can act on.

use serde::{Deserialize, Serialize};

use crate::Explanation;

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
    /// `max_mean_abs_shap / scale`.
    pub score: f64,
    /// Some action drives it (`score ≥ threshold`).
    pub affected: bool,
    /// Actions whose own score reaches the threshold, strongest first.
    pub driven_by: Vec<String>,
}

impl StateVerdict {
    /// The verdict in words, as the CSV and the CLI print it.
    pub fn verdict(&self) -> &'static str {
        if self.affected {
            "relevant"
        } else {
            "not affected by any action"
        }
    }
}

/// What one action drives.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ActionVerdict {
    /// Action feature.
    pub name: String,
    /// State features it drives, strongest (by score) first.
    pub drives: Vec<String>,
    /// Their scores, same order.
    pub scores: Vec<f64>,
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
    /// Threshold on the score.
    pub threshold: f64,
    /// The decision rule in words.
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
    /// State features no action affects (candidates for removal from the state space).
    pub unaffected: Vec<String>,
}

/// `mean_abs / scale`; 0 for a feature that never changes in the data (whatever small
/// attribution a network gives it, the data shows no action changing it).
fn score(mean_abs: f64, scale: f64) -> f64 {
    if scale > 0.0 { mean_abs / scale } else { 0.0 }
}

/// Builds the report of `explanation` with `threshold` (see [`DEFAULT_THRESHOLD`]).
pub fn relevance(explanation: &Explanation, threshold: f64) -> Relevance {
    let actions = explanation.action_names().to_vec();
    let states = explanation.state_names().to_vec();
    let mean_abs = explanation.action_mean_abs();
    let scale = &explanation.state_scale;
    let scores: Vec<Vec<f64>> = mean_abs
        .iter()
        .map(|row| row.iter().zip(scale).map(|(&m, &s)| score(m, s)).collect())
        .collect();
    let state_verdicts: Vec<StateVerdict> = states
        .iter()
        .enumerate()
        .map(|(j, name)| {
            let (best, max) = (0..actions.len())
                .map(|a| (a, mean_abs[a][j]))
                .fold((0, f64::NEG_INFINITY), |b, c| if c.1 > b.1 { c } else { b });
            let mut driven: Vec<usize> = (0..actions.len())
                .filter(|&a| scores[a][j] >= threshold)
                .collect();
            driven.sort_by(|&p, &q| scores[q][j].total_cmp(&scores[p][j]));
            StateVerdict {
                name: name.clone(),
                scale: scale[j],
                max_mean_abs_shap: max,
                strongest_action: actions[best].clone(),
                score: score(max, scale[j]),
                affected: !driven.is_empty(),
                driven_by: driven.into_iter().map(|a| actions[a].clone()).collect(),
            }
        })
        .collect();
    let action_verdicts = actions
        .iter()
        .enumerate()
        .map(|(a, name)| {
            let mut driven: Vec<usize> = (0..states.len())
                .filter(|&j| scores[a][j] >= threshold)
                .collect();
            driven.sort_by(|&p, &q| scores[a][q].total_cmp(&scores[a][p]));
            ActionVerdict {
                name: name.clone(),
                drives: driven.iter().map(|&j| states[j].clone()).collect(),
                scores: driven.iter().map(|&j| scores[a][j]).collect(),
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
            .filter(|v| !v.affected)
            .map(|v| v.name.clone())
            .collect(),
        action_names: actions,
        state_names: states,
        mean_abs_shap: mean_abs,
        states: state_verdicts,
        actions: action_verdicts,
    }
}

impl Relevance {
    /// The state verdicts as CSV (one row per state feature, header first).
    pub fn to_csv(&self) -> String {
        let mut out = String::from(
            "state,verdict,score,max_mean_abs_shap,strongest_action,scale,driven_by\n",
        );
        for v in &self.states {
            out.push_str(&format!(
                "{},{},{:.6e},{:.6e},{},{:.6e},{}\n",
                v.name,
                v.verdict(),
                v.score,
                v.max_mean_abs_shap,
                v.strongest_action,
                v.scale,
                v.driven_by.join(";")
            ));
        }
        out
    }

    /// Score (mean |SHAP| / scale) of action number `action` on state feature number
    /// `state`, by the rule the verdicts use.
    pub fn score(&self, action: usize, state: usize) -> f64 {
        score(self.mean_abs_shap[action][state], self.states[state].scale)
    }

    /// Whether `action` drives `state` under the report's rule.
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
