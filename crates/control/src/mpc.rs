//! Model-predictive control in mental simulation: the cross-entropy method (CEM) samples
//! action sequences, a learned forward model FM [s(t), a(t)] → s(t+1) rolls each one
//! out, and the first action of the best-scoring plan is executed; the next step plans
//! again from the observed state (issue 17 item 2).
//!
//! The state is the experiment's (exp 1: θ and ef; exp 2 also the cube, the effector's
//! orientation and the magnet), an action its 7 joint deltas (exp 2: the magnet kept as it
//! is). A sequence's cost is the effector's predicted distance to the target summed over
//! the horizon, so plans that get close early win.

use std::time::Instant;

use causal_arm_kinematics::ArmModel;
use causal_arm_protocol::{ARM_DOF, Command, SimState};
use rand::{SeedableRng, rngs::StdRng};
use rand_distr::{Distribution, StandardNormal};

use crate::{ControlError, Controller, StateLayout, Vector3, joint_command};

/// What a plan is scored on: where the effector, or the cube, is predicted to be.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Goal {
    /// The effector at this position (reaching).
    Effector(Vector3<f64>),
    /// The effector at this position, the tool pointing straight down (picking; exp 2).
    EffectorDown(Vector3<f64>),
    /// The cube at this position, the tool pointing down (carrying it; exp 2).
    Cube(Vector3<f64>),
}

impl Goal {
    fn point(&self) -> Vector3<f64> {
        match self {
            Self::Effector(p) | Self::EffectorDown(p) | Self::Cube(p) => *p,
        }
    }
}

/// Cost of a tilted tool, m per unit of (1 + cos(pitch) cos(roll)), which is 0 pointing
/// straight down and 2 pointing up: 10° of tilt costs as much as 7.6 mm of distance.
const TILT_COST: f64 = 0.5;

/// A learned forward model FM [s(t), a(t)] → s(t+1), asked for a batch of rows.
pub trait ForwardModel {
    /// `rows` next states for `rows` (state, action) pairs, row-major.
    fn next_states(&self, states: &[f64], actions: &[f64], rows: usize)
    -> Result<Vec<f64>, String>;
}

/// The cross-entropy method's budget and search spread.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct CemSettings {
    /// Steps each sampled sequence looks ahead.
    pub horizon: usize,
    /// Sequences sampled per iteration.
    pub samples: usize,
    /// Best sequences the sampling distribution is refitted to.
    pub elites: usize,
    /// Refits per decision.
    pub iterations: usize,
    /// Initial standard deviation of each joint delta, rad.
    pub spread: f64,
    /// Largest joint delta of one step, rad (exp 1's babbling moves ~0.35 rad per joint).
    pub max_delta: f64,
}

impl Default for CemSettings {
    fn default() -> Self {
        Self {
            horizon: 1,
            samples: 64,
            elites: 8,
            iterations: 4,
            spread: 0.2,
            max_delta: 0.35,
        }
    }
}

impl CemSettings {
    /// Refuses settings the method cannot run with, naming the field.
    pub fn check(&self) -> Result<(), ControlError> {
        let bad = |what: String| Err(ControlError::Options(what));
        if self.horizon == 0 || self.samples == 0 || self.iterations == 0 {
            return bad(format!(
                "CEM horizon ({}), samples ({}) and iterations ({}) must be positive",
                self.horizon, self.samples, self.iterations
            ));
        }
        if self.elites == 0 || self.elites > self.samples {
            return bad(format!(
                "CEM elites must be between 1 and the samples ({}), got {}",
                self.samples, self.elites
            ));
        }
        for (name, v) in [("spread", self.spread), ("max_delta", self.max_delta)] {
            if !(v.is_finite() && v > 0.0) {
                return bad(format!(
                    "CEM {name} must be a positive number of rad, got {v}"
                ));
            }
        }
        Ok(())
    }
}

/// What the planner saw: decisions, time per decision and how well its FM predicted
/// the effector after each executed action (to relate rollout accuracy to success).
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct MpcLog {
    /// Decisions taken.
    pub decisions: usize,
    /// Wall time of all decisions, s.
    pub decision_seconds: f64,
    /// Per target (per goal when placing): mean distance between the effector (or cube)
    /// position the FM predicted after the executed action and the one observed, m
    /// (NaN before the first observation).
    pub prediction_error_per_target: Vec<f64>,
}

