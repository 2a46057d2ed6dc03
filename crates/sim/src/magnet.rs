//! The magnet of the kinematic arm: grips the cube rigidly when switched on near it,
//! releases it with the tip's velocity when switched off. (The dynamic arm's magnet holds
//! the cube by a joint: `dynamic.rs`.)

use ::nalgebra::Isometry3;
use rapier3d::math::Vector;
use rapier3d::prelude::RigidBodyType;

use crate::Simulator;
use crate::world::to_pose;

impl Simulator {
    /// Grips, carries or releases the cube after the tip moved from `previous_ef`.
    pub(crate) fn update_magnet(&mut self, previous_ef: &Isometry3<f64>, dt: f64) {
        let Some(cube) = self.body_pose(self.cube) else {
            return;
        };
        let grip = match (self.magnet_on, self.hold_offset) {
            (true, None) if self.cube_within_capture(&cube) => Some(self.ef.inverse() * cube),
            _ => None,
        };
        let Some(body) = self.world.bodies.get_mut(self.cube) else {
            return;
        };
        match (self.magnet_on, self.hold_offset) {
            (true, Some(offset)) => body.set_next_kinematic_position(to_pose(&(self.ef * offset))),
            (true, None) => {
                if let Some(offset) = grip {
                    self.hold_offset = Some(offset);
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
