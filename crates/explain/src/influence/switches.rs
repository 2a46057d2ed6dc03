//! In-support evidence for a discrete action (the magnet command): the forward model is
//! probed only where the data switched the action, and its answer is calibrated against
//! negative controls.
//!
//! - CAI at random states probes a command switched in a few percent of the rows mostly
//!   where the data never switched it; there the network extrapolates (on the exp2 paper
//!   bag a 100-epoch FM's CAI gives a_mgt → ef_x 1.2 × its error; the magnet moves no
//!   joint). At the rows where the data did switch it, the switched value is what the
//!   model was trained on and the common value is seen in like states (the same discrete
//!   state, magnet on or off, [`ActionDraws`]): the contrast stays within the data.
//! - Even there a network answers a little to any input. The features the data rules out
//!   for the action (predicted to their resolution without it: the joints, under realized
//!   actions) are negative controls, as in epidemiology (Lipsitch et al. 2010): the model's
//!   largest effect on them is the size of its answer where there is provably none. An
//!   edge needs the 95 % bootstrap lower bound of its effect above κ × that level (and
//!   above κ), in units of the model's error on the feature.
//! - Without a negative control, or without switches, the evidence decides nothing.
//! - Judged per discrete state (stratum), against the model's error on that stratum's
//!   rows; an edge is claimed where any stratum claims it.

use std::collections::BTreeMap;

use causal_arm_discovery::DataTest;
use causal_arm_scoring::Verdict;

use super::*;

/// Switch observations a stratum needs before it is judged: fewer give bootstrap
/// intervals too wide to decide anything.
pub const MIN_STRATUM_OBSERVATIONS: usize = 20;

/// Seed offset of the draw of switch rows (independent of the other probes' draws).
const SWITCH_SEED: u64 = 0x5717_C4ED;

/// One edge's in-support evidence, in the stratum where it is strongest.
#[derive(Debug, Clone, PartialEq)]
pub struct SwitchEdge {
    /// Mean CAI effect over the model's error on the feature, in the stratum.
    pub score: f64,
    /// 95 % bootstrap interval of `score`.
    pub interval: [f64; 2],
    /// What the lower bound must exceed: κ × max(1, the negative controls' highest score).
    pub threshold: f64,
    /// The stratum, e.g. `mgt = 1`.
    pub stratum: String,
    /// Switch observations in the stratum.
    pub observations: usize,
}

impl SwitchEdge {
    /// Whether the evidence decides "drives".
    pub fn claimed(&self) -> bool {
        self.interval[0] > self.threshold
    }

    /// The evidence in words, for a verdict's reason.
    pub fn describe(&self) -> String {
        format!(
            "cai where the data switched this command ({}, {} rows probed): effect {:.2} x the model's error, 95 % lower bound {:.2} {} {:.2} (kappa x max(1, its largest effect on the features the data rules out))",
            self.stratum,
            self.observations,
            self.score,
            self.interval[0],
            if self.claimed() { "above" } else { "not above" },
            self.threshold
        )
    }

    /// Lower bound over threshold: > 1 exactly where claimed.
    fn margin(&self) -> f64 {
        if self.threshold > 0.0 {
            self.interval[0] / self.threshold
        } else {
            f64::INFINITY
        }
    }
}

/// Per action and feature, the in-support evidence of the discrete actions.
#[derive(Debug, Clone, Default)]
pub struct SwitchEvidence {
    /// `[action][state]`: `None` for a continuous action, or where nothing was judged.
    pub edges: Vec<Vec<Option<SwitchEdge>>>,
    /// Per action: why a discrete action has no evidence (empty where it has, or for a
    /// continuous action).
    pub missing: Vec<String>,
}

impl SwitchEvidence {
    /// The evidence on edge (a, k), if any was judged.
    pub fn edge(&self, a: usize, k: usize) -> Option<&SwitchEdge> {
        self.edges.get(a)?.get(k)?.as_ref()
    }
}

