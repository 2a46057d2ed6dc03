//! The simulated world of the experiments: the iiwa arm with its magnet, a table and a
//! cube, stepped one babbling command at a time.
//!
//! Design choices (see the crate README section in the project README):
//! - **Arm motors** are position servos integrated in joint space, with the URDF velocity
//!   limit and an acceleration limit derived from the URDF effort limit and the inertia
//!   the joint moves (distal links at the home pose). The arm's links are kinematic bodies
//!   in rapier3d placed by our own forward kinematics, so they push the cube but are not
//!   pushed back. This keeps joint tracking exact, deterministic and fast: physics only
//!   integrates the cube (the one free body) and its contacts.
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

use ::nalgebra::{Isometry3, Point3, Quaternion, Translation3, UnitQuaternion, Vector3};
use causal_arm_kinematics::{ArmModel, KinematicsError};
use causal_arm_protocol::{ARM_DOF, Command, Scene, SimState, frames, scene};
use rand::{Rng, SeedableRng, rngs::StdRng};
use rapier3d::math::{Pose, Rotation, Vector};
use rapier3d::prelude::{
    ColliderBuilder, PhysicsWorld, RigidBodyBuilder, RigidBodyHandle, RigidBodyType,
};
use thiserror::Error;

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
}

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
}

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

#[derive(Clone)]
struct LinkBody {
    /// Index of the link in `ArmModel::link_poses` order.
    chain_index: usize,
    body: RigidBodyHandle,
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
    accel_limit: [f64; ARM_DOF],
    joint_inertia: [f64; ARM_DOF],
    velocity_limit: [f64; ARM_DOF],
    lower: [f64; ARM_DOF],
    upper: [f64; ARM_DOF],
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
            accel_limit: self.accel_limit,
            joint_inertia: self.joint_inertia,
            velocity_limit: self.velocity_limit,
            lower: self.lower,
            upper: self.upper,
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

/// Copies every piece of simulation state of `world`. The pipelines hold only workspace
/// buffers (rapier's own snapshot rule: they are skipped by its serde snapshots too), so
/// the copy gets fresh ones.
fn clone_world(world: &PhysicsWorld) -> PhysicsWorld {
    PhysicsWorld {
        gravity: world.gravity,
        integration_parameters: world.integration_parameters,
        physics_pipeline: rapier3d::prelude::PhysicsPipeline::new(),
        collision_pipeline: rapier3d::prelude::CollisionPipeline::new(),
        islands: world.islands.clone(),
        broad_phase: world.broad_phase.clone(),
        narrow_phase: world.narrow_phase.clone(),
        bodies: world.bodies.clone(),
        colliders: world.colliders.clone(),
        impulse_joints: world.impulse_joints.clone(),
        multibody_joints: world.multibody_joints.clone(),
        soft_bodies: world.soft_bodies.clone(),
        ccd_solver: world.ccd_solver.clone(),
    }
}

fn to_pose(iso: &Isometry3<f64>) -> Pose {
    let t = iso.translation.vector;
    let r = iso.rotation.coords;
    Pose::from_parts(
        Vector::new(t.x as f32, t.y as f32, t.z as f32),
        Rotation::from_xyzw(r.x as f32, r.y as f32, r.z as f32, r.w as f32).normalize(),
    )
}

fn from_pose(pose: &Pose) -> Isometry3<f64> {
    let t = pose.translation;
    let r = pose.rotation;
    Isometry3::from_parts(
        Translation3::new(t.x as f64, t.y as f64, t.z as f64),
        UnitQuaternion::from_quaternion(Quaternion::new(
            r.w as f64, r.x as f64, r.y as f64, r.z as f64,
        )),
    )
}

fn urdf_pose(pose: &urdf_rs::Pose) -> Isometry3<f64> {
    let [x, y, z] = *pose.xyz;
    let [roll, pitch, yaw] = *pose.rpy;
    Isometry3::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(roll, pitch, yaw),
    )
}

