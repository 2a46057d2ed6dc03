//! The paper's learning problems as input/target matrices cut from a [`Dataset`].

use causal_arm_dataset::{
    Dataset, Experiment, FeatureGroup, action_names, state_groups, state_names, wrap_angle,
};
use serde::{Deserialize, Serialize};

/// One output head of a problem: a named block of target columns with one MAE figure.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HeadInfo {
    /// Head name (`theta`, `ef`, `joint`, `magnet`, …).
    pub name: String,
    /// First target column.
    pub start: usize,
    /// Number of columns.
    pub len: usize,
    /// Unit of the MAE.
    pub unit: String,
    /// Errors are wrapped into (−π, π] (Euler angles).
    pub angular: bool,
}

impl From<&FeatureGroup> for HeadInfo {
    fn from(g: &FeatureGroup) -> Self {
        Self {
            name: g.name.to_owned(),
            start: g.start,
            len: g.len,
            unit: g.unit.to_owned(),
            angular: g.angular,
        }
    }
}

impl From<&HeadInfo> for causal_arm_mlp::Head {
    fn from(h: &HeadInfo) -> Self {
        Self {
            name: h.name.clone(),
            size: h.len,
        }
    }
}

/// How the forward model predicts s(t+1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum FmTarget {
    /// The network outputs s(t+1) − s(t) and s(t) is added back (default: a tanh MLP
    /// struggles to reproduce an absolute θ(t+1) to 1e-3 rad, see DESIGN.md).
    #[default]
    Delta,
    /// The network outputs s(t+1) directly, as the paper describes.
    Absolute,
}

causal_arm_protocol::choice!(FmTarget, "forward-model target", [
    FmTarget::Delta => "delta",
    FmTarget::Absolute => "absolute",
]);

/// A supervised problem: `truth = network output + offset` row by row.
#[derive(Debug, Clone)]
pub struct Problem {
    /// Input features `[rows, inputs]`.
    pub inputs: Vec<f32>,
    /// What the prediction is judged against, in raw units `[rows, outputs]`.
    pub truth: Vec<f32>,
    /// Added to the network output to get the prediction (s(t) for a delta FM), same
    /// shape as `truth`; `None` means zero.
    pub offset: Option<Vec<f32>>,
    /// Input columns that make up `offset` (stored in model files so a loaded model can
    /// add them back).
    pub offset_columns: Option<Vec<usize>>,
    /// Names of the input features.
    pub input_names: Vec<String>,
    /// Names of the outputs.
    pub output_names: Vec<String>,
    /// Output heads.
    pub heads: Vec<HeadInfo>,
}

impl Problem {
    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.truth.len() / self.output_names.len()
    }

    /// The network's training targets: truth − offset, with differences of Euler angles
    /// wrapped into (−π, π] so a turn across ±π is a small step, not a 2π jump.
    pub fn targets(&self) -> Vec<f32> {
        let Some(offset) = &self.offset else {
            return self.truth.clone();
        };
        let width = self.output_names.len();
        let angular: Vec<bool> = (0..width)
            .map(|c| {
                self.heads
                    .iter()
                    .any(|h| h.angular && (h.start..h.start + h.len).contains(&c))
            })
            .collect();
        self.truth
            .iter()
            .zip(offset)
            .enumerate()
            .map(|(i, (t, o))| {
                let d = t - o;
                if angular[i % width] {
                    wrap_angle(d as f64) as f32
                } else {
                    d
                }
            })
            .collect()
    }
}

/// Columns `cols` of a row-major matrix of width `width`, concatenated per row with
/// the columns of the other parts.
pub(crate) fn concat_columns(rows: usize, parts: &[(&[f32], usize, &[usize])]) -> Vec<f32> {
    let width: usize = parts.iter().map(|(_, _, cols)| cols.len()).sum();
    let mut out = Vec::with_capacity(rows * width);
    for r in 0..rows {
        for (data, w, cols) in parts {
            let row = &data[r * w..(r + 1) * w];
            out.extend(cols.iter().map(|&c| row[c]));
        }
    }
    out
}

fn all(n: usize) -> Vec<usize> {
    (0..n).collect()
}

/// Indices of θ in s.
pub fn theta_columns(experiment: Experiment) -> Vec<usize> {
    let g = state_groups(experiment)
        .into_iter()
        .find(|g| g.name == "theta")
        .expect("every experiment has θ");
    (g.start..g.start + g.len).collect()
}

/// s′ = s without θ (what the monolithic IM and the pre-network see of s(t+1)).
fn without_theta(experiment: Experiment) -> Vec<usize> {
    let theta = theta_columns(experiment);
    (0..state_names(experiment).len())
        .filter(|c| !theta.contains(c))
        .collect()
}

fn suffixed(names: &[String], cols: &[usize], suffix: &str) -> Vec<String> {
    cols.iter()
        .map(|&c| format!("{}{suffix}", names[c]))
        .collect()
}

