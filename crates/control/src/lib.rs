//! Acting with the arm: reaching a target effector position with a controller, scored as
//! the paper's "next step" asks (issue 17). Pure logic over the simulator: reachable
//! targets, three controllers behind one trait, and the episode loop.
//!
//! - [`JacobianController`]: the analytic baseline, a damped least-squares step of the
//!   kinematics crate's Jacobian toward the target.
//! - [`ImController`]: asks a learned inverse model IM [s(t), s*] → a for the action that
//!   takes the state to an intermediate s*, a full step toward the target (the action
//!   scaled down to the remaining distance near it; one babbled step when it stalls). The exp 1
//!   state is (θ, ef) and θ(t+1) = θ(t) + a, so s* must be consistent: its θ* is θ plus
//!   the joint step that moves ef by the clipped Δef (a Jacobian step), its ef* is ef + Δef.
//!   Giving the IM θ* = θ with a moved ef would ask it for a contradiction.
//! - [`RandomController`]: motor babbling, exp 1's random joint targets, as the floor.
//! - [`MpcController`]: model-predictive control with a learned forward model, planned
//!   by the cross-entropy method in mental simulation ([`mpc`]).

pub mod layout;
pub mod mpc;
pub mod place;

pub use layout::StateLayout;
pub use mpc::{CemSettings, ForwardModel, Goal, MpcController, MpcLog};
pub use place::{
    PlaceController, PlaceSummary, PlaceTrial, run_place_trial, sample_spots, summarize_place,
};

use causal_arm_kinematics::{ArmModel, IkOptions, IkTarget};
use causal_arm_protocol::{ARM_DOF, Command, Experiment, Scene, SimState};
use causal_arm_sim::Simulator;
use nalgebra::Matrix3;
/// Targets and displacements are nalgebra vectors (re-exported so callers need not pin it).
pub use nalgebra::Vector3;
use rand::{SeedableRng, rngs::StdRng};
use rand_distr::{Distribution, Normal};

/// Why a controller or an episode could not go on.
#[derive(Debug, thiserror::Error)]
pub enum ControlError {
    /// The kinematics refused the joint values.
    #[error("kinematics: {0}")]
    Kinematics(String),
    /// The simulator refused a command.
    #[error("simulator: {0}")]
    Sim(String),
    /// The inverse model gave no usable action.
    #[error("inverse model: {0}")]
    Model(String),
    /// Bad options, named.
    #[error("{0}")]
    Options(String),
}

/// Targets the arm can reach, where the models were trained: the effector positions of
/// joint configurations drawn as exp 1's babbler draws its targets (normal with `sigma`
/// around zero, clipped to the joint limits).
pub fn sample_targets(
    model: &ArmModel,
    count: usize,
    sigma: f64,
    seed: u64,
) -> Result<Vec<Vector3<f64>>, ControlError> {
    let normal = spread(sigma)?;
    let mut rng = StdRng::seed_from_u64(seed);
    (0..count)
        .map(|_| {
            let q: Vec<f64> = (model.limits().iter())
                .map(|l| normal.sample(&mut rng).clamp(l.lower, l.upper))
                .collect();
            let pose = model.ef_pose(&q).map_err(kinematics_err)?;
            Ok(pose.translation.vector)
        })
        .collect()
}

/// Reachable targets where exp 2 works: uniform over the table's top, 5 to 30 cm above
/// it (each checked reachable; the IK's solution then lies within the joint limits).
pub fn sample_table_targets(
    model: &ArmModel,
    scene: &Scene,
    count: usize,
    seed: u64,
) -> Result<Vec<Vector3<f64>>, ControlError> {
    use rand::Rng as _;
    let mut rng = StdRng::seed_from_u64(seed);
    let [cx, cy] = scene.table_center;
    let [hx, hy] = scene.table_half_extents;
    let mut targets = Vec::with_capacity(count);
    let mut tries = 0;
    while targets.len() < count {
        tries += 1;
        if tries > 100 * count + 1000 {
            return Err(ControlError::Options(
                "no reachable targets above the table".into(),
            ));
        }
        let goal = Vector3::new(
            rng.random_range(cx - hx..=cx + hx),
            rng.random_range(cy - hy..=cy + hy),
            scene.table_top_z + rng.random_range(0.05..=0.30),
        );
        if check_reachable(model, &goal).is_ok() {
            targets.push(goal);
        }
    }
    Ok(targets)
}

