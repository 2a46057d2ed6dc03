//! The simulated world of the experiments: the iiwa arm with its magnet, a table and a
//! cube, stepped one babbling command at a time.
//!
//! Design choices (see the crate README section in the project README):
//! - **Arm motors** are position servos integrated in joint space, with the URDF velocity
//!   limit and an acceleration limit derived from the URDF effort limit and the inertia
//!   the joint moves (distal links at the home pose). The arm's links are kinematic bodies
//!   in rapier3d placed by our own forward kinematics, so they push the cube but are not
//!   pushed back. This keeps joint tracking exact, deterministic and fast: physics only
//!   integrates the cube (the one free body) and its contacts. `SimConfig::arm =
//!   ArmMode::Dynamic` makes the arm a rapier multibody instead, under gravity, whose
//!   speed- and torque-limited joint motors track the same servo path (`dynamic.rs`).
//! - **Physics** is rapier3d at 240 Hz; each command runs for `substeps` steps (10).
//!   The links' URDF cylinders become capsules of the same radius and length (see
//!   [`LinkCylinders`]); the magnet tool keeps its exact cylinder.
//! - **Magnet**: when on and the cube is within `capture_distance` of the `ef` tip it
//!   grips the cube rigidly; when switched off it releases it with the tip's velocity and
//!   the cube falls and settles under gravity and friction.
//!
//! Node wrappers publish [`SimState`] as ROS messages; this crate has no DDS in it, so
//! it is tested and benchmarked directly.

// Joint loops index several parallel per-joint arrays; an index reads better than zips.
#![allow(clippy::needless_range_loop)]

mod config;
mod dynamic;
mod loads;
mod magnet;
mod probe;
mod servo;
mod world;

pub use config::{ArmMode, LinkCylinders, MAGNET_LINK, SimConfig};
pub use dynamic::SELF_COLLISION_EXEMPT;
pub use probe::TableProbe;

use ::nalgebra::Isometry3;
use causal_arm_kinematics::{ArmModel, KinematicsError};
use causal_arm_msgs::std_msgs::msg::String as RosString;
use causal_arm_protocol::{
    ARM_DOF, Command, LatchedMessages, SimState, StepMessages, frames, static_tf_message,
    step_messages,
};
use rand::rngs::StdRng;
use rapier3d::prelude::{PhysicsWorld, RigidBodyHandle};
use thiserror::Error;

use dynamic::DynamicArm;
use servo::ServoLimits;
use world::{LinkBody, clone_world, from_pose};

/// Why a simulator could not be built or a command was refused.
#[derive(Debug, Error)]
pub enum SimError {
    /// The arm model is unusable.
    #[error(transparent)]
    Kinematics(#[from] KinematicsError),
    /// A command is malformed (wrong length, not finite).
    #[error("invalid command: {0}")]
    Command(String),
    /// The configuration is inconsistent.
    #[error("invalid simulator configuration: {0}")]
    Config(String),
}

/// The world. One instance per run; episodes are reset in place.
///
/// `clone()` is a snapshot: the copy holds the whole state (rapier bodies, colliders,
/// contacts, islands and broad phase; servo velocities; magnet grip; cube colour; the
/// placement RNG; step and episode counters) and steps exactly as the original would,
/// bit for bit. Interventions branch from it: restore, step with an edited command,
/// compare.
pub struct Simulator {
    config: SimConfig,
    model: ArmModel,
    world: PhysicsWorld,
    links: Vec<LinkBody>,
    cube: RigidBodyHandle,
    q: [f64; ARM_DOF],
    qd: [f64; ARM_DOF],
    effort: [f64; ARM_DOF],
    limits: ServoLimits,
    dynamic: Option<DynamicArm>,
    ef: Isometry3<f64>,
    magnet_on: bool,
    hold_offset: Option<Isometry3<f64>>,
    cube_rgb: [f32; 3],
    rng: StdRng,
    step: u64,
    episode: u32,
}

impl Clone for Simulator {
    fn clone(&self) -> Self {
        Self {
            config: self.config.clone(),
            model: self.model.clone(),
            world: clone_world(&self.world),
            links: self.links.clone(),
            cube: self.cube,
            q: self.q,
            qd: self.qd,
            effort: self.effort,
            limits: self.limits.clone(),
            dynamic: self.dynamic.clone(),
            ef: self.ef,
            magnet_on: self.magnet_on,
            hold_offset: self.hold_offset,
            cube_rgb: self.cube_rgb,
            rng: self.rng.clone(),
            step: self.step,
            episode: self.episode,
        }
    }
}

impl Simulator {
    /// Builds the world from the embedded URDF.
    pub fn new(config: SimConfig) -> Result<Self, SimError> {
        let robot = urdf_rs::read_from_string(causal_arm_kinematics::EMBEDDED_IIWA_URDF)
            .map_err(|e| SimError::Config(format!("embedded URDF: {e}")))?;
        Self::from_robot(&robot, config)
    }

