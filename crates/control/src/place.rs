//! Exp 2's task for the planner: move the cube to a spot on the table. The arm moves by
//! FM-MPC ([`MpcController::step_toward`]): to the cube's top scored on the FM's
//! predicted effector, then, holding the cube, to above the spot scored on the FM's
//! predicted *cube* position, so carrying relies on the model knowing that a held cube
//! follows the magnet. The magnet is switched by rule on the observed state: on once the
//! tip is at the cube's top, off once the cube hangs over the spot.

use causal_arm_protocol::{Command, Scene, SimState};
use causal_arm_sim::Simulator;
use rand::{Rng as _, SeedableRng, rngs::StdRng};

use crate::mpc::Goal;
use crate::{ControlError, ForwardModel, MpcController, Vector3, hold, p10_p50_p90};

/// Where the arm is in the task.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum Phase {
    /// Moving the magnet above the cube.
    Approach,
    /// Lowering the magnet onto the cube's top.
    Descend,
    /// Magnet switched on; waiting to see the cube held.
    Grasp,
    /// Carrying the cube over the spot.
    Carry,
    /// Over the spot, holding still so the magnet lets go of a cube at rest (a moving
    /// tip throws the cube with its velocity).
    Settle,
    /// Magnet switched off over the spot; the cube drops.
    Release,
}

/// How close the tip must be to the cube's top before the magnet is switched on, m
/// (the magnet grips within 2 cm of the cube's surface).
const GRASP_WITHIN: f64 = 0.012;
/// Height above the cube's top from which the magnet descends onto it, m.
const APPROACH_HEIGHT: f64 = 0.08;
/// Height of the carried cube's centre above its resting height, m.
const CARRY_HEIGHT: f64 = 0.015;
/// How close (horizontally) the carried cube must hang over the spot before release, m.
const RELEASE_WITHIN: f64 = 0.008;

/// Picks the cube and places it on a spot, planning the motion with an FM.
pub struct PlaceController<F> {
    mpc: MpcController<F>,
    scene: Scene,
    phase: Phase,
    grasps: usize,
    last_ef: Option<Vector3<f64>>,
}

impl<F: ForwardModel> PlaceController<F> {
    /// The task over `mpc` (an exp 2 FM-MPC controller) in `scene`.
    pub fn new(mpc: MpcController<F>, scene: Scene) -> Self {
        Self {
            mpc,
            scene,
            phase: Phase::Approach,
            grasps: 0,
            last_ef: None,
        }
    }

    /// A new trial begins: the cube lies somewhere, the magnet is off.
    pub fn reset(&mut self) {
        (self.phase, self.grasps, self.last_ef) = (Phase::Approach, 0, None);
    }

    /// The phase the last command was in.
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// Magnet switch-ons so far in this trial.
    pub fn grasps(&self) -> usize {
        self.grasps
    }

    /// The planner's report (its CEM settings, decisions and prediction errors).
    pub fn report(&self) -> serde_json::Value {
        use crate::Controller as _;
        self.mpc.report()
    }

    /// The command for this step toward placing the cube on `spot` (x, y on the table).
    pub fn command(
        &mut self,
        state: &SimState,
        spot: &Vector3<f64>,
    ) -> Result<Command, ControlError> {
        let cube = state.cube_pose.translation.vector;
        let ef = state.ef_pose.translation.vector;
        let still = self.last_ef.is_some_and(|last| (ef - last).norm() < 5e-4);
        self.last_ef = Some(ef);
        let resting_z = self.scene.table_top_z + self.scene.cube_size / 2.0;
        self.phase = match (self.phase, state.holding) {
            (Phase::Grasp, true) => Phase::Carry,
            // The magnet caught nothing (or lost the cube): try again.
            (Phase::Grasp | Phase::Carry | Phase::Settle, false) => Phase::Approach,
            (phase, _) => phase,
        };
        match self.phase {
            Phase::Approach | Phase::Descend => {
                let ef = state.ef_pose.translation.vector;
                let top = cube + Vector3::new(0.0, 0.0, self.scene.cube_size / 2.0);
                let above = top + Vector3::new(0.0, 0.0, APPROACH_HEIGHT);
                if (ef - top).norm() <= GRASP_WITHIN {
                    (self.phase, self.grasps) = (Phase::Grasp, self.grasps + 1);
                    return Ok(Command {
                        magnet: 1,
                        ..hold(state)
                    });
                }
                let over = Vector3::new(ef.x - top.x, ef.y - top.y, 0.0).norm() <= 0.015;
                // Down only from straight above the cube, so no link sweeps it away.
                self.phase = match (self.phase, over && ef.z > top.z) {
                    (Phase::Approach, true) if (ef - above).norm() <= 0.015 => Phase::Descend,
                    (Phase::Descend, false) => Phase::Approach,
                    (phase, _) => phase,
                };
                let goal = match self.phase {
                    Phase::Descend => top,
                    _ => above,
                };
                self.mpc.step_toward(state, Goal::EffectorDown(goal), 0)
            }
            Phase::Grasp => Ok(hold(state)),
            Phase::Carry | Phase::Settle => {
                let over = Vector3::new(spot.x, spot.y, resting_z + CARRY_HEIGHT);
                let off = Vector3::new(cube.x - over.x, cube.y - over.y, 0.0).norm();
                let there = off <= RELEASE_WITHIN && (cube.z - over.z).abs() <= 0.01;
                match (self.phase, there, still) {
                    (Phase::Settle, true, true) => {
                        self.phase = Phase::Release;
                        Ok(Command {
                            magnet: -1,
                            ..hold(state)
                        })
                    }
                    (_, true, _) => {
                        self.phase = Phase::Settle;
                        Ok(hold(state))
                    }
                    _ => {
                        self.phase = Phase::Carry;
                        self.mpc.step_toward(state, Goal::Cube(over), 0)
                    }
                }
            }
            Phase::Release => Ok(hold(state)),
        }
    }
}

