//! The dynamic arm (`ArmMode::Dynamic`): a rapier multibody built from the URDF's links,
//! masses and inertias, moved by joint motors limited in speed and torque by the URDF.
//!
//! Each motor works as PyBullet's POSITION_CONTROL does: a velocity target that closes
//! `motor_position_gain` of the position error per physics step, clamped to the URDF
//! velocity limit, held by a velocity constraint whose torque is clamped to the URDF
//! effort limit. The position it tracks is the servo's reference, the same velocity- and
//! acceleration-limited path to the command that the kinematic arm follows exactly. Here
//! gravity acts on the links. The arm collides with the table, the floor, the cube and
//! its own non-adjacent links (but for [`SELF_COLLISION_EXEMPT`]). An arm that meets the
//! table stalls on it at its effort limits instead of entering it. The magnet holds the
//! cube with a fixed joint instead of placing it.

use ::nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};
use causal_arm_kinematics::ArmModel;
use causal_arm_protocol::ARM_DOF;
use rapier3d::math::{Matrix, Vector};
use rapier3d::prelude::{
    FixedJointBuilder, GenericJoint, GenericJointBuilder, Group, ImpulseJointHandle,
    InteractionGroups, JointAxesMask, JointAxis, MassProperties, MotorModel, MultibodyJointHandle,
    PhysicsWorld, RigidBodyBuilder, RigidBodyHandle,
};

use crate::loads::{ArmInertials, inertia_tensor};
use crate::world::{link_shapes, to_pose, urdf_pose};
use crate::{SimConfig, SimError, Simulator};

/// The state of the dynamic arm beside the rapier world (handles, gains, reference, grip).
#[derive(Clone)]
pub(crate) struct DynamicArm {
    /// The multibody joint of each actuated joint, in joint order.
    joints: [MultibodyJointHandle; ARM_DOF],
    /// The body of the chain's last body link (the magnet); the gripped cube is fixed to it.
    tool_body: RigidBodyHandle,
    /// Effort limit of each joint (URDF), N m.
    effort_limit: [f64; ARM_DOF],
    /// The links' inertial data (the efforts the motors hold against gravity).
    inertials: ArmInertials,
    /// The velocity each motor was last told to hold, rad/s.
    velocity_target: [f64; ARM_DOF],
    /// The joint velocities before the last physics step, rad/s.
    previous_velocity: [f64; ARM_DOF],
    /// Where the motors are told to be: the servo's path toward the command.
    reference: [f64; ARM_DOF],
    /// The reference's velocity, rad/s.
    reference_velocity: [f64; ARM_DOF],
    /// The fixed joint that holds the cube while the magnet grips it.
    grip: Option<ImpulseJointHandle>,
}

/// Damping of the motors' velocity constraint, N m s/rad: large enough to make it rigid
/// (rapier softens it by 1 / (dt × damping)); the effort limit alone bounds the torque.
const RIGID_VELOCITY_DAMPING: f32 = 1e9;

/// A motor counts as saturated when the joint misses its velocity target by more than
/// this, rad/s. The solver leaves an unsaturated motor up to ~5 mrad/s off its target
/// (measured holding still); a stalled one misses by its whole target.
const SATURATION_MISS: f64 = 0.05;

/// Mass properties of a URDF link in its own frame (centre of mass and full inertia tensor).
fn link_mass_properties(link: &urdf_rs::Link) -> MassProperties {
    let inertial = &link.inertial;
    let frame = urdf_pose(&inertial.origin);
    let local = inertia_tensor(&inertial.inertia);
    let r = frame.rotation.to_rotation_matrix();
    let tensor = r.matrix() * local * r.matrix().transpose();
    let col = |c: usize| {
        Vector::new(
            tensor[(0, c)] as f32,
            tensor[(1, c)] as f32,
            tensor[(2, c)] as f32,
        )
    };
    let com = frame.translation.vector;
    MassProperties::with_inertia_matrix(
        Vector::new(com.x as f32, com.y as f32, com.z as f32),
        inertial.mass.value as f32,
        Matrix::from_cols(col(0), col(1), col(2)),
    )
}

/// The rotation that takes rapier's revolute axis (x) to the URDF joint axis.
fn align_x_to(axis: &Vector3<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::rotation_between(&Vector3::x(), axis).unwrap_or_else(|| {
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::PI)
    })
}