/// Collider for a URDF geometry, in the link frame (rapier cylinders run along y, URDF's along z).
fn collider_for(
    geometry: &urdf_rs::Geometry,
    origin: &Isometry3<f64>,
    cylinders: LinkCylinders,
) -> Option<ColliderBuilder> {
    let (builder, local) = match geometry {
        urdf_rs::Geometry::Box { size } => (
            ColliderBuilder::cuboid(
                size[0] as f32 / 2.0,
                size[1] as f32 / 2.0,
                size[2] as f32 / 2.0,
            ),
            Isometry3::identity(),
        ),
        urdf_rs::Geometry::Cylinder { radius, length } => (
            match cylinders {
                LinkCylinders::Exact => {
                    ColliderBuilder::cylinder(*length as f32 / 2.0, *radius as f32)
                }
                LinkCylinders::Capsules => ColliderBuilder::capsule_y(
                    (*length as f32 / 2.0 - *radius as f32).max(0.0),
                    *radius as f32,
                ),
            },
            Isometry3::rotation(Vector3::x() * std::f64::consts::FRAC_PI_2),
        ),
        urdf_rs::Geometry::Sphere { radius } => {
            (ColliderBuilder::ball(*radius as f32), Isometry3::identity())
        }
        _ => return None,
    };
    Some(builder.position(to_pose(&(origin * local))))
}

impl Simulator {
    /// Builds the world from the embedded URDF.
    pub fn new(config: SimConfig) -> Result<Self, SimError> {
        let robot = urdf_rs::read_from_string(causal_arm_kinematics::EMBEDDED_IIWA_URDF)
            .map_err(|e| SimError::Config(format!("embedded URDF: {e}")))?;
        Self::from_robot(&robot, config)
    }

    /// Builds the world from a parsed URDF of the arm.
    pub fn from_robot(robot: &urdf_rs::Robot, config: SimConfig) -> Result<Self, SimError> {
        if !(config.dt > 0.0
            && config.substeps > 0
            && config.servo_gain > 0.0
            && config.velocity_scale > 0.0)
        {
            return Err(SimError::Config(format!(
                "dt ({}), substeps ({}), servo_gain ({}) and velocity_scale ({}) must be positive",
                config.dt, config.substeps, config.servo_gain, config.velocity_scale
            )));
        }
        let model = ArmModel::from_robot(robot, "<arm URDF>")?;
        let mut world = PhysicsWorld::new();
        world.gravity = Vector::new(0.0, 0.0, -9.81);
        world.integration_parameters.dt = config.dt as f32;

        // Floor and table are fixed.
        world.insert(
            RigidBodyBuilder::fixed().translation(Vector::new(0.0, 0.0, -0.05)),
            ColliderBuilder::cuboid(5.0, 5.0, 0.05).friction(config.friction as f32),
        );
        let [cx, cy] = config.table_center;
        let [hx, hy] = config.table_half_extents;
        world.insert(
            RigidBodyBuilder::fixed().translation(Vector::new(
                cx as f32,
                cy as f32,
                config.table_top_z as f32 - 0.02,
            )),
            ColliderBuilder::cuboid(hx as f32, hy as f32, 0.02).friction(config.friction as f32),
        );

        // Arm links: kinematic bodies carrying the URDF collision shapes.
        let q0 = config.home;
        let poses = model.link_poses(&q0)?;
        let mut links = Vec::new();
        for (chain_index, (name, pose)) in poses.iter().enumerate() {
            let Some(link) = robot.links.iter().find(|l| &l.name == name) else {
                continue;
            };
            let shapes: Vec<ColliderBuilder> = link
                .collision
                .iter()
                .filter_map(|c| {
                    // The tool's flat face is what touches the cube: always exact.
                    let cylinders = if link.name == MAGNET_LINK {
                        LinkCylinders::Exact
                    } else {
                        config.link_cylinders
                    };
                    collider_for(&c.geometry, &urdf_pose(&c.origin), cylinders)
                })
                .collect();
            if shapes.is_empty() {
                continue;
            }
            let body =
                world.insert_body(RigidBodyBuilder::kinematic_position_based().pose(to_pose(pose)));
            for shape in shapes {
                world.colliders.insert_with_parent(
                    shape.friction(config.friction as f32),
                    body,
                    &mut world.bodies,
                );
            }
            links.push(LinkBody { chain_index, body });
        }
        // The cube.
        let half = config.cube_size as f32 / 2.0;
        let (cube, _) = world.insert(
            RigidBodyBuilder::dynamic().ccd_enabled(true),
            ColliderBuilder::cuboid(half, half, half)
                .mass(config.cube_mass as f32)
                .friction(config.friction as f32),
        );

        let limits = model.limits().to_vec();
        let joint_inertia = Self::joint_inertias(robot, &model, &q0)?;
        let mut accel_limit = [0.0; ARM_DOF];
        let mut velocity_limit = [0.0; ARM_DOF];
        let mut lower = [0.0; ARM_DOF];
        let mut upper = [0.0; ARM_DOF];
        for i in 0..ARM_DOF {
            accel_limit[i] = limits[i].effort / joint_inertia[i].max(1e-3);
            velocity_limit[i] = limits[i].velocity * config.velocity_scale;
            lower[i] = limits[i].lower;
            upper[i] = limits[i].upper;
        }
        let ef = model.ef_pose(&q0)?;
        let rng = StdRng::seed_from_u64(config.seed);
        let mut sim = Self {
            config,
            model,
            world,
            links,
            cube,
            q: q0,
            qd: [0.0; ARM_DOF],
            effort: [0.0; ARM_DOF],
            accel_limit,
            joint_inertia,
            velocity_limit,
            lower,
            upper,
            ef,
            magnet_on: false,
            hold_offset: None,
            cube_rgb: [0.8, 0.1, 0.1],
            rng,
            step: 0,
            episode: 0,
        };
        sim.place_episode();
        Ok(sim)
    }

