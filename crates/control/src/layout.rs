//! Where an experiment's state and action vectors keep what reaching needs, and how a
//! simulator state becomes the vector the learned models were trained on.
//!
//! The vector is made by the dataset crate's own `state_features` from the messages the
//! simulator publishes for the state, so a controller hands its models exactly the
//! features and conventions (Euler angles from the messages' quaternions) of their data.

use causal_arm_dataset::{action_names, state_features, state_groups};
use causal_arm_kinematics::ArmModel;
use causal_arm_protocol::{ARM_DOF, Experiment, SimState, step_messages};

use crate::{ControlError, Vector3, kinematics_err};

/// The state and action layout of one experiment.
#[derive(Debug, Clone)]
pub struct StateLayout {
    /// The experiment.
    pub experiment: Experiment,
    /// Features in s.
    pub width: usize,
    /// Index of θ0 in s (θ0..θ6 follow).
    pub theta: usize,
    /// Index of ef_x in s (ef_y, ef_z follow; exp 2 then its three Euler angles).
    pub ef: usize,
    /// Whether s carries the effector's orientation after its position (exp 2).
    pub ef_orientation: bool,
    /// Index of the cube's x in s, if s carries the cube (exp 2: o_x, o_y, o_z).
    pub object: Option<usize>,
    /// Features in a (the 7 joint deltas first; exp 2 then the magnet command).
    pub action_width: usize,
    joint_names: Vec<String>,
}

impl StateLayout {
    /// The layout of `experiment`'s vectors, for `model`'s arm.
    pub fn of(experiment: Experiment, model: &ArmModel) -> Self {
        let groups = state_groups(experiment);
        let start = |names: &[&str]| {
            (groups.iter())
                .find(|g| names.contains(&g.name))
                .map(|g| (g.start, g.len))
                .expect("every experiment's state has θ and the effector position")
        };
        let (ef, ef_len) = start(&["ef", "ef_pos"]);
        let ef_orientation = groups.iter().any(|g| g.name == "ef_rot");
        debug_assert_eq!(ef_len, 3);
        Self {
            experiment,
            width: groups.iter().map(|g| g.start + g.len).max().unwrap_or(0),
            theta: start(&["theta"]).0,
            ef,
            ef_orientation,
            object: (groups.iter().find(|g| g.name == "obj_pos")).map(|g| g.start),
            action_width: action_names(experiment).len(),
            joint_names: model.joint_names().iter().map(|n| n.to_string()).collect(),
        }
    }

    /// s(t) of `state`, as the dataset builder makes it from the state's messages.
    pub fn state(&self, state: &SimState) -> Vec<f64> {
        let names: Vec<&str> = self.joint_names.iter().map(String::as_str).collect();
        state_features(self.experiment, &step_messages(state, &names, Vec::new()))
    }

    /// The effector position in a state vector.
    pub fn ef_position(&self, s: &[f64]) -> Vector3<f64> {
        Vector3::new(s[self.ef], s[self.ef + 1], s[self.ef + 2])
    }

    /// The cube's position in a state vector, if it carries one.
    pub fn object_position(&self, s: &[f64]) -> Option<Vector3<f64>> {
        self.object.map(|o| Vector3::new(s[o], s[o + 1], s[o + 2]))
    }

    /// `now` with the arm moved: θ replaced by `q`, the effector position by `ef`, and
    /// (exp 2) its orientation by that of FK(q), so the state is one the arm can be in.
    pub fn moved(
        &self,
        model: &ArmModel,
        now: &[f64],
        q: &[f64; ARM_DOF],
        ef: &Vector3<f64>,
    ) -> Result<Vec<f64>, ControlError> {
        let mut s = now.to_vec();
        s[self.theta..self.theta + ARM_DOF].copy_from_slice(q);
        s[self.ef..self.ef + 3].copy_from_slice(ef.as_slice());
        if self.ef_orientation {
            let pose = model.ef_pose(q).map_err(kinematics_err)?;
            let (roll, pitch, yaw) = pose.rotation.euler_angles();
            s[self.ef + 3..self.ef + 6].copy_from_slice(&[roll, pitch, yaw]);
        }
        Ok(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use causal_arm_dataset::state_names;
    use causal_arm_sim::{SimConfig, Simulator};

    #[test]
    fn the_layouts_name_theta_and_the_effector_where_the_datasets_do() {
        let model = ArmModel::embedded();
        let state = Simulator::new(SimConfig::default()).unwrap().state();
        for experiment in [Experiment::Exp1, Experiment::Exp2] {
            let layout = StateLayout::of(experiment, &model);
            let names = state_names(experiment);
            assert_eq!(layout.width, names.len());
            assert_eq!(names[layout.theta], "theta0");
            assert_eq!(names[layout.ef], "ef_x");
            let s = layout.state(&state);
            assert_eq!(s.len(), layout.width);
            assert_eq!(layout.ef_position(&s), state.ef_pose.translation.vector);
            assert_eq!(
                s[layout.theta..layout.theta + ARM_DOF],
                state.joint_positions
            );
        }
        assert_eq!(StateLayout::of(Experiment::Exp2, &model).action_width, 8);
    }

    #[test]
    fn a_moved_state_is_one_the_arm_can_be_in() {
        let model = ArmModel::embedded();
        let layout = StateLayout::of(Experiment::Exp2, &model);
        let sim = Simulator::new(SimConfig::default()).unwrap();
        let now = layout.state(&sim.state());
        let q = [0.2, 0.4, -0.1, -1.2, 0.3, 0.5, 0.1];
        let ef = model.ef_pose(&q).unwrap().translation.vector;
        let moved = layout.moved(&model, &now, &q, &ef).unwrap();
        let mut arm = sim.state();
        arm.joint_positions = q;
        arm.ef_pose = model.ef_pose(&q).unwrap();
        let expected = layout.state(&arm);
        for (i, (a, b)) in moved.iter().zip(&expected).enumerate() {
            assert!((a - b).abs() < 1e-9, "feature {i}: {a} vs {b}");
        }
    }
}
