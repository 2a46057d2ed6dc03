//! The learning data of the paper, built from experiment bags: transitions
//! (s(t), a(t), s(t+1)) joined by stamp, with feature names (DESIGN.md "Data model").
//!
//! A bag alone is a complete dataset: every state message of a simulator step carries the
//! step's stamp and the babbler's action carries the stamp of the state it answers. The
//! builder refuses bags with gaps, missing topics or the wrong experiment, naming bag,
//! topic and stamp. Built tensors are cached by bag content hash ([`Cache`]) so training
//! again does not decode millions of messages again.

mod build;
mod cache;
mod contexts;
mod features;

pub use build::{BagSource, from_bag, state_features};
pub use cache::{Cache, CacheOutcome, load_bags, write_safetensors};
pub use causal_arm_protocol::Experiment;
pub use contexts::{Context, ContextReader, ContextState};
pub use features::{
    FeatureGroup, action_names, angular_features, state_groups, state_names, wrap_angle,
};

use std::path::PathBuf;

/// Which action vector a transition carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ActionSource {
    /// θ(t+1) − θ(t), what the joints really did (the paper's definition).
    #[default]
    Realized,
    /// The babbler's commanded deltas (target − position), before velocity limits.
    Commanded,
}

causal_arm_protocol::choice!(ActionSource, "action source", [
    ActionSource::Realized => "realized",
    ActionSource::Commanded => "commanded",
]);

impl ActionSource {
    /// The action a causal question about `bags` should be asked of: on the kinematic arm
    /// the realized joint change (the paper's), which equals the command up to the
    /// velocity limit; on the dynamic arm the command, because there the realized change
    /// is an outcome of the command, the motors and the other joints, and the simulator's
    /// truth intervenes on the command (with realized actions the data test denied 17–41
    /// true command couplings, docs/RESULTS.md). A bag written before the dynamic arm
    /// existed is kinematic. Bags of both arms together are refused.
    pub fn of_bags(bags: &[PathBuf]) -> Result<Self, DatasetError> {
        let mut found: Option<(Self, PathBuf)> = None;
        for bag in cache::expand_shard_sets(bags)? {
            let arm = causal_arm_bag::BagReader::open(&bag)?
                .custom_data()
                .get(causal_arm_protocol::bag_keys::ARM)
                .cloned();
            let source = match arm.as_deref() {
                Some("dynamic") => Self::Commanded,
                _ => Self::Realized,
            };
            match &found {
                Some((first, at)) if *first != source => {
                    return Err(DatasetError::Mixed(format!(
                        "{} and {} were recorded with different arms (custom_data {}): give --action",
                        at.display(),
                        bag.display(),
                        causal_arm_protocol::bag_keys::ARM
                    )));
                }
                Some(_) => {}
                None => found = Some((source, bag)),
            }
        }
        Ok(found.map_or(Self::Realized, |(source, _)| source))
    }

    /// The action the user gave (`--action`), else the one [`Self::of_bags`] chooses.
    pub fn given_or_of_bags(given: Option<Self>, bags: &[PathBuf]) -> Result<Self, DatasetError> {
        match given {
            Some(action) => Ok(action),
            None => Self::of_bags(bags),
        }
    }
}

/// Transitions of one experiment, row-major f32 matrices with one row per transition.
#[derive(Debug, Clone, PartialEq)]
pub struct Dataset {
    /// Which experiment's data model the rows follow.
    pub experiment: Experiment,
    /// Where the actions come from.
    pub action_source: ActionSource,
    /// s(t), `[rows, state_width]`.
    pub states: Vec<f32>,
    /// a(t), `[rows, action_width]`.
    pub actions: Vec<f32>,
    /// s(t+1), `[rows, state_width]`.
    pub next_states: Vec<f32>,
    /// Episode of each row (trajectories never cross episodes).
    pub episodes: Vec<u32>,
    /// 1 where the magnet held the cube in s(t), else 0 (`/magnet/state` holding): not a
    /// state feature, but the context in which actions move the cube, so causal claims can
    /// be scored per context.
    pub holding: Vec<u8>,
    /// Step within the episode of s(t).
    pub steps: Vec<u32>,
    /// Sim-time stamp of s(t), ns.
    pub stamps_ns: Vec<u64>,
    /// Per row, which actions the babbler's design drew at random in s(t) (bit j: action
    /// j; the rest were scripted, so no evidence of what they cause); `None` when a bag
    /// does not record its design (a foreign bag, or one recorded before `Action.design`).
    pub randomized: Option<Vec<u32>>,
    /// Bags the rows came from, in row order.
    pub sources: Vec<BagSource>,
}