/// The in-support evidence of every discrete action of `data` under `explainer`'s forward
/// model, with the negative controls `data_test` (the one-step data test) rules out.
pub fn switch_evidence(
    explainer: &Explainer,
    data: &Dataset,
    settings: &InfluenceSettings,
    data_test: &DataTest,
) -> Result<SwitchEvidence> {
    check(settings, data.rows())?;
    let (na, ns) = (data.action_width(), data.state_width());
    let draws = ActionDraws::new(data);
    let mut evidence = SwitchEvidence {
        edges: vec![vec![None; ns]; na],
        missing: vec![String::new(); na],
    };
    let pool = error_pool(data, settings, 1);
    for j in (0..na).filter(|&j| draws.discrete[j].is_some()) {
        let controls = negative_controls(data_test, j);
        let switched = switch_rows(data, j);
        if controls.is_empty() {
            evidence.missing[j] = "the data rules out no feature for this action, so the model's answer where it has no effect cannot be measured (no negative control)".into();
            continue;
        }
        if switched.is_empty() {
            evidence.missing[j] = "the data never switches this action".into();
            continue;
        }
        let mut rng = StdRng::seed_from_u64(settings.seed ^ SWITCH_SEED);
        let take = settings.observations.min(switched.len());
        let rows = sample(&mut rng, switched.len(), take)
            .into_iter()
            .map(|i| switched[i])
            .collect();
        let effects = cai_effects_at(explainer, data, settings, Probe::at_rows(data, rows, rng))?;
        let strata = strata(data, &draws, &effects.rows);
        let mut judged = 0;
        for (key, members) in &strata {
            if members.len() < MIN_STRATUM_OBSERVATIONS {
                continue;
            }
            let stratum_rows: Vec<usize> = pool
                .iter()
                .copied()
                .filter(|&r| &ActionDraws::key(&draws.discrete_states, data.state(r)) == key)
                .collect();
            if stratum_rows.is_empty() {
                continue;
            }
            judged += 1;
            let error = feature_error(explainer.model(), data, &stratum_rows)?;
            let stratum = describe_stratum(data, &draws.discrete_states, key);
            let edges = judge_stratum(
                &effects,
                members,
                &error,
                settings,
                (j, &controls),
                &stratum,
            );
            for (k, edge) in edges.into_iter().enumerate() {
                let slot = &mut evidence.edges[j][k];
                if slot.as_ref().is_none_or(|old| edge.margin() > old.margin()) {
                    *slot = Some(edge);
                }
            }
        }
        if judged == 0 {
            evidence.missing[j] = format!(
                "fewer than {MIN_STRATUM_OBSERVATIONS} switches in every discrete state ({} switch rows)",
                switched.len()
            );
        }
    }
    Ok(evidence)
}

/// The features the data rules out for action `j` although they change (predicted to their
/// resolution without it): the negative controls.
pub fn negative_controls(data_test: &DataTest, j: usize) -> Vec<usize> {
    (0..data_test.state_names.len())
        .filter(|&k| data_test.changes[k] && data_test.decide(j, k).verdict == Verdict::DoesNot)
        .collect()
}

/// Rows where discrete action `j` takes a value other than its most common one.
pub fn switch_rows(data: &Dataset, j: usize) -> Vec<usize> {
    let mut counts: Vec<(f32, usize)> = Vec::new();
    for r in 0..data.rows() {
        let v = data.action(r)[j];
        match counts.iter_mut().find(|(u, _)| *u == v) {
            Some((_, n)) => *n += 1,
            None => counts.push((v, 1)),
        }
    }
    let Some(&(common, _)) = counts.iter().max_by_key(|(_, n)| *n) else {
        return Vec::new();
    };
    (0..data.rows())
        .filter(|&r| data.action(r)[j] != common)
        .collect()
}

/// Observation indices grouped by the discrete state of their row.
fn strata(data: &Dataset, draws: &ActionDraws, rows: &[usize]) -> BTreeMap<Vec<u32>, Vec<usize>> {
    let mut strata: BTreeMap<Vec<u32>, Vec<usize>> = BTreeMap::new();
    for (o, &r) in rows.iter().enumerate() {
        strata
            .entry(ActionDraws::key(&draws.discrete_states, data.state(r)))
            .or_default()
            .push(o);
    }
    strata
}

/// A stratum in words: the discrete state features that vary in the data, with their
/// values (`mgt = 1`); `all states` when none varies.
fn describe_stratum(data: &Dataset, columns: &[usize], key: &[u32]) -> String {
    let names = causal_arm_dataset::state_names(data.experiment);
    let words: Vec<String> = columns
        .iter()
        .zip(key)
        .filter(|&(&k, _)| distinct_values(data.rows(), |r| data.state(r)[k], 1).is_none())
        .map(|(&k, &bits)| format!("{} = {}", names[k], f32::from_bits(bits)))
        .collect();
    if words.is_empty() {
        "all states".into()
    } else {
        words.join(", ")
    }
}

/// Action `j`'s edges in the stratum named `stratum`: the calibrated score and interval of
/// every feature, against κ × max(1, the highest score among the negative controls
/// `controls`).
fn judge_stratum(
    effects: &Effects,
    members: &[usize],
    error: &[f64],
    settings: &InfluenceSettings,
    (j, controls): (usize, &[usize]),
    stratum: &str,
) -> Vec<SwitchEdge> {
    let claims = calibrated_claims(effects, members, error, settings, "", &[], &[]);
    let interval = claims.interval.unwrap_or_default();
    let level = controls
        .iter()
        .map(|&k| claims.score[j][k])
        .fold(0.0, f64::max);
    let threshold = settings.kappa * level.max(1.0);
    (0..effects.n_state)
        .map(|k| SwitchEdge {
            score: claims.score[j][k],
            interval: interval[j][k],
            threshold,
            stratum: stratum.to_owned(),
            observations: members.len(),
        })
        .collect()
}