    /// Starts a new episode: arm at home, magnet off, cube at a random spot on the table
    /// with a random yaw and a random colour.
    /// The sim clock keeps running (the reset takes no sim time; the last state of the
    /// previous episode is superseded), so stamps never repeat.
    pub fn reset_episode(&mut self) {
        self.episode += 1;
        self.place_episode();
    }

    /// Validates a command (7 finite targets, magnet in −1..=1).
    pub fn check_command(command: &Command) -> Result<(), SimError> {
        if let Some((i, v)) = command
            .joint_targets
            .iter()
            .enumerate()
            .find(|(_, v)| !v.is_finite())
        {
            return Err(SimError::Command(format!("joint target {i} is {v}")));
        }
        if !(-1..=1).contains(&command.magnet) {
            return Err(SimError::Command(format!(
                "magnet must be -1, 0 or 1, got {}",
                command.magnet
            )));
        }
        Ok(())
    }

    /// Executes one command for `substeps` physics steps and returns the new state.
    pub fn step(&mut self, command: &Command) -> Result<SimState, SimError> {
        Self::check_command(command)?;
        match command.magnet {
            1 => self.magnet_on = true,
            -1 => self.magnet_on = false,
            _ => {}
        }
        let target: [f64; ARM_DOF] = std::array::from_fn(|i| {
            command.joint_targets[i].clamp(self.limits.lower[i], self.limits.upper[i])
        });
        let dt = self.config.dt;
        for _ in 0..self.config.substeps {
            match self.dynamic.is_some() {
                false => {
                    self.servo(&target, dt);
                    let previous_ef = self.ef;
                    self.place_arm(false);
                    self.update_magnet(&previous_ef, dt);
                    self.world.step();
                }
                true => {
                    self.drive_dynamic_arm(&target, dt);
                    self.world.step();
                    self.read_dynamic_joints();
                    self.update_dynamic_magnet();
                }
            }
        }
        self.step += 1;
        Ok(self.state())
    }

    /// The current state.
    pub fn state(&self) -> SimState {
        let cube_pose = self
            .body_pose(self.cube)
            .unwrap_or_else(Isometry3::identity);
        let step_duration_ns = self.config.dt * self.config.substeps as f64 * 1e9;
        SimState {
            stamp_ns: (self.step as f64 * step_duration_ns).round() as u64,
            step: self.step,
            episode: self.episode,
            joint_positions: self.q,
            joint_velocities: self.qd,
            joint_efforts: self.effort,
            ef_pose: self.ef,
            cube_pose,
            cube_rgb: self.cube_rgb,
            magnet_on: self.magnet_on,
            holding: self.hold_offset.is_some(),
        }
    }

    /// The pose of one of the world's bodies (the cube, a link), if it exists.
    fn body_pose(&self, body: RigidBodyHandle) -> Option<Isometry3<f64>> {
        self.world.bodies.get(body).map(|b| from_pose(b.position()))
    }

    /// The arm model the simulator uses (for IK in the babbler and for names).
    pub fn model(&self) -> &ArmModel {
        &self.model
    }

    /// The configuration in use.
    pub fn config(&self) -> &SimConfig {
        &self.config
    }

    /// The messages a simulator publishes for `state` (one of this simulator's), `/tf`
    /// with the arm's revolute joints at the state's joint values.
    pub fn step_messages(&self, state: &SimState) -> StepMessages {
        let frames = self
            .model
            .moving_frames(&state.joint_positions)
            .expect("the arm model has ARM_DOF joints (checked when it was built)");
        step_messages(state, &self.model.joint_names(), frames)
    }

    /// What the run publishes once, latched: the URDF the arm was built from and
    /// `/tf_static` (the arm's fixed joints and the table of this configuration).
    pub fn latched_messages(&self) -> LatchedMessages {
        LatchedMessages {
            robot_description: RosString {
                data: causal_arm_kinematics::EMBEDDED_IIWA_URDF.to_owned(),
            },
            tf_static: static_tf_message(&self.model.fixed_frames(), &self.config.scene()),
        }
    }

    /// Name of the tool frame reported as `ef_pose`.
    pub fn ef_frame() -> &'static str {
        frames::EF
    }
}

#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_dynamic;
