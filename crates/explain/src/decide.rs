//! The product's default verdicts: drives, does not or undecided per edge, from the data's
//! own test and the forward model's calibrated evidence, never from a ground truth.
//!
//! - The data decides first ([`causal_arm_discovery::DataTest`]): motor babbling is a
//!   randomized experiment, so a significant robust test of a_j on Δs_k is evidence of an
//!   edge, and a change predicted to the recording's resolution without a_j is evidence of
//!   none.
//! - Where the data leaves an edge undecided, the model may decide "drives": CAI or SHAP
//!   above κ × the model's error on the feature (the `/err` rules), but only on features
//!   the model has learned, whose error is well below predicting the mean change
//!   ([`MAX_ERROR_RATIO`]), and only for a continuous action. An untrained or random model
//!   has learned nothing and decides nothing. A discrete command switched in a few percent
//!   of the rows (the magnet's) is probed by CAI at random states mostly where the data
//!   rarely switches it: there a model extrapolates what the babbler did around its
//!   switches (on the exp2 quick bag, a 100-epoch FM's CAI "finds" a_mgt → ef_x, ef_y,
//!   ef_z, ef_rx, ef_ry; the magnet moves no joint). For such an action only the in-support
//!   evidence counts ([`crate::influence::switch_evidence`]): CAI where the data switched
//!   it, above the model's answer on the negative controls.
//! - Otherwise "undecided", with why and what would decide it.

use causal_arm_dataset::Dataset;
use causal_arm_discovery::DataTest;
use causal_arm_scoring::{Decision, EdgeClaims, Verdict};

use crate::influence::{SwitchEdge, SwitchEvidence};

/// A model's evidence on a feature counts only where its error on the feature's next
/// value is below this share of the error of predicting the mean one-step change. An
/// untrained network's ratio is near 1 or above; the quick-profile forward models reach
/// 0.01–0.3 on the features they have learned.
pub const MAX_ERROR_RATIO: f64 = 0.5;

/// What the forward model contributes to the default: its claims by the calibrated rules
/// (context `all`) and, per feature, its error beside predicting the mean change.
pub struct ModelEvidence<'a> {
    /// Claim sets by the error-ratio rule (`cai/err`, `kernel/err`, …), context `all`.
    pub parts: Vec<&'a EdgeClaims>,
    /// Per feature: the model's MAE on s_k(t+1).
    pub error: Vec<f64>,
    /// Per feature: MAE of predicting the mean one-step change.
    pub mean_change_error: Vec<f64>,
    /// Per action: whether it takes a few discrete values (the magnet command), on which
    /// only the in-support evidence `switches` decides.
    pub discrete: Vec<bool>,
    /// The discrete actions' in-support evidence (none: their model claims stay undecided).
    pub switches: Option<&'a SwitchEvidence>,
}

impl ModelEvidence<'_> {
    /// The model's error over the mean-change predictor's on feature `k` (∞ where the
    /// feature never changes).
    pub fn error_ratio(&self, k: usize) -> f64 {
        let baseline = self.mean_change_error[k];
        if baseline > 0.0 {
            self.error[k] / baseline
        } else {
            f64::INFINITY
        }
    }

    fn learned(&self, k: usize) -> bool {
        self.error_ratio(k) < MAX_ERROR_RATIO
    }

    /// The 95 % interval of [`Self::deciding_score`], in the same unit.
    fn deciding_interval(&self, a: usize, k: usize, kappa: f64) -> Option<[f64; 2]> {
        if self.discrete[a] {
            let e = self.switch(a, k)?;
            Some(e.interval.map(|v| v / e.threshold))
        } else {
            let part = self.claim(a, k)?;
            Some(part.interval.as_ref()?[a][k].map(|v| v / kappa))
        }
    }

    /// The in-support evidence on (a, k) of a discrete action.
    fn switch(&self, a: usize, k: usize) -> Option<&SwitchEdge> {
        self.switches?.edge(a, k)
    }

    /// The model's claim on (a, k) as its score over its threshold, where it decides:
    /// on a feature the model has learned, by the calibrated parts for a continuous
    /// action, by the in-support evidence for a discrete one.
    fn deciding_score(&self, a: usize, k: usize, kappa: f64) -> Option<f64> {
        if !self.learned(k) {
            return None;
        }
        if self.discrete[a] {
            self.switch(a, k)
                .filter(|e| e.claimed())
                .map(|e| e.score / e.threshold)
        } else {
            self.claim(a, k).map(|p| p.score[a][k] / kappa)
        }
    }

    /// The strongest calibrated part claiming (a, k), by score.
    fn claim(&self, a: usize, k: usize) -> Option<&EdgeClaims> {
        self.parts
            .iter()
            .copied()
            .filter(|p| p.drives[a][k])
            .max_by(|p, q| p.score[a][k].total_cmp(&q.score[a][k]))
    }
}

