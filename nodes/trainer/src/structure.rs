//! The paper's stated use of its explanation: a smaller state space. Given the causal graph
//! the explainer found (which actions drive which state features), the trainer can
//! - leave out the state features no action drives (*reduction*: they are removed from the
//!   inputs and the outputs of every model, as the paper proposes for the colour), and
//! - give each forward-model head only its parents (*factoring*): the head of θ sees the
//!   state and the joint actions, never the magnet command, so it cannot learn a shortcut
//!   the graph rules out.
//!
//! The graph is read from `causal-arm explain`'s `claims.json`: its first claim set in
//! context `all` is the run's default verdict. Everything here works by feature name on a
//! [`Problem`], so FM and IM problems are reduced alike.

use std::path::Path;

use causal_arm_dataset::{Experiment, action_names, state_names};
use serde::Deserialize;

use crate::TrainError;
use crate::problems::{HeadInfo, Problem, concat_columns};

/// Which actions drive which state features, as an explanation claimed them.
#[derive(Debug, Clone, PartialEq)]
pub struct FoundGraph {
    /// Where the graph came from (file and claim method), for metrics and messages.
    pub source: String,
    /// Action names (rows of `drives`).
    pub action_names: Vec<String>,
    /// State feature names (columns of `drives`).
    pub state_names: Vec<String>,
    /// `[action][state]`: the action drives the feature.
    pub drives: Vec<Vec<bool>>,
}

/// The fields of one claim set this module reads (the rest of `EdgeClaims` is ignored).
#[derive(Deserialize)]
struct ClaimSet {
    method: String,
    context: String,
    #[serde(default = "one")]
    horizon: usize,
    action_names: Vec<String>,
    state_names: Vec<String>,
    drives: Vec<Vec<bool>>,
}

fn one() -> usize {
    1
}

impl FoundGraph {
    /// Reads the default claims (first set in context `all` at horizon 1) of a
    /// `claims.json` and checks they are `experiment`'s feature names.
    pub fn load(path: &Path, experiment: Experiment) -> Result<Self, TrainError> {
        let bad = |problem: String| TrainError::File {
            path: path.to_owned(),
            problem,
        };
        let text = std::fs::read_to_string(path).map_err(|e| bad(format!("cannot read: {e}")))?;
        let sets: Vec<ClaimSet> = serde_json::from_str(&text).map_err(|e| {
            bad(format!(
                "not a claims file of `causal-arm explain` (a JSON list of claim sets): {e}"
            ))
        })?;
        let set = sets
            .into_iter()
            .find(|s| s.context == "all" && s.horizon == 1)
            .ok_or_else(|| bad("holds no claim set in context \"all\" at horizon 1".into()))?;
        let graph = Self {
            source: format!("{} ({})", path.display(), set.method),
            action_names: set.action_names,
            state_names: set.state_names,
            drives: set.drives,
        };
        graph.check(experiment).map_err(bad)?;
        Ok(graph)
    }

    /// The graph must name exactly the experiment's features and be `[action][state]`.
    fn check(&self, experiment: Experiment) -> Result<(), String> {
        if self.action_names != action_names(experiment)
            || self.state_names != state_names(experiment)
        {
            return Err(format!(
                "its claims are about actions {:?} and states {:?}, not the features of {experiment}",
                self.action_names, self.state_names
            ));
        }
        let (na, ns) = (self.action_names.len(), self.state_names.len());
        if self.drives.len() != na || self.drives.iter().any(|r| r.len() != ns) {
            return Err(format!("its verdicts are not {na} actions × {ns} states"));
        }
        Ok(())
    }

    /// State features no action drives: removable from the state (the paper's colour).
    pub fn unaffected(&self) -> Vec<String> {
        self.state_names
            .iter()
            .enumerate()
            .filter(|&(k, _)| self.drives.iter().all(|row| !row[k]))
            .map(|(_, name)| name.clone())
            .collect()
    }

    /// Actions that drive at least one of `states`.
    pub fn drivers_of(&self, states: &[&str]) -> Vec<String> {
        self.action_names
            .iter()
            .zip(&self.drives)
            .filter(|(_, row)| {
                self.state_names
                    .iter()
                    .zip(row.iter())
                    .any(|(s, &d)| d && states.contains(&s.as_str()))
            })
            .map(|(a, _)| a.clone())
            .collect()
    }
}

/// The feature a column name stands for: `o_R_next` and `o_R` are both `o_R`.
fn feature_of(name: &str) -> &str {
    name.strip_suffix("_next").unwrap_or(name)
}

/// Columns `cols` of every row of a row-major matrix `width` wide.
fn columns(data: &[f32], width: usize, cols: &[usize]) -> Vec<f32> {
    concat_columns(data.len() / width.max(1), &[(data, width, cols)])
}

