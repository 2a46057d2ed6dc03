//! What the simulator and the babbler exchange each step, as plain Rust values.
//!
//! The babbler decides from a [`SimState`] and answers with a [`Command`]; neither needs the
//! physics engine to know these shapes, so they live here and the babbler does not depend
//! on the simulator.

use nalgebra::Isometry3;

/// Number of actuated joints of the arm.
pub const ARM_DOF: usize = 7;

/// What the babbler asks for in one step.
#[derive(Debug, Clone, PartialEq)]
pub struct Command {
    /// Absolute joint targets, rad (clamped to the URDF limits by the motors).
    pub joint_targets: [f64; ARM_DOF],
    /// −1 switch off, 0 keep, +1 switch on.
    pub magnet: i8,
}

/// Everything the simulator reports after a step, all at one sim time.
#[derive(Debug, Clone, PartialEq)]
pub struct SimState {
    /// Sim time, ns since the start of the run.
    pub stamp_ns: u64,
    /// Step index since the start of the run.
    pub step: u64,
    /// Episode index.
    pub episode: u32,
    /// Joint positions, rad.
    pub joint_positions: [f64; ARM_DOF],
    /// Joint velocities, rad/s.
    pub joint_velocities: [f64; ARM_DOF],
    /// Commanded joint torques are not modelled; the servo's acceleration times the joint
    /// inertia is reported as effort, N m.
    pub joint_efforts: [f64; ARM_DOF],
    /// `ef` pose in the world frame.
    pub ef_pose: Isometry3<f64>,
    /// Cube pose in the world frame.
    pub cube_pose: Isometry3<f64>,
    /// Cube colour, RGB in [0, 1].
    pub cube_rgb: [f32; 3],
    /// Magnet switched on.
    pub magnet_on: bool,
    /// Magnet holds the cube.
    pub holding: bool,
}
