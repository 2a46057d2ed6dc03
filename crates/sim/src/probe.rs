//! How deep the arm reaches into the table at given joint angles: the collision shapes the
//! simulator gives the links, placed by forward kinematics, against the table's box. Reads
//! any recorded state, so the kinematic and the dynamic arm's data are judged alike.

use causal_arm_kinematics::ArmModel;
use causal_arm_protocol::ARM_DOF;
use rapier3d::math::{Pose, Vector};
use rapier3d::parry::query::contact;
use rapier3d::prelude::{ColliderBuilder, SharedShape};

use crate::world::{link_shapes, to_pose};
use crate::{SimConfig, SimError};

/// The arm's link shapes and the table top, for measuring penetration.
pub struct TableProbe {
    model: ArmModel,
    /// (index in `ArmModel::link_poses`, shape pose in the link frame, shape).
    shapes: Vec<(usize, Pose, SharedShape)>,
    table_pose: Pose,
    table: SharedShape,
}

impl TableProbe {
    /// The probe of the embedded arm in the scene of `config`.
    pub fn new(config: &SimConfig) -> Result<Self, SimError> {
        let robot = urdf_rs::read_from_string(causal_arm_kinematics::EMBEDDED_IIWA_URDF)
            .map_err(|e| SimError::Config(format!("embedded URDF: {e}")))?;
        let model = ArmModel::from_robot(&robot, "<embedded arm URDF>")?;
        let zero = [0.0; ARM_DOF];
        let mut shapes = Vec::new();
        for (index, (name, _)) in model.link_poses(&zero)?.iter().enumerate() {
            let Some(link) = robot.links.iter().find(|l| &l.name == name) else {
                continue;
            };
            for ColliderBuilder {
                shape, position, ..
            } in link_shapes(link, config)
            {
                shapes.push((index, position, shape));
            }
        }
        let [cx, cy] = config.table_center;
        let [hx, hy] = config.table_half_extents;
        let hz = causal_arm_protocol::scene::TABLE_THICKNESS / 2.0;
        Ok(Self {
            model,
            shapes,
            table_pose: Pose::from_translation(Vector::new(
                cx as f32,
                cy as f32,
                (config.table_top_z - hz) as f32,
            )),
            table: SharedShape::cuboid(hx as f32, hy as f32, hz as f32),
        })
    }

    /// The arm's link shapes placed at joint angles `q`: (index of the link in
    /// `ArmModel::link_poses`, world pose, shape).
    pub(crate) fn placed_shapes(
        &self,
        q: &[f64; ARM_DOF],
    ) -> Result<Vec<(usize, Pose, &SharedShape)>, SimError> {
        let poses = self.model.link_poses(q)?;
        Ok(self
            .shapes
            .iter()
            .map(|(index, local, shape)| (*index, to_pose(&poses[*index].1) * *local, shape))
            .collect())
    }

    /// How far the deepest link shape reaches into the table at joint angles `q`, m; 0 when
    /// no link touches it.
    pub fn penetration(&self, q: &[f64; ARM_DOF]) -> Result<f64, SimError> {
        let mut deepest = 0.0f64;
        for (_, pose, shape) in self.placed_shapes(q)? {
            let found = contact(
                &pose,
                shape.as_ref(),
                &self.table_pose,
                self.table.as_ref(),
                0.0,
            )
            .map_err(|e| SimError::Config(format!("link shape against the table: {e:?}")))?;
            if let Some(c) = found {
                deepest = deepest.max(-(c.dist as f64));
            }
        }
        Ok(deepest)
    }
}
