//! The changes every data-level test explains: one step, Δs(t) = s(t+1) − s(t)
//! ([`Dataset::change`]), or h steps on, s(t+h) − s(t) ([`Dataset::change_ahead`]), on a
//! seeded draw of the transitions.

use causal_arm_dataset::{Dataset, angular_features};
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand::seq::index::sample;

/// A draw of transitions with their states, actions and changes as f64 columns.
#[derive(Debug, Clone)]
pub struct Changes {
    /// Dataset rows drawn, ascending.
    pub rows: Vec<usize>,
    /// s(t) per row, `[row][state]`.
    pub states: Vec<Vec<f64>>,
    /// Whether the magnet held the cube in s(t), per row (1 or 0): observed before the
    /// action, so as legitimate a control as the state, and the context in which the
    /// joints move the cube.
    pub holding: Vec<f64>,
    /// a(t) per row, `[row][action]`.
    pub actions: Vec<Vec<f64>>,
    /// s(t+h) − s(t) per row, `[row][state]`.
    pub deltas: Vec<Vec<f64>>,
    /// h: how many steps on the change is taken (1: the one-step change).
    pub horizon: usize,
    /// For h > 1, per row, the stretch of its episode it lies in ([`CLUSTER_SPAN`] × h
    /// steps): the changes of rows less than h apart share steps, so their errors are
    /// correlated, and the robust test sums its scores over each stretch (cluster-robust)
    /// instead of trusting rows to be independent. `None` for one-step changes.
    pub clusters: Option<Vec<u64>>,
    /// Per feature: whether it is an Euler angle.
    pub angular: Vec<bool>,
    /// Per feature: the f32 resolution of its recorded values (2⁻²³ × RMS of s_k(t+h)),
    /// the finest change the data can show.
    pub resolution: Vec<f64>,
}

/// Length of a cluster of h-step changes, in multiples of h: windows that overlap across a
/// cluster's border (at most h − 1 of every `CLUSTER_SPAN` × h rows) are the only
/// correlation the cluster-robust test leaves out.
pub const CLUSTER_SPAN: usize = 10;

impl Changes {
    /// At most `max_rows` of the transitions `candidates` of `data`, drawn uniformly with
    /// `seed` (all of them when there are fewer).
    pub fn draw(data: &Dataset, candidates: &[usize], max_rows: usize, seed: u64) -> Self {
        Self::draw_ahead(data, candidates, 1, max_rows, seed)
    }

    /// As [`Self::draw`], for the change `horizon` steps on: `candidates` must start that
    /// many consecutive transitions ([`Dataset::chainable_rows`]).
    pub fn draw_ahead(
        data: &Dataset,
        candidates: &[usize],
        horizon: usize,
        max_rows: usize,
        seed: u64,
    ) -> Self {
        let horizon = horizon.max(1);
        let mut rows: Vec<usize> = if candidates.len() <= max_rows {
            candidates.to_vec()
        } else {
            let mut rng = StdRng::seed_from_u64(seed);
            let picked = sample(&mut rng, candidates.len(), max_rows);
            picked.into_iter().map(|i| candidates[i]).collect()
        };
        rows.sort_unstable();
        let span = (CLUSTER_SPAN * horizon) as u64;
        let clusters = (horizon > 1).then(|| {
            rows.iter()
                .map(|&r| (u64::from(data.episodes[r]) << 32) | (u64::from(data.steps[r]) / span))
                .collect()
        });
        let to_f64 = |v: &[f32]| v.iter().map(|&x| x as f64).collect::<Vec<f64>>();
        let states = rows.iter().map(|&r| to_f64(data.state(r))).collect();
        let actions = rows.iter().map(|&r| to_f64(data.action(r))).collect();
        let holding = rows.iter().map(|&r| f64::from(data.holding[r])).collect();
        let deltas = rows
            .iter()
            .map(|&r| data.change_ahead(r, horizon))
            .collect();
        let n = rows.len().max(1) as f64;
        let resolution = (0..data.state_width())
            .map(|k| {
                let ms = rows
                    .iter()
                    .map(|&r| (data.next_state(r + horizon - 1)[k] as f64).powi(2))
                    .sum::<f64>()
                    / n;
                ms.sqrt() * f32::EPSILON as f64
            })
            .collect();
        Self {
            angular: angular_features(data.experiment),
            rows,
            states,
            holding,
            actions,
            deltas,
            horizon,
            clusters,
            resolution,
        }
    }

    /// The drawn transitions at positions `members` (ascending) of this draw, with the
    /// draw's resolution: a context's share of it.
    pub fn subset(&self, members: &[usize]) -> Self {
        let pick = |v: &[Vec<f64>]| members.iter().map(|&i| v[i].clone()).collect();
        Self {
            rows: members.iter().map(|&i| self.rows[i]).collect(),
            states: pick(&self.states),
            holding: members.iter().map(|&i| self.holding[i]).collect(),
            actions: pick(&self.actions),
            deltas: pick(&self.deltas),
            horizon: self.horizon,
            clusters: self
                .clusters
                .as_ref()
                .map(|c| members.iter().map(|&i| c[i]).collect()),
            angular: self.angular.clone(),
            resolution: self.resolution.clone(),
        }
    }

    /// The changes as a matrix, `[row][state]`: what the tests regress.
    pub(crate) fn delta_matrix(&self) -> nalgebra::DMatrix<f64> {
        let ns = self.resolution.len();
        nalgebra::DMatrix::from_fn(self.deltas.len(), ns, |r, k| self.deltas[r][k])
    }

    /// Whether feature `k` changed in any drawn transition.
    pub fn ever_changes(&self, k: usize) -> bool {
        self.deltas.iter().any(|d| d[k] != 0.0)
    }
}
