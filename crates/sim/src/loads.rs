//! The loads on each joint, from the URDF's inertial data: the inertia a joint moves (the
//! servos turn it into an acceleration limit) and the torque gravity puts on it (the
//! dynamic arm reports the torque its motors hold against).

use ::nalgebra::{Isometry3, Matrix3, Point3, Vector3};
use causal_arm_kinematics::ArmModel;
use causal_arm_protocol::ARM_DOF;

use crate::SimError;
use crate::world::urdf_pose;

/// A URDF inertia as the symmetric tensor it stands for (in the inertial frame), kg m².
pub(crate) fn inertia_tensor(i: &urdf_rs::Inertia) -> Matrix3<f64> {
    Matrix3::new(
        i.ixx, i.ixy, i.ixz, i.ixy, i.iyy, i.iyz, i.ixz, i.iyz, i.izz,
    )
}

/// One link's mass, centre of mass and inertia tensor, at its place in the FK chain.
#[derive(Clone)]
struct LinkInertial {
    /// Index of the link in `ArmModel::link_poses`.
    pose_index: usize,
    /// Mass, kg.
    mass: f64,
    /// Centre-of-mass frame in the link frame.
    com: Isometry3<f64>,
    /// Inertia tensor about the centre of mass, in the com frame, kg m².
    tensor: Matrix3<f64>,
}

/// The arm's inertial data, read once from the URDF.
#[derive(Clone)]
pub(crate) struct ArmInertials {
    links: Vec<LinkInertial>,
    /// Per joint, the `link_poses` index of the first link it moves.
    first_moved: [usize; ARM_DOF],
}

/// Each joint's axis and origin, world frame, and every link pose at `q`.
type JointFrames = ([(Vector3<f64>, Vector3<f64>); ARM_DOF], Vec<Isometry3<f64>>);

impl ArmInertials {
    /// Reads the links' inertial data in the model's FK order.
    pub(crate) fn from_urdf(robot: &urdf_rs::Robot, model: &ArmModel) -> Result<Self, SimError> {
        let poses = model.link_poses(&[0.0; ARM_DOF])?;
        let mut links = Vec::new();
        let mut moved = Vec::new();
        for (index, (name, _)) in poses.iter().enumerate() {
            if name.starts_with("iiwa_link_") && *name != "iiwa_link_0" {
                moved.push(index);
            }
            let Some(link) = robot.links.iter().find(|l| &l.name == name) else {
                continue;
            };
            links.push(LinkInertial {
                pose_index: index,
                mass: link.inertial.mass.value,
                com: urdf_pose(&link.inertial.origin),
                tensor: inertia_tensor(&link.inertial.inertia),
            });
        }
        if moved.len() != ARM_DOF {
            return Err(SimError::Config(format!(
                "URDF: expected {ARM_DOF} links iiwa_link_1.., found {}",
                moved.len()
            )));
        }
        Ok(Self {
            links,
            first_moved: std::array::from_fn(|i| moved[i]),
        })
    }

    fn joint_frames(&self, model: &ArmModel, q: &[f64; ARM_DOF]) -> Result<JointFrames, SimError> {
        let poses: Vec<Isometry3<f64>> = model.link_poses(q)?.into_iter().map(|(_, p)| p).collect();
        let jacobian = model.jacobian(q)?;
        let frames = std::array::from_fn(|i| {
            let axis: Vector3<f64> = jacobian.fixed_view::<3, 1>(3, i).into_owned();
            (axis, poses[self.first_moved[i]].translation.vector)
        });
        Ok((frames, poses))
    }

    /// The links joint `i` moves: those at or after its first moved link in FK order.
    fn moved_by(&self, i: usize) -> impl Iterator<Item = &LinkInertial> {
        let first = self.first_moved[i];
        self.links.iter().filter(move |l| l.pose_index >= first)
    }

    /// The moment of inertia each joint moves at `q`, kg m² (the links beyond it, rigid).
    pub(crate) fn joint_inertias(
        &self,
        model: &ArmModel,
        q: &[f64; ARM_DOF],
    ) -> Result<[f64; ARM_DOF], SimError> {
        let (frames, poses) = self.joint_frames(model, q)?;
        Ok(std::array::from_fn(|i| {
            let (axis, origin) = frames[i];
            self.moved_by(i)
                .map(|link| {
                    let com = poses[link.pose_index] * link.com;
                    let r = com.translation.vector - origin;
                    let d_perp = r - axis * axis.dot(&r);
                    let local_axis = com.rotation.inverse() * axis;
                    local_axis.dot(&(link.tensor * local_axis)) + link.mass * d_perp.norm_squared()
                })
                .sum()
        }))
    }

    /// The torque each joint's motor must apply at `q` to hold the links beyond it, and a
    /// `payload` (mass, world centre of mass) carried by the last link, against `gravity`.
    pub(crate) fn holding_torques(
        &self,
        model: &ArmModel,
        q: &[f64; ARM_DOF],
        gravity: &Vector3<f64>,
        payload: Option<(f64, Point3<f64>)>,
    ) -> Result<[f64; ARM_DOF], SimError> {
        let (frames, poses) = self.joint_frames(model, q)?;
        Ok(std::array::from_fn(|i| {
            let (axis, origin) = frames[i];
            let weights = self
                .moved_by(i)
                .map(|link| {
                    let com = poses[link.pose_index] * Point3::from(link.com.translation.vector);
                    (link.mass, com)
                })
                .chain(payload);
            let gravity_torque: f64 = weights
                .map(|(mass, com)| axis.dot(&(com.coords - origin).cross(&(gravity * mass))))
                .sum();
            -gravity_torque
        }))
    }
}
