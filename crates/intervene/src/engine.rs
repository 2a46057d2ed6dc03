//! Re-simulating a bag and intervening on the states it visited.

use std::path::Path;
use std::sync::mpsc;
use std::time::Instant;

use causal_arm_dataset::{
    Context, ContextState, action_names, angular_features, state_features, state_names, wrap_angle,
};
use causal_arm_protocol::{Command, Experiment, SimState, sim_seed};
use causal_arm_sim::{SimConfig, Simulator};
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand::seq::index::sample;

use causal_arm_truth::{EdgeMatrix, FORMAT, Plan, Truth};

use crate::{InterveneError, Trace};

/// What the interventions at one state found.
struct StateEffects {
    /// Trace index of the state.
    index: usize,
    /// Which contexts the state belongs to, in [`Context::of`] order.
    contexts: Vec<bool>,
    /// `[horizon][action][state]`: the largest |Δ| any intervention on the action caused.
    effects: Vec<f64>,
    /// Largest |Δ| between two identical replays.
    replay: f64,
    /// The factual one-step change s(t+1) − s(t) per feature (Euler angles wrapped).
    step: Vec<f64>,
}

/// Everything a worker needs besides the snapshot.
struct Setup<'a> {
    trace: &'a Trace,
    plan: &'a Plan,
    joint_deltas: Vec<Vec<f64>>,
    angular: Vec<bool>,
    n_action: usize,
    n_state: usize,
    contexts: Vec<Context>,
}

impl Setup<'_> {
    /// The features of s(t+1) … s(t+horizon) from `snapshot` when the command at t is
    /// `first` and the recorded ones follow.
    fn rollout(
        &self,
        snapshot: &Simulator,
        index: usize,
        first: &Command,
    ) -> Result<Vec<f64>, InterveneError> {
        let mut sim = snapshot.clone();
        let mut out = Vec::with_capacity(self.plan.horizon * self.n_state);
        for h in 0..self.plan.horizon {
            let command = if h == 0 {
                first
            } else {
                &self.trace.steps[index + h].command
            };
            let state = sim.step(command)?;
            out.extend(state_features(
                self.trace.experiment,
                &sim.step_messages(&state),
            ));
        }
        Ok(out)
    }

    /// a − b per feature, Euler angles wrapped.
    fn signed_difference(&self, a: &[f64], b: &[f64], k: usize) -> f64 {
        let d = a[k] - b[k];
        if self.angular[k % self.n_state] {
            wrap_angle(d)
        } else {
            d
        }
    }

    /// |a − b| per feature, Euler angles wrapped.
    fn difference(&self, a: &[f64], b: &[f64], k: usize) -> f64 {
        self.signed_difference(a, b, k).abs()
    }

    /// Intervenes on every action at the trace's state `index` (the snapshot).
    fn effects_at(
        &self,
        index: usize,
        snapshot: Simulator,
    ) -> Result<StateEffects, InterveneError> {
        let recorded = &self.trace.steps[index].command;
        let factual = self.rollout(&snapshot, index, recorded)?;
        let replayed = self.rollout(&snapshot, index, recorded)?;
        let replay = (0..factual.len())
            .map(|k| self.difference(&factual, &replayed, k))
            .fold(0.0, f64::max);
        let (h_len, a_len) = (self.n_action * self.n_state, self.n_state);
        let mut effects = vec![0f64; self.plan.horizon * h_len];
        let mut record = |action: usize, counterfactual: &[f64]| {
            for h in 0..self.plan.horizon {
                for k in 0..self.n_state {
                    let d = self.difference(counterfactual, &factual, h * self.n_state + k);
                    let e = &mut effects[h * h_len + action * a_len + k];
                    *e = f64::max(*e, d);
                }
            }
        };
        for (j, deltas) in self.joint_deltas.iter().enumerate() {
            for &delta in deltas {
                let mut command = recorded.clone();
                command.joint_targets[j] += delta;
                record(j, &self.rollout(&snapshot, index, &command)?);
            }
        }
        if self.trace.experiment == Experiment::Exp2 {
            for magnet in [-1, 0, 1].into_iter().filter(|&m| m != recorded.magnet) {
                let command = Command {
                    magnet,
                    ..recorded.clone()
                };
                // a_mgt is the last action, after the seven joint deltas.
                record(
                    self.n_action - 1,
                    &self.rollout(&snapshot, index, &command)?,
                );
            }
        }
        let state = snapshot.state();
        let now = state_features(self.trace.experiment, &snapshot.step_messages(&state));
        let step = (0..self.n_state)
            .map(|k| self.signed_difference(&factual, &now, k))
            .collect();
        Ok(StateEffects {
            index,
            contexts: self
                .contexts
                .iter()
                .map(|c| c.holds(&ContextState::of_sim(&state), &snapshot.config().scene()))
                .collect(),
            effects,
            replay,
            step,
        })
    }
}