/// The multibody joint of a URDF revolute joint: rapier's revolute axis (x of both joint
/// frames) turned onto the URDF axis, the URDF position limits, and a velocity motor
/// (at rest until driven) whose torque is limited to the URDF effort.
fn revolute_joint(
    joint: &urdf_rs::Joint,
    limits: &causal_arm_kinematics::JointLimits,
) -> GenericJoint {
    let [x, y, z] = *joint.axis.xyz;
    let align = Isometry3::from_parts(
        Default::default(),
        align_x_to(&Vector3::new(x, y, z).normalize()),
    );
    GenericJointBuilder::new(JointAxesMask::LOCKED_REVOLUTE_AXES)
        .local_frame1(to_pose(&(urdf_pose(&joint.origin) * align)))
        .local_frame2(to_pose(&align))
        .limits(JointAxis::AngX, [limits.lower as f32, limits.upper as f32])
        .motor_model(JointAxis::AngX, MotorModel::ForceBased)
        .motor_velocity(JointAxis::AngX, 0.0, RIGID_VELOCITY_DAMPING)
        .motor_max_force(JointAxis::AngX, limits.effort as f32)
        .contacts_enabled(false)
        .build()
}

/// Link pairs of the dynamic arm that do not collide with each other. The URDF's
/// collision cylinders of links 5 and 7 overlap once |A6| passes 1.75 rad (by 2.9 cm at
/// its 2.09 rad limit), where the real iiwa's wrist bends freely: with contacts the
/// wrist stalled at 1.74 rad and the babbler's reaches that needed more timed out. No
/// other pair of the arm's links overlaps anywhere in its joints' ranges
/// (tests_dynamic).
pub const SELF_COLLISION_EXEMPT: [(&str, &str); 1] = [("iiwa_link_5", "iiwa_link_7")];

/// Collision groups of a link's colliders: the first link of an exempt pair is alone in
/// its own group, which the second one's filter leaves out; everything else is rapier's
/// default (group 1, colliding with all).
fn link_collision_groups(name: &str) -> InteractionGroups {
    let default = InteractionGroups::default();
    let exempt = Group::GROUP_2;
    if SELF_COLLISION_EXEMPT
        .iter()
        .any(|(first, _)| *first == name)
    {
        InteractionGroups::new(exempt, Group::ALL, default.test_mode)
    } else if SELF_COLLISION_EXEMPT
        .iter()
        .any(|(_, second)| *second == name)
    {
        InteractionGroups::new(default.memberships, Group::ALL - exempt, default.test_mode)
    } else {
        default
    }
}

/// Inserts the arm as a multibody rooted at the fixed base link, at the zero configuration.
/// The chain's last link, when it has no collision shape (the `ef` frame), gets no body.
pub(crate) fn insert_dynamic_arm(
    world: &mut PhysicsWorld,
    robot: &urdf_rs::Robot,
    model: &ArmModel,
    config: &SimConfig,
) -> Result<DynamicArm, SimError> {
    let zero = [0.0; ARM_DOF];
    let poses = model.link_poses(&zero)?;
    let mut bodies: Vec<(&str, RigidBodyHandle)> = Vec::new();
    let mut effort_limits = Vec::new();
    let mut handles = Vec::new();
    let limits = model.limits();
    for (index, (name, pose)) in poses.iter().enumerate() {
        let link = robot
            .links
            .iter()
            .find(|l| &l.name == name)
            .ok_or_else(|| SimError::Config(format!("URDF has no link {name:?}")))?;
        let shapes = link_shapes(link, config);
        if shapes.is_empty() && index + 1 == poses.len() {
            continue; // the tool frame (ef): its nominal mass (1 g) is left out
        }
        let builder = match index {
            0 => RigidBodyBuilder::fixed(),
            _ => RigidBodyBuilder::dynamic()
                .additional_mass_properties(link_mass_properties(link))
                .can_sleep(false),
        };
        let body = world.insert_body(builder.pose(to_pose(pose)));
        for shape in shapes {
            world.colliders.insert_with_parent(
                shape
                    .density(0.0)
                    .friction(config.friction as f32)
                    .collision_groups(link_collision_groups(name)),
                body,
                &mut world.bodies,
            );
        }
        if index > 0 {
            let joint = robot
                .joints
                .iter()
                .find(|j| j.child.link == *name)
                .ok_or_else(|| SimError::Config(format!("URDF has no joint above {name:?}")))?;
            let parent = bodies
                .iter()
                .find(|(n, _)| *n == joint.parent.link)
                .map(|(_, b)| *b)
                .ok_or_else(|| {
                    SimError::Config(format!(
                        "dynamic arm: the parent {:?} of {name:?} has no body",
                        joint.parent.link
                    ))
                })?;
            let data = match joint.joint_type {
                urdf_rs::JointType::Revolute => {
                    let i = effort_limits.len();
                    effort_limits.push(limits[i].effort);
                    revolute_joint(joint, &limits[i])
                }
                _ => FixedJointBuilder::new()
                    .local_frame1(to_pose(&urdf_pose(&joint.origin)))
                    .contacts_enabled(false)
                    .build()
                    .into(),
            };
            let handle = world.multibody_joints.insert(parent, body, data, true);
            if let urdf_rs::JointType::Revolute = joint.joint_type {
                handles.push(handle);
            }
            handle.ok_or_else(|| {
                SimError::Config(format!("rapier refused the joint above {name:?}"))
            })?;
        }
        bodies.push((name, body));
    }
    if effort_limits.len() != ARM_DOF {
        return Err(SimError::Config(format!(
            "dynamic arm: expected {ARM_DOF} revolute joints, built {}",
            effort_limits.len()
        )));
    }
    let tool_body = bodies.last().map(|(_, b)| *b).expect("the base has a body");
    Ok(DynamicArm {
        joints: std::array::from_fn(|i| handles[i].expect("checked above")),
        tool_body,
        effort_limit: std::array::from_fn(|i| effort_limits[i]),
        inertials: ArmInertials::from_urdf(robot, model)?,
        velocity_target: zero,
        previous_velocity: zero,
        reference: zero,
        reference_velocity: zero,
        grip: None,
    })
}

