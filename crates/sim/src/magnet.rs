//! The magnet: grips the cube rigidly when switched on near it, releases it with the
//! tip's velocity when switched off.

use ::nalgebra::{Isometry3, Point3, Vector3};
use rapier3d::math::Vector;
use rapier3d::prelude::RigidBodyType;

use crate::Simulator;
use crate::world::{from_pose, to_pose};

impl Simulator {
    /// Grips, carries or releases the cube after the tip moved from `previous_ef`.
    pub(crate) fn update_magnet(&mut self, previous_ef: &Isometry3<f64>, dt: f64) {
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
}