/// Runs the interventions of `plan` on the states of `bag` (an `experiment` bag written by
/// `causal-arm generate` or `launch`). `progress(done, total)` follows the re-simulation.
pub fn intervene(
    bag: &Path,
    experiment: Experiment,
    plan: &Plan,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Truth, InterveneError> {
    plan.check()?;
    let started = Instant::now();
    let trace = Trace::read(bag, experiment)?;
    let starts = trace.transition_starts(plan.horizon);
    if starts.len() < plan.states {
        return Err(InterveneError::Options(format!(
            "{}: the bag has {} states with {} more steps in the same episode; --states {} asks for more",
            bag.display(),
            starts.len(),
            plan.horizon,
            plan.states
        )));
    }
    let mut rng = StdRng::seed_from_u64(plan.seed);
    let mut chosen: Vec<usize> = sample(&mut rng, starts.len(), plan.states)
        .into_iter()
        .map(|i| starts[i])
        .collect();
    chosen.sort_unstable();
    let sigma = trace.command_delta_std();
    let setup = Setup {
        trace: &trace,
        plan,
        joint_deltas: sigma
            .iter()
            .map(|s| {
                plan.delta_scales
                    .iter()
                    .flat_map(|k| [-k * s, k * s])
                    .collect()
            })
            .collect(),
        angular: angular_features(experiment),
        n_action: action_names(experiment).len(),
        n_state: state_names(experiment).len(),
        contexts: Context::of(experiment),
    };
    let (mut found, resimulated) = run_workers(&setup, &chosen, progress)?;
    found.sort_by_key(|e| e.index);
    let feature_step_std = step_std(setup.n_state, &found);
    Ok(Truth {
        format: FORMAT.to_owned(),
        experiment: experiment.to_string(),
        bag: bag.display().to_string(),
        action_names: action_names(experiment),
        state_names: state_names(experiment),
        plan: plan.clone(),
        joint_deltas: setup.joint_deltas.clone(),
        resimulated_steps: resimulated,
        noise_floor: found.iter().map(|e| e.replay).fold(0.0, f64::max),
        seconds: started.elapsed().as_secs_f64(),
        matrices: summarise(&setup, &found, &feature_step_std),
        feature_step_std,
    })
}

/// The simulator settings the bag's run used.
fn simulator_config(trace: &Trace) -> SimConfig {
    SimConfig {
        seed: sim_seed(trace.seed),
        velocity_scale: trace.velocity_scale,
        arm: trace.arm,
        ..SimConfig::default()
    }
}

/// Re-simulates the trace up to the last chosen state on this thread, handing a snapshot
/// of every chosen state to worker threads. Returns the effects and the steps checked.
fn run_workers(
    setup: &Setup,
    chosen: &[usize],
    progress: &mut dyn FnMut(u64, u64),
) -> Result<(Vec<StateEffects>, usize), InterveneError> {
    let threads = setup.plan.threads.unwrap_or_else(|| {
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
    });
    let (task_tx, task_rx) = mpsc::sync_channel::<(usize, Simulator)>(2 * threads);
    let task_rx = std::sync::Mutex::new(task_rx);
    let (done_tx, done_rx) = mpsc::channel();
    std::thread::scope(|scope| {
        for _ in 0..threads {
            let done_tx = done_tx.clone();
            let task_rx = &task_rx;
            scope.spawn(move || {
                loop {
                    let task = task_rx.lock().map(|rx| rx.recv());
                    let Ok(Ok((index, snapshot))) = task else {
                        break;
                    };
                    if done_tx.send(setup.effects_at(index, snapshot)).is_err() {
                        break;
                    }
                }
            });
        }
        drop(done_tx);
        let resimulated = resimulate(setup.trace, chosen, &task_tx, progress);
        drop(task_tx);
        let found: Result<Vec<StateEffects>, InterveneError> = done_rx.iter().collect();
        Ok((found?, resimulated?))
    })
}

/// Steps the simulator through the bag's commands, checking every state against the
/// recorded joints and stamp, and sends a snapshot of each chosen state.
fn resimulate(
    trace: &Trace,
    chosen: &[usize],
    tasks: &mpsc::SyncSender<(usize, Simulator)>,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<usize, InterveneError> {
    let Some(&last) = chosen.last() else {
        return Ok(0);
    };
    let mut sim = Simulator::new(simulator_config(trace))?;
    let mut next = 0;
    for (i, recorded) in trace.steps[..=last].iter().enumerate() {
        if recorded.episode != sim.state().episode {
            sim.reset_episode();
        }
        let state = sim.state();
        check_against_bag(&state, recorded)?;
        if chosen.get(next) == Some(&i) {
            next += 1;
            if tasks.send((i, sim.clone())).is_err() {
                break; // a worker failed; its error is reported
            }
        }
        sim.step(&recorded.command)?;
        progress(i as u64 + 1, last as u64 + 1);
    }
    Ok(last + 1)
}

/// The re-simulated state must be the recorded one, bit for bit.
fn check_against_bag(state: &SimState, recorded: &crate::TraceStep) -> Result<(), InterveneError> {
    let diverged = |what: String| {
        Err(InterveneError::Options(format!(
            "re-simulation left the bag at stamp {} ns (episode {}, step {}): {what}; the bag was not written by this simulator version with the settings it records",
            recorded.stamp_ns, recorded.episode, recorded.step
        )))
    };
    if state.stamp_ns != recorded.stamp_ns || state.episode != recorded.episode {
        return diverged(format!(
            "simulated stamp {} ns in episode {}",
            state.stamp_ns, state.episode
        ));
    }
    for j in 0..7 {
        if state.joint_positions[j].to_bits() != recorded.theta[j].to_bits() {
            return diverged(format!(
                "theta{j} recorded {:e}, simulated {:e}",
                recorded.theta[j], state.joint_positions[j]
            ));
        }
    }
    Ok(())
}

/// Std of each feature's factual one-step change over the intervened states.
fn step_std(n_state: usize, found: &[StateEffects]) -> Vec<f64> {
    let n = found.len().max(1) as f64;
    (0..n_state)
        .map(|k| {
            let mean = found.iter().map(|e| e.step[k]).sum::<f64>() / n;
            let var = found
                .iter()
                .map(|e| (e.step[k] - mean).powi(2))
                .sum::<f64>()
                / n;
            var.sqrt()
        })
        .collect()
}

/// Edge statistics per context and horizon. An effect on feature k counts above the plan's
/// tolerance and its effect size times the feature's step std (`feature_step_std[k]`).
fn summarise(setup: &Setup, found: &[StateEffects], feature_step_std: &[f64]) -> Vec<EdgeMatrix> {
    let (na, ns) = (setup.n_action, setup.n_state);
    let thresholds: Vec<f64> = feature_step_std
        .iter()
        .map(|std| f64::max(setup.plan.tolerance, setup.plan.effect_size * std))
        .collect();
    let mut out = Vec::new();
    for h in 0..setup.plan.horizon {
        for (c, context) in setup.contexts.iter().enumerate() {
            let members: Vec<&StateEffects> = found.iter().filter(|e| e.contexts[c]).collect();
            let cell = |a: usize, k: usize| {
                let values = members.iter().map(|e| e.effects[h * na * ns + a * ns + k]);
                let active: Vec<f64> = values.clone().filter(|&v| v > thresholds[k]).collect();
                let fraction = active.len() as f64 / members.len().max(1) as f64;
                let mean = active.iter().sum::<f64>() / active.len().max(1) as f64;
                (fraction, mean, values.fold(0.0, f64::max))
            };
            let cells: Vec<Vec<(f64, f64, f64)>> = (0..na)
                .map(|a| (0..ns).map(|k| cell(a, k)).collect())
                .collect();
            let pick = |f: fn(&(f64, f64, f64)) -> f64| {
                cells
                    .iter()
                    .map(|row| row.iter().map(f).collect())
                    .collect()
            };
            out.push(EdgeMatrix {
                context: context.name.to_owned(),
                horizon: h + 1,
                states: members.len(),
                active_fraction: pick(|c| c.0),
                mean_effect: pick(|c| c.1),
                max_effect: pick(|c| c.2),
            });
        }
    }
    out
}