/// Targets for `experiment`: where its babbler moves the effector (exp 1 joint draws of
/// spread 0.35 rad, exp 2 the space above the table).
pub fn experiment_targets(
    experiment: Experiment,
    model: &ArmModel,
    count: usize,
    seed: u64,
) -> Result<Vec<Vector3<f64>>, ControlError> {
    match experiment {
        Experiment::Exp1 => sample_targets(model, count, 0.35, seed),
        Experiment::Exp2 => sample_table_targets(model, &Scene::default(), count, seed),
    }
}

/// How close IK must bring the effector to a target for it to count as reachable, m.
pub const REACHABLE_WITHIN_M: f64 = 1e-3;

/// Refuses a target the arm cannot reach (no joint values within the limits put the
/// effector within [`REACHABLE_WITHIN_M`] of it), saying how close the arm gets, so no
/// controller is scored on an impossible goal.
pub fn check_reachable(model: &ArmModel, target: &Vector3<f64>) -> Result<(), ControlError> {
    if !target.iter().all(|v| v.is_finite()) {
        return Err(ControlError::Options(format!(
            "target ({}, {}, {}) is not a finite position",
            target.x, target.y, target.z
        )));
    }
    let options = IkOptions {
        tolerance_m: REACHABLE_WITHIN_M,
        ..IkOptions::default()
    };
    model
        .inverse(&IkTarget::position(target.x, target.y, target.z), &options)
        .map(|_| ())
        .map_err(|e| ControlError::Options(format!("out of the arm's reach: {e}")))
}

/// The joint step that moves the effector by `dx` (damped least squares on the position
/// rows of the Jacobian: Jᵀ (J Jᵀ + λ² I)⁻¹ dx).
pub fn jacobian_step(
    model: &ArmModel,
    q: &[f64],
    dx: &Vector3<f64>,
    damping: f64,
) -> Result<[f64; ARM_DOF], ControlError> {
    let jacobian = model.jacobian(q).map_err(kinematics_err)?;
    let linear = jacobian.rows(0, 3);
    let gram = linear * linear.transpose() + Matrix3::identity() * damping * damping;
    let solve = gram
        .try_inverse()
        .ok_or_else(|| ControlError::Kinematics("singular Jacobian".into()))?;
    let dq = linear.transpose() * (solve * dx);
    let mut out = [0.0; ARM_DOF];
    for (o, v) in out.iter_mut().zip(dq.iter()) {
        *o = *v;
    }
    Ok(out)
}

/// A reaching policy: one command per step, from the state and the target.
pub trait Controller {
    /// Name in reports.
    fn name(&self) -> &str;
    /// The command for this step.
    fn command(&mut self, state: &SimState, target: &Vector3<f64>)
    -> Result<Command, ControlError>;
    /// What the controller has to report beyond the episodes (its settings, time per
    /// decision, its model's accuracy along the way); nothing by default.
    fn report(&self) -> serde_json::Value {
        serde_json::Value::Null
    }
}

/// Moves toward the target by at most `max_step` metres per step, through the Jacobian.
pub struct JacobianController {
    model: ArmModel,
    /// Largest effector displacement asked for in one step, m.
    pub max_step: f64,
    /// Damping λ of the least-squares step.
    pub damping: f64,
}

impl JacobianController {
    /// A controller of `model` with the given step limit and damping 0.01.
    pub fn new(model: ArmModel, max_step: f64) -> Self {
        Self {
            model,
            max_step,
            damping: 0.01,
        }
    }
}

impl Controller for JacobianController {
    fn name(&self) -> &str {
        "jacobian"
    }

    fn command(
        &mut self,
        state: &SimState,
        target: &Vector3<f64>,
    ) -> Result<Command, ControlError> {
        let q = state.joint_positions;
        let dx = clipped_step(state, target, self.max_step);
        let dq = jacobian_step(&self.model, &q, &dx, self.damping)?;
        Ok(joint_command(&self.model, &q, &dq))
    }
}

/// A learned inverse model: the action a(t) that takes s(t) to s(t+1).
pub trait InverseModel {
    /// The action for `state` → `next_state` (exp 1: θ and ef, 10 features each).
    fn action(&self, state: &[f64], next_state: &[f64]) -> Result<Vec<f64>, String>;
}

