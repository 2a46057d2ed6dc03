//! Settings of the simulated world: physics rate, servo gain, table, cube and arm shapes.

use causal_arm_protocol::{ARM_DOF, Scene, scene};

use crate::SimError;

/// Simulator settings; defaults follow the paper's protocol (PyBullet-like 240 Hz, 10 substeps).
#[derive(Debug, Clone)]
pub struct SimConfig {
    /// Physics step, s.
    pub dt: f64,
    /// Physics steps per command.
    pub substeps: u32,
    /// Servo gain: commanded joint velocity = gain × position error (1/s), before limits.
    pub servo_gain: f64,
    /// Scales the URDF velocity limits (1.0 = as the URDF says).
    pub velocity_scale: f64,
    /// Magnet grips when the cube's nearest face is within this distance of the tip, m.
    pub capture_distance: f64,
    /// Edge length of the cube, m.
    pub cube_size: f64,
    /// Mass of the cube, kg.
    pub cube_mass: f64,
    /// Height of the table's top surface, m.
    pub table_top_z: f64,
    /// Table top centre (x, y) and half extents (x, y), m.
    pub table_center: [f64; 2],
    /// Half extents of the table top, m.
    pub table_half_extents: [f64; 2],
    /// Cube spawn area on the table: margin from the table edge, m.
    pub spawn_margin: f64,
    /// Friction coefficient of cube, table and floor.
    pub friction: f64,
    /// Joint configuration at the start of each episode, rad.
    pub home: [f64; ARM_DOF],
    /// Seed of cube placement and colour.
    pub seed: u64,
    /// Collision shape of the arm links' URDF cylinders (the magnet tool is always exact).
    pub link_cylinders: LinkCylinders,
    /// How the arm moves: placed by forward kinematics, or a multibody moved by motors.
    pub arm: ArmMode,
    /// Dynamic arm: the share of a joint's position error its motor's velocity target
    /// closes per physics step, PyBullet's `positionGain` (myGym drives the arm with 0.7).
    pub motor_position_gain: f64,
}

/// How the simulated arm moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ArmMode {
    /// Links are kinematic bodies placed by forward kinematics from the servo: exact,
    /// deterministic and fast, but they pass through the table and push the cube with
    /// unlimited force.
    #[default]
    Kinematic,
    /// A rapier multibody with the URDF masses and inertias under gravity, moved by joint
    /// motors limited to the URDF velocities and efforts: it stalls on the table and can
    /// be pushed back.
    Dynamic,
}

causal_arm_protocol::choice!(ArmMode, "arm mode", [
    ArmMode::Kinematic => "kinematic",
    ArmMode::Dynamic => "dynamic",
]);

/// URDF link whose collision shape is always kept exact: the magnet tool touching the cube.
pub const MAGNET_LINK: &str = "magnet";

/// How the arm links' URDF cylinders become rapier colliders.
///
/// Cylinder–cube contacts go through GJK/EPA in parry, capsule–cube contacts have a
/// closed form; with capsules exp2 generation runs 14.8k → 19.0k steps/s. The capsule
/// keeps the cylinder's radius and overall length and rounds its ends, which only
/// matters where a link edge brushes the cube.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LinkCylinders {
    /// Capsules inscribed in the URDF cylinder's length (default, fast).
    Capsules,
    /// The URDF cylinders as they are.
    Exact,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            dt: 1.0 / 240.0,
            substeps: 10,
            servo_gain: 40.0,
            velocity_scale: 1.0,
            capture_distance: 0.02,
            cube_size: scene::CUBE_SIZE,
            cube_mass: 0.1,
            table_top_z: scene::TABLE_TOP_Z,
            table_center: scene::TABLE_CENTER,
            table_half_extents: scene::TABLE_HALF_EXTENTS,
            spawn_margin: 0.05,
            friction: 0.8,
            home: [0.0, 0.5, 0.0, -1.2, 0.0, 0.8, 0.0],
            seed: 0,
            link_cylinders: LinkCylinders::Capsules,
            arm: ArmMode::Kinematic,
            motor_position_gain: 0.7,
        }
    }
}

impl SimConfig {
    /// The table and cube this configuration builds, for judging its states (contexts).
    pub fn scene(&self) -> Scene {
        Scene {
            table_top_z: self.table_top_z,
            table_center: self.table_center,
            table_half_extents: self.table_half_extents,
            cube_size: self.cube_size,
        }
    }

    /// Refuses settings that would make the physics or the servo meaningless.
    pub(crate) fn check(&self) -> Result<(), SimError> {
        if !(self.dt > 0.0
            && self.substeps > 0
            && self.servo_gain > 0.0
            && self.velocity_scale > 0.0
            && self.motor_position_gain > 0.0)
        {
            return Err(SimError::Config(format!(
                "dt ({}), substeps ({}), servo_gain ({}), velocity_scale ({}) and motor_position_gain ({}) must be positive",
                self.dt,
                self.substeps,
                self.servo_gain,
                self.velocity_scale,
                self.motor_position_gain
            )));
        }
        Ok(())
    }
}
