//! The arm's joint servos: each joint moves toward its target within the URDF velocity
//! limit and an acceleration limit derived from the URDF effort limit.

use causal_arm_kinematics::ArmModel;
use causal_arm_protocol::ARM_DOF;

use crate::loads::ArmInertials;
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
        let joint_inertia = ArmInertials::from_urdf(robot, model)?.joint_inertias(model, q0)?;
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