impl Dataset {
    /// A dataset with no rows, to be filled row by row (the bag decoder, hand-made test
    /// data).
    pub fn empty(experiment: Experiment, action_source: ActionSource) -> Self {
        Self {
            experiment,
            action_source,
            states: Vec::new(),
            actions: Vec::new(),
            next_states: Vec::new(),
            episodes: Vec::new(),
            holding: Vec::new(),
            steps: Vec::new(),
            stamps_ns: Vec::new(),
            randomized: None,
            sources: Vec::new(),
        }
    }

    /// What the bags say of how their actions were drawn, in a line: per action the share
    /// of rows where the design drew it at random, or that no design is recorded.
    pub fn design_summary(&self) -> String {
        let Some(randomized) = &self.randomized else {
            return "design: not recorded in the bags (foreign, or recorded before Action.design); every row is taken as randomized".to_owned();
        };
        let rows = randomized.len().max(1) as f64;
        let shares: Vec<String> = (features::action_names(self.experiment).iter().enumerate())
            .map(|(a, name)| {
                let drawn = randomized.iter().filter(|m| *m & (1 << a) != 0).count();
                format!("{name} {:.1} %", 100.0 * drawn as f64 / rows)
            })
            .collect();
        format!(
            "design: recorded; rows where each action was drawn at random (else scripted): {}",
            shares.join(", ")
        )
    }

    /// Whether the design drew action `a` at random in row `r`: `None` when the design is
    /// not recorded.
    pub fn randomized(&self, r: usize, a: usize) -> Option<bool> {
        Some(self.randomized.as_ref()?[r] & (1 << a) != 0)
    }

    /// Number of transitions.
    pub fn rows(&self) -> usize {
        self.episodes.len()
    }

    /// Width of s (constant time: row accessors call it for every row).
    pub fn state_width(&self) -> usize {
        features::state_width(self.experiment)
    }

    /// Width of a.
    pub fn action_width(&self) -> usize {
        features::action_width(self.experiment)
    }

    /// Row `i` of s(t).
    pub fn state(&self, i: usize) -> &[f32] {
        let w = self.state_width();
        &self.states[i * w..(i + 1) * w]
    }

    /// Row `i` of a(t).
    pub fn action(&self, i: usize) -> &[f32] {
        let w = self.action_width();
        &self.actions[i * w..(i + 1) * w]
    }

    /// Row `i` of s(t+1).
    pub fn next_state(&self, i: usize) -> &[f32] {
        let w = self.state_width();
        &self.next_states[i * w..(i + 1) * w]
    }

    /// The one-step change s(t+1) − s(t) of transition `i`, in f64 (exact for f32 states),
    /// Euler angles wrapped into (−π, π]: what an action causes, in the feature's unit.
    pub fn change(&self, i: usize) -> Vec<f64> {
        self.change_ahead(i, 1)
    }

    /// The change s(t+h) − s(t) from transition `i` over `horizon` consecutive transitions
    /// (row `i + horizon − 1`'s s(t+1)), Euler angles wrapped: what an action at t causes h
    /// steps on. The caller makes sure the rows chain ([`Self::chainable_rows`]).
    pub fn change_ahead(&self, i: usize, horizon: usize) -> Vec<f64> {
        let angular = angular_features(self.experiment);
        self.next_state(i + horizon.max(1) - 1)
            .iter()
            .zip(self.state(i))
            .zip(&angular)
            .map(|((&later, &now), &angle)| {
                let d = later as f64 - now as f64;
                if angle { wrap_angle(d) } else { d }
            })
            .collect()
    }

