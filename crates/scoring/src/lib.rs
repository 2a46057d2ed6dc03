//! Scores of causal claims against a ground truth.
//!
//! A claim set says, for every (action, state feature) pair, whether the action drives the
//! feature (a verdict) and how strongly (a raw score, higher = more likely an edge). The
//! truth labels each pair present, absent or not scored (an edge too rare to demand). The
//! verdicts give precision, recall, F1 and the structural Hamming distance (on a bipartite
//! action → state graph: false edges plus missed edges); the raw scores give the
//! threshold-free AUROC and average precision. Pure functions, no I/O.

#![warn(missing_docs)]

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Counts and rates of one comparison. Rates are `None` where undefined (no claims for
/// precision, no true edges for recall, one class missing for AUROC and AP).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Scores {
    /// Pairs scored (present or absent in the truth).
    pub scored: usize,
    /// Pairs left out (rare in the truth).
    pub not_scored: usize,
    /// Claimed and present.
    pub true_positives: usize,
    /// Claimed and absent.
    pub false_positives: usize,
    /// Present but not claimed.
    pub false_negatives: usize,
    /// Scored pairs left undecided (neither claimed nor denied; counted in the false
    /// negatives where present).
    #[serde(default)]
    pub undecided: usize,
    /// Present pairs the method denied outright ("does not"): confident wrong negatives.
    #[serde(default)]
    pub false_denials: usize,
    /// TP / (TP + FP).
    pub precision: Option<f64>,
    /// TP / (TP + FN).
    pub recall: Option<f64>,
    /// Harmonic mean of precision and recall.
    pub f1: Option<f64>,
    /// Structural Hamming distance: FP + FN.
    pub shd: usize,
    /// Probability that a random present pair scores above a random absent one (ties ½).
    pub auroc: Option<f64>,
    /// Area under the precision–recall curve as a step function (sklearn's definition).
    pub average_precision: Option<f64>,
}

/// Scores `verdicts` and raw `scores` against `truth` (`Some(true)` present, `Some(false)`
/// absent, `None` not scored), over the pairs `include` selects. All slices are aligned.
/// An undecided pair counts as not claimed; a denied present pair is also a false denial.
pub fn score(
    truth: &[Option<bool>],
    verdicts: &[Verdict],
    scores: &[f64],
    include: impl Fn(usize) -> bool,
) -> Scores {
    let (mut tp, mut fp, mut fn_, mut not_scored) = (0, 0, 0, 0);
    let (mut undecided, mut false_denials) = (0, 0);
    let mut ranked: Vec<(f64, bool)> = Vec::new();
    for i in (0..truth.len()).filter(|&i| include(i)) {
        let Some(present) = truth[i] else {
            not_scored += 1;
            continue;
        };
        ranked.push((scores[i], present));
        let claimed = verdicts[i] == Verdict::Drives;
        undecided += usize::from(verdicts[i] == Verdict::Undecided);
        false_denials += usize::from(verdicts[i] == Verdict::DoesNot && present);
        match (claimed, present) {
            (true, true) => tp += 1,
            (true, false) => fp += 1,
            (false, true) => fn_ += 1,
            (false, false) => {}
        }
    }
    let ratio = |a: usize, b: usize| (b > 0).then(|| a as f64 / b as f64);
    let precision = ratio(tp, tp + fp);
    let recall = ratio(tp, tp + fn_);
    let f1 = match (precision, recall) {
        (Some(p), Some(r)) if p + r > 0.0 => Some(2.0 * p * r / (p + r)),
        (Some(_), Some(_)) => Some(0.0),
        _ => None,
    };
    Scores {
        scored: ranked.len(),
        not_scored,
        true_positives: tp,
        false_positives: fp,
        false_negatives: fn_,
        undecided,
        false_denials,
        precision,
        recall,
        f1,
        shd: fp + fn_,
        auroc: auroc(&ranked),
        average_precision: average_precision(&ranked),
    }
}

