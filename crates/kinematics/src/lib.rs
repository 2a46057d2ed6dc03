//! Kinematics of the iiwa arm straight from its URDF: forward kinematics of every link and
//! of the `ef` frame, the arm's tf tree, the geometric Jacobian, and damped-least-squares
//! inverse kinematics.
//!
//! The simulator, the babbler (reaching for the cube) and the dataset builder all need the
//! same arm model; building it from the URDF file keeps one source of truth, and errors
//! name the file, joint and limits involved so a broken model is fixed at the source.

mod error;
mod forward;
mod frames;
mod ik;
mod model;

pub use error::{KinematicsError, LimitViolation};
pub use forward::pose_vector;
pub use ik::{IkOptions, IkSolution, IkTarget};
pub use model::{ArmModel, JointLimits};

/// The project's arm (iiwa 14 + magnet tool), compiled in so tools work without a checkout.
pub const EMBEDDED_IIWA_URDF: &str = include_str!("../../../urdf/iiwa14_magnet.urdf");

/// Random joint values within the limits, shared by the tests of several modules.
#[cfg(test)]
pub(crate) fn random_q(model: &ArmModel, rng: &mut rand::rngs::StdRng) -> Vec<f64> {
    use rand::Rng;
    model
        .limits()
        .iter()
        .map(|l| rng.random_range(l.lower..l.upper))
        .collect()
}