    /// Whether row `r + 1` continues row `r`: same episode, the next step, and its s(t) is
    /// the s(t+1) of row `r` (a dropped message leaves a hole a chain must not jump).
    pub fn continues(&self, r: usize) -> bool {
        r + 1 < self.rows()
            && self.episodes[r + 1] == self.episodes[r]
            && self.steps[r + 1] == self.steps[r].wrapping_add(1)
            && self.state(r + 1) == self.next_state(r)
    }

    /// Per row, the number of consecutive transitions of its episode that start at it
    /// (itself included): h steps ahead of row r are in the data when `reach[r] ≥ h`.
    pub fn chain_reach(&self) -> Vec<usize> {
        let mut reach = vec![1; self.rows()];
        for r in (0..self.rows().saturating_sub(1)).rev() {
            if self.continues(r) {
                reach[r] = reach[r + 1] + 1;
            }
        }
        reach
    }

    /// Rows from which `horizon` consecutive transitions of one episode follow.
    pub fn chainable_rows(&self, horizon: usize) -> Vec<usize> {
        self.chain_reach()
            .iter()
            .enumerate()
            .filter(|&(_, &reach)| reach >= horizon)
            .map(|(r, _)| r)
            .collect()
    }

    /// Appends `other` (same experiment and action source), renumbering its episodes
    /// after ours so episodes from different bags stay distinct.
    pub fn append(&mut self, other: Dataset) -> Result<(), DatasetError> {
        if other.experiment != self.experiment {
            return Err(DatasetError::Mixed(format!(
                "{} holds {} data but {} holds {}",
                other
                    .sources
                    .first()
                    .map(|s| s.path.as_str())
                    .unwrap_or("?"),
                other.experiment,
                self.sources.first().map(|s| s.path.as_str()).unwrap_or("?"),
                self.experiment
            )));
        }
        if other.action_source != self.action_source {
            return Err(DatasetError::Mixed(
                "datasets use different action sources".into(),
            ));
        }
        let offset = self.episodes.iter().max().map(|e| e + 1).unwrap_or(0);
        self.states.extend(other.states);
        self.actions.extend(other.actions);
        self.next_states.extend(other.next_states);
        self.episodes
            .extend(other.episodes.iter().map(|e| e + offset));
        self.holding.extend(other.holding);
        self.steps.extend(other.steps);
        self.stamps_ns.extend(other.stamps_ns);
        // The design is known only where every bag records it.
        self.randomized = match (self.randomized.take(), other.randomized) {
            (Some(mut ours), Some(theirs)) => {
                ours.extend(theirs);
                Some(ours)
            }
            _ => None,
        };
        self.sources.extend(other.sources);
        Ok(())
    }
}

/// Why a dataset could not be built or loaded.
#[derive(Debug, thiserror::Error)]
pub enum DatasetError {
    /// The bag could not be read.
    #[error(transparent)]
    Bag(#[from] causal_arm_bag::BagError),
    /// The bag's content breaks the step protocol (gap, missing topic, bad message).
    #[error("{bag}: {problem}")]
    Content {
        /// Bag directory or file.
        bag: PathBuf,
        /// What is wrong, with topic and stamp.
        problem: String,
    },
    /// The bag holds the other experiment.
    #[error("{bag}: holds {found} data ({how}), expected {expected}")]
    WrongExperiment {
        /// Bag directory or file.
        bag: PathBuf,
        /// What it holds.
        found: Experiment,
        /// What was asked for.
        expected: Experiment,
        /// How that was determined.
        how: String,
    },
    /// Bags of different kinds were combined.
    #[error("cannot combine bags: {0}")]
    Mixed(String),
    /// The cache could not be read or written.
    #[error("dataset cache {path}: {problem}")]
    Cache {
        /// Cache file.
        path: PathBuf,
        /// What failed.
        problem: String,
    },
}
