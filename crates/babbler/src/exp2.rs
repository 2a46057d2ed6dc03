//! Experiment 2: babbles empty-handed; at random switches the magnet on, then reaches the
//! cube (IK, from above), picks it, manoeuvres randomly for a random number of steps,
//! places it and switches the magnet off, and babbles again.

use causal_arm_kinematics::{ArmModel, IkOptions, IkTarget};
use causal_arm_protocol::{ARM_DOF, Command, Design, Draw, Drawn, SimState, ToolRegion, scene};
use rand::{Rng, SeedableRng, rngs::StdRng};
use rand_distr::{Distribution, Normal};

use crate::limits_of;

/// Redraws of a random move before the babbler holds the arm instead.
const MOVE_TRIES: u32 = 20;

/// How the joints of the step being chosen were drawn (experiment 2).
#[derive(Debug, Clone, Copy, PartialEq)]
enum JointDraw {
    /// Set by the script (IK, holding still).
    Scripted,
    /// A random move of spread `sigma` around the current configuration, kept inside the
    /// safe region (over the table area too when `over_table`).
    Near { sigma: f64, over_table: bool },
}

/// Settings of experiment 2.
#[derive(Debug, Clone)]
pub struct Exp2Config {
    /// Probability per step of switching the magnet on while babbling empty-handed.
    pub switch_on_probability: f64,
    /// Probability per step of a spurious "off" command while babbling (magnet already off).
    /// Default 0: such a command changes nothing, so no model can tell it from "keep" given
    /// (s(t), s(t+1)); at 0.02 it put an MAE floor of 0.0094 under the exp2 inverse model's
    /// magnet head (paper: 4.6e-4).
    pub spurious_off_probability: f64,
    /// Spread of the empty-handed babbling around the current configuration, rad.
    pub babble_sigma: f64,
    /// Move while switching the magnet: the switch-on step babbles (spread `babble_sigma`)
    /// and the release step moves a little (spread `babble_sigma` / 3) instead of holding
    /// the arm still. Holding still makes a magnet command always coincide with a resting
    /// arm, so no model can learn from the data that the magnet does not move the joints
    /// (docs/RESULTS.md, "Causal claims against the simulator"). On by default, as in the
    /// paper's myGym, where the magnet command is one more component of an action whose
    /// joint part is babbled at the same step.
    pub move_while_switching: bool,
    /// Spread of the manoeuvres while holding, rad.
    pub manoeuvre_sigma: f64,
    /// Manoeuvre duration range, steps.
    pub manoeuvre_steps: (u32, u32),
    /// Minimum babbling duration before the magnet may switch on again, steps.
    pub min_babble_steps: u32,
    /// Give up reaching after this many steps.
    pub reach_timeout_steps: u32,
    /// Height above the cube centre of the approach pose, m.
    pub approach_height: f64,
    /// Lowest height of ef above the table top while babbling or manoeuvring, m.
    pub min_clearance: f64,
    /// Table top height, m (from the simulator configuration).
    pub table_top_z: f64,
    /// Cube edge length, m.
    pub cube_size: f64,
    /// While holding, ef stays above this table area (centre x, y and half extents, m), so
    /// a released cube lands on the table.
    pub table_area: ([f64; 2], [f64; 2]),
    /// Height of the cube's bottom above the table top when it is released, m.
    pub release_height: f64,
    /// Give up carrying the cube to its release point after this many steps (release where
    /// it is).
    pub place_timeout_steps: u32,
    /// Seed.
    pub seed: u64,
}

impl Default for Exp2Config {
    fn default() -> Self {
        Self {
            switch_on_probability: 0.05,
            spurious_off_probability: 0.0,
            babble_sigma: 0.15,
            move_while_switching: true,
            manoeuvre_sigma: 0.1,
            manoeuvre_steps: (20, 80),
            min_babble_steps: 10,
            reach_timeout_steps: 80,
            approach_height: 0.12,
            min_clearance: 0.06,
            table_top_z: scene::TABLE_TOP_Z,
            cube_size: scene::CUBE_SIZE,
            // The table less a cube edge on each side (datagen derives it the same way).
            table_area: (scene::TABLE_CENTER, [0.15, 0.25]),
            release_height: 0.03,
            place_timeout_steps: 40,
            seed: 0,
        }
    }
}