/// Where each next-state feature an inverse model takes (as `/trainer/model_info` names
/// them) sits in the state (`state`: the state's feature names), so the controller can
/// hand it exactly those features of the intermediate state.
pub fn next_state_indices(state: &[String], next: &[String]) -> Result<Vec<usize>, ControlError> {
    if next.is_empty() {
        return Err(ControlError::Model(
            "it names no next-state features: not an inverse model".into(),
        ));
    }
    next.iter()
        .map(|n| {
            state.iter().position(|s| s == n).ok_or_else(|| {
                ControlError::Model(format!(
                    "its next-state feature {n} is not a state feature ({state:?})"
                ))
            })
        })
        .collect()
}

/// Asks an inverse model for the action toward an intermediate state each step.
pub struct ImController<M> {
    model: ArmModel,
    layout: StateLayout,
    im: M,
    /// Largest effector displacement asked for in one step, m.
    pub max_step: f64,
    stall: Stall,
}

/// Progress toward the current target, to notice when the IM no longer brings the
/// effector closer (a configuration its actions do not lead out of) and babble once.
struct Stall {
    target: Vector3<f64>,
    best: f64,
    since_best: usize,
    rng: StdRng,
    jitter: Normal<f64>,
}

/// Steps without 1 mm of progress after which the IM controller babbles once.
const STALL_STEPS: usize = 20;

impl<M: InverseModel> ImController<M> {
    /// An IM controller of `model`, for states laid out as `layout`, with the given step
    /// limit.
    pub fn new(model: ArmModel, layout: StateLayout, im: M, max_step: f64) -> Self {
        Self {
            model,
            layout,
            im,
            max_step,
            stall: Stall {
                target: Vector3::repeat(f64::NAN),
                best: f64::INFINITY,
                since_best: 0,
                rng: StdRng::seed_from_u64(0),
                jitter: Normal::new(0.0, 0.3).expect("positive spread"),
            },
        }
    }

    /// s(t), the intermediate s* it asks the IM about (the arm moved, the rest of the
    /// state as it is), and the factor the IM's action is scaled by.
    ///
    /// s* always lies a full `max_step` toward the target. Closer to the target than
    /// that, the action for the full step is scaled down to the remaining distance,
    /// which is right to first order (the effector moves linearly in a small joint
    /// change). Asked for the short remaining step itself, a learned IM stalls or
    /// drifts: on 100 targets the paper-profile exp 1 IM reached 62 % within 1 cm
    /// unscaled and 84 % scaled (docs/runs/reach/exp1_100_targets.txt).
    pub fn query(
        &self,
        state: &SimState,
        target: &Vector3<f64>,
    ) -> Result<(Vec<f64>, Vec<f64>, f64), ControlError> {
        let q = state.joint_positions;
        let ef = state.ef_pose.translation.vector;
        let remaining = (target - ef).norm();
        let (dx, scale) = if remaining > 0.0 {
            let full = (target - ef) * (self.max_step / remaining);
            (full, (remaining / self.max_step).min(1.0))
        } else {
            (Vector3::zeros(), 0.0)
        };
        let dq = jacobian_step(&self.model, &q, &dx, 0.01)?;
        let now = self.layout.state(state);
        let mut goal_q = q;
        for (g, d) in goal_q.iter_mut().zip(dq) {
            *g += d;
        }
        let goal = self.layout.moved(&self.model, &now, &goal_q, &(ef + dx))?;
        Ok((now, goal, scale))
    }
}

impl<M: InverseModel> Controller for ImController<M> {
    fn name(&self) -> &str {
        "im"
    }

    fn command(
        &mut self,
        state: &SimState,
        target: &Vector3<f64>,
    ) -> Result<Command, ControlError> {
        if let Some(command) = self.babble_if_stalled(state, target) {
            return Ok(command);
        }
        let (now, goal, scale) = self.query(state, target)?;
        let action = self.im.action(&now, &goal).map_err(ControlError::Model)?;
        if action.len() < ARM_DOF || action.iter().take(ARM_DOF).any(|a| !a.is_finite()) {
            return Err(ControlError::Model(format!(
                "expected {ARM_DOF} finite joint deltas, got {action:?}"
            )));
        }
        let q = state.joint_positions;
        let mut dq = [0.0; ARM_DOF];
        for (d, a) in dq.iter_mut().zip(&action) {
            *d = a * scale;
        }
        Ok(joint_command(&self.model, &q, &dq))
    }
}