/// Spots on the table to place the cube on: uniform where the simulator spawns cubes
/// (the table's top less `margin` at each edge).
pub fn sample_spots(scene: &Scene, margin: f64, count: usize, seed: u64) -> Vec<Vector3<f64>> {
    let mut rng = StdRng::seed_from_u64(seed);
    let [cx, cy] = scene.table_center;
    let [hx, hy] = scene.table_half_extents;
    (0..count)
        .map(|_| {
            Vector3::new(
                rng.random_range(cx - hx + margin..cx + hx - margin),
                rng.random_range(cy - hy + margin..cy + hy - margin),
                scene.table_top_z,
            )
        })
        .collect()
}

/// How one placing trial went.
#[derive(Debug, Clone, serde::Serialize)]
pub struct PlaceTrial {
    /// The spot, m (z: the table's top).
    pub spot: [f64; 3],
    /// The cube's horizontal distance to the spot at the start, m.
    pub start_distance: f64,
    /// Its horizontal distance at the end, m.
    pub final_distance: f64,
    /// The cube rests on the table at the end (not held, not on the floor).
    pub resting: bool,
    /// Step at which the cube was first held, if ever.
    pub held_at: Option<usize>,
    /// Step at which the magnet released it over the spot, if ever.
    pub released_at: Option<usize>,
    /// Magnet switch-ons.
    pub grasps: usize,
    /// Steps run.
    pub steps: usize,
}

/// Steps the cube gets to land after the release before a trial is over.
pub const SETTLE_STEPS: usize = 10;

impl PlaceTrial {
    /// A trial toward `spot` that starts in `state`, no step run yet.
    pub fn start(spot: &Vector3<f64>, state: &SimState, scene: &Scene) -> Self {
        let mut trial = Self {
            spot: [spot.x, spot.y, spot.z],
            start_distance: 0.0,
            final_distance: 0.0,
            resting: false,
            held_at: None,
            released_at: None,
            grasps: 0,
            steps: 0,
        };
        trial.observe(state, scene);
        trial.start_distance = trial.final_distance;
        trial
    }

    /// One more step has run, its command switching the magnet by `magnet`, and left
    /// the world in `state`; `grasps` is the controller's count of switch-ons.
    pub fn record(&mut self, magnet: i8, state: &SimState, scene: &Scene, grasps: usize) {
        if magnet == -1 && self.released_at.is_none() {
            self.released_at = Some(self.steps);
        }
        self.steps += 1;
        if state.holding {
            self.held_at.get_or_insert(self.steps);
        }
        self.grasps = grasps;
        self.observe(state, scene);
    }

    /// Over: the cube has had [`SETTLE_STEPS`] to land since the release.
    pub fn over(&self) -> bool {
        self.released_at
            .is_some_and(|r| self.steps >= r + SETTLE_STEPS)
    }

    fn observe(&mut self, state: &SimState, scene: &Scene) {
        let c = state.cube_pose.translation.vector;
        self.final_distance = Vector3::new(c.x - self.spot[0], c.y - self.spot[1], 0.0).norm();
        self.resting = !state.holding && scene.cube_rests_on_table([c.x, c.y, c.z]);
    }

    /// Placed: resting on the table within `within` m of the spot.
    pub fn placed(&self, within: f64) -> bool {
        self.resting && self.final_distance <= within
    }
}