impl Exp2Config {
    /// The design in words, for the bag's metadata.
    pub fn design_words(&self) -> String {
        let floor = self.table_top_z + self.min_clearance;
        let ([cx, cy], [hx, hy]) = self.table_area;
        let switching = match self.move_while_switching {
            true => "the arm moves as it babbles",
            false => "the arm holds still",
        };
        format!(
            "exp2: babbling: joint targets ~ clamp(theta + N(0, {b}^2), limits), redrawn together (up to {MOVE_TRIES} tries, else held: scripted) until the tool is at z >= {floor:.3} m; \
             magnet on with probability {on} once {min} babbling steps have passed (then {switching}), off with probability {off}, else keep; \
             holding: targets ~ clamp(theta + N(0, {m}^2), limits) with the tool also over |x - {cx}| <= {hx}, |y - {cy}| <= {hy}, magnet keep (scripted); \
             release: targets ~ clamp(theta + N(0, {r}^2), limits) above z >= {floor:.3} m, magnet off (scripted); \
             approach, descend, lift and place: IK from the state and the cube (scripted)",
            b = self.babble_sigma,
            on = self.switch_on_probability,
            min = self.min_babble_steps,
            off = self.spurious_off_probability,
            m = self.manoeuvre_sigma,
            r = self.babble_sigma / 3.0,
        )
    }
}

/// Where the exp 2 babbler is in its cycle.
#[derive(Debug, Clone, PartialEq)]
pub enum Phase {
    /// Empty-handed babbling, for at least the given number of further steps.
    Babble { min_remaining: u32 },
    /// Moving above the cube with the magnet on.
    Approach { steps: u32 },
    /// Descending onto the cube until it is held.
    Descend { steps: u32 },
    /// Random moves while holding, for the given number of further steps.
    Manoeuvre { remaining: u32 },
    /// Carrying the cube to a release point low over the table (x, y), then switching off.
    /// Releasing mid-manoeuvre threw the cube with the tip's velocity, off the table in 63 %
    /// of the drops, where it lay out of reach for the rest of the episode.
    Place { steps: u32, x: f64, y: f64 },
}

/// Magnet-driven babbling (experiment 2).
pub struct Exp2Babbler {
    config: Exp2Config,
    model: ArmModel,
    rng: StdRng,
    lower: [f64; ARM_DOF],
    upper: [f64; ARM_DOF],
    phase: Phase,
    ik_seed: u64,
    ik_cache: Option<(IkTarget, [f64; ARM_DOF])>,
    /// How the step being chosen drew its joints and its magnet command (values and
    /// probabilities); reset at every step.
    joint_draw: JointDraw,
    magnet_draw: Option<(Vec<f64>, Vec<f64>)>,
}

impl Exp2Babbler {
    /// A babbler for `model` with `config`.
    pub fn new(model: &ArmModel, config: Exp2Config) -> Result<Self, String> {
        if !(0.0..=1.0).contains(&config.switch_on_probability) {
            return Err(format!(
                "switch_on_probability must be in [0, 1], got {}",
                config.switch_on_probability
            ));
        }
        if config.manoeuvre_steps.0 == 0 || config.manoeuvre_steps.0 > config.manoeuvre_steps.1 {
            return Err(format!(
                "manoeuvre_steps must be 1 <= min <= max, got {:?}",
                config.manoeuvre_steps
            ));
        }
        let (lower, upper) = limits_of(model);
        Ok(Self {
            rng: StdRng::seed_from_u64(config.seed),
            phase: Phase::Babble {
                min_remaining: config.min_babble_steps,
            },
            config,
            model: model.clone(),
            lower,
            upper,
            ik_seed: 0,
            ik_cache: None,
            joint_draw: JointDraw::Scripted,
            magnet_draw: None,
        })
    }

