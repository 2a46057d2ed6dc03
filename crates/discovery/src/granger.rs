//! Granger-style tests of every action on every one-step change: least squares of Δs_k on
//! the design, and a test that the coefficients of a_j's block are all zero.

use causal_arm_dataset::{Dataset, action_names, state_names};
use causal_arm_scoring::{Decision, EdgeClaims, Verdict};
use statrs::distribution::{ContinuousCDF, Normal};

use crate::contexts::{ContextTest, intermittent_features, tests_within_contexts};
use crate::design::{Design, Terms};
use crate::fit::{PairTest, cluster_index, fit_and_test};
use crate::{Changes, DiscoveryError, Result};

/// How a test is run and decided.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GrangerSettings {
    /// The terms of each action's block.
    pub terms: Terms,
    /// Heteroscedasticity-robust (HC1) Wald test instead of the classical F test: the
    /// cube's change is 0 except while held, so its noise is anything but constant.
    pub robust: bool,
    /// Family-wise error rate over all action × state pairs (Bonferroni).
    pub alpha: f64,
    /// Transitions used at most (a seeded uniform draw beyond that).
    pub max_rows: usize,
    /// Seed of the draw.
    pub seed: u64,
    /// "Does not" when the change is predicted to within this many times its f32
    /// resolution without a_j (the three-valued test only).
    pub resolution_margin: f64,
    /// Also test the intermittent features within each context of the state
    /// ([`crate::ContextTest`], one-step changes only), Bonferroni over every test: an
    /// effect confined to one context is found there.
    #[serde(default)]
    pub within_contexts: bool,
}

impl GrangerSettings {
    /// A standard anchor: the classical F test of `terms`, Bonferroni at 5 %.
    pub fn anchor(terms: Terms) -> Self {
        Self {
            terms,
            robust: false,
            alpha: 0.05,
            max_rows: 50_000,
            seed: 0,
            resolution_margin: 0.0,
            within_contexts: false,
        }
    }

    /// The data half of the product's verdicts: action × state terms and squared actions,
    /// the robust Wald test at a family-wise 1 %, "does not" within 4 × the resolution.
    pub fn data_test() -> Self {
        Self {
            terms: Terms::Full,
            robust: true,
            alpha: 0.01,
            max_rows: 50_000,
            seed: 0,
            resolution_margin: 4.0,
            within_contexts: true,
        }
    }

    fn check(&self) -> Result<()> {
        if !(self.alpha > 0.0 && self.alpha < 1.0) {
            return Err(DiscoveryError::Options(format!(
                "the test's family-wise error rate must lie in (0, 1), got {}",
                self.alpha
            )));
        }
        if !(self.resolution_margin.is_finite() && self.resolution_margin >= 0.0) {
            return Err(DiscoveryError::Options(format!(
                "the resolution margin must be a non-negative number, got {}",
                self.resolution_margin
            )));
        }
        Ok(())
    }
}

/// The score of a denied edge in the data's claims: below every test's deviate.
const DENIED_SCORE: f64 = -41.0;

/// Every pair's test on one draw of the data, and what the data shows of each feature.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct DataTest {
    /// How it was run.
    pub settings: GrangerSettings,
    /// Action names (rows).
    pub action_names: Vec<String>,
    /// State feature names (columns).
    pub state_names: Vec<String>,
    /// h: the change tested is s(t+h) − s(t) (1: the one-step change).
    #[serde(default = "one_step")]
    pub horizon: usize,
    /// Transitions used.
    pub rows: usize,
    /// Transitions in the data.
    pub data_rows: usize,
    /// `[action][state]`.
    pub pairs: Vec<Vec<PairTest>>,
    /// Per feature: the f32 resolution of its values.
    pub resolution: Vec<f64>,
    /// Per feature: whether it changed in any transition used.
    pub changes: Vec<bool>,
    /// The same tests within each context of the state (with
    /// [`GrangerSettings::within_contexts`]; contexts too small to test are left out).
    #[serde(default)]
    pub within: Vec<ContextTest>,
    /// Per feature: whether it is intermittent (moves in at most
    /// [`crate::INTERMITTENT_SHARE`] of the rows), so tested within each context too.
    #[serde(default)]
    pub intermittent: Vec<bool>,
    /// The transitions the test needs when the data has fewer (twice the design's
    /// columns): then no pair is tested, and every edge of a feature that changed is
    /// undecided, saying so. Too little data is an answer, not an error.
    #[serde(default)]
    pub rows_needed: Option<usize>,
    /// Wall time, s.
    pub seconds: f64,
}