impl<M> ImController<M> {
    fn babble_if_stalled(&mut self, state: &SimState, target: &Vector3<f64>) -> Option<Command> {
        let stall = &mut self.stall;
        let distance = (target - state.ef_pose.translation.vector).norm();
        if stall.target != *target {
            (stall.target, stall.best, stall.since_best) = (*target, distance, 0);
        } else if distance < stall.best - 1e-3 {
            (stall.best, stall.since_best) = (distance, 0);
        } else {
            stall.since_best += 1;
        }
        if stall.since_best < STALL_STEPS {
            return None;
        }
        (stall.best, stall.since_best) = (distance, 0);
        let q = state.joint_positions;
        let mut dq = [0.0; ARM_DOF];
        for d in &mut dq {
            *d = stall.jitter.sample(&mut stall.rng);
        }
        Some(joint_command(&self.model, &q, &dq))
    }
}

/// Exp 1's babbling: random joint targets, whatever the target.
pub struct RandomController {
    rng: StdRng,
    normal: Normal<f64>,
    limits: Vec<(f64, f64)>,
}

impl RandomController {
    /// Babbling with spread `sigma`, seeded.
    pub fn new(model: &ArmModel, sigma: f64, seed: u64) -> Result<Self, ControlError> {
        Ok(Self {
            rng: StdRng::seed_from_u64(seed),
            normal: spread(sigma)?,
            limits: model.limits().iter().map(|l| (l.lower, l.upper)).collect(),
        })
    }
}

impl Controller for RandomController {
    fn name(&self) -> &str {
        "random"
    }

    fn command(&mut self, _: &SimState, _: &Vector3<f64>) -> Result<Command, ControlError> {
        let mut joint_targets = [0.0; ARM_DOF];
        for (t, (lo, hi)) in joint_targets.iter_mut().zip(&self.limits) {
            *t = self.normal.sample(&mut self.rng).clamp(*lo, *hi);
        }
        Ok(Command {
            joint_targets,
            magnet: 0,
        })
    }
}

/// How one reaching episode went.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Episode {
    /// Target effector position, m.
    pub target: [f64; 3],
    /// Distance to the target at the start, m.
    pub start_error: f64,
    /// Distance at the end of the episode, m.
    pub final_error: f64,
    /// First step after which the effector was within 1 cm, if ever.
    pub within_1cm_at: Option<usize>,
    /// First step after which it was within 5 mm, if ever.
    pub within_5mm_at: Option<usize>,
    /// Steps run (the episode ends at 5 mm or after the step budget).
    pub steps: usize,
}

impl Episode {
    /// An episode toward `target` that starts in `state`, no step run yet.
    pub fn start(target: &Vector3<f64>, state: &SimState) -> Self {
        let error = distance(state, target);
        Self {
            target: [target.x, target.y, target.z],
            start_error: error,
            final_error: error,
            within_1cm_at: None,
            within_5mm_at: None,
            steps: 0,
        }
    }

    /// One more step has run and left the arm in `state`.
    pub fn record(&mut self, state: &SimState) {
        let error = distance(state, &Vector3::from(self.target));
        self.steps += 1;
        self.final_error = error;
        if error <= 0.01 {
            self.within_1cm_at.get_or_insert(self.steps);
        }
        if error <= 0.005 {
            self.within_5mm_at.get_or_insert(self.steps);
        }
    }

    /// Within 5 mm: the episode is over (the arm holds still from here).
    pub fn reached(&self) -> bool {
        self.within_5mm_at.is_some()
    }
}

/// The effector's distance to `target` in `state`, m.
fn distance(state: &SimState, target: &Vector3<f64>) -> f64 {
    (state.ef_pose.translation.vector - target).norm()
}

/// The command that keeps the arm where it is (what a reached target gets while the
/// rest of a fixed-length episode runs out).
pub fn hold(state: &SimState) -> Command {
    Command {
        joint_targets: state.joint_positions,
        magnet: 0,
    }
}

/// Runs one episode from the simulator's current state (a fresh simulator's, or one
/// just reset with `reset_episode`, as the simulator node does between episodes): at
/// most `max_steps` commands, ending early once within 5 mm.
pub fn run_episode(
    sim: &mut Simulator,
    controller: &mut dyn Controller,
    target: &Vector3<f64>,
    max_steps: usize,
) -> Result<Episode, ControlError> {
    let mut state = sim.state();
    let mut episode = Episode::start(target, &state);
    while episode.steps < max_steps && !episode.reached() {
        let command = controller.command(&state, target)?;
        state = sim
            .step(&command)
            .map_err(|e| ControlError::Sim(e.to_string()))?;
        episode.record(&state);
    }
    Ok(episode)
}