    /// The current phase (for logs and tests).
    pub fn phase(&self) -> &Phase {
        &self.phase
    }

    /// Starts a new episode (the simulator reset the arm and cube).
    pub fn reset(&mut self) {
        self.phase = Phase::Babble {
            min_remaining: self.config.min_babble_steps,
        };
    }

    /// A random configuration near `q` whose ef stays above the table top (and, when
    /// `over_table`, above the table area).
    fn random_near(&mut self, q: &[f64; ARM_DOF], sigma: f64, over_table: bool) -> [f64; ARM_DOF] {
        let normal = Normal::new(0.0, sigma.max(1e-9)).expect("positive sigma");
        // The region the design records is the one the moves are kept in.
        let region = self.region(over_table);
        for _ in 0..region.tries {
            let candidate: [f64; ARM_DOF] = std::array::from_fn(|i| {
                (q[i] + normal.sample(&mut self.rng)).clamp(self.lower[i], self.upper[i])
            });
            let ok = (self.model.ef_pose(&candidate))
                .is_ok_and(|p| region.holds(p.translation.vector.into()));
            if ok {
                self.joint_draw = JointDraw::Near { sigma, over_table };
                return candidate;
            }
        }
        // No safe random move found: stay where we are.
        *q
    }

    /// The region a random move of the joints must keep the tool in.
    fn region(&self, over_table: bool) -> ToolRegion {
        let ([cx, cy], [hx, hy]) = self.config.table_area;
        ToolRegion {
            tries: MOVE_TRIES,
            min_tool_z: self.config.table_top_z + self.config.min_clearance,
            tool_area: over_table.then_some([cx, cy, hx, hy]),
        }
    }

    /// How the step just chosen from joint positions `q` was drawn: the joints, then the
    /// magnet.
    fn design(&self, q: &[f64; ARM_DOF]) -> Design {
        let joints = (0..ARM_DOF).map(|i| match self.joint_draw {
            JointDraw::Near { sigma, over_table } if sigma > 0.0 => Draw::Normal {
                center: q[i],
                sigma,
                lower: self.lower[i],
                upper: self.upper[i],
                region: Some(self.region(over_table)),
            },
            _ => Draw::Scripted,
        });
        let magnet = match &self.magnet_draw {
            Some((values, probabilities)) if values.len() > 1 => Draw::Categorical {
                values: values.clone(),
                probabilities: probabilities.clone(),
            },
            _ => Draw::Scripted,
        };
        joints.chain(std::iter::once(magnet)).collect()
    }

    /// IK for `target`, solved once per distinct target: while the babbler approaches or
    /// descends onto a resting cube the target is the same every step, so the joint-space
    /// goal is reused (the servo moves toward it) instead of re-solved.
    fn ik(&mut self, q: &[f64; ARM_DOF], target: IkTarget) -> Option<[f64; ARM_DOF]> {
        if let Some((cached_target, joints)) = &self.ik_cache
            && (cached_target.position - target.position).norm() < 1e-9
            && cached_target.orientation == target.orientation
        {
            return Some(*joints);
        }
        let solved = self.solve_ik(q, &target);
        if let Some(joints) = solved {
            self.ik_cache = Some((target, joints));
        }
        solved
    }

    fn solve_ik(&mut self, q: &[f64; ARM_DOF], target: &IkTarget) -> Option<[f64; ARM_DOF]> {
        self.ik_seed += 1;
        let options = IkOptions {
            initial: Some(q.to_vec()),
            seed: self.ik_seed,
            max_attempts: 5,
            tolerance_m: 1e-3,
            tolerance_rad: 2e-2,
            ..IkOptions::default()
        };
        self.model
            .inverse(target, &options)
            .ok()
            .map(|s| s.joints.try_into().expect("7 joints"))
    }

