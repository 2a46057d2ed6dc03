//! The errors of loading and using the arm model; each names the file, joint or target
//! involved so a broken model or request is fixed at the source.

use std::fmt;
use std::path::PathBuf;

use causal_arm_protocol::frames::EF as EF_FRAME;
use nalgebra::Point3;
use thiserror::Error;

/// Everything that can go wrong loading the model or using it; each names the culprit.
#[derive(Debug, Error)]
pub enum KinematicsError {
    /// The URDF file could not be read.
    #[error("{path}: cannot read URDF: {error}")]
    Io {
        /// File asked for.
        path: PathBuf,
        /// OS error (not a `#[source]`, so chains do not print it twice).
        error: std::io::Error,
    },
    /// The URDF is not valid XML/URDF.
    #[error("{origin}: malformed URDF: {message}")]
    Malformed {
        /// File or `<embedded>`.
        origin: String,
        /// Parser message.
        message: String,
    },
    /// A link the chain needs is missing.
    #[error(
        "{origin}: link {link:?} not found (the chain runs from the root link to {EF_FRAME:?})"
    )]
    MissingLink {
        /// File or `<embedded>`.
        origin: String,
        /// Missing link.
        link: String,
    },
    /// The chain has the wrong number of revolute joints or an unsupported joint type.
    #[error("{origin}: {message}")]
    Chain {
        /// File or `<embedded>`.
        origin: String,
        /// What is wrong.
        message: String,
    },
    /// Wrong number of joint values.
    #[error("expected {expected} joint values ({names}), got {got}")]
    JointCount {
        /// Joints of the model.
        expected: usize,
        /// Their names, for the message.
        names: String,
        /// Values given.
        got: usize,
    },
    /// Joint values outside the URDF limits or not finite.
    #[error("{}", .0.iter().map(ToString::to_string).collect::<Vec<_>>().join("; "))]
    OutOfLimits(Vec<LimitViolation>),
    /// IK found no solution within tolerance.
    #[error(
        "target ({:.4}, {:.4}, {:.4}) m is unreachable: best solution is {best_error_m:.4} m away after {attempts} attempts",
        target.x, target.y, target.z
    )]
    Unreachable {
        /// Requested position.
        target: Point3<f64>,
        /// Closest distance reached.
        best_error_m: f64,
        /// Restarts tried.
        attempts: usize,
    },
}

/// One joint value outside its limits.
#[derive(Debug, Clone, PartialEq)]
pub struct LimitViolation {
    /// Joint name from the URDF.
    pub joint: String,
    /// Value given.
    pub value: f64,
    /// Lower limit.
    pub lower: f64,
    /// Upper limit.
    pub upper: f64,
}

impl fmt::Display for LimitViolation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.value.is_finite() {
            write!(
                f,
                "joint {} = {} rad is outside its limits [{}, {}]",
                self.joint, self.value, self.lower, self.upper
            )
        } else {
            write!(
                f,
                "joint {} = {} is not a finite number",
                self.joint, self.value
            )
        }
    }
}