/// Per action: whether it takes a few discrete values (the magnet command), on which the
/// model's evidence alone decides nothing ([`ModelEvidence::discrete`]).
pub fn discrete_actions(data: &Dataset) -> Vec<bool> {
    (0..data.action_width())
        .map(|j| crate::influence::discrete_values(data, j).is_some())
        .collect()
}

/// The default claims named `method`: the data's verdicts, with model "drives" where the
/// data is undecided and the model has learned the feature. Score: evidence over its
/// threshold (the data's z over the critical z, or the model part's score over κ), ≥ 1
/// exactly where claimed; −1 where denied. Interval: the deciding evidence's 95 % interval
/// in the same unit (z ± 1.96 for the data, the model part's bootstrap interval).
pub fn default_claims(
    method: &str,
    data: &DataTest,
    model: &ModelEvidence,
    kappa: f64,
) -> EdgeClaims {
    let mut claims = data.claims(method);
    let data_rule = std::mem::take(&mut claims.rule);
    let data_decisions = claims
        .decisions
        .take()
        .expect("the data test's claims are three-valued");
    let z_crit = data.critical_z();
    let (na, ns) = (data.action_names.len(), data.state_names.len());
    let mut decisions = Vec::with_capacity(na);
    let mut interval = vec![vec![[0.0; 2]; ns]; na];
    for (a, data_row) in data_decisions.into_iter().enumerate() {
        let mut row = Vec::with_capacity(ns);
        for (k, data_decision) in data_row.into_iter().enumerate() {
            let data_score = data.strongest(a, k).1.z / z_crit;
            let model_score = model.deciding_score(a, k, kappa);
            let (decision, score) = combine(data_decision, data_score, model, model_score, (a, k));
            claims.score[a][k] = score;
            claims.drives[a][k] = decision.verdict == Verdict::Drives;
            interval[a][k] = match decision.source.as_str() {
                "model" => model.deciding_interval(a, k, kappa).unwrap_or([score; 2]),
                _ if decision.verdict == Verdict::DoesNot => [score; 2],
                _ => [score - 1.96 / z_crit, score + 1.96 / z_crit],
            };
            row.push(decision);
        }
        decisions.push(row);
    }
    claims.decisions = Some(decisions);
    claims.interval = Some(interval);
    claims.rule = format!(
        "drives where the data test does, or, where it is undecided, the forward model's CAI influence or SHAP above kappa x its error ({}) does on a feature the model has learned (error < {MAX_ERROR_RATIO} x that of predicting the mean change); for a discrete action, CAI at the rows where the data switched it, above kappa x max(1, its largest effect on the features the data rules out); does not where the data shows none; else undecided. {}",
        model
            .parts
            .iter()
            .map(|p| p.method.as_str())
            .collect::<Vec<_>>()
            .join(", "),
        data_rule
    );
    claims
}