/// Runs one episode as the simulator node runs it for the reacher: `run_episode`, then
/// the arm held still until the episode's `max_steps + 1` actions are done (the last
/// state's action included), so the world (the cube, its contacts) goes on exactly as
/// over DDS and the next episode starts from the same simulator.
pub fn run_fixed_episode(
    sim: &mut Simulator,
    controller: &mut dyn Controller,
    target: &Vector3<f64>,
    max_steps: usize,
) -> Result<Episode, ControlError> {
    let episode = run_episode(sim, controller, target, max_steps)?;
    for _ in episode.steps..=max_steps {
        let state = sim.state();
        sim.step(&hold(&state))
            .map_err(|e| ControlError::Sim(e.to_string()))?;
    }
    Ok(episode)
}

/// Success rates and error quantiles of a controller's episodes.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Summary {
    /// Controller name.
    pub controller: String,
    /// Episodes run.
    pub episodes: usize,
    /// Share of episodes that came within 1 cm.
    pub success_1cm: f64,
    /// Share that came within 5 mm.
    pub success_5mm: f64,
    /// Median steps to 1 cm over the successful episodes.
    pub median_steps_to_1cm: Option<usize>,
    /// Final error quantiles (10 %, 50 %, 90 %), m.
    pub final_error_p10_p50_p90: [f64; 3],
}

/// The 10 %, 50 % and 90 % quantiles of `values` (nearest rank; NaN when empty).
pub(crate) fn p10_p50_p90(values: impl Iterator<Item = f64>) -> [f64; 3] {
    let mut sorted: Vec<f64> = values.collect();
    sorted.sort_by(f64::total_cmp);
    [0.1, 0.5, 0.9].map(|p| match sorted.len() {
        0 => f64::NAN,
        len => sorted[((len - 1) as f64 * p).round() as usize],
    })
}

/// Summarises `episodes` of `controller`.
pub fn summarize(controller: &str, episodes: &[Episode]) -> Summary {
    let n = episodes.len().max(1) as f64;
    let share = |f: fn(&Episode) -> bool| episodes.iter().filter(|e| f(e)).count() as f64 / n;
    let mut steps: Vec<usize> = episodes.iter().filter_map(|e| e.within_1cm_at).collect();
    steps.sort_unstable();
    Summary {
        controller: controller.to_owned(),
        episodes: episodes.len(),
        success_1cm: share(|e| e.within_1cm_at.is_some()),
        success_5mm: share(|e| e.within_5mm_at.is_some()),
        median_steps_to_1cm: steps.get(steps.len() / 2).copied(),
        final_error_p10_p50_p90: p10_p50_p90(episodes.iter().map(|e| e.final_error)),
    }
}

/// A zero-mean normal of standard deviation `sigma`, which must be positive.
fn spread(sigma: f64) -> Result<Normal<f64>, ControlError> {
    match sigma.is_finite() && sigma > 0.0 {
        true => Normal::new(0.0, sigma).map_err(|e| ControlError::Options(e.to_string())),
        false => Err(ControlError::Options(format!(
            "the joint spread must be a positive number of radians, got {sigma}"
        ))),
    }
}

fn clipped_step(state: &SimState, target: &Vector3<f64>, max_step: f64) -> Vector3<f64> {
    let dx = target - state.ef_pose.translation.vector;
    match dx.norm() > max_step {
        true => dx * (max_step / dx.norm()),
        false => dx,
    }
}

fn joint_command(model: &ArmModel, q: &[f64; ARM_DOF], dq: &[f64; ARM_DOF]) -> Command {
    let mut joint_targets = [0.0; ARM_DOF];
    for (i, (t, l)) in joint_targets.iter_mut().zip(model.limits()).enumerate() {
        *t = (q[i] + dq[i]).clamp(l.lower, l.upper);
    }
    Command {
        joint_targets,
        magnet: 0,
    }
}

fn kinematics_err(e: impl std::fmt::Display) -> ControlError {
    ControlError::Kinematics(e.to_string())
}

#[cfg(test)]
mod tests;