    /// Moment of inertia each joint moves: distal link masses and inertias about the joint
    /// axis at `q` (a constant approximation used to turn effort limits into acceleration limits).
    fn joint_inertias(
        robot: &urdf_rs::Robot,
        model: &ArmModel,
        q: &[f64; ARM_DOF],
    ) -> Result<[f64; ARM_DOF], SimError> {
        let poses = model.link_poses(q)?;
        let jac_axes = model.jacobian(q)?;
        let mut joint_frames = Vec::new();
        // Joint i rotates every link after it; its axis passes through the frame of link i+1
        // (for the iiwa chain the revolute joints are followed by their child links in order).
        let mut revolute_children = Vec::new();
        for (name, pose) in &poses {
            if name.starts_with("iiwa_link_") && *name != "iiwa_link_0" {
                revolute_children.push((*name, *pose));
            }
        }
        for i in 0..ARM_DOF {
            let axis: Vector3<f64> = jac_axes.fixed_view::<3, 1>(3, i).into_owned();
            let origin = revolute_children
                .get(i)
                .map(|(_, p)| p.translation.vector)
                .unwrap_or_default();
            joint_frames.push((axis, origin));
        }
        let first_child_index: Vec<usize> = revolute_children
            .iter()
            .map(|(n, _)| poses.iter().position(|(m, _)| m == n).unwrap_or(0))
            .collect();
        let mut out = [0.0; ARM_DOF];
        for (i, (axis, origin)) in joint_frames.iter().enumerate() {
            let start = first_child_index.get(i).copied().unwrap_or(0);
            let mut inertia = 0.0;
            for (name, pose) in &poses[start..] {
                let Some(link) = robot.links.iter().find(|l| &l.name == name) else {
                    continue;
                };
                let m = link.inertial.mass.value;
                let com_local = urdf_pose(&link.inertial.origin);
                let com = pose * com_local;
                let r = com.translation.vector - origin;
                let d_perp = r - axis * axis.dot(&r);
                let i = &link.inertial.inertia;
                let local_axis = com.rotation.inverse() * axis;
                let tensor = ::nalgebra::Matrix3::new(
                    i.ixx, i.ixy, i.ixz, i.ixy, i.iyy, i.iyz, i.ixz, i.iyz, i.izz,
                );
                inertia += local_axis.dot(&(tensor * local_axis)) + m * d_perp.norm_squared();
            }
            out[i] = inertia;
        }
        Ok(out)
    }

    /// Starts a new episode: arm at home, magnet off, cube at a random spot on the table
    /// with a random yaw and a random colour.
    /// The sim clock keeps running (the reset takes no sim time; the last state of the
    /// previous episode is superseded), so stamps never repeat.
    pub fn reset_episode(&mut self) {
        self.episode += 1;
        self.place_episode();
    }

    fn place_episode(&mut self) {
        self.q = self.config.home;
        self.qd = [0.0; ARM_DOF];
        self.effort = [0.0; ARM_DOF];
        self.magnet_on = false;
        self.hold_offset = None;
        self.place_arm(true);
        let [cx, cy] = self.config.table_center;
        let [hx, hy] = self.config.table_half_extents;
        let m = self.config.spawn_margin;
        let x = self.rng.random_range(cx - hx + m..cx + hx - m);
        let y = self.rng.random_range(cy - hy + m..cy + hy - m);
        let yaw = self
            .rng
            .random_range(-std::f64::consts::PI..std::f64::consts::PI);
        self.cube_rgb = [self.rng.random(), self.rng.random(), self.rng.random()];
        let z = self.config.table_top_z + self.config.cube_size / 2.0 + 1e-4;
        let pose = Isometry3::from_parts(
            Translation3::new(x, y, z),
            UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
        );
        if let Some(body) = self.world.bodies.get_mut(self.cube) {
            body.set_body_type(RigidBodyType::Dynamic, true);
            body.set_position(to_pose(&pose), true);
            body.set_linvel(Vector::ZERO, true);
            body.set_angvel(Vector::ZERO, true);
        }
    }

