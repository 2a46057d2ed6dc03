//! Mental simulation (the paper's Fig. 5): chain the forward model over the true actions
//! of fresh trajectories and measure how the error grows step by step.

use causal_arm_dataset::{Dataset, state_groups, wrap_angle};
use serde::{Deserialize, Serialize};

use crate::{LoadedModel, TrainError};

/// MAE of one state sub-vector after each chained step, over all trajectories.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct StepCurve {
    /// State group (`theta`, `ef`, `obj_pos`, …).
    pub group: String,
    /// Unit of the MAE.
    pub unit: String,
    /// Mean over trajectories of the per-trajectory MAE after step k+1.
    pub mean: Vec<f64>,
    /// Standard deviation over trajectories.
    pub std: Vec<f64>,
}

/// Result of a mental simulation run.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct MentalSimulation {
    /// Trajectories evaluated.
    pub trajectories: usize,
    /// Steps chained.
    pub steps: usize,
    /// One curve per state group.
    pub curves: Vec<StepCurve>,
}

/// Start rows of up to `wanted` non-overlapping windows of `steps` consecutive transitions
/// inside one episode.
fn windows(data: &Dataset, steps: usize, wanted: usize) -> Vec<usize> {
    let mut starts = Vec::new();
    let mut r = 0;
    while r + steps <= data.rows() && starts.len() < wanted {
        let ok = (1..steps).all(|k| {
            data.episodes[r + k] == data.episodes[r]
                && data.steps[r + k] == data.steps[r] + k as u32
        });
        if ok {
            starts.push(r);
            r += steps;
        } else {
            r += 1;
        }
    }
    starts
}

/// Chains `fm` from the first state of each window over the window's true actions.
pub fn mental_simulation(
    fm: &LoadedModel,
    data: &Dataset,
    trajectories: usize,
    steps: usize,
) -> Result<MentalSimulation, TrainError> {
    if fm.experiment()? != data.experiment {
        return Err(TrainError::Options(format!(
            "the model is for {} but the bag holds {} data",
            fm.meta.experiment, data.experiment
        )));
    }
    if steps == 0 || trajectories == 0 {
        return Err(TrainError::Options(
            "--steps and --trajectories must be at least 1".into(),
        ));
    }
    let starts = windows(data, steps, trajectories);
    if starts.len() < trajectories {
        return Err(TrainError::Options(format!(
            "the bag holds only {} windows of {steps} consecutive steps inside an episode; {trajectories} were asked for (record a longer bag)",
            starts.len()
        )));
    }
    let (sw, aw) = (data.state_width(), data.action_width());
    let groups = state_groups(data.experiment);
    // errors[k][g][t]: MAE of group g after step k on trajectory t.
    let mut errors = vec![vec![Vec::with_capacity(starts.len()); groups.len()]; steps];
    let mut states: Vec<f32> = starts
        .iter()
        .flat_map(|&r| data.state(r).to_vec())
        .collect();
    for (k, step_errors) in errors.iter_mut().enumerate() {
        let mut inputs = Vec::with_capacity(starts.len() * (sw + aw));
        for (t, &r) in starts.iter().enumerate() {
            inputs.extend_from_slice(&states[t * sw..(t + 1) * sw]);
            inputs.extend_from_slice(data.action(r + k));
        }
        states = fm.predict(&inputs)?;
        for (t, &r) in starts.iter().enumerate() {
            let predicted = &states[t * sw..(t + 1) * sw];
            let truth = data.next_state(r + k);
            for (g, group) in groups.iter().enumerate() {
                let cols = group.start..group.start + group.len;
                let sum: f64 = cols
                    .map(|c| {
                        let d = predicted[c] as f64 - truth[c] as f64;
                        if group.angular {
                            wrap_angle(d).abs()
                        } else {
                            d.abs()
                        }
                    })
                    .sum();
                step_errors[g].push(sum / group.len as f64);
            }
        }
    }
    let curves = groups
        .iter()
        .enumerate()
        .map(|(g, group)| {
            let (mean, std) = errors
                .iter()
                .map(|step_errors| {
                    let e = &step_errors[g];
                    let n = e.len() as f64;
                    let m = e.iter().sum::<f64>() / n;
                    (
                        m,
                        (e.iter().map(|v| (v - m).powi(2)).sum::<f64>() / n).sqrt(),
                    )
                })
                .unzip();
            StepCurve {
                group: group.name.to_owned(),
                unit: group.unit.to_owned(),
                mean,
                std,
            }
        })
        .collect();
    Ok(MentalSimulation {
        trajectories: starts.len(),
        steps,
        curves,
    })
}