    /// The next command for `state`.
    pub fn next(&mut self, state: &SimState) -> Command {
        self.next_drawn(state).command
    }

    /// The next command for `state` and how it was drawn: random moves and the magnet's
    /// switch-on while babbling, random moves while holding and at the release; the
    /// reaching, lifting and placing are scripted.
    pub fn next_drawn(&mut self, state: &SimState) -> Drawn {
        self.joint_draw = JointDraw::Scripted;
        self.magnet_draw = None;
        let command = match self.phase.clone() {
            Phase::Babble { min_remaining } => self.babble(&state.joint_positions, min_remaining),
            Phase::Approach { steps } => self.approach(state, steps),
            Phase::Descend { steps } => self.descend(state, steps),
            Phase::Manoeuvre { remaining } => self.manoeuvre(state, remaining),
            Phase::Place { steps, x, y } => self.place(state, steps, x, y),
        };
        Drawn {
            design: self.design(&state.joint_positions),
            command,
        }
    }

    /// The magnet command's distribution while babbling: on with the switch-on
    /// probability once the babbling has lasted long enough, else a spurious off with its
    /// probability, else keep (values with a positive probability only).
    fn babble_magnet_draw(&self, may_switch_on: bool) -> (Vec<f64>, Vec<f64>) {
        let on = if may_switch_on {
            self.config.switch_on_probability
        } else {
            0.0
        };
        let off = (1.0 - on) * self.config.spurious_off_probability;
        [(-1.0, off), (0.0, 1.0 - on - off), (1.0, on)]
            .into_iter()
            .filter(|&(_, p)| p > 0.0)
            .unzip()
    }

    /// Empty-handed babbling near `q`; at random switches the magnet on and starts the
    /// approach (or sends a spurious "off").
    fn babble(&mut self, q: &[f64; ARM_DOF], min_remaining: u32) -> Command {
        let switch_on =
            min_remaining == 0 && self.rng.random_bool(self.config.switch_on_probability);
        let spurious_off = self.rng.random_bool(self.config.spurious_off_probability);
        self.magnet_draw = Some(self.babble_magnet_draw(min_remaining == 0));
        let targets = self.random_near(q, self.config.babble_sigma, false);
        if switch_on {
            self.phase = Phase::Approach { steps: 0 };
            if !self.config.move_while_switching {
                // Given the switch-on, the arm holds still.
                self.joint_draw = JointDraw::Scripted;
            }
            return Command {
                joint_targets: if self.config.move_while_switching {
                    targets
                } else {
                    *q
                },
                magnet: 1,
            };
        }
        self.phase = Phase::Babble {
            min_remaining: min_remaining.saturating_sub(1),
        };
        Command {
            joint_targets: targets,
            magnet: if spurious_off { -1 } else { 0 },
        }
    }

    /// Point `approach_height` above the top of the cube in `state`, where ef goes before
    /// descending and where it lifts the picked cube to.
    fn above_cube(&self, state: &SimState) -> nalgebra::Vector3<f64> {
        let cube = state.cube_pose.translation.vector;
        let half = self.config.cube_size / 2.0;
        nalgebra::Vector3::new(cube.x, cube.y, cube.z + half + self.config.approach_height)
    }

    /// Moves above the cube; descends once there, gives up (releases) on timeout or
    /// when IK fails.
    fn approach(&mut self, state: &SimState, steps: u32) -> Command {
        let q = state.joint_positions;
        let above = self.above_cube(state);
        let Some(targets) = self.ik(&q, IkTarget::pointing_down(above.x, above.y, above.z)) else {
            return self.release(&q);
        };
        let close = (state.ef_pose.translation.vector - above).norm() < 0.01;
        self.phase = if close {
            Phase::Descend { steps: steps + 1 }
        } else {
            Phase::Approach { steps: steps + 1 }
        };
        if steps >= self.config.reach_timeout_steps {
            return self.release(&q);
        }
        Command {
            joint_targets: targets,
            magnet: 0,
        }
    }