/// AUROC of `(score, positive)` pairs by the rank-sum (Mann–Whitney) statistic, ties at
/// half weight. `None` without both classes.
pub fn auroc(ranked: &[(f64, bool)]) -> Option<f64> {
    let pos = ranked.iter().filter(|r| r.1).count();
    let neg = ranked.len() - pos;
    if pos == 0 || neg == 0 {
        return None;
    }
    let mut sorted = ranked.to_vec();
    sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
    // Sum of the positives' (tie-averaged) ranks, ranks from 1.
    let mut rank_sum = 0.0;
    let mut i = 0;
    while i < sorted.len() {
        let j = (i..sorted.len())
            .find(|&j| sorted[j].0 != sorted[i].0)
            .unwrap_or(sorted.len());
        let average_rank = (i + 1 + j) as f64 / 2.0;
        rank_sum += average_rank * sorted[i..j].iter().filter(|r| r.1).count() as f64;
        i = j;
    }
    let u = rank_sum - (pos * (pos + 1)) as f64 / 2.0;
    Some(u / (pos * neg) as f64)
}

/// Average precision: Σ over distinct score thresholds, high to low, of
/// (recall gained) × (precision there). `None` without a positive.
pub fn average_precision(ranked: &[(f64, bool)]) -> Option<f64> {
    let pos = ranked.iter().filter(|r| r.1).count();
    if pos == 0 {
        return None;
    }
    let mut sorted = ranked.to_vec();
    sorted.sort_by(|a, b| b.0.total_cmp(&a.0));
    let (mut tp, mut seen, mut ap, mut last_recall) = (0usize, 0usize, 0.0, 0.0);
    let mut i = 0;
    while i < sorted.len() {
        let j = (i..sorted.len())
            .find(|&j| sorted[j].0 != sorted[i].0)
            .unwrap_or(sorted.len());
        tp += sorted[i..j].iter().filter(|r| r.1).count();
        seen += j - i;
        let recall = tp as f64 / pos as f64;
        ap += (recall - last_recall) * tp as f64 / seen as f64;
        last_recall = recall;
        i = j;
    }
    Some(ap)
}

/// What a method claims about every (action, state feature) pair in one context, at one
/// horizon (s(t+k)). `score`, `drives` and `interval` are `[action][state]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EdgeClaims {
    /// Method that produced the raw scores (`cai`, `deep`, `kernel`).
    pub method: String,
    /// Decision rule that turned them into verdicts, in words.
    pub rule: String,
    /// Context of the observations (`all`, `holding`, …).
    pub context: String,
    /// k of s(t+k).
    pub horizon: usize,
    /// Observations the scores average over.
    pub observations: usize,
    /// Action names (rows).
    pub action_names: Vec<String>,
    /// State feature names (columns).
    pub state_names: Vec<String>,
    /// Raw score, higher = stronger evidence of an edge (threshold-free metrics use it).
    pub score: Vec<Vec<f64>>,
    /// 95 % bootstrap interval of the score over observations, where the method has one.
    pub interval: Option<Vec<Vec<[f64; 2]>>>,
    /// The verdict: the action drives the feature.
    pub drives: Vec<Vec<bool>>,
    /// Three-valued verdicts with their reasons, where the method decides "does not" apart
    /// from "undecided" (`None`: a two-valued rule, where not claimed means does not).
    /// `drives` is always `verdict == Drives`, so readers of two-valued claims keep working.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub decisions: Option<Vec<Vec<Decision>>>,
}

/// What a method concludes about one edge. Only evidence decides "drives" or "does not";
/// where it does not, the honest answer is "undecided".
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Verdict {
    /// The action changes the feature.
    Drives,
    /// The evidence bounds the action's effect on the feature below what the data resolves.
    DoesNot,
    /// Neither is shown by the evidence at hand.
    Undecided,
}

impl Verdict {
    /// Name in tables and files.
    pub fn name(self) -> &'static str {
        match self {
            Verdict::Drives => "drives",
            Verdict::DoesNot => "does-not",
            Verdict::Undecided => "undecided",
        }
    }
}