impl DataTest {
    /// Runs every pair's test on all of `data` (a draw of `settings.max_rows` of it).
    pub fn run(data: &Dataset, settings: &GrangerSettings) -> Result<Self> {
        let all: Vec<usize> = (0..data.rows()).collect();
        let changes = Changes::draw(data, &all, settings.max_rows, settings.seed);
        Self::on(&changes, data, settings)
    }

    /// Runs every pair's test of a(t) on s(t+`horizon`) − s(t), over the rows of `data` that
    /// start `horizon` consecutive transitions of one episode (a draw of
    /// `settings.max_rows` of them). The later actions are not controlled: motor babbling
    /// draws them afresh, so the test asks for a_j(t)'s total effect h steps on, through
    /// whatever the arm does next.
    pub fn run_ahead(data: &Dataset, horizon: usize, settings: &GrangerSettings) -> Result<Self> {
        let candidates = data.chainable_rows(horizon);
        if candidates.is_empty() {
            return Err(DiscoveryError::Options(format!(
                "none of the data's {} transitions starts {horizon} consecutive transitions inside an episode: a test {horizon} steps on needs longer episodes",
                data.rows()
            )));
        }
        let changes =
            Changes::draw_ahead(data, &candidates, horizon, settings.max_rows, settings.seed);
        Self::on(&changes, data, settings)
    }

    /// Runs every pair's test on `changes`, a draw of `data`'s transitions: several tests
    /// (the data test and the anchors) share one draw. Data too small for the design (2 ×
    /// its columns) tests no pair and says how many transitions it needs.
    pub fn on(changes: &Changes, data: &Dataset, settings: &GrangerSettings) -> Result<Self> {
        settings.check()?;
        let started = std::time::Instant::now();
        let design = Design::build(changes, settings.terms);
        let (n, p) = design.x.shape();
        let (na, ns) = (data.action_width(), data.state_width());
        // No rows leave no columns either (dependent ones are dropped).
        let (pairs, within, intermittent, rows_needed) = if n == 0 || n < 2 * p {
            let untested = vec![vec![PairTest::untested(0.0, n); ns]; na];
            (untested, Vec::new(), vec![false; ns], Some((2 * p).max(1)))
        } else {
            let (pairs, within, intermittent) = fit_all(changes, data, settings, &design);
            (pairs, within, intermittent, None)
        };
        Ok(Self {
            settings: settings.clone(),
            action_names: action_names(data.experiment),
            state_names: state_names(data.experiment),
            horizon: changes.horizon,
            rows: n,
            data_rows: data.rows(),
            pairs,
            within,
            intermittent,
            changes: (0..ns).map(|k| changes.ever_changes(k)).collect(),
            resolution: changes.resolution.clone(),
            rows_needed,
            seconds: started.elapsed().as_secs_f64(),
        })
    }

    /// Why no pair was tested, when the data is too small for the design.
    fn too_few_words(&self) -> Option<String> {
        let needed = self.rows_needed?;
        if self.rows == 0 {
            return Some("the data has no transitions to test".to_owned());
        }
        Some(format!(
            "the data test needs at least {needed} transitions for its design, the data has {}",
            self.rows
        ))
    }

    /// The change of s_k predicted to within this RMS is predicted to its resolution.
    fn resolution_bound(&self, k: usize) -> f64 {
        self.settings.resolution_margin * self.resolution[k]
    }

    /// The per-test significance level after the Bonferroni correction over every pair and
    /// every context tested.
    pub fn level(&self) -> f64 {
        let features = self.state_names.len()
            + self.within.len() * self.intermittent.iter().filter(|&&c| c).count();
        self.settings.alpha / (self.action_names.len() * features).max(1) as f64
    }

    /// The strongest test of a_j on s_k, over all rows or within a context, and the
    /// context's name (`None`: all rows).
    pub fn strongest(&self, a: usize, k: usize) -> (Option<&str>, &PairTest) {
        self.within
            .iter()
            .map(|c| (Some(c.context.as_str()), &c.pairs[a][k]))
            // A context where the change is predicted to its resolution without a_j has
            // no noise to test against: its statistic would be rounding.
            .filter(|(_, t)| t.dof > 0 && t.rms_without > self.resolution_bound(k))
            .fold((None, &self.pairs[a][k]), |best, next| {
                if next.1.z > best.1.z { next } else { best }
            })
    }

