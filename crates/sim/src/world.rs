//! The rapier world: floor, table, the arm's kinematic link bodies and the free cube,
//! built from the URDF, and placing the arm and the cube for each episode.

use ::nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use causal_arm_kinematics::ArmModel;
use causal_arm_protocol::ARM_DOF;
use rand::{Rng, SeedableRng, rngs::StdRng};
use rapier3d::math::{Pose, Rotation, Vector};
use rapier3d::prelude::{
    ColliderBuilder, PhysicsWorld, RigidBodyBuilder, RigidBodyHandle, RigidBodyType,
};

use crate::dynamic::insert_dynamic_arm;
use crate::servo::ServoLimits;
use crate::{ArmMode, LinkCylinders, MAGNET_LINK, SimConfig, SimError, Simulator};

/// The kinematic rapier body of one arm link, placed from forward kinematics each substep.
#[derive(Clone)]
pub(crate) struct LinkBody {
    /// Index of the link in `ArmModel::link_poses` order.
    pub(crate) chain_index: usize,
    /// The link's rapier body.
    pub(crate) body: RigidBodyHandle,
}

/// Copies every piece of simulation state of `world`. The pipelines hold only workspace
/// buffers (rapier's own snapshot rule: they are skipped by its serde snapshots too), so
/// the copy gets fresh ones.
pub(crate) fn clone_world(world: &PhysicsWorld) -> PhysicsWorld {
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

/// Our f64 pose as a rapier (f32) pose.
pub(crate) fn to_pose(iso: &Isometry3<f64>) -> Pose {
    let t = iso.translation.vector;
    let r = iso.rotation.coords;
    Pose::from_parts(
        Vector::new(t.x as f32, t.y as f32, t.z as f32),
        Rotation::from_xyzw(r.x as f32, r.y as f32, r.z as f32, r.w as f32).normalize(),
    )
}

/// A rapier (f32) pose as our f64 pose.
pub(crate) fn from_pose(pose: &Pose) -> Isometry3<f64> {
    let t = pose.translation;
    let r = pose.rotation;
    Isometry3::from_parts(
        Translation3::new(t.x as f64, t.y as f64, t.z as f64),
        UnitQuaternion::from_quaternion(Quaternion::new(
            r.w as f64, r.x as f64, r.y as f64, r.z as f64,
        )),
    )
}

/// A URDF `<origin>` as a pose (roll, pitch, yaw as URDF defines them).
pub(crate) fn urdf_pose(pose: &urdf_rs::Pose) -> Isometry3<f64> {
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

/// Solver passes per substep in the dynamic arm's world (rapier's default is 1).
const DYNAMIC_ARM_SOLVER_PASSES: usize = 4;

/// Contact depth the dynamic arm's world leaves uncorrected, m (rapier's default 5 mm).
const DYNAMIC_ARM_CONTACT_SLOP: f32 = 0.001;

/// Natural frequency of the dynamic arm's world's contacts with fixed bodies, Hz
/// (rapier's default 60).
const DYNAMIC_ARM_STATIC_CONTACT_FREQUENCY: f32 = 240.0;

/// A world with gravity, the physics step, and the fixed floor and table.
fn world_with_floor_and_table(config: &SimConfig) -> PhysicsWorld {
    let mut world = PhysicsWorld::new();
    world.gravity = Vector::new(0.0, 0.0, -9.81);
    world.integration_parameters.dt = config.dt as f32;
    if config.arm == ArmMode::Dynamic {
        // The seven motors of one multibody are coupled through its mass matrix; one
        // solver pass per substep leaves them 25 % over their velocity targets at worst,
        // four leave 3 % (tests_dynamic), at 8 % more time per step.
        world.integration_parameters.num_internal_pgs_iterations = DYNAMIC_ARM_SOLVER_PASSES;
        // rapier leaves contacts up to 5 mm deep uncorrected by default; the arm reached
        // 5.4 mm into the table (paper-size exp2 bag). 1 mm, as the probe counts.
        world.integration_parameters.normalized_allowed_linear_error = DYNAMIC_ARM_CONTACT_SLOP;
        // Contacts with fixed bodies are springs of 60 Hz by default: a link swept into
        // the table's edge at full speed reached 6.0 mm. Four times stiffer.
        world
            .integration_parameters
            .static_contact_softness
            .natural_frequency = DYNAMIC_ARM_STATIC_CONTACT_FREQUENCY;
        // rapier keeps a pair's contact points while the pair moved less than 5 cm since
        // they were found. A link sweeping past the table's edge at full speed then pushes
        // against stale points and normals: one state of the paper-size exp2 bag was
        // 11.1 mm deep; re-simulated bit-exactly to it with fresh contacts, 0.6 mm. Fresh
        // contacts every substep cost no measurable time (2,010 against 2,015 steps/s).
        world.integration_parameters.contact_recycling = false;
    }

    // Floor and table are fixed.
    world.insert(
        RigidBodyBuilder::fixed().translation(Vector::new(0.0, 0.0, -0.05)),
        ColliderBuilder::cuboid(5.0, 5.0, 0.05).friction(config.friction as f32),
    );
    let [cx, cy] = config.table_center;
    let [hx, hy] = config.table_half_extents;
    let hz = (causal_arm_protocol::scene::TABLE_THICKNESS / 2.0) as f32;
    world.insert(
        RigidBodyBuilder::fixed().translation(Vector::new(
            cx as f32,
            cy as f32,
            config.table_top_z as f32 - hz,
        )),
        ColliderBuilder::cuboid(hx as f32, hy as f32, hz).friction(config.friction as f32),
    );

    world
}

/// The colliders of one arm link, in the link frame (URDF collision shapes; cylinders as
/// `config.link_cylinders` says, but the magnet tool's flat face, which touches the cube,
/// always exact).
pub(crate) fn link_shapes(link: &urdf_rs::Link, config: &SimConfig) -> Vec<ColliderBuilder> {
    let cylinders = if link.name == MAGNET_LINK {
        LinkCylinders::Exact
    } else {
        config.link_cylinders
    };
    link.collision
        .iter()
        .filter_map(|c| collider_for(&c.geometry, &urdf_pose(&c.origin), cylinders))
        .collect()
}

/// Arm links: kinematic bodies carrying the URDF collision shapes, placed at `q0`.
fn insert_arm_links(
    world: &mut PhysicsWorld,
    robot: &urdf_rs::Robot,
    model: &ArmModel,
    config: &SimConfig,
    q0: &[f64; ARM_DOF],
) -> Result<Vec<LinkBody>, SimError> {
    let poses = model.link_poses(q0)?;
    let mut links = Vec::new();
    for (chain_index, (name, pose)) in poses.iter().enumerate() {
        let Some(link) = robot.links.iter().find(|l| &l.name == name) else {
            continue;
        };
        let shapes = link_shapes(link, config);
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
    Ok(links)
}

/// The cube: the one dynamic body, placed later by `place_episode`.
fn insert_cube(world: &mut PhysicsWorld, config: &SimConfig) -> RigidBodyHandle {
    let half = config.cube_size as f32 / 2.0;
    let (cube, _) = world.insert(
        RigidBodyBuilder::dynamic().ccd_enabled(true),
        ColliderBuilder::cuboid(half, half, half)
            .mass(config.cube_mass as f32)
            .friction(config.friction as f32),
    );
    cube
}

impl Simulator {
    /// Builds the world from a parsed URDF of the arm.
    pub fn from_robot(robot: &urdf_rs::Robot, config: SimConfig) -> Result<Self, SimError> {
        config.check()?;
        let model = ArmModel::from_robot(robot, "<arm URDF>")?;
        let mut world = world_with_floor_and_table(&config);
        let q0 = config.home;
        let limits = ServoLimits::from_urdf(robot, &model, &config, &q0)?;
        let (links, dynamic) = match config.arm {
            ArmMode::Kinematic => (
                insert_arm_links(&mut world, robot, &model, &config, &q0)?,
                None,
            ),
            ArmMode::Dynamic => {
                let arm = insert_dynamic_arm(&mut world, robot, &model, &config)?;
                (Vec::new(), Some(arm))
            }
        };
        let cube = insert_cube(&mut world, &config);
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
            limits,
            dynamic,
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

    /// Puts the arm at home with the magnet off and the cube at a random spot, yaw and colour.
    pub(crate) fn place_episode(&mut self) {
        self.q = self.config.home;
        self.qd = [0.0; ARM_DOF];
        self.effort = [0.0; ARM_DOF];
        self.magnet_on = false;
        self.hold_offset = None;
        match self.dynamic.is_some() {
            false => self.place_arm(true),
            true => self.teleport_dynamic_arm(&self.config.home.clone()),
        }
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
    pub(crate) fn place_arm(&mut self, teleport: bool) {
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
}