/// A verdict with the evidence behind it, so a user can see why an edge is (not) claimed
/// and what would settle an undecided one.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Decision {
    /// The verdict.
    pub verdict: Verdict,
    /// Which evidence decided it (`data`, `model`, `data+model`, or empty when undecided).
    pub source: String,
    /// Why, in words, with the figures that decided.
    pub reason: String,
    /// For an undecided edge: what would decide it (more steps, more epochs, …).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub to_decide: String,
}

impl EdgeClaims {
    /// The verdict on edge (`a`, `k`): the three-valued decision where the method makes
    /// one, else drives or does not by the two-valued rule.
    pub fn verdict(&self, a: usize, k: usize) -> Verdict {
        match &self.decisions {
            Some(d) => d[a][k].verdict,
            None if self.drives[a][k] => Verdict::Drives,
            None => Verdict::DoesNot,
        }
    }

    /// How many edges get each verdict: (drives, does not, undecided).
    pub fn verdict_counts(&self) -> (usize, usize, usize) {
        let mut counts = (0, 0, 0);
        for a in 0..self.action_names.len() {
            for k in 0..self.state_names.len() {
                match self.verdict(a, k) {
                    Verdict::Drives => counts.0 += 1,
                    Verdict::DoesNot => counts.1 += 1,
                    Verdict::Undecided => counts.2 += 1,
                }
            }
        }
        counts
    }

    /// The verdicts for a terminal: per action what it drives, the counts, and the
    /// commonest reasons for "undecided" (their first clause, with how many edges), so a
    /// user sees why nothing was claimed.
    pub fn summary(&self) -> String {
        let mut out = String::new();
        for (a, action) in self.action_names.iter().enumerate() {
            let driven: Vec<&str> = (0..self.state_names.len())
                .filter(|&k| self.drives[a][k])
                .map(|k| self.state_names[k].as_str())
                .collect();
            let driven = match driven.is_empty() {
                true => "nothing".to_owned(),
                false => driven.join(", "),
            };
            out += &format!("{action:<6} drives ({}) {driven}\n", self.method);
        }
        let (drives, does_not, undecided) = self.verdict_counts();
        out += &format!(
            "verdicts ({}): {drives} drives, {does_not} does not, {undecided} undecided\n",
            self.method
        );
        for (reason, count) in self.undecided_reasons().into_iter().take(3) {
            out += &format!("  undecided ({count}): {reason}\n");
        }
        out
    }

    /// The reasons for "undecided", by their first clause, commonest first.
    pub fn undecided_reasons(&self) -> Vec<(String, usize)> {
        let mut counts: BTreeMap<String, usize> = BTreeMap::new();
        for row in self.decisions.iter().flatten() {
            for d in row.iter().filter(|d| d.verdict == Verdict::Undecided) {
                let clause = d.reason.split([';', '(']).next().unwrap_or_default();
                *counts.entry(clause.trim().to_owned()).or_default() += 1;
            }
        }
        let mut reasons: Vec<(String, usize)> = counts.into_iter().collect();
        reasons.sort_by_key(|r| std::cmp::Reverse(r.1));
        reasons
    }

    /// Whether `action` drives `state` (false for unknown names).
    pub fn drives(&self, action: &str, state: &str) -> bool {
        let a = self.action_names.iter().position(|n| n == action);
        let s = self.state_names.iter().position(|n| n == state);
        matches!((a, s), (Some(a), Some(s)) if self.drives[a][s])
    }

    /// Checks that every matrix is `[action][state]`.
    pub fn check_shape(&self) -> Result<(), String> {
        let (na, ns) = (self.action_names.len(), self.state_names.len());
        fn bad<T>(m: &[Vec<T>], na: usize, ns: usize) -> bool {
            m.len() != na || m.iter().any(|r| r.len() != ns)
        }
        if bad(&self.score, na, ns)
            || bad(&self.drives, na, ns)
            || self.interval.as_ref().is_some_and(|i| bad(i, na, ns))
            || self.decisions.as_ref().is_some_and(|d| bad(d, na, ns))
        {
            return Err(format!(
                "claims of {} ({}) are not {na} actions × {ns} states",
                self.method, self.context
            ));
        }
        if let Some(d) = &self.decisions
            && (0..na)
                .any(|a| (0..ns).any(|k| (d[a][k].verdict == Verdict::Drives) != self.drives[a][k]))
        {
            return Err(format!(
                "claims of {} ({}): drives disagrees with the verdicts",
                self.method, self.context
            ));
        }
        Ok(())
    }
}