    /// The standard-normal deviate a pair's `z` must reach to be significant at
    /// [`Self::level`]: the unit of the test's evidence in a combined score.
    pub fn critical_z(&self) -> f64 {
        Normal::standard().inverse_cdf(1.0 - self.level())
    }

    /// The test in words, for the rules: which test of which block on which change.
    fn test_words(&self) -> String {
        let test = match (self.settings.robust, self.horizon) {
            (true, 1) => "robust Wald".to_owned(),
            (true, h) => format!(
                "cluster-robust Wald (stretches of {} steps)",
                crate::changes::CLUSTER_SPAN * h
            ),
            (false, _) => "F".to_owned(),
        };
        let change = match self.horizon {
            1 => "the one-step change".to_owned(),
            h => format!("s(t+{h}) - s(t)"),
        };
        format!(
            "{test} test of a_j's block ({}) on {change}",
            terms_words(self.settings.terms)
        )
    }

    /// The tests within contexts in words, for the rules (empty when none ran).
    fn context_words(&self) -> String {
        if self.within.is_empty() {
            return String::new();
        }
        let names = |it: &mut dyn Iterator<Item = &str>| it.collect::<Vec<_>>().join(", ");
        format!(
            " over all rows, and for the intermittent features ({}) within each context ({}) too",
            names(
                &mut self
                    .state_names
                    .iter()
                    .zip(&self.intermittent)
                    .filter(|(_, i)| **i)
                    .map(|(n, _)| n.as_str())
            ),
            names(&mut self.within.iter().map(|c| c.context.as_str()))
        )
    }

    /// Two-valued claims of the standard anchor: drives where p is below the corrected level.
    pub fn anchor_claims(&self, method: &str) -> EdgeClaims {
        let level = self.level();
        let mut claims = self.claims_frame(method);
        if let Some(words) = self.too_few_words() {
            claims.rule = format!("not run: {words}; no edge claimed");
            return claims;
        }
        claims.rule = format!(
            "drives when the {} has p < {:.1e} (family-wise {} with Bonferroni over {} pairs), {} transitions",
            self.test_words(),
            level,
            self.settings.alpha,
            self.action_names.len() * self.state_names.len(),
            self.rows
        );
        for (a, row) in self.pairs.iter().enumerate() {
            for (k, t) in row.iter().enumerate() {
                claims.drives[a][k] = self.changes[k] && t.dof > 0 && t.p_value < level;
            }
        }
        claims
    }

    /// The three-valued rule in words, for a test that ran.
    fn rule_words(&self) -> String {
        format!(
            "data: drives when the {}{} has p < {:.1e} (family-wise {}, Bonferroni over every test); does not when s_k never changes or is predicted without a_j to within {} x its f32 resolution; else undecided ({} of {} transitions)",
            self.test_words(),
            self.context_words(),
            self.level(),
            self.settings.alpha,
            self.settings.resolution_margin,
            self.rows,
            self.data_rows
        )
    }

    /// Three-valued claims: drives where the test decides, does not where the feature
    /// never changes or is predicted to its resolution without the action, else undecided.
    pub fn claims(&self, method: &str) -> EdgeClaims {
        let mut claims = self.claims_frame(method);
        claims.rule = match self.too_few_words() {
            Some(words) => {
                format!("data: not run: {words}; does not where s_k never changed, else undecided")
            }
            None => self.rule_words(),
        };
        let decisions: Vec<Vec<Decision>> = (0..self.action_names.len())
            .map(|a| {
                (0..self.state_names.len())
                    .map(|k| self.decide(a, k))
                    .collect()
            })
            .collect();
        for (a, row) in decisions.iter().enumerate() {
            for (k, d) in row.iter().enumerate() {
                claims.drives[a][k] = d.verdict == Verdict::Drives;
                // A denial is the strongest evidence against an edge, whatever a test on
                // rounding noise says: it ranks last.
                if d.verdict == Verdict::DoesNot {
                    claims.score[a][k] = DENIED_SCORE;
                }
            }
        }
        claims.decisions = Some(decisions);
        claims
    }