/// Plans each step by CEM over the forward model and executes the first action.
pub struct MpcController<F> {
    model: ArmModel,
    layout: StateLayout,
    fm: F,
    settings: CemSettings,
    rng: StdRng,
    /// The last plan, shifted by one step: the next decision's starting mean.
    warm: Vec<f64>,
    /// The position the FM predicted after the last executed action.
    predicted: Option<Vector3<f64>>,
    goal: Option<Goal>,
    errors: (f64, usize),
    log: MpcLog,
}

impl<F: ForwardModel> MpcController<F> {
    /// An FM-MPC controller of `model`'s arm, for states laid out as `layout`, seeded.
    pub fn new(
        model: ArmModel,
        layout: StateLayout,
        fm: F,
        settings: CemSettings,
        seed: u64,
    ) -> Result<Self, ControlError> {
        settings.check()?;
        Ok(Self {
            model,
            layout,
            fm,
            settings,
            rng: StdRng::seed_from_u64(seed),
            warm: vec![0.0; settings.horizon * ARM_DOF],
            predicted: None,
            goal: None,
            errors: (0.0, 0),
            log: MpcLog::default(),
        })
    }

    /// The planner's log so far.
    pub fn log(&self) -> MpcLog {
        let mut log = self.log.clone();
        if self.goal.is_some() {
            log.prediction_error_per_target.push(self.mean_error());
        }
        log
    }

    fn mean_error(&self) -> f64 {
        match self.errors.1 {
            0 => f64::NAN,
            n => self.errors.0 / n as f64,
        }
    }

    /// Starts the bookkeeping of a new goal, or scores the last prediction.
    fn observe(&mut self, state: &SimState, goal: &Goal) {
        if self.goal != Some(*goal) {
            if self.goal.is_some() {
                let error = self.mean_error();
                self.log.prediction_error_per_target.push(error);
            }
            (self.goal, self.predicted, self.errors) = (Some(*goal), None, (0.0, 0));
            self.warm.fill(0.0);
        } else if let Some(predicted) = self.predicted {
            let observed = match goal {
                Goal::Effector(_) | Goal::EffectorDown(_) => state.ef_pose.translation.vector,
                Goal::Cube(_) => state.cube_pose.translation.vector,
            };
            self.errors.0 += (observed - predicted).norm();
            self.errors.1 += 1;
        }
    }

    /// The best plan CEM finds from `state` (horizon × joint deltas) and the position
    /// (of the effector or cube) its first step is predicted to reach.
    fn plan(
        &mut self,
        state: &SimState,
        goal: &Goal,
        magnet: i8,
    ) -> Result<(Vec<f64>, Vector3<f64>), ControlError> {
        let s = self.settings;
        let width = s.horizon * ARM_DOF;
        let mut mean = self.warm.clone();
        let mut std = vec![s.spread; width];
        let mut best: Option<(f64, Vec<f64>, Vector3<f64>)> = None;
        for _ in 0..s.iterations {
            let plans: Vec<Vec<f64>> = (0..s.samples)
                .map(|_| self.sample_plan(state, &mean, &std))
                .collect();
            let (costs, firsts) = self.score(state, goal, magnet, &plans)?;
            let mut order: Vec<usize> = (0..plans.len()).collect();
            order.sort_by(|&a, &b| costs[a].total_cmp(&costs[b]));
            if best.as_ref().is_none_or(|b| costs[order[0]] < b.0) {
                best = Some((costs[order[0]], plans[order[0]].clone(), firsts[order[0]]));
            }
            let elites = &order[..s.elites];
            for j in 0..width {
                let m = elites.iter().map(|&e| plans[e][j]).sum::<f64>() / s.elites as f64;
                let v = elites
                    .iter()
                    .map(|&e| (plans[e][j] - m).powi(2))
                    .sum::<f64>()
                    / s.elites as f64;
                (mean[j], std[j]) = (m, v.sqrt().max(1e-4));
            }
        }
        let (_, plan, first) = best.expect("at least one iteration");
        Ok((plan, first))
    }

