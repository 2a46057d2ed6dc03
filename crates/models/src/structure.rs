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

/// Which outputs beside its own a factored head's network learns. A separate network loses
/// the supervision a shared one gets from the other heads' targets (docs/RESULTS.md,
/// "State-space reduction"), but not every head gains from it: the exp2 cube position is
/// 2.8× better alone, its orientation better with every other target. So `Auto` chooses
/// per head, on rows the test fold never sees.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Auxiliary {
    /// The head's own features only.
    None,
    /// The features that may be an ancestor of one of the head's features inside the
    /// slice t+1 (θ(t+1) of ef(t+1) = FK(θ(t+1))): whatever drives an ancestor drives its
    /// descendant through it, so an ancestor's drivers are a non-empty strict subset of the
    /// feature's.
    Upstream,
    /// Every feature the head's parents determine: driven by no action outside the head's.
    /// A target its parents cannot explain would only add noise, so none is taken.
    Determined,
    /// The fixed policy whose network predicts the head best on a validation slice of the
    /// training rows.
    Auto,
}

impl Auxiliary {
    /// Every policy, in the order `--help` lists them.
    pub const ALL: [Self; 4] = [Self::None, Self::Upstream, Self::Determined, Self::Auto];
    /// The policies `Auto` chooses among.
    pub const FIXED: [Self; 3] = [Self::None, Self::Upstream, Self::Determined];

    /// The policy's name on the command line and in metrics.json.
    pub fn name(self) -> &'static str {
        causal_arm_protocol::Choice::choice_name(self)
    }
}

causal_arm_protocol::choice!(Auxiliary, "auxiliary policy", [
    Auxiliary::None => "none",
    Auxiliary::Upstream => "upstream",
    Auxiliary::Determined => "determined",
    Auxiliary::Auto => "auto",
]);

/// One head of a forward model with its own network: the problem it is trained on and
/// which of that problem's heads is the one it is for (the others are auxiliary outputs,
/// trained on but never reported as the FM's figures).
#[derive(Debug, Clone)]
pub struct HeadNet {
    /// The auxiliary policy that chose the outputs.
    pub auxiliary: Auxiliary,
    /// Inputs: the head's parents; outputs: the head and its auxiliary outputs.
    pub problem: Problem,
    /// Index in `problem.heads` of the head this network predicts.
    pub primary: usize,
}

/// One head of a forward-model `problem` as a problem of its own, whose inputs are the
/// head's parents in `graph`: every state feature of s(t) the problem has, and only the
/// actions that drive one of the head's features; its outputs are the head's and those
/// `auxiliary` adds (a fixed policy; [`head_candidates`] expands `Auto`).
pub fn head_problem(
    problem: &Problem,
    head: &HeadInfo,
    graph: &FoundGraph,
    auxiliary: Auxiliary,
) -> Result<HeadNet, TrainError> {
    if auxiliary == Auxiliary::Auto {
        return Err(TrainError::Options(
            "head_problem takes a fixed auxiliary policy; head_candidates expands auto".into(),
        ));
    }
    let head_range = head.start..head.start + head.len;
    let features: Vec<&str> = problem.output_names[head_range.clone()]
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
    let feature_drivers: Vec<Vec<String>> =
        features.iter().map(|&f| graph.drivers_of(&[f])).collect();
    let subset = |own: &[String], of: &[String]| own.iter().all(|a| of.contains(a));
    let takes = |output: &str| {
        let own = graph.drivers_of(&[feature_of(output)]);
        match auxiliary {
            Auxiliary::None => false,
            Auxiliary::Upstream => {
                !own.is_empty()
                    && feature_drivers
                        .iter()
                        .any(|of| own.len() < of.len() && subset(&own, of))
            }
            Auxiliary::Determined => subset(&own, &drivers),
            Auxiliary::Auto => false,
        }
    };
    let outputs: Vec<usize> = (0..problem.output_names.len())
        .filter(|&o| head_range.contains(&o) || takes(&problem.output_names[o]))
        .collect();
    let problem = select(problem, &inputs, &outputs)?;
    let primary = problem
        .heads
        .iter()
        .position(|h| h.name == head.name)
        .ok_or_else(|| TrainError::Options(format!("head {} lost its outputs", head.name)))?;
    Ok(HeadNet {
        auxiliary,
        problem,
        primary,
    })
}