    /// The data's verdict on one pair, with its reason.
    pub fn decide(&self, a: usize, k: usize) -> Decision {
        let t = &self.pairs[a][k];
        let (action, state) = (&self.action_names[a], &self.state_names[k]);
        let bound = self.resolution_bound(k);
        let decision = |verdict, reason: String, to_decide: &str| Decision {
            verdict,
            source: if verdict == Verdict::Undecided {
                ""
            } else {
                "data"
            }
            .into(),
            reason,
            to_decide: to_decide.into(),
        };
        if !self.changes[k] && self.rows > 0 {
            return decision(
                Verdict::DoesNot,
                format!(
                    "{state} never changed in {} transitions while {action} varied",
                    self.rows
                ),
                "",
            );
        }
        if let (Some(needed), Some(words)) = (self.rows_needed, self.too_few_words()) {
            return decision(
                Verdict::Undecided,
                words,
                &format!(
                    "{} more transitions (the data test), or a forward model whose error on this feature is below the effect",
                    needed - self.rows
                ),
            );
        }
        if t.dof == 0 {
            return decision(
                Verdict::Undecided,
                format!("{action} never varied in the data"),
                "babbling that varies this action",
            );
        }
        if t.rms_without <= bound {
            return decision(
                Verdict::DoesNot,
                format!(
                    "without {action} the change of {state} is predicted to {:.1e} RMS, within {} x its f32 resolution {:.1e}",
                    t.rms_without, self.settings.resolution_margin, self.resolution[k]
                ),
                "",
            );
        }
        let (context, best) = self.strongest(a, k);
        if best.p_value < self.level() {
            return decision(
                Verdict::Drives,
                format!(
                    "p = {:.1e} < {:.1e} ({} columns, z = {:.1}{}); effect std {:.2e}",
                    best.p_value,
                    self.level(),
                    best.dof,
                    best.z,
                    context.map_or(String::new(), |c| format!(", within context {c}")),
                    best.effect
                ),
                "",
            );
        }
        decision(
            Verdict::Undecided,
            format!(
                "not significant in the data (p = {:.2}, effect std {:.1e} vs residual {:.1e}{})",
                t.p_value,
                t.effect,
                t.rms_without,
                context.map_or(String::new(), |c| format!(
                    "; within context {c}: p = {:.1e}",
                    best.p_value
                ))
            ),
            "more transitions (the data test), or a forward model whose error on this feature is below the effect",
        )
    }

    fn claims_frame(&self, method: &str) -> EdgeClaims {
        let (na, ns) = (self.action_names.len(), self.state_names.len());
        EdgeClaims {
            method: method.to_owned(),
            rule: String::new(),
            context: causal_arm_dataset::Context::ALL.to_owned(),
            horizon: self.horizon,
            observations: self.rows,
            action_names: self.action_names.clone(),
            state_names: self.state_names.clone(),
            score: (0..na)
                .map(|a| (0..ns).map(|k| self.strongest(a, k).1.z).collect())
                .collect(),
            interval: None,
            drives: vec![vec![false; ns]; na],
            decisions: None,
        }
    }
}

/// Every pair's test over all rows of `changes` on `design`, beside the intermittent
/// features' tests within each context (one step on only: h steps on, the scripted
/// phases' later commands depend on the context, which then confounds the test); and
/// which features are intermittent.
fn fit_all(
    changes: &Changes,
    data: &Dataset,
    settings: &GrangerSettings,
    design: &Design,
) -> (Vec<Vec<PairTest>>, Vec<ContextTest>, Vec<bool>) {
    let clusters = changes.clusters.as_deref().map(cluster_index);
    let intermittent = if settings.within_contexts && changes.horizon == 1 {
        intermittent_features(changes, settings.resolution_margin)
    } else {
        vec![false; data.state_width()]
    };
    let (pairs, within) = rayon::join(
        || {
            let y = changes.delta_matrix();
            fit_and_test(design, &y, settings.robust, clusters.as_ref())
        },
        || match intermittent.contains(&true) {
            true => tests_within_contexts(changes, data, settings, &intermittent),
            false => Vec::new(),
        },
    );
    (pairs, within, intermittent)
}

/// The standard anchor's two-valued claims: the classical F test of `terms`, Bonferroni at
/// 5 %, named `method`.
pub fn granger_claims(data: &Dataset, terms: Terms, method: &str) -> Result<EdgeClaims> {
    Ok(DataTest::run(data, &GrangerSettings::anchor(terms))?.anchor_claims(method))
}

fn one_step() -> usize {
    1
}

fn terms_words(terms: Terms) -> &'static str {
    match terms {
        Terms::Linear => "a_j alone, the state as control",
        Terms::Interaction => "a_j and a_j x s, the state as control",
        Terms::Full => {
            "a_j, a_j^2, hinges of a_j at its 5, 20, 80 and 95 % quantiles and a_j x s, the state as control"
        }
    }
}