    /// A sequence of joint deltas drawn around `mean`, each step kept within the step
    /// bound and the joint limits along the way.
    fn sample_plan(&mut self, state: &SimState, mean: &[f64], std: &[f64]) -> Vec<f64> {
        let limits = self.model.limits();
        let mut q = state.joint_positions;
        let mut plan = vec![0.0; mean.len()];
        for (h, step) in plan.chunks_mut(ARM_DOF).enumerate() {
            for (j, d) in step.iter_mut().enumerate() {
                let i = h * ARM_DOF + j;
                let noise: f64 = StandardNormal.sample(&mut self.rng);
                let want = (mean[i] + std[i] * noise)
                    .clamp(-self.settings.max_delta, self.settings.max_delta);
                let next = (q[j] + want).clamp(limits[j].lower, limits[j].upper);
                *d = next - q[j];
                q[j] = next;
            }
        }
        plan
    }

    /// Each plan's cost (summed predicted distance to the target) and the effector its
    /// first step is predicted to reach, rolling all plans out as one FM batch per step.
    fn score(
        &self,
        state: &SimState,
        goal: &Goal,
        magnet: i8,
        plans: &[Vec<f64>],
    ) -> Result<(Vec<f64>, Vec<Vector3<f64>>), ControlError> {
        let (target, on_cube) = (goal.point(), matches!(goal, Goal::Cube(_)));
        let down = !matches!(goal, Goal::Effector(_));
        if (on_cube && self.layout.object.is_none()) || (down && !self.layout.ef_orientation) {
            return Err(ControlError::Options(format!(
                "the {} state carries no cube to place or tool orientation to keep",
                self.layout.experiment
            )));
        }
        let rows = plans.len();
        let (width, action_width) = (self.layout.width, self.layout.action_width);
        let mut states: Vec<f64> = self.layout.state(state).repeat(rows);
        let mut costs = vec![0.0; rows];
        let mut firsts = vec![Vector3::zeros(); rows];
        for h in 0..self.settings.horizon {
            // The joint deltas, and (exp 2) the magnet command, then kept as it is.
            let magnet = if h == 0 { f64::from(magnet) } else { 0.0 };
            let actions: Vec<f64> = (plans.iter())
                .flat_map(|p| {
                    let deltas = p[h * ARM_DOF..(h + 1) * ARM_DOF].iter().copied();
                    deltas.chain(std::iter::repeat_n(magnet, action_width - ARM_DOF))
                })
                .collect();
            states = self
                .fm
                .next_states(&states, &actions, rows)
                .map_err(ControlError::Model)?;
            if states.len() != rows * width || states.iter().any(|v| !v.is_finite()) {
                return Err(ControlError::Model(format!(
                    "expected {rows} finite next states of {width} features, got {} values",
                    states.len()
                )));
            }
            for (r, row) in states.chunks(width).enumerate() {
                let point = match on_cube {
                    true => self.layout.object_position(row).expect("checked above"),
                    false => self.layout.ef_position(row),
                };
                costs[r] += (point - target).norm();
                if down {
                    let (roll, pitch) = (row[self.layout.ef + 3], row[self.layout.ef + 4]);
                    costs[r] += TILT_COST * (1.0 + pitch.cos() * roll.cos());
                }
                if h == 0 {
                    firsts[r] = point;
                }
            }
        }
        Ok((costs, firsts))
    }
}

impl<F: ForwardModel> MpcController<F> {
    /// The command of the plan CEM finds toward `goal`, with magnet command `magnet`
    /// (−1 off, 0 keep, +1 on) sent with its first step.
    pub fn step_toward(
        &mut self,
        state: &SimState,
        goal: Goal,
        magnet: i8,
    ) -> Result<Command, ControlError> {
        self.observe(state, &goal);
        let started = Instant::now();
        let (plan, first) = self.plan(state, &goal, magnet)?;
        self.log.decisions += 1;
        self.log.decision_seconds += started.elapsed().as_secs_f64();
        self.predicted = Some(first);
        // Warm start: the rest of this plan, then standing still.
        self.warm = plan[ARM_DOF..].to_vec();
        self.warm.extend([0.0; ARM_DOF]);
        let mut dq = [0.0; ARM_DOF];
        dq.copy_from_slice(&plan[..ARM_DOF]);
        let mut command = joint_command(&self.model, &state.joint_positions, &dq);
        command.magnet = magnet;
        Ok(command)
    }
}

