//! Forward kinematics of the chain: world poses of every link and of `ef`, and the
//! geometric Jacobian of `ef`.

use nalgebra::{Isometry3, Matrix6xX, UnitQuaternion, Vector6};

use crate::model::Motion;
use crate::{ArmModel, KinematicsError};

impl ArmModel {
    /// World pose of every link on the chain (root excluded), in chain order.
    pub fn link_poses(&self, q: &[f64]) -> Result<Vec<(&str, Isometry3<f64>)>, KinematicsError> {
        self.count_ok(q)?;
        let mut pose = Isometry3::identity();
        let mut out = Vec::with_capacity(self.segments.len());
        for seg in &self.segments {
            pose *= seg.origin;
            if let Motion::Revolute { axis, index } = &seg.motion {
                pose *= UnitQuaternion::from_axis_angle(axis, q[*index]);
            }
            out.push((seg.child_link.as_str(), pose));
        }
        Ok(out)
    }

    /// World pose of `ef`. Does not check limits (the simulator may overshoot them slightly);
    /// call [`ArmModel::check_joints`] for user input.
    pub fn ef_pose(&self, q: &[f64]) -> Result<Isometry3<f64>, KinematicsError> {
        Ok(self
            .link_poses(q)?
            .last()
            .map(|(_, p)| *p)
            .unwrap_or_else(Isometry3::identity))
    }

    /// Geometric Jacobian of `ef` in the world frame: rows 0–2 linear, 3–5 angular velocity.
    pub fn jacobian(&self, q: &[f64]) -> Result<Matrix6xX<f64>, KinematicsError> {
        self.count_ok(q)?;
        let mut pose = Isometry3::identity();
        let mut axes = Vec::with_capacity(self.limits.len());
        for seg in &self.segments {
            pose *= seg.origin;
            if let Motion::Revolute { axis, index } = &seg.motion {
                axes.push((pose.rotation * axis.into_inner(), pose.translation.vector));
                pose *= UnitQuaternion::from_axis_angle(axis, q[*index]);
            }
        }
        let tip = pose.translation.vector;
        let mut j = Matrix6xX::zeros(self.limits.len());
        for (col, (z, p)) in axes.iter().enumerate() {
            let linear = z.cross(&(tip - p));
            j.fixed_view_mut::<3, 1>(0, col).copy_from(&linear);
            j.fixed_view_mut::<3, 1>(3, col).copy_from(z);
        }
        Ok(j)
    }
}

/// Vector of the 6 pose components used when comparing poses in tests and tools.
pub fn pose_vector(pose: &Isometry3<f64>) -> Vector6<f64> {
    let t = pose.translation.vector;
    let r = pose.rotation.scaled_axis();
    Vector6::new(t.x, t.y, t.z, r.x, r.y, r.z)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::random_q;
    use nalgebra::Vector3;
    use rand::{SeedableRng, rngs::StdRng};

    #[test]
    fn zero_configuration_points_straight_up() {
        let m = ArmModel::embedded();
        let p = m.ef_pose(&[0.0; 7]).unwrap();
        let height = 0.1575 + 0.2025 + 0.2045 + 0.2155 + 0.1845 + 0.2155 + 0.081 + 0.045 + 0.05;
        assert!(
            (p.translation.vector - Vector3::new(0.0, 0.0, height)).norm() < 1e-12,
            "{p}"
        );
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let m = ArmModel::embedded();
        let mut rng = StdRng::seed_from_u64(7);
        for _ in 0..20 {
            let q = random_q(&m, &mut rng);
            let j = m.jacobian(&q).unwrap();
            let p0 = m.ef_pose(&q).unwrap();
            let h = 1e-7;
            for c in 0..7 {
                let mut q1 = q.clone();
                q1[c] += h;
                let p1 = m.ef_pose(&q1).unwrap();
                let dv = (p1.translation.vector - p0.translation.vector) / h;
                let dw = (p1.rotation * p0.rotation.inverse()).scaled_axis() / h;
                assert!(
                    (dv - j.fixed_view::<3, 1>(0, c)).norm() < 1e-5,
                    "linear col {c}"
                );
                assert!(
                    (dw - j.fixed_view::<3, 1>(3, c)).norm() < 1e-5,
                    "angular col {c}"
                );
            }
        }
    }

    #[test]
    fn link_poses_cover_every_frame_of_the_chain() {
        let m = ArmModel::embedded();
        let q = [0.3, -0.4, 0.5, -0.6, 0.7, -0.8, 0.9];
        let poses = m.link_poses(&q).unwrap();
        let names: Vec<&str> = poses.iter().map(|(n, _)| *n).collect();
        assert_eq!(
            names,
            [
                "iiwa_link_0",
                "iiwa_link_1",
                "iiwa_link_2",
                "iiwa_link_3",
                "iiwa_link_4",
                "iiwa_link_5",
                "iiwa_link_6",
                "iiwa_link_7",
                "magnet",
                "ef"
            ]
        );
        assert_eq!(poses.last().unwrap().1, m.ef_pose(&q).unwrap());
        // ef is 0.05 m along the magnet frame's z axis, which is link 7's z axis.
        let link7 = poses[7].1;
        let ef = poses[9].1;
        let offset = link7.inverse() * ef;
        assert!((offset.translation.vector - Vector3::new(0.0, 0.0, 0.095)).norm() < 1e-12);
        assert!(offset.rotation.angle() < 1e-12);
        // Joint 1 turns everything about the world z axis.
        let mut q1 = q;
        q1[0] += 0.25;
        let turned = m.ef_pose(&q1).unwrap().translation.vector;
        let expected =
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.25) * ef.translation.vector;
        assert!((turned - expected).norm() < 1e-12);
    }
}