    /// Moves the link bodies to the current joint configuration.
    fn place_arm(&mut self, teleport: bool) {
        let Ok(poses) = self.model.link_poses(&self.q) else {
            return;
        };
        self.ef = poses.last().map(|(_, p)| *p).unwrap_or(self.ef);
        for link in &self.links {
            let pose = to_pose(&poses[link.chain_index].1);
            if let Some(body) = self.world.bodies.get_mut(link.body) {
                if teleport {
                    body.set_position(pose, true);
                } else {
                    body.set_next_kinematic_position(pose);
                }
            }
        }
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
        let target: [f64; ARM_DOF] =
            std::array::from_fn(|i| command.joint_targets[i].clamp(self.lower[i], self.upper[i]));
        let dt = self.config.dt;
        for _ in 0..self.config.substeps {
            self.servo(&target, dt);
            let previous_ef = self.ef;
            self.place_arm(false);
            self.update_magnet(&previous_ef, dt);
            self.world.step();
        }
        self.step += 1;
        Ok(self.state())
    }

    fn servo(&mut self, target: &[f64; ARM_DOF], dt: f64) {
        for i in 0..ARM_DOF {
            let v_max = self.velocity_limit[i];
            let desired = (self.config.servo_gain * (target[i] - self.q[i])).clamp(-v_max, v_max);
            // Do not overshoot the target within this substep.
            let desired = if desired.abs() * dt > (target[i] - self.q[i]).abs() {
                (target[i] - self.q[i]) / dt
            } else {
                desired
            };
            let dv_max = self.accel_limit[i] * dt;
            let dv = (desired - self.qd[i]).clamp(-dv_max, dv_max);
            self.effort[i] = self.joint_inertia[i] * dv / dt;
            self.qd[i] += dv;
            let next = self.q[i] + self.qd[i] * dt;
            if next <= self.lower[i] || next >= self.upper[i] {
                self.q[i] = next.clamp(self.lower[i], self.upper[i]);
                self.qd[i] = 0.0;
            } else {
                self.q[i] = next;
            }
        }
    }

    fn update_magnet(&mut self, previous_ef: &Isometry3<f64>, dt: f64) {
        let Some(body) = self.world.bodies.get_mut(self.cube) else {
            return;
        };
        match (self.magnet_on, self.hold_offset) {
            (true, Some(offset)) => body.set_next_kinematic_position(to_pose(&(self.ef * offset))),
            (true, None) => {
                let cube = from_pose(body.position());
                // Distance from the tip to the cube's surface (box distance in the cube frame).
                let tip_local =
                    cube.inverse_transform_point(&Point3::from(self.ef.translation.vector));
                let h = self.config.cube_size / 2.0;
                let outside = Vector3::new(
                    (tip_local.x.abs() - h).max(0.0),
                    (tip_local.y.abs() - h).max(0.0),
                    (tip_local.z.abs() - h).max(0.0),
                );
                if outside.norm() <= self.config.capture_distance {
                    self.hold_offset = Some(self.ef.inverse() * cube);
                    body.set_body_type(RigidBodyType::KinematicPositionBased, true);
                    body.set_next_kinematic_position(to_pose(&cube));
                }
            }
            (false, Some(_)) => {
                self.hold_offset = None;
                let v = (self.ef.translation.vector - previous_ef.translation.vector) / dt;
                body.set_body_type(RigidBodyType::Dynamic, true);
                body.set_linvel(Vector::new(v.x as f32, v.y as f32, v.z as f32), true);
            }
            (false, None) => {}
        }
    }

    /// The current state.
    pub fn state(&self) -> SimState {
        let cube_pose = self
            .world
            .bodies
            .get(self.cube)
            .map(|b| from_pose(b.position()))
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

    /// The arm model the simulator uses (for IK in the babbler and for names).
    pub fn model(&self) -> &ArmModel {
        &self.model
    }

    /// The configuration in use.
    pub fn config(&self) -> &SimConfig {
        &self.config
    }

    /// Name of the tool frame reported as `ef_pose`.
    pub fn ef_frame() -> &'static str {
        frames::EF
    }
}

#[cfg(test)]
mod tests;