impl Simulator {
    /// Puts the dynamic arm at rest at `q` (teleports it: episode start), its reference too.
    pub(crate) fn teleport_dynamic_arm(&mut self, q: &[f64; ARM_DOF]) {
        let Some(arm) = self.dynamic.as_mut() else {
            return;
        };
        if let Some(grip) = arm.grip.take() {
            self.world.impulse_joints.remove(grip, true);
        }
        arm.reference = *q;
        arm.reference_velocity = [0.0; ARM_DOF];
        arm.velocity_target = [0.0; ARM_DOF];
        arm.previous_velocity = [0.0; ARM_DOF];
        let Some((multibody, _)) = self.world.multibody_joints.get_mut(arm.joints[0]) else {
            return;
        };
        let mut displacement = vec![0.0f32; multibody.ndofs()];
        for (i, handle) in arm.joints.iter().enumerate() {
            // Every joint of the arm is in the one multibody; its link holds its coordinate.
            let Some((multibody, link_id)) = self.world.multibody_joints.get(*handle) else {
                continue;
            };
            let Some(link) = multibody.link(link_id) else {
                continue;
            };
            let current = link.joint.coords()[3];
            displacement[link.assembly_id()] = q[i] as f32 - current;
        }
        let Some((multibody, _)) = self.world.multibody_joints.get_mut(arm.joints[0]) else {
            return;
        };
        multibody.apply_displacements(&displacement);
        multibody.generalized_velocity_mut().fill(0.0);
        multibody.forward_kinematics(&self.world.bodies, false);
        multibody.update_rigid_bodies(&mut self.world.bodies, false);
        self.read_dynamic_joints();
    }

    /// Moves the reference one substep toward `target` and gives each motor the velocity
    /// that follows it: the reference's velocity plus `motor_position_gain` of the position
    /// error per step, within the joint's velocity limit.
    pub(crate) fn drive_dynamic_arm(&mut self, target: &[f64; ARM_DOF], dt: f64) {
        let Some(arm) = self.dynamic.as_ref() else {
            return;
        };
        let mut reference = arm.reference;
        let mut velocity = arm.reference_velocity;
        let mut unused_effort = [0.0; ARM_DOF];
        let limits = self.servo_limits();
        limits.step(
            self.config.servo_gain,
            target,
            &mut reference,
            &mut velocity,
            &mut unused_effort,
            dt,
        );
        let gain = self.config.motor_position_gain / dt;
        let velocity_target: [f64; ARM_DOF] = std::array::from_fn(|i| {
            let v_max = limits.velocity_limit[i];
            (velocity[i] + gain * (reference[i] - self.q[i])).clamp(-v_max, v_max)
        });
        let Some(arm) = self.dynamic.as_mut() else {
            return;
        };
        arm.reference = reference;
        arm.reference_velocity = velocity;
        arm.velocity_target = velocity_target;
        arm.previous_velocity = self.qd;
        for (i, handle) in arm.joints.iter().enumerate() {
            let link = self
                .world
                .multibody_joints
                .get_mut(*handle)
                .and_then(|(multibody, link_id)| multibody.link_mut(link_id));
            if let Some(link) = link {
                link.joint.data.set_motor_velocity(
                    JointAxis::AngX,
                    velocity_target[i] as f32,
                    RIGID_VELOCITY_DAMPING,
                );
            }
        }
    }