/// FM: [s(t), a(t)] → s(t+1), one head per state sub-vector.
pub fn forward_model(data: &Dataset, target: FmTarget) -> Problem {
    let (exp, sw, aw, rows) = (
        data.experiment,
        data.state_width(),
        data.action_width(),
        data.rows(),
    );
    let names = state_names(exp);
    Problem {
        inputs: concat_columns(
            rows,
            &[(&data.states, sw, &all(sw)), (&data.actions, aw, &all(aw))],
        ),
        truth: data.next_states.clone(),
        offset: (target == FmTarget::Delta).then(|| data.states.clone()),
        offset_columns: (target == FmTarget::Delta).then(|| all(sw)),
        input_names: names.iter().cloned().chain(action_names(exp)).collect(),
        output_names: suffixed(&names, &all(sw), "_next"),
        heads: state_groups(exp).iter().map(HeadInfo::from).collect(),
    }
}

fn action_heads(experiment: Experiment) -> Vec<HeadInfo> {
    let joint = HeadInfo {
        name: "joint".into(),
        start: 0,
        len: 7,
        unit: "rad".into(),
        angular: false,
    };
    match experiment {
        Experiment::Exp1 => vec![joint],
        Experiment::Exp2 => vec![
            joint,
            HeadInfo {
                name: "magnet".into(),
                start: 7,
                len: 1,
                unit: String::new(),
                angular: false,
            },
        ],
    }
}

/// Monolithic IM: [s(t), s′(t+1)] → a(t) (exp 2: separate joint and magnet losses).
pub fn inverse_model(data: &Dataset) -> Problem {
    let (exp, sw, rows) = (data.experiment, data.state_width(), data.rows());
    let names = state_names(exp);
    let rest = without_theta(exp);
    Problem {
        inputs: concat_columns(
            rows,
            &[(&data.states, sw, &all(sw)), (&data.next_states, sw, &rest)],
        ),
        truth: data.actions.clone(),
        offset: None,
        offset_columns: None,
        input_names: names
            .iter()
            .cloned()
            .chain(suffixed(&names, &rest, "_next"))
            .collect(),
        output_names: action_names(exp),
        heads: action_heads(exp),
    }
}

/// Base IM of the pre-computation approach: [s(t), s(t+1)] → a(t), θ(t+1) included.
pub fn base_inverse_model(data: &Dataset) -> Problem {
    let (exp, sw, rows) = (data.experiment, data.state_width(), data.rows());
    let names = state_names(exp);
    Problem {
        inputs: concat_columns(
            rows,
            &[
                (&data.states, sw, &all(sw)),
                (&data.next_states, sw, &all(sw)),
            ],
        ),
        truth: data.actions.clone(),
        offset: None,
        offset_columns: None,
        input_names: names
            .iter()
            .cloned()
            .chain(suffixed(&names, &all(sw), "_next"))
            .collect(),
        output_names: action_names(exp),
        heads: action_heads(exp),
    }
}

/// Pre-network: [s(t), s′(t+1)] → θ(t+1).
pub fn pre_network(data: &Dataset) -> Problem {
    let (exp, sw, rows) = (data.experiment, data.state_width(), data.rows());
    let names = state_names(exp);
    let rest = without_theta(exp);
    let theta = theta_columns(exp);
    Problem {
        inputs: concat_columns(
            rows,
            &[(&data.states, sw, &all(sw)), (&data.next_states, sw, &rest)],
        ),
        truth: concat_columns(rows, &[(&data.next_states, sw, &theta)]),
        offset: None,
        offset_columns: None,
        input_names: names
            .iter()
            .cloned()
            .chain(suffixed(&names, &rest, "_next"))
            .collect(),
        output_names: suffixed(&names, &theta, "_next"),
        heads: vec![HeadInfo {
            name: "theta".into(),
            start: 0,
            len: theta.len(),
            unit: "rad".into(),
            angular: false,
        }],
    }
}

/// Where θ(t+1) sits in the base IM's input, so an assembly or an ablation can replace it.
pub fn base_theta_next_columns(experiment: Experiment) -> Vec<usize> {
    let sw = state_names(experiment).len();
    theta_columns(experiment)
        .into_iter()
        .map(|c| sw + c)
        .collect()
}

/// Builds base-IM inputs from pre-network inputs and a θ(t+1) per row (the assembly).
pub fn base_inputs_from(
    experiment: Experiment,
    pre_inputs: &[f32],
    theta_next: &[f32],
) -> Vec<f32> {
    let sw = state_names(experiment).len();
    let rest = without_theta(experiment);
    let theta = theta_columns(experiment);
    let pre_width = sw + rest.len();
    let rows = pre_inputs.len() / pre_width;
    let mut out = Vec::with_capacity(rows * 2 * sw);
    for r in 0..rows {
        let row = &pre_inputs[r * pre_width..(r + 1) * pre_width];
        out.extend_from_slice(&row[..sw]);
        let mut next = vec![0f32; sw];
        for (k, &c) in rest.iter().enumerate() {
            next[c] = row[sw + k];
        }
        for (k, &c) in theta.iter().enumerate() {
            next[c] = theta_next[r * theta.len() + k];
        }
        out.extend(next);
    }
    out
}