/// Runs one trial from the simulator's current state as the simulator node runs it for
/// the reacher: commands until the trial is over ([`SETTLE_STEPS`] after the release)
/// or `max_steps` ran, then the arm held still until `max_steps + 1` actions are done.
pub fn run_place_trial<F: ForwardModel>(
    sim: &mut Simulator,
    controller: &mut PlaceController<F>,
    spot: &Vector3<f64>,
    max_steps: usize,
) -> Result<PlaceTrial, ControlError> {
    controller.reset();
    let scene = sim.config().scene();
    let step = |sim: &mut Simulator, command: &Command| {
        sim.step(command)
            .map_err(|e| ControlError::Sim(e.to_string()))
    };
    let mut state = sim.state();
    let mut trial = PlaceTrial::start(spot, &state, &scene);
    while trial.steps < max_steps && !trial.over() {
        let command = controller.command(&state, spot)?;
        state = step(sim, &command)?;
        trial.record(command.magnet, &state, &scene, controller.grasps());
    }
    for _ in trial.steps..=max_steps {
        state = step(sim, &hold(&state))?;
    }
    Ok(trial)
}

/// Success shares of placing trials.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct PlaceSummary {
    /// Trials run.
    pub trials: usize,
    /// Share placed within 3 cm (the criterion).
    pub placed_3cm: f64,
    /// Share placed within 1 cm.
    pub placed_1cm: f64,
    /// Share in which the cube was ever held.
    pub held: f64,
    /// Final horizontal distance quantiles (10 %, 50 %, 90 %), m.
    pub final_distance_p10_p50_p90: [f64; 3],
}

/// Summarises placing trials.
pub fn summarize_place(trials: &[PlaceTrial]) -> PlaceSummary {
    let n = trials.len().max(1) as f64;
    let share = |f: &dyn Fn(&PlaceTrial) -> bool| trials.iter().filter(|t| f(t)).count() as f64 / n;
    PlaceSummary {
        trials: trials.len(),
        placed_3cm: share(&|t| t.placed(0.03)),
        placed_1cm: share(&|t| t.placed(0.01)),
        held: share(&|t| t.held_at.is_some()),
        final_distance_p10_p50_p90: p10_p50_p90(trials.iter().map(|t| t.final_distance)),
    }
}

#[cfg(test)]
mod tests {
    use std::cell::RefCell;
    use std::rc::Rc;

    use causal_arm_kinematics::ArmModel;
    use causal_arm_protocol::{ARM_DOF, Experiment};
    use causal_arm_sim::SimConfig;

    use super::*;
    use crate::{CemSettings, StateLayout};

    /// The simulator itself as a one-step FM: each row is the snapshot of the current
    /// state stepped with that row's action. With it the task logic must place the cube.
    struct SimFm {
        now: Rc<RefCell<Simulator>>,
        layout: StateLayout,
    }

    impl ForwardModel for SimFm {
        fn next_states(&self, _: &[f64], actions: &[f64], rows: usize) -> Result<Vec<f64>, String> {
            let width = self.layout.action_width;
            let mut out = Vec::new();
            for a in actions.chunks(width).take(rows) {
                let mut sim = self.now.borrow().clone();
                let q = sim.state().joint_positions;
                let mut command = hold(&sim.state());
                for j in 0..ARM_DOF {
                    command.joint_targets[j] = q[j] + a[j];
                }
                command.magnet = a[ARM_DOF] as i8;
                let next = sim.step(&command).map_err(|e| e.to_string())?;
                out.extend(self.layout.state(&next));
            }
            Ok(out)
        }
    }

    #[test]
    fn with_an_exact_model_the_cube_is_picked_carried_and_placed() {
        let model = ArmModel::embedded();
        let layout = StateLayout::of(Experiment::Exp2, &model);
        let sim = Rc::new(RefCell::new(Simulator::new(SimConfig::default()).unwrap()));
        sim.borrow_mut().reset_episode();
        let fm = SimFm {
            now: sim.clone(),
            layout: layout.clone(),
        };
        let settings = CemSettings {
            samples: 24,
            iterations: 2,
            ..CemSettings::default()
        };
        let mpc = MpcController::new(model, layout, fm, settings, 0).unwrap();
        let scene = sim.borrow().config().scene();
        let mut controller = PlaceController::new(mpc, scene);
        let spot = sample_spots(&scene, 0.05, 1, 9)[0];
        let mut released = false;
        for _ in 0..300 {
            let state = sim.borrow().state();
            let command = controller.command(&state, &spot).unwrap();
            released |= command.magnet == -1;
            sim.borrow_mut().step(&command).unwrap();
        }
        let cube = sim.borrow().state().cube_pose.translation.vector;
        let off = Vector3::new(cube.x - spot.x, cube.y - spot.y, 0.0).norm();
        assert!(
            released && controller.grasps() >= 1,
            "{:?}",
            controller.phase()
        );
        assert!(
            off <= 0.03 && scene.cube_rests_on_table([cube.x, cube.y, cube.z]),
            "{cube:?} vs {spot:?}"
        );
    }
}
