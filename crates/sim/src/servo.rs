//! The arm's joint servos: each joint moves toward its target within the URDF velocity
//! limit and an acceleration limit derived from the URDF effort limit.

use ::nalgebra::Vector3;
use causal_arm_kinematics::ArmModel;
use causal_arm_protocol::ARM_DOF;

use crate::world::urdf_pose;
use crate::{SimConfig, SimError, Simulator};

/// Per-joint limits of the servos, worked out once from the URDF when the world is built.
#[derive(Clone)]
pub(crate) struct ServoLimits {
    /// Largest joint acceleration, rad/s² (effort limit / moved inertia).
    pub(crate) accel_limit: [f64; ARM_DOF],
    /// Moment of inertia each joint moves, kg m² (turns accelerations into efforts).
    pub(crate) joint_inertia: [f64; ARM_DOF],
    /// Largest joint speed, rad/s (URDF limit × `velocity_scale`).
    pub(crate) velocity_limit: [f64; ARM_DOF],
    /// Lower position limits, rad.
    pub(crate) lower: [f64; ARM_DOF],
    /// Upper position limits, rad.
    pub(crate) upper: [f64; ARM_DOF],
}

impl ServoLimits {
    /// The limits of the arm at the configuration `q0` (the inertias depend on it).
    pub(crate) fn from_urdf(
        robot: &urdf_rs::Robot,
        model: &ArmModel,
        config: &SimConfig,
        q0: &[f64; ARM_DOF],
    ) -> Result<Self, SimError> {
        let limits = model.limits().to_vec();
        let joint_inertia = Self::joint_inertias(robot, model, q0)?;
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
        Ok(Self {
            accel_limit,
            joint_inertia,
            velocity_limit,
            lower,
            upper,
        })
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
}

impl ServoLimits {
    /// Moves every joint of (`q`, `qd`) one substep toward `target` within the velocity
    /// and acceleration limits, recording in `effort` the torque that took.
    pub(crate) fn step(
        &self,
        gain: f64,
        target: &[f64; ARM_DOF],
        q: &mut [f64; ARM_DOF],
        qd: &mut [f64; ARM_DOF],
        effort: &mut [f64; ARM_DOF],
        dt: f64,
    ) {
        for i in 0..ARM_DOF {
            let v_max = self.velocity_limit[i];
            let desired = (gain * (target[i] - q[i])).clamp(-v_max, v_max);
            // Do not overshoot the target within this substep.
            let desired = if desired.abs() * dt > (target[i] - q[i]).abs() {
                (target[i] - q[i]) / dt
            } else {
                desired
            };
            let dv_max = self.accel_limit[i] * dt;
            let dv = (desired - qd[i]).clamp(-dv_max, dv_max);
            effort[i] = self.joint_inertia[i] * dv / dt;
            qd[i] += dv;
            let next = q[i] + qd[i] * dt;
            if next <= self.lower[i] || next >= self.upper[i] {
                q[i] = next.clamp(self.lower[i], self.upper[i]);
                qd[i] = 0.0;
            } else {
                q[i] = next;
            }
        }
    }
}

impl Simulator {
    /// Moves every joint one substep toward `target` within its velocity and acceleration
    /// limits, recording the effort that took (the kinematic arm: the servo is the motion).
    pub(crate) fn servo(&mut self, target: &[f64; ARM_DOF], dt: f64) {
        let gain = self.config.servo_gain;
        self.limits.step(
            gain,
            target,
            &mut self.q,
            &mut self.qd,
            &mut self.effort,
            dt,
        );
    }

    /// The servo limits (the dynamic arm's reference moves within them too).
    pub(crate) fn servo_limits(&self) -> &ServoLimits {
        &self.limits
    }
}