/// The networks a head may be trained as under `auxiliary`: one for a fixed policy, and
/// for `Auto` one per fixed policy that gives a different set of outputs (the first policy
/// of each set names it).
pub fn head_candidates(
    problem: &Problem,
    head: &HeadInfo,
    graph: &FoundGraph,
    auxiliary: Auxiliary,
) -> Result<Vec<HeadNet>, TrainError> {
    if auxiliary != Auxiliary::Auto {
        return Ok(vec![head_problem(problem, head, graph, auxiliary)?]);
    }
    let mut candidates: Vec<HeadNet> = Vec::new();
    for policy in Auxiliary::FIXED {
        let net = head_problem(problem, head, graph, policy)?;
        if !candidates
            .iter()
            .any(|c| c.problem.output_names == net.problem.output_names)
        {
            candidates.push(net);
        }
    }
    Ok(candidates)
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
        let ab = head_problem(&p, &p.heads[0], &g, Auxiliary::None)
            .unwrap()
            .problem;
        assert_eq!(ab.input_names, ["a", "b", "c", "u", "v"]);
        let c = head_problem(&p, &p.heads[1], &g, Auxiliary::None)
            .unwrap()
            .problem;
        assert_eq!(c.input_names, ["a", "b", "c"]);
        assert_eq!(c.output_names, ["c_next"]);
        assert_eq!(c.offset_columns, Some(vec![2]));
        assert_eq!(c.inputs, vec![1., 2., 3., 4., 5., 6.]);
        assert_eq!((c.heads[0].start, c.heads[0].len), (0, 1));
    }

    #[test]
    fn a_head_learns_as_auxiliary_outputs_the_features_driven_by_fewer_of_its_actions() {
        let p = problem();
        // u drives a and c, v drives c only, nothing drives b: a may be upstream of c, and
        // b, driven by nothing, is upstream of nothing.
        let g = FoundGraph {
            drives: vec![vec![true, false, true], vec![false, false, true]],
            ..graph()
        };
        let c = head_problem(&p, &p.heads[1], &g, Auxiliary::Upstream).unwrap();
        assert_eq!(c.problem.output_names, ["a_next", "c_next"]);
        assert_eq!(c.problem.heads[c.primary].name, "c");
        assert_eq!((c.problem.heads[c.primary].start, c.primary), (1, 1));
        assert_eq!(c.problem.truth, vec![1.5, 3., 4.5, 6.]);
        // c's drivers are no subset of a's: the head ab takes no auxiliary output.
        let ab = head_problem(&p, &p.heads[0], &g, Auxiliary::Upstream).unwrap();
        assert_eq!(ab.problem.output_names, ["a_next", "b_next"]);
        assert_eq!(ab.primary, 0);
        let plain = head_problem(&p, &p.heads[1], &g, Auxiliary::None).unwrap();
        assert_eq!(plain.problem.output_names, ["c_next"]);
        // u drives a and c, v drives b: c's drivers are a strict subset of the head ab's
        // together, but of none of its features (as ef_y's of the θ head's), so no
        // auxiliary output.
        let g = FoundGraph {
            drives: vec![vec![true, false, true], vec![false, true, false]],
            ..graph()
        };
        let ab = head_problem(&p, &p.heads[0], &g, Auxiliary::Upstream).unwrap();
        assert_eq!(ab.problem.output_names, ["a_next", "b_next"]);
    }

    #[test]
    fn determined_takes_every_feature_driven_only_by_the_heads_actions_and_auto_each_distinct_set()
    {
        let p = problem();
        // u drives a and c, v drives c; nothing drives b.
        let g = FoundGraph {
            drives: vec![vec![true, false, true], vec![false, false, true]],
            ..graph()
        };
        let c = head_problem(&p, &p.heads[1], &g, Auxiliary::Determined).unwrap();
        assert_eq!(c.problem.output_names, ["a_next", "b_next", "c_next"]);
        assert_eq!(c.problem.heads[c.primary].name, "c");
        let names = |nets: Vec<HeadNet>| -> Vec<Vec<String>> {
            nets.into_iter().map(|n| n.problem.output_names).collect()
        };
        let auto = head_candidates(&p, &p.heads[1], &g, Auxiliary::Auto).unwrap();
        assert_eq!(
            auto.iter().map(|n| n.auxiliary).collect::<Vec<_>>(),
            Auxiliary::FIXED
        );
        assert_eq!(
            names(auto),
            [
                vec!["c_next"],
                vec!["a_next", "c_next"],
                vec!["a_next", "b_next", "c_next"]
            ]
        );
        // ab is driven by u alone; c needs v too: every policy gives ab alone, one network.
        let ab = head_candidates(&p, &p.heads[0], &g, Auxiliary::Auto).unwrap();
        assert_eq!(names(ab), [vec!["a_next", "b_next"]]);
        assert!(head_problem(&p, &p.heads[0], &g, Auxiliary::Auto).is_err());
        assert_eq!(
            "determined".parse::<Auxiliary>().unwrap(),
            Auxiliary::Determined
        );
        let unknown = "all".parse::<Auxiliary>().unwrap_err().to_string();
        assert!(
            unknown.contains("\"all\"") && unknown.contains("upstream"),
            "{unknown}"
        );
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