    /// Reads the joint positions and velocities from the multibody, the tool pose by
    /// forward kinematics, and each motor's effort (`motor_efforts`).
    pub(crate) fn read_dynamic_joints(&mut self) {
        let Some(arm) = self.dynamic.as_ref() else {
            return;
        };
        let mut q = self.q;
        let mut qd = self.qd;
        for (i, handle) in arm.joints.iter().enumerate() {
            let Some((multibody, link_id)) = self.world.multibody_joints.get(*handle) else {
                continue;
            };
            let Some(link) = multibody.link(link_id) else {
                continue;
            };
            q[i] = link.joint.coords()[3] as f64;
            qd[i] = multibody.generalized_velocity()[link.assembly_id()] as f64;
        }
        self.q = q;
        self.qd = qd;
        if let Ok(ef) = self.model.ef_pose(&self.q) {
            self.ef = ef;
        }
        if let Some(effort) = self.motor_efforts() {
            self.effort = effort;
        }
    }

    /// The torque of each motor over the last physics step. rapier does not report the
    /// impulses of multibody motors, so it is worked out: a motor that missed its velocity
    /// target was at its effort limit; one that met it held the links against gravity (and
    /// the gripped cube) and gave the joint's own inertia its acceleration.
    fn motor_efforts(&self) -> Option<[f64; ARM_DOF]> {
        let arm = self.dynamic.as_ref()?;
        let payload = arm.grip.and_then(|_| {
            let cube = self.world.bodies.get(self.cube)?;
            let com = cube.center_of_mass();
            Some((
                cube.mass() as f64,
                Point3::new(com.x as f64, com.y as f64, com.z as f64),
            ))
        });
        let g = self.world.gravity;
        let gravity = Vector3::new(g.x as f64, g.y as f64, g.z as f64);
        let holding = arm
            .inertials
            .holding_torques(&self.model, &self.q, &gravity, payload)
            .ok()?;
        let inertia = &self.servo_limits().joint_inertia;
        Some(std::array::from_fn(|i| {
            let limit = arm.effort_limit[i];
            let miss = arm.velocity_target[i] - self.qd[i];
            if miss.abs() > SATURATION_MISS {
                return limit.copysign(miss);
            }
            let acceleration = (self.qd[i] - arm.previous_velocity[i]) / self.config.dt;
            (holding[i] + inertia[i] * acceleration).clamp(-limit, limit)
        }))
    }

    /// The magnet of the dynamic arm: on and near the cube, fixes the cube to the tool
    /// body where it is; off, removes that joint (the cube keeps its velocity).
    pub(crate) fn update_dynamic_magnet(&mut self) {
        let Some(arm) = self.dynamic.as_ref() else {
            return;
        };
        let (tool_body, grip) = (arm.tool_body, arm.grip);
        match (self.magnet_on, grip) {
            (true, None) => {
                let Some(cube) = self.body_pose(self.cube) else {
                    return;
                };
                if !self.cube_within_capture(&cube) {
                    return;
                }
                let Some(tool) = self.body_pose(tool_body) else {
                    return;
                };
                let joint = FixedJointBuilder::new()
                    .local_frame1(to_pose(&(tool.inverse() * cube)))
                    .contacts_enabled(false);
                let handle = self
                    .world
                    .impulse_joints
                    .insert(tool_body, self.cube, joint, true);
                self.hold_offset = Some(self.ef.inverse() * cube);
                if let Some(arm) = self.dynamic.as_mut() {
                    arm.grip = Some(handle);
                }
            }
            (false, Some(handle)) => {
                self.world.impulse_joints.remove(handle, true);
                self.hold_offset = None;
                if let Some(arm) = self.dynamic.as_mut() {
                    arm.grip = None;
                }
            }
            _ => {}
        }
    }

    /// Whether the cube at `cube` is within the magnet's capture distance of the tip.
    pub(crate) fn cube_within_capture(&self, cube: &Isometry3<f64>) -> bool {
        let tip_local = cube.inverse_transform_point(&Point3::from(self.ef.translation.vector));
        let h = self.config.cube_size / 2.0;
        let outside = Vector3::new(
            (tip_local.x.abs() - h).max(0.0),
            (tip_local.y.abs() - h).max(0.0),
            (tip_local.z.abs() - h).max(0.0),
        );
        outside.norm() <= self.config.capture_distance
    }
}