/// `problem` restricted to the input columns `inputs` and output columns `outputs` (both
/// ascending). Heads keep the outputs they still have; a head left with none is dropped.
/// Every offset column an output needs must be kept among the inputs.
fn select(problem: &Problem, inputs: &[usize], outputs: &[usize]) -> Result<Problem, TrainError> {
    let (n_in, n_out) = (problem.input_names.len(), problem.output_names.len());
    let offset_columns = match &problem.offset_columns {
        None => None,
        Some(cols) => Some(
            outputs
                .iter()
                .map(|&o| {
                    inputs.iter().position(|&i| i == cols[o]).ok_or_else(|| {
                        TrainError::Options(format!(
                            "output {} is predicted as a change of input {}, which is left out",
                            problem.output_names[o], problem.input_names[cols[o]]
                        ))
                    })
                })
                .collect::<Result<Vec<_>, _>>()?,
        ),
    };
    let mut heads = Vec::new();
    for head in &problem.heads {
        let kept: Vec<usize> = (0..outputs.len())
            .filter(|&k| (head.start..head.start + head.len).contains(&outputs[k]))
            .collect();
        if let (Some(&start), len) = (kept.first(), kept.len()) {
            heads.push(HeadInfo {
                start,
                len,
                ..head.clone()
            });
        }
    }
    Ok(Problem {
        inputs: columns(&problem.inputs, n_in, inputs),
        truth: columns(&problem.truth, n_out, outputs),
        offset: problem.offset.as_ref().map(|o| columns(o, n_out, outputs)),
        offset_columns,
        input_names: inputs
            .iter()
            .map(|&i| problem.input_names[i].clone())
            .collect(),
        output_names: outputs
            .iter()
            .map(|&o| problem.output_names[o].clone())
            .collect(),
        heads,
    })
}

/// `problem` without the features `drop` (as inputs of s(t) or s(t+1), and as outputs).
pub fn reduce(problem: &Problem, drop: &[String]) -> Result<Problem, TrainError> {
    let keep = |names: &[String]| -> Vec<usize> {
        (0..names.len())
            .filter(|&i| !drop.iter().any(|d| d == feature_of(&names[i])))
            .collect()
    };
    let outputs = keep(&problem.output_names);
    if outputs.is_empty() {
        return Err(TrainError::Options(format!(
            "leaving out {drop:?} leaves the model nothing to predict"
        )));
    }
    select(problem, &keep(&problem.input_names), &outputs)
}