/// The state-feature groups edges are scored by (the action → θ, → ef, → object,
/// → magnet), from a feature's name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Block {
    /// Joint positions `theta*`.
    Theta,
    /// Effector pose `ef_*`.
    Ef,
    /// Cube pose and colour `o_*`.
    Object,
    /// Magnet state `mgt`.
    Magnet,
}

impl Block {
    /// All blocks, in report order.
    pub const ALL: [Block; 4] = [Block::Theta, Block::Ef, Block::Object, Block::Magnet];

    /// The block of a state feature, by the project's naming (DESIGN "Data model").
    pub fn of(state: &str) -> Option<Block> {
        if state.starts_with("theta") {
            Some(Block::Theta)
        } else if state.starts_with("ef_") {
            Some(Block::Ef)
        } else if state.starts_with("o_") {
            Some(Block::Object)
        } else if state == "mgt" {
            Some(Block::Magnet)
        } else {
            None
        }
    }

    /// Name in tables.
    pub fn name(self) -> &'static str {
        match self {
            Block::Theta => "theta",
            Block::Ef => "ef",
            Block::Object => "object",
            Block::Magnet => "magnet",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_and_rates_follow_their_definitions() {
        let truth = [Some(true), Some(true), Some(false), Some(false), None];
        use Verdict::{DoesNot, Drives, Undecided};
        let verdicts = [Drives, Undecided, Drives, DoesNot, Drives];
        let scores = [0.9, 0.2, 0.5, 0.1, 0.7];
        let s = score(&truth, &verdicts, &scores, |_| true);
        assert_eq!(
            (s.true_positives, s.false_positives, s.false_negatives),
            (1, 1, 1)
        );
        assert_eq!((s.scored, s.not_scored, s.shd), (4, 1, 2));
        assert_eq!((s.undecided, s.false_denials), (1, 0));
        let denied = score(&truth, &[DoesNot; 5], &scores, |_| true);
        assert_eq!((denied.false_denials, denied.undecided), (2, 0));
        assert_eq!(
            (s.precision, s.recall, s.f1),
            (Some(0.5), Some(0.5), Some(0.5))
        );
        // Positives 0.9, 0.2 vs negatives 0.5, 0.1: pairs won 0.9>0.5, 0.9>0.1, 0.2>0.1.
        assert_eq!(s.auroc, Some(0.75));
        // Ranking 0.9(+) 0.5(−) 0.2(+) 0.1(−): AP = ½·1 + ½·⅔.
        assert!((s.average_precision.unwrap() - (0.5 + 1.0 / 3.0)).abs() < 1e-12);
    }

    #[test]
    fn perfect_ties_and_empty_cases() {
        let ranked = [(1.0, true), (1.0, false)];
        assert_eq!(auroc(&ranked), Some(0.5));
        assert_eq!(average_precision(&ranked), Some(0.5));
        assert_eq!(auroc(&[(1.0, true)]), None);
        assert_eq!(average_precision(&[(1.0, false)]), None);
        let s = score(&[Some(false)], &[Verdict::DoesNot], &[0.0], |_| true);
        assert_eq!((s.precision, s.recall, s.f1), (None, None, None));
        let perfect = score(
            &[Some(true), Some(false)],
            &[Verdict::Drives, Verdict::DoesNot],
            &[2.0, 1.0],
            |_| true,
        );
        assert_eq!(
            (perfect.auroc, perfect.average_precision, perfect.f1),
            (Some(1.0), Some(1.0), Some(1.0))
        );
    }

    #[test]
    fn blocks_follow_feature_names() {
        assert_eq!(Block::of("theta3"), Some(Block::Theta));
        assert_eq!(Block::of("ef_rz"), Some(Block::Ef));
        assert_eq!(Block::of("o_B"), Some(Block::Object));
        assert_eq!(Block::of("mgt"), Some(Block::Magnet));
        assert_eq!(Block::of("speed"), None);
    }
}