    /// Descends onto the cube; once it is held, lifts it and starts a manoeuvre of random
    /// length. Gives up (releases) on timeout or when IK fails.
    fn descend(&mut self, state: &SimState, steps: u32) -> Command {
        let q = state.joint_positions;
        if state.holding {
            let (lo, hi) = self.config.manoeuvre_steps;
            let remaining = self.rng.random_range(lo..=hi);
            self.phase = Phase::Manoeuvre { remaining };
            let above = self.above_cube(state);
            let lift = self.ik(&q, IkTarget::pointing_down(above.x, above.y, above.z));
            return Command {
                joint_targets: lift.unwrap_or(q),
                magnet: 0,
            };
        }
        if steps >= self.config.reach_timeout_steps {
            return self.release(&q);
        }
        let cube = state.cube_pose.translation.vector;
        let half = self.config.cube_size / 2.0;
        let touch = IkTarget::pointing_down(cube.x, cube.y, cube.z + half + 0.005);
        let Some(targets) = self.ik(&q, touch) else {
            return self.release(&q);
        };
        self.phase = Phase::Descend { steps: steps + 1 };
        Command {
            joint_targets: targets,
            magnet: 0,
        }
    }

    /// Random moves over the table while holding; when they are done, picks a release
    /// point and starts placing the cube there.
    fn manoeuvre(&mut self, state: &SimState, remaining: u32) -> Command {
        let q = state.joint_positions;
        if !state.holding {
            return self.release(&q);
        }
        if remaining == 0 {
            let ([cx, cy], [hx, hy]) = self.config.table_area;
            let x = cx + self.rng.random_range(-0.8..=0.8) * hx;
            let y = cy + self.rng.random_range(-0.8..=0.8) * hy;
            self.phase = Phase::Place { steps: 0, x, y };
            return self.place_command(&q, x, y);
        }
        self.phase = Phase::Manoeuvre {
            remaining: remaining - 1,
        };
        let targets = self.random_near(&q, self.config.manoeuvre_sigma, true);
        Command {
            joint_targets: targets,
            magnet: 0,
        }
    }

    /// Carries the cube to its release point (x, y) and releases it on arrival, when it
    /// was lost, or on timeout.
    fn place(&mut self, state: &SimState, steps: u32, x: f64, y: f64) -> Command {
        let q = state.joint_positions;
        let target = self.release_pose(x, y).position;
        let arrived = (state.ef_pose.translation.vector - target.coords).norm() < 0.01
            && state.joint_velocities.iter().all(|v| v.abs() < 0.05);
        if !state.holding || arrived || steps >= self.config.place_timeout_steps {
            return self.release(&q);
        }
        self.phase = Phase::Place {
            steps: steps + 1,
            x,
            y,
        };
        self.place_command(&q, x, y)
    }

    /// Pose of ef that holds the cube `release_height` above the table at (x, y).
    fn release_pose(&self, x: f64, y: f64) -> IkTarget {
        IkTarget::pointing_down(
            x,
            y,
            self.config.table_top_z + self.config.cube_size + self.config.release_height,
        )
    }

    fn place_command(&mut self, q: &[f64; ARM_DOF], x: f64, y: f64) -> Command {
        let target = self.release_pose(x, y);
        match self.ik(q, target) {
            Some(joint_targets) => Command {
                joint_targets,
                magnet: 0,
            },
            None => self.release(q),
        }
    }

    /// Switches the magnet off where the arm is and goes back to babbling.
    fn release(&mut self, q: &[f64; ARM_DOF]) -> Command {
        self.phase = Phase::Babble {
            min_remaining: self.config.min_babble_steps,
        };
        let joint_targets = if self.config.move_while_switching {
            self.random_near(q, self.config.babble_sigma / 3.0, false)
        } else {
            *q
        };
        Command {
            joint_targets,
            magnet: -1,
        }
    }
}