impl<F: ForwardModel> Controller for MpcController<F> {
    fn name(&self) -> &str {
        "fm-mpc"
    }

    fn command(
        &mut self,
        state: &SimState,
        target: &Vector3<f64>,
    ) -> Result<Command, ControlError> {
        self.step_toward(state, Goal::Effector(*target), 0)
    }

    fn report(&self) -> serde_json::Value {
        serde_json::json!({"cem": self.settings, "log": self.log()})
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use causal_arm_sim::{SimConfig, Simulator};

    /// The true exp 1 dynamics as a "learned" FM: θ' = θ + a, ef' = FK(θ'). With it,
    /// MPC must reach like the Jacobian controller does.
    struct ExactFm(ArmModel);

    const STATE_WIDTH: usize = ARM_DOF + 3;

    fn exp1() -> StateLayout {
        StateLayout::of(causal_arm_protocol::Experiment::Exp1, &ArmModel::embedded())
    }

    impl ForwardModel for ExactFm {
        fn next_states(&self, s: &[f64], a: &[f64], rows: usize) -> Result<Vec<f64>, String> {
            let mut out = Vec::with_capacity(rows * STATE_WIDTH);
            for r in 0..rows {
                let q: Vec<f64> = (0..ARM_DOF)
                    .map(|j| s[r * STATE_WIDTH + j] + a[r * ARM_DOF + j])
                    .collect();
                let ef = self.0.ef_pose(&q).map_err(|e| e.to_string())?;
                out.extend(&q);
                out.extend(ef.translation.vector.iter());
            }
            Ok(out)
        }
    }

    #[test]
    fn with_an_exact_model_mpc_reaches_and_logs_its_predictions() {
        let model = ArmModel::embedded();
        let targets = crate::sample_targets(&model, 3, 0.35, 5).unwrap();
        let fm = ExactFm(model.clone());
        let mut mpc = MpcController::new(model, exp1(), fm, CemSettings::default(), 0).unwrap();
        let mut sim = Simulator::new(SimConfig::default()).unwrap();
        for target in &targets {
            sim.reset_episode();
            let episode = crate::run_episode(&mut sim, &mut mpc, target, 100).unwrap();
            assert!(episode.within_1cm_at.is_some(), "{episode:?}");
        }
        let log = mpc.log();
        assert_eq!(log.prediction_error_per_target.len(), 3);
        assert!(log.decisions > 0 && log.decision_seconds > 0.0);
    }

    #[test]
    fn bad_settings_are_refused_naming_the_field() {
        let bad = |s: CemSettings| s.check().unwrap_err().to_string();
        let d = CemSettings::default();
        assert!(
            bad(CemSettings { elites: 99, ..d })
                .contains("elites must be between 1 and the samples (64), got 99")
        );
        assert!(bad(CemSettings { horizon: 0, ..d }).contains("horizon (0)"));
        assert!(bad(CemSettings { spread: -1.0, ..d }).contains("spread must be a positive"));
    }

    #[test]
    fn sampled_steps_stay_within_the_step_bound_and_the_joint_limits() {
        let model = ArmModel::embedded();
        let settings = CemSettings {
            horizon: 3,
            ..CemSettings::default()
        };
        let mut mpc =
            MpcController::new(model.clone(), exp1(), ExactFm(model.clone()), settings, 1).unwrap();
        let state = Simulator::new(SimConfig::default()).unwrap().state();
        let mean = vec![5.0; 3 * ARM_DOF];
        let plan = mpc.sample_plan(&state, &mean, &[1.0; 3 * ARM_DOF]);
        let mut q = state.joint_positions;
        for step in plan.chunks(ARM_DOF) {
            for (j, d) in step.iter().enumerate() {
                assert!(d.abs() <= settings.max_delta + 1e-12);
                q[j] += d;
                let l = &model.limits()[j];
                assert!(q[j] >= l.lower - 1e-12 && q[j] <= l.upper + 1e-12);
            }
        }
    }
}
