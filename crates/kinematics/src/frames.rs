//! The arm as a tf tree, the way robot_state_publisher reads a URDF: one parent → child
//! transform per joint, the fixed joints once (`/tf_static`) and the revolute joints at
//! the current joint values (`/tf`). Every link has exactly one parent: its joint's.

use causal_arm_protocol::FrameTransform;
use nalgebra::UnitQuaternion;

use crate::model::Motion;
use crate::{ArmModel, KinematicsError};

impl ArmModel {
    /// Parent → child of every fixed joint of the chain (world → base, flange → magnet,
    /// magnet → ef): what `/tf_static` carries, since they never move.
    pub fn fixed_frames(&self) -> Vec<FrameTransform> {
        self.segments
            .iter()
            .filter(|seg| matches!(seg.motion, Motion::Fixed))
            .map(|seg| FrameTransform {
                parent: seg.parent_link.clone(),
                child: seg.child_link.clone(),
                pose: seg.origin,
            })
            .collect()
    }

    /// Parent → child of every revolute joint at joint values `q`: what `/tf` carries each
    /// step. Composed with [`ArmModel::fixed_frames`] they give [`ArmModel::link_poses`].
    pub fn moving_frames(&self, q: &[f64]) -> Result<Vec<FrameTransform>, KinematicsError> {
        self.count_ok(q)?;
        Ok(self
            .segments
            .iter()
            .filter_map(|seg| match &seg.motion {
                Motion::Fixed => None,
                Motion::Revolute { axis, index } => Some(FrameTransform {
                    parent: seg.parent_link.clone(),
                    child: seg.child_link.clone(),
                    pose: seg.origin * UnitQuaternion::from_axis_angle(axis, q[*index]),
                }),
            })
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use std::collections::HashMap;

    use nalgebra::Isometry3;
    use rand::SeedableRng;

    use super::*;
    use crate::random_q;

    /// World pose of every frame, composed from the root down the parent links.
    fn compose(frames: &[FrameTransform], root: &str) -> HashMap<String, Isometry3<f64>> {
        let mut poses = HashMap::from([(root.to_owned(), Isometry3::identity())]);
        while poses.len() <= frames.len() {
            let before = poses.len();
            for f in frames {
                if let Some(parent) = poses.get(&f.parent).copied() {
                    poses.entry(f.child.clone()).or_insert(parent * f.pose);
                }
            }
            assert!(poses.len() > before, "a frame is not connected to {root}");
        }
        poses
    }

    #[test]
    fn static_and_moving_frames_compose_to_the_link_poses() {
        let model = ArmModel::embedded();
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        for _ in 0..20 {
            let q = random_q(&model, &mut rng);
            let mut frames = model.fixed_frames();
            frames.extend(model.moving_frames(&q).unwrap());
            let poses = compose(&frames, model.root_link());
            for (link, want) in model.link_poses(&q).unwrap() {
                let got = poses[link];
                assert!((got.translation.vector - want.translation.vector).norm() < 1e-12);
                assert!(got.rotation.angle_to(&want.rotation) < 1e-12, "{link}");
            }
        }
    }

    #[test]
    fn every_frame_has_one_parent_and_the_fixed_ones_are_static() {
        let model = ArmModel::embedded();
        let fixed = model.fixed_frames();
        let moving = model.moving_frames(&[0.3; 7]).unwrap();
        let children: Vec<&str> = fixed
            .iter()
            .chain(&moving)
            .map(|f| f.child.as_str())
            .collect();
        let mut unique = children.clone();
        unique.sort();
        unique.dedup();
        assert_eq!(unique.len(), children.len(), "{children:?}");
        assert_eq!(moving.len(), 7);
        let fixed_children: Vec<&str> = fixed.iter().map(|f| f.child.as_str()).collect();
        assert_eq!(fixed_children, ["iiwa_link_0", "magnet", "ef"]);
        assert_eq!(fixed[0].parent, "world");
        assert!(model.moving_frames(&[0.0; 6]).is_err());
    }
}
