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
    let na = truth.action_names.len();
    let verdicts: Vec<_> = (0..na * ns)
        .map(|i| claims.verdict(i / ns, i % ns))
        .collect();
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

/// The horizons k of s(t+k) at which `truth` has matrices, ascending.
pub fn truth_horizons(truth: &Truth) -> Vec<usize> {
    let mut horizons: Vec<usize> = truth.matrices.iter().map(|m| m.horizon).collect();
    horizons.sort_unstable();
    horizons.dedup();
    horizons
}

/// Refuses `horizon` when `truth` has no matrices for it, naming the horizons it has:
/// claims at s(t+k) can only be scored against the simulator's answer at the same k.
/// Callers check before computing claims, as with [`check_names`].
pub fn check_horizon(truth: &Truth, horizon: usize) -> Result<(), TruthError> {
    let horizons = truth_horizons(truth);
    if horizons.contains(&horizon) {
        return Ok(());
    }
    let listed: Vec<String> = horizons.iter().map(|h| h.to_string()).collect();
    Err(TruthError::File {
        path: truth.bag.clone().into(),
        problem: format!(
            "the truth has no matrices at horizon {horizon} (its horizons: {}); write one with `causal-arm intervene … --horizon {horizon}`",
            listed.join(", ")
        ),
    })
}

/// Scores claims at their own horizons: claims about s(t+k) against the truth's matrix of
/// the same context at k ([`score_claims`] per claim set). Every horizon is checked first,
/// so a truth that lacks one is refused before anything is scored.
pub fn score_horizons(truth: &Truth, claims: &[EdgeClaims]) -> Result<Vec<ScoreRow>, TruthError> {
    for c in claims {
        check_horizon(truth, c.horizon)?;
    }
    let mut rows = Vec::new();
    for c in claims {
        rows.extend(score_claims(truth, c)?);
    }
    Ok(rows)
}

/// A fixed-width table of score rows, for terminals and logs.
pub fn score_table(rows: &[ScoreRow]) -> String {
    let rate = |v: Option<f64>| v.map_or("   n/a".to_owned(), |v| format!("{v:>6.3}"));
    let mut out = format!(
        "{:<14} {:<14} {:<8} {:>2} {:>6} {:>6} {:>6} {:>4} {:>6} {:>6} {:>5} {:>4} {:>5} {:>6}\n",
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
        "rare",
        "undec",
        "denied"
    );
    for r in rows {
        let s = &r.scores;
        out.push_str(&format!(
            "{:<14} {:<14} {:<8} {:>2} {} {} {} {:>4} {} {} {:>5} {:>4} {:>5} {:>6}\n",
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
            s.not_scored,
            s.undecided,
            s.false_denials
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{EdgeMatrix, FORMAT, Plan};

    /// Two actions × two features; at k = 1 a0 moves theta0 only, at k = 2 also ef_x (the
    /// arm has moved on with the changed joint).
    fn truth() -> Truth {
        let matrix = |horizon: usize, active: [[f64; 2]; 2]| EdgeMatrix {
            context: "all".into(),
            horizon,
            states: 100,
            active_fraction: active.iter().map(|r| r.to_vec()).collect(),
            mean_effect: vec![vec![0.0; 2]; 2],
            max_effect: vec![vec![0.0; 2]; 2],
        };
        Truth {
            format: FORMAT.into(),
            experiment: "exp1".into(),
            bag: "bag".into(),
            action_names: vec!["a0".into(), "a1".into()],
            state_names: vec!["theta0".into(), "ef_x".into()],
            plan: Plan {
                horizon: 2,
                ..Plan::default()
            },
            joint_deltas: vec![],
            resimulated_steps: 0,
            noise_floor: 0.0,
            feature_step_std: vec![0.1, 0.1],
            seconds: 0.0,
            matrices: vec![
                matrix(1, [[1.0, 0.0], [0.0, 0.0]]),
                matrix(2, [[1.0, 0.5], [0.0, 0.0]]),
            ],
        }
    }

    fn claims(horizon: usize) -> EdgeClaims {
        EdgeClaims {
            method: "cai/err".into(),
            rule: "r".into(),
            context: "all".into(),
            horizon,
            observations: 10,
            action_names: vec!["a0".into(), "a1".into()],
            state_names: vec!["theta0".into(), "ef_x".into()],
            score: vec![vec![3.0, 2.0], vec![0.1, 0.2]],
            interval: None,
            drives: vec![vec![true, true], vec![false, false]],
            decisions: None,
        }
    }

    #[test]
    fn claims_are_scored_against_the_truth_at_their_own_horizon() {
        let truth = truth();
        assert_eq!(truth_horizons(&truth), vec![1, 2]);
        let rows = score_horizons(&truth, &[claims(1), claims(2)]).unwrap();
        let overall = |k: usize| {
            rows.iter()
                .find(|r| r.horizon == k && r.block == "all")
                .map(|r| r.scores.clone())
                .unwrap()
        };
        // At k = 1, a0 → ef_x is absent: one false claim.
        let one = overall(1);
        assert_eq!(
            (one.precision, one.recall, one.shd),
            (Some(0.5), Some(1.0), 1)
        );
        // At k = 2 the same verdicts are exactly right.
        let two = overall(2);
        assert_eq!(
            (two.precision, two.recall, two.shd),
            (Some(1.0), Some(1.0), 0)
        );
        assert_eq!(two.auroc, Some(1.0));
        // Blocks are scored per horizon as at one step.
        assert!(rows.iter().any(|r| r.horizon == 2 && r.block == "ef"));
    }

    #[test]
    fn a_horizon_the_truth_lacks_is_refused_by_name() {
        let truth = truth();
        let err = score_horizons(&truth, &[claims(1), claims(3)])
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("no matrices at horizon 3") && err.contains("its horizons: 1, 2"),
            "{err}"
        );
        assert!(check_horizon(&truth, 2).is_ok());
        assert!(check_horizon(&truth, 0).is_err());
    }
}