/// One head of a forward-model `problem` as a problem of its own, whose inputs are the
/// head's parents in `graph`: every state feature of s(t) the problem has, and only the
/// actions that drive one of the head's features.
pub fn head_problem(
    problem: &Problem,
    head: &HeadInfo,
    graph: &FoundGraph,
) -> Result<Problem, TrainError> {
    let features: Vec<&str> = problem.output_names[head.start..head.start + head.len]
        .iter()
        .map(|n| feature_of(n))
        .collect();
    let drivers = graph.drivers_of(&features);
    let inputs: Vec<usize> = (0..problem.input_names.len())
        .filter(|&i| {
            let name = &problem.input_names[i];
            !graph.action_names.contains(name) || drivers.contains(name)
        })
        .collect();
    let outputs: Vec<usize> = (head.start..head.start + head.len).collect();
    select(problem, &inputs, &outputs)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problems::FmTarget;

    fn problem() -> Problem {
        // inputs s = [a, b, c], action [u, v]; outputs a_next, b_next, c_next in heads
        // "ab" (a, b) and "c" (c); delta model.
        let heads = vec![
            HeadInfo {
                name: "ab".into(),
                start: 0,
                len: 2,
                unit: "m".into(),
                angular: false,
            },
            HeadInfo {
                name: "c".into(),
                start: 2,
                len: 1,
                unit: String::new(),
                angular: false,
            },
        ];
        Problem {
            inputs: vec![1., 2., 3., 10., 20., 4., 5., 6., 40., 50.],
            truth: vec![1.5, 2.5, 3., 4.5, 5.5, 6.],
            offset: Some(vec![1., 2., 3., 4., 5., 6.]),
            offset_columns: Some(vec![0, 1, 2]),
            input_names: ["a", "b", "c", "u", "v"].map(String::from).to_vec(),
            output_names: ["a_next", "b_next", "c_next"].map(String::from).to_vec(),
            heads,
        }
    }

    fn graph() -> FoundGraph {
        FoundGraph {
            source: "test".into(),
            action_names: vec!["u".into(), "v".into()],
            state_names: vec!["a".into(), "b".into(), "c".into()],
            // u drives a; v drives b; nothing drives c.
            drives: vec![vec![true, false, false], vec![false, true, false]],
        }
    }

    #[test]
    fn reduction_drops_a_feature_from_inputs_outputs_heads_and_offsets() {
        let g = graph();
        assert_eq!(g.unaffected(), vec!["c".to_owned()]);
        let r = reduce(&problem(), &g.unaffected()).unwrap();
        assert_eq!(r.input_names, ["a", "b", "u", "v"]);
        assert_eq!(r.output_names, ["a_next", "b_next"]);
        assert_eq!(r.inputs, vec![1., 2., 10., 20., 4., 5., 40., 50.]);
        assert_eq!(r.truth, vec![1.5, 2.5, 4.5, 5.5]);
        assert_eq!(r.offset, Some(vec![1., 2., 4., 5.]));
        assert_eq!(r.offset_columns, Some(vec![0, 1]));
        assert_eq!(r.heads.len(), 1);
        assert_eq!((r.heads[0].start, r.heads[0].len), (0, 2));
    }

    #[test]
    fn a_head_sees_the_state_and_only_its_driving_actions() {
        let p = problem();
        let g = graph();
        let ab = head_problem(&p, &p.heads[0], &g).unwrap();
        assert_eq!(ab.input_names, ["a", "b", "c", "u", "v"]);
        let c = head_problem(&p, &p.heads[1], &g).unwrap();
        assert_eq!(c.input_names, ["a", "b", "c"]);
        assert_eq!(c.output_names, ["c_next"]);
        assert_eq!(c.offset_columns, Some(vec![2]));
        assert_eq!(c.inputs, vec![1., 2., 3., 4., 5., 6.]);
        assert_eq!((c.heads[0].start, c.heads[0].len), (0, 1));
    }

    #[test]
    fn dropping_every_output_or_an_offset_input_is_refused() {
        let p = problem();
        let all: Vec<String> = ["a", "b", "c"].map(String::from).to_vec();
        assert!(matches!(reduce(&p, &all), Err(TrainError::Options(_))));
        let err = select(&p, &[1, 2, 3, 4], &[0, 1, 2]).unwrap_err();
        assert!(err.to_string().contains("a_next"), "{err}");
    }

    #[test]
    fn an_fm_problem_reduces_by_name() {
        use causal_arm_dataset::Experiment;
        let names = state_names(Experiment::Exp2);
        let colour: Vec<String> = ["o_R", "o_G", "o_B"].map(String::from).to_vec();
        let (sw, aw, rows) = (names.len(), action_names(Experiment::Exp2).len(), 3);
        let mut data = causal_arm_dataset::Dataset::empty(
            Experiment::Exp2,
            causal_arm_dataset::ActionSource::Realized,
        );
        data.states = (0..rows * sw).map(|v| v as f32).collect();
        data.actions = vec![0.0; rows * aw];
        data.next_states = (0..rows * sw).map(|v| v as f32 + 0.5).collect();
        data.episodes = vec![0; rows];
        data.holding = vec![0; rows];
        data.steps = (0..rows as u32).collect();
        data.stamps_ns = (0..rows as u64).collect();
        let fm = crate::problems::forward_model(&data, FmTarget::Delta);
        let r = reduce(&fm, &colour).unwrap();
        assert_eq!(r.output_names.len(), names.len() - 3);
        assert!(r.heads.iter().all(|h| h.name != "colour"));
        assert!(!r.input_names.iter().any(|n| colour.contains(n)));
    }

    #[test]
    fn missing_malformed_foreign_and_empty_claim_files_are_refused_by_name() {
        let dir = std::env::temp_dir().join(format!("structure-load-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let load = |name: &str, text: Option<&str>| {
            let path = dir.join(name);
            if let Some(text) = text {
                std::fs::write(&path, text).unwrap();
            }
            FoundGraph::load(&path, Experiment::Exp1)
                .unwrap_err()
                .to_string()
        };
        let missing = load("missing.json", None);
        assert!(
            missing.contains("missing.json") && missing.contains("cannot read"),
            "{missing}"
        );
        let junk = load("junk.json", Some("{\"not\": \"a list\"}"));
        assert!(junk.contains("not a claims file"), "{junk}");
        let none = load("none.json", Some("[]"));
        assert!(none.contains("no claim set in context"), "{none}");
        let g = graph();
        let foreign = format!(
            r#"[{{"method":"m","context":"all","horizon":1,"action_names":{:?},"state_names":{:?},"drives":{:?}}}]"#,
            g.action_names, g.state_names, g.drives
        );
        let foreign = load("foreign.json", Some(&foreign));
        assert!(foreign.contains("not the features of exp1"), "{foreign}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_graph_of_other_names_is_refused() {
        let mut g = graph();
        g.state_names = state_names(Experiment::Exp1);
        assert!(
            g.check(Experiment::Exp1)
                .unwrap_err()
                .contains("not the features")
        );
    }
}