/// One edge's verdict from the data's decision and the model's claim (its score over κ,
/// where it claims and has learned the feature).
fn combine(
    data: Decision,
    data_score: f64,
    model: &ModelEvidence,
    model_score: Option<f64>,
    (a, k): (usize, usize),
) -> (Decision, f64) {
    match (data.verdict, model_score) {
        (Verdict::Drives, Some(m)) => (
            Decision {
                source: "data+model".into(),
                reason: format!(
                    "{}; the model agrees ({:.1} x its threshold)",
                    data.reason, m
                ),
                ..data
            },
            data_score.max(m),
        ),
        (Verdict::Drives, None) => (data, data_score),
        (Verdict::DoesNot, _) => (data, -1.0),
        (Verdict::Undecided, Some(m)) => {
            let evidence = match model.switch(a, k).filter(|_| model.discrete[a]) {
                Some(e) => e.describe(),
                None => format!(
                    "{}: effect {m:.1} x the model's threshold",
                    model.claim(a, k).map_or("", |p| p.method.as_str())
                ),
            };
            let reason = format!(
                "{evidence} (error ratio {:.2} on this feature); the data alone: {}",
                model.error_ratio(k),
                data.reason
            );
            let decision = Decision {
                verdict: Verdict::Drives,
                source: "model".into(),
                reason,
                to_decide: String::new(),
            };
            (decision, m)
        }
        (Verdict::Undecided, None) => {
            let (why, to_decide) = undecided_by_model(model, a, k);
            let decision = Decision {
                reason: format!("{}; {why}", data.reason),
                to_decide: format!("{}; {to_decide}", data.to_decide),
                ..data
            };
            (decision, data_score.min(0.999))
        }
    }
}

/// Why the model did not decide an undecided edge, and what would let it.
fn undecided_by_model(model: &ModelEvidence, a: usize, k: usize) -> (String, &'static str) {
    let ratio = model.error_ratio(k);
    if model.discrete[a] && ratio < MAX_ERROR_RATIO {
        return undecided_discrete(model, a, k);
    }
    if ratio >= MAX_ERROR_RATIO {
        (
            format!(
                "the model has not learned this feature (its error is {ratio:.2} x that of predicting the mean change)"
            ),
            "more training epochs or steps for the forward model",
        )
    } else {
        (
            format!(
                "the model's evidence is below its threshold (error {:.1e} on this feature)",
                model.error[k]
            ),
            "a forward model with a smaller error on this feature",
        )
    }
}

/// Why the in-support evidence did not decide an edge of a discrete action.
fn undecided_discrete(model: &ModelEvidence, a: usize, k: usize) -> (String, &'static str) {
    let to_decide = "more rows with this command switching, or a forward model with a smaller error on this feature";
    match (model.switch(a, k), model.switches) {
        (Some(e), _) => (e.describe(), to_decide),
        (None, Some(switches)) if !switches.missing[a].is_empty() => (
            format!("the model's evidence on this discrete command is not judged: {}", switches.missing[a]),
            to_decide,
        ),
        _ => (
            "this command is discrete and rarely switched: the model's evidence at random states extrapolates and does not decide".into(),
            to_decide,
        ),
    }
}

/// The model-only verdicts of a claim set `model` (CAI through the chained forward model h
/// steps on), three-valued with the data's one sure answer: "drives" where the model claims
/// it, "does not" where the data never shows the feature change, else undecided. Used
/// beyond one step, where the data's own test answers a different question than the
/// simulator's (it measures a(t)'s effect through everything the babbler does next, the
/// truth with the later commands held fixed).
pub fn model_only_claims(method: &str, model: &EdgeClaims, data: &DataTest) -> EdgeClaims {
    let mut claims = model.clone();
    claims.method = method.to_owned();
    let decisions = (0..claims.action_names.len())
        .map(|a| {
            (0..claims.state_names.len())
                .map(|k| model_only_decision(&mut claims, data, a, k))
                .collect()
        })
        .collect();
    claims.decisions = Some(decisions);
    claims.rule = format!(
        "drives where {} does; does not where the data never shows the feature change; else undecided. {}",
        model.method, model.rule
    );
    claims
}

fn model_only_decision(claims: &mut EdgeClaims, data: &DataTest, a: usize, k: usize) -> Decision {
    let state = &claims.state_names[k];
    if !data.changes[k] {
        claims.drives[a][k] = false;
        return Decision {
            verdict: Verdict::DoesNot,
            source: "data".into(),
            reason: format!("{state} never changed in {} transitions", data.rows),
            to_decide: String::new(),
        };
    }
    let score = claims.score[a][k];
    if claims.drives[a][k] {
        Decision {
            verdict: Verdict::Drives,
            source: "model".into(),
            reason: format!("{}: {score:.2} x its threshold", claims.method),
            to_decide: String::new(),
        }
    } else {
        Decision {
            verdict: Verdict::Undecided,
            source: String::new(),
            reason: format!("the model's evidence is {score:.2} x its threshold"),
            to_decide: "a forward model whose error this many steps on is below the effect".into(),
        }
    }
}
