//! Contexts: subsets of states in which an action's effects differ (an arm joint moves the
//! cube only while it is held; the magnet drops it only on release). One definition serves
//! the simulator's ground truth and the explainer's claims, so both split states alike.

use causal_arm_protocol::{Scene, SimState};

use crate::{Dataset, Experiment, state_names};

/// What a context is judged on: the state s(t) the action is taken in.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContextState {
    /// The magnet holds the cube.
    pub holding: bool,
    /// The magnet is switched on.
    pub magnet_on: bool,
    /// Cube centre, m.
    pub cube: [f64; 3],
}

impl ContextState {
    /// From a simulator state.
    pub fn of_sim(state: &SimState) -> Self {
        let p = state.cube_pose.translation.vector;
        Self {
            holding: state.holding,
            magnet_on: state.magnet_on,
            cube: [p.x, p.y, p.z],
        }
    }
}

/// Reads the [`ContextState`] of dataset rows; the feature positions are looked up once, not
/// per row (row loops run over tens of thousands of rows).
#[derive(Debug, Clone)]
pub struct ContextReader {
    mgt: Option<usize>,
    cube: [Option<usize>; 3],
}

impl ContextReader {
    /// A reader for rows of `experiment` (exp 1 has no magnet or cube: never held, off, NaN).
    pub fn new(experiment: Experiment) -> Self {
        let names = state_names(experiment);
        let at = |n: &str| names.iter().position(|m| m == n);
        Self {
            mgt: at("mgt"),
            cube: [at("o_x"), at("o_y"), at("o_z")],
        }
    }

    /// The context state of row `row` of `data` (s(t) and its holding flag).
    pub fn at(&self, data: &Dataset, row: usize) -> ContextState {
        let s = data.state(row);
        let value = |i: Option<usize>| i.map(|i| s[i] as f64).unwrap_or(f64::NAN);
        ContextState {
            holding: data.holding.get(row).is_some_and(|&h| h != 0),
            magnet_on: value(self.mgt) > 0.5,
            cube: self.cube.map(value),
        }
    }

    /// Whether row `row` of `data` lies in `context` (the table of the default scene).
    pub fn holds(&self, data: &Dataset, row: usize, context: &Context) -> bool {
        context.holds(&self.at(data, row), &Scene::default())
    }
}

/// A named subset of states.
#[derive(Debug, Clone, Copy)]
pub struct Context {
    /// Name used in truth files, reports and score tables.
    pub name: &'static str,
    holds: fn(&ContextState, &Scene) -> bool,
}

impl Context {
    /// Name of the context of every state.
    pub const ALL: &'static str = "all";

    /// The contexts of `experiment`, `all` first.
    pub fn of(experiment: Experiment) -> Vec<Context> {
        let all = Context {
            name: Self::ALL,
            holds: |_, _| true,
        };
        let context = |name, holds| Context { name, holds };
        match experiment {
            Experiment::Exp1 => vec![all],
            Experiment::Exp2 => vec![
                all,
                context("holding", |s, _| s.holding),
                context("not_holding", |s, _| !s.holding),
                context("magnet_on", |s, _| s.magnet_on),
                context("magnet_off", |s, _| !s.magnet_on),
                context("cube_on_table", cube_on_table),
                context("cube_elsewhere", |s, c| !cube_on_table(s, c)),
            ],
        }
    }

    /// Whether a state belongs to the context (`scene`: the table's geometry).
    pub fn holds(&self, state: &ContextState, scene: &Scene) -> bool {
        (self.holds)(state, scene)
    }
}

/// The cube rests on the table top: not held, its centre half an edge above the top
/// (within 5 mm) and over the table.
fn cube_on_table(s: &ContextState, scene: &Scene) -> bool {
    !s.holding && scene.cube_rests_on_table(s.cube)
}
