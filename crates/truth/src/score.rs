//! Claims scored against the simulator's truth, overall and per block of state features.

use causal_arm_scoring::{Block, EdgeClaims, Scores, score};
use serde::{Deserialize, Serialize};

use crate::{Edge, Truth, TruthError};

/// One line of a score table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ScoreRow {
    /// Method of the claims.
    pub method: String,
    /// Their decision rule.
    pub rule: String,
    /// Context scored.
    pub context: String,
    /// k of s(t+k).
    pub horizon: usize,
    /// `all` or a [`Block`] name.
    pub block: String,
    /// The scores.
    pub scores: Scores,
}

/// Refuses claims by `method` about `actions` × `states` that `truth` cannot score: a
/// truth of the other experiment, or of other feature names. Callers check before
/// computing claims, so a wrong truth file costs no attribution time.
pub fn check_names(
    truth: &Truth,
    method: &str,
    actions: &[String],
    states: &[String],
) -> Result<(), TruthError> {
    if states == truth.state_names && actions == truth.action_names {
        return Ok(());
    }
    Err(TruthError::File {
        path: truth.bag.clone().into(),
        problem: format!(
            "the truth ({}) has actions {:?} and state features {:?}; the {method} claims have actions {actions:?} and state features {states:?}",
            truth.experiment, truth.action_names, truth.state_names
        ),
    })
}

/// Scores `claims` against the matching matrix of `truth`: one row over all pairs, then
/// one per block the experiment has. Refuses claims whose names or context the truth
/// does not share (a truth of the other experiment, other feature names).
pub fn score_claims(truth: &Truth, claims: &EdgeClaims) -> Result<Vec<ScoreRow>, TruthError> {
    let mismatch = |problem: String| TruthError::File {
        path: truth.bag.clone().into(),
        problem,
    };
    check_names(
        truth,
        &claims.method,
        &claims.action_names,
        &claims.state_names,
    )?;
    claims.check_shape().map_err(mismatch)?;
    let m = truth
        .matrix(&claims.context, claims.horizon)
        .ok_or_else(|| {
            mismatch(format!(
                "the truth has no matrix of context {:?} at horizon {} (contexts: {:?}; horizons 1..={})",
                claims.context,
                claims.horizon,
                truth
                    .matrices
                    .iter()
                    .filter(|m| m.horizon == 1)
                    .map(|m| m.context.as_str())
                    .collect::<Vec<_>>(),
                truth.plan.horizon
            ))
        })?;
    let ns = truth.state_names.len();
    let labels: Vec<Option<bool>> = (0..truth.action_names.len() * ns)
        .map(|i| match m.edge(i / ns, i % ns, truth.plan.min_fraction) {
            Edge::Present => Some(true),
            Edge::Absent => Some(false),
            Edge::Rare => None,
        })
        .collect();
    let verdicts: Vec<bool> = claims.drives.iter().flatten().copied().collect();
    let raw: Vec<f64> = claims.score.iter().flatten().copied().collect();
    let row = |block: &str, scores: Scores| ScoreRow {
        method: claims.method.clone(),
        rule: claims.rule.clone(),
        context: claims.context.clone(),
        horizon: claims.horizon,
        block: block.to_owned(),
        scores,
    };
    let mut rows = vec![row("all", score(&labels, &verdicts, &raw, |_| true))];
    for block in Block::ALL {
        let in_block = |i: usize| Block::of(&truth.state_names[i % ns]) == Some(block);
        if (0..labels.len()).any(in_block) {
            rows.push(row(block.name(), score(&labels, &verdicts, &raw, in_block)));
        }
    }
    Ok(rows)
}

/// A fixed-width table of score rows, for terminals and logs.
pub fn score_table(rows: &[ScoreRow]) -> String {
    let rate = |v: Option<f64>| v.map_or("   n/a".to_owned(), |v| format!("{v:>6.3}"));
    let mut out = format!(
        "{:<14} {:<14} {:<8} {:>2} {:>6} {:>6} {:>6} {:>4} {:>6} {:>6} {:>5} {:>4}\n",
        "method",
        "context",
        "block",
        "k",
        "prec",
        "recall",
        "F1",
        "SHD",
        "AUROC",
        "AP",
        "pairs",
        "rare"
    );
    for r in rows {
        let s = &r.scores;
        out.push_str(&format!(
            "{:<14} {:<14} {:<8} {:>2} {} {} {} {:>4} {} {} {:>5} {:>4}\n",
            r.method,
            r.context,
            r.block,
            r.horizon,
            rate(s.precision),
            rate(s.recall),
            rate(s.f1),
            s.shd,
            rate(s.auroc),
            rate(s.average_precision),
            s.scored,
            s.not_scored
        ));
    }
    out
}
