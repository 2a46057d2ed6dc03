//! What a well-formed sample of each graph topic looks like. Any ROS 2 node may publish on
//! the graph's topics; the nodes check every sample against these rules before it can
//! take a step's place, and count and skip the ones that fail, so a stray or malformed
//! sample can neither end a run nor end up in a bag.

use causal_arm_msgs::geometry_msgs::msg::{Pose, PoseStamped};
use causal_arm_msgs::msg::{Action, MagnetState, ObjectColor};
use causal_arm_msgs::rosgraph_msgs::msg::Clock;
use causal_arm_msgs::sensor_msgs::msg::JointState;
use causal_arm_msgs::tf2_msgs::msg::TFMessage;

use crate::step::{ARM_DOF, Command};

/// A sample that can be checked before use.
pub trait WellFormed {
    /// `Ok` when the sample could have come from the graph's own nodes, else what is wrong.
    fn well_formed(&self) -> Result<(), String>;
}

fn arm_values(values: &[f64], field: &str) -> Result<(), String> {
    if values.len() != ARM_DOF {
        return Err(format!(
            "{field} has {} values, expected {ARM_DOF}",
            values.len()
        ));
    }
    match values.iter().position(|v| !v.is_finite()) {
        Some(i) => Err(format!("{field}[{i}] is {}", values[i])),
        None => Ok(()),
    }
}

fn finite(values: &[f64], what: &str) -> Result<(), String> {
    match values.iter().find(|v| !v.is_finite()) {
        Some(v) => Err(format!("{what} has a {v} component")),
        None => Ok(()),
    }
}

fn pose(p: &Pose, what: &str) -> Result<(), String> {
    let (t, q) = (&p.position, &p.orientation);
    finite(&[t.x, t.y, t.z], &format!("{what} position"))?;
    finite(&[q.x, q.y, q.z, q.w], &format!("{what} orientation"))?;
    let norm = (q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w).sqrt();
    if (norm - 1.0).abs() > 1e-3 {
        return Err(format!("{what} orientation has norm {norm}, expected 1"));
    }
    Ok(())
}

impl WellFormed for JointState {
    fn well_formed(&self) -> Result<(), String> {
        if self.name.len() != ARM_DOF {
            return Err(format!(
                "name has {} joints, expected {ARM_DOF}",
                self.name.len()
            ));
        }
        arm_values(&self.position, "position")?;
        arm_values(&self.velocity, "velocity")?;
        arm_values(&self.effort, "effort")
    }
}

impl WellFormed for PoseStamped {
    fn well_formed(&self) -> Result<(), String> {
        pose(&self.pose, "pose")
    }
}

impl WellFormed for ObjectColor {
    fn well_formed(&self) -> Result<(), String> {
        let c = &self.color;
        match [c.r, c.g, c.b, c.a]
            .iter()
            .find(|v| !(0.0..=1.0).contains(*v))
        {
            Some(v) => Err(format!("colour component {v} is outside [0, 1]")),
            None => Ok(()),
        }
    }
}

impl WellFormed for MagnetState {
    fn well_formed(&self) -> Result<(), String> {
        if self.holding && !self.on {
            return Err("holding with the magnet off".into());
        }
        Ok(())
    }
}

impl WellFormed for Clock {
    fn well_formed(&self) -> Result<(), String> {
        Ok(())
    }
}

impl WellFormed for TFMessage {
    fn well_formed(&self) -> Result<(), String> {
        if self.transforms.is_empty() {
            return Err("no transforms".into());
        }
        for t in &self.transforms {
            let (v, q) = (&t.transform.translation, &t.transform.rotation);
            finite(&[v.x, v.y, v.z, q.x, q.y, q.z, q.w], &t.child_frame_id)?;
        }
        Ok(())
    }
}

impl WellFormed for Action {
    fn well_formed(&self) -> Result<(), String> {
        arm_values(&self.joint_targets, "joint_targets")?;
        arm_values(&self.joint_deltas, "joint_deltas")?;
        if ![Action::MAGNET_OFF, Action::MAGNET_KEEP, Action::MAGNET_ON].contains(&self.magnet) {
            return Err(format!("magnet is {}, expected -1, 0 or 1", self.magnet));
        }
        Ok(())
    }
}

/// The simulator's command in a well-formed action.
pub fn command_of(action: &Action) -> Result<Command, String> {
    action.well_formed()?;
    Ok(Command {
        joint_targets: action.joint_targets.as_slice().try_into().expect("checked"),
        magnet: action.magnet,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::design::Drawn;
    use crate::messages::{action_message, step_messages};
    use crate::step::SimState;

    fn state() -> SimState {
        SimState {
            stamp_ns: 41_666_667,
            step: 1,
            episode: 0,
            joint_positions: [0.1; ARM_DOF],
            joint_velocities: [0.0; ARM_DOF],
            joint_efforts: [0.0; ARM_DOF],
            ef_pose: nalgebra::Isometry3::translation(0.5, 0.0, 0.4),
            cube_pose: nalgebra::Isometry3::translation(0.6, 0.1, 0.02),
            cube_rgb: [0.9, 0.1, 0.1],
            magnet_on: false,
            holding: false,
        }
    }

    fn keep() -> Command {
        Command {
            joint_targets: [0.0; ARM_DOF],
            magnet: Action::MAGNET_KEEP,
        }
    }

    #[test]
    fn the_graphs_own_messages_are_well_formed() {
        let names = ["a", "b", "c", "d", "e", "f", "g"];
        let m = step_messages(&state(), &names, Vec::new());
        m.joint_states.well_formed().unwrap();
        m.ef_pose.well_formed().unwrap();
        m.object_pose.well_formed().unwrap();
        m.object_color.well_formed().unwrap();
        m.magnet.well_formed().unwrap();
        m.tf.well_formed().unwrap();
        let command = Command {
            joint_targets: [0.2; ARM_DOF],
            magnet: Action::MAGNET_ON,
        };
        let action = action_message(&state(), &Drawn::scripted(command.clone(), 0), 3);
        assert_eq!(command_of(&action).unwrap(), command);
    }

    #[test]
    fn short_nan_and_out_of_range_samples_are_named() {
        let mut action = action_message(&state(), &Drawn::scripted(keep(), 0), 0);
        action.joint_targets.truncate(3);
        assert_eq!(
            command_of(&action).unwrap_err(),
            "joint_targets has 3 values, expected 7"
        );
        let mut action = action_message(&state(), &Drawn::scripted(keep(), 0), 0);
        action.joint_targets[2] = f64::NAN;
        assert_eq!(command_of(&action).unwrap_err(), "joint_targets[2] is NaN");
        let mut action = action_message(&state(), &Drawn::scripted(keep(), 0), 0);
        action.magnet = 7;
        assert!(command_of(&action).unwrap_err().contains("magnet is 7"));
        let mut js = step_messages(&state(), &["j"; 7], Vec::new()).joint_states;
        js.position.push(0.0);
        assert!(
            js.well_formed()
                .unwrap_err()
                .contains("position has 8 values")
        );
        let mut pose = step_messages(&state(), &["j"; 7], Vec::new()).ef_pose;
        pose.pose.orientation.w = 2.0;
        assert!(pose.well_formed().unwrap_err().contains("norm"));
    }
}
