//! The arm chain read from the URDF: the segments from the root link to `ef`, and the
//! limits of its actuated joints, with checks of joint values against them.

use std::path::Path;

use causal_arm_protocol::ARM_DOF;
use causal_arm_protocol::frames::EF as EF_FRAME;
use nalgebra::{Isometry3, Rotation3, Translation3, Unit, UnitQuaternion, Vector3};

use crate::{EMBEDDED_IIWA_URDF, KinematicsError, LimitViolation};

/// Limits of one actuated joint, as the URDF states them.
#[derive(Debug, Clone, PartialEq)]
pub struct JointLimits {
    /// Joint name.
    pub name: String,
    /// Lower position limit, rad.
    pub lower: f64,
    /// Upper position limit, rad.
    pub upper: f64,
    /// Velocity limit, rad/s.
    pub velocity: f64,
    /// Effort limit, N m.
    pub effort: f64,
}

#[derive(Debug, Clone)]
pub(crate) enum Motion {
    Fixed,
    Revolute {
        axis: Unit<Vector3<f64>>,
        index: usize,
    },
}

#[derive(Debug, Clone)]
pub(crate) struct Segment {
    pub(crate) origin: Isometry3<f64>,
    pub(crate) motion: Motion,
    pub(crate) parent_link: String,
    pub(crate) child_link: String,
}

/// A serial chain from the URDF root to `ef`.
#[derive(Debug, Clone)]
pub struct ArmModel {
    pub(crate) segments: Vec<Segment>,
    root_link: String,
    pub(crate) limits: Vec<JointLimits>,
}

fn isometry(pose: &urdf_rs::Pose) -> Isometry3<f64> {
    let [x, y, z] = *pose.xyz;
    let [roll, pitch, yaw] = *pose.rpy;
    // URDF: fixed-axis roll about X, then pitch about Y, then yaw about Z (R = Rz Ry Rx).
    Isometry3::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_euler_angles(roll, pitch, yaw)),
    )
}

impl ArmModel {
    /// The embedded project arm.
    pub fn embedded() -> Self {
        Self::from_urdf_str(EMBEDDED_IIWA_URDF, "<embedded iiwa14_magnet.urdf>")
            .expect("the embedded URDF is valid (checked by tests)")
    }

    /// Loads a URDF file.
    pub fn from_urdf_file(path: &Path) -> Result<Self, KinematicsError> {
        let text = std::fs::read_to_string(path).map_err(|error| KinematicsError::Io {
            path: path.to_owned(),
            error,
        })?;
        Self::from_urdf_str(&text, &path.display().to_string())
    }

    /// Parses URDF text; `origin` names it in errors.
    pub fn from_urdf_str(text: &str, origin: &str) -> Result<Self, KinematicsError> {
        let robot = urdf_rs::read_from_string(text).map_err(|e| KinematicsError::Malformed {
            origin: origin.to_owned(),
            message: e.to_string(),
        })?;
        Self::from_robot(&robot, origin)
    }

    /// Builds the chain from a parsed URDF.
    pub fn from_robot(robot: &urdf_rs::Robot, origin: &str) -> Result<Self, KinematicsError> {
        let chain_err = |message: String| KinematicsError::Chain {
            origin: origin.to_owned(),
            message,
        };
        if !robot.links.iter().any(|l| l.name == EF_FRAME) {
            return Err(KinematicsError::MissingLink {
                origin: origin.to_owned(),
                link: EF_FRAME.to_owned(),
            });
        }
        // Walk from ef up to the root.
        let mut joints = Vec::new();
        let mut link = EF_FRAME.to_owned();
        while let Some(joint) = robot.joints.iter().find(|j| j.child.link == link) {
            if joints.len() > robot.joints.len() {
                return Err(chain_err(format!("joint loop above link {link:?}")));
            }
            joints.push(joint);
            link = joint.parent.link.clone();
        }
        let root_link = link;
        joints.reverse();
        let mut segments = Vec::new();
        let mut limits = Vec::new();
        for joint in joints {
            check_finite_joint(joint).map_err(chain_err)?;
            let motion = match joint.joint_type {
                urdf_rs::JointType::Fixed => Motion::Fixed,
                urdf_rs::JointType::Revolute => {
                    let [x, y, z] = *joint.axis.xyz;
                    let axis = Vector3::new(x, y, z);
                    if axis.norm() < 1e-9 {
                        return Err(chain_err(format!("joint {} has a zero axis", joint.name)));
                    }
                    let l = &joint.limit;
                    if l.lower.partial_cmp(&l.upper) != Some(std::cmp::Ordering::Less) {
                        return Err(chain_err(format!(
                            "joint {} has limits [{}, {}]: lower must be below upper",
                            joint.name, l.lower, l.upper
                        )));
                    }
                    limits.push(JointLimits {
                        name: joint.name.clone(),
                        lower: l.lower,
                        upper: l.upper,
                        velocity: l.velocity,
                        effort: l.effort,
                    });
                    Motion::Revolute {
                        axis: Unit::new_normalize(axis),
                        index: limits.len() - 1,
                    }
                }
                ref other => {
                    return Err(chain_err(format!(
                        "joint {} is {other:?}; the arm chain supports revolute and fixed joints only",
                        joint.name
                    )));
                }
            };
            segments.push(Segment {
                origin: isometry(&joint.origin),
                motion,
                parent_link: joint.parent.link.clone(),
                child_link: joint.child.link.clone(),
            });
        }
        if limits.len() != ARM_DOF {
            return Err(chain_err(format!(
                "expected {ARM_DOF} revolute joints between {root_link:?} and {EF_FRAME:?}, found {}",
                limits.len()
            )));
        }
        Ok(Self {
            segments,
            root_link,
            limits,
        })
    }

    /// Name of the chain's root link (the world frame).
    pub fn root_link(&self) -> &str {
        &self.root_link
    }

    /// Actuated joint names in chain order.
    pub fn joint_names(&self) -> Vec<&str> {
        self.limits.iter().map(|l| l.name.as_str()).collect()
    }

    /// Limits of the actuated joints in chain order.
    pub fn limits(&self) -> &[JointLimits] {
        &self.limits
    }

    /// Checks count, finiteness and limits; reports every offending joint.
    pub fn check_joints(&self, q: &[f64]) -> Result<(), KinematicsError> {
        self.count_ok(q)?;
        let violations: Vec<LimitViolation> = self
            .limits
            .iter()
            .zip(q)
            .filter(|(l, v)| !v.is_finite() || **v < l.lower || **v > l.upper)
            .map(|(l, v)| LimitViolation {
                joint: l.name.clone(),
                value: *v,
                lower: l.lower,
                upper: l.upper,
            })
            .collect();
        if violations.is_empty() {
            Ok(())
        } else {
            Err(KinematicsError::OutOfLimits(violations))
        }
    }

    /// Checks only the number of joint values (forward kinematics and IK starts).
    pub(crate) fn count_ok(&self, q: &[f64]) -> Result<(), KinematicsError> {
        if q.len() == self.limits.len() {
            Ok(())
        } else {
            Err(KinematicsError::JointCount {
                expected: self.limits.len(),
                names: self.joint_names().join(", "),
                got: q.len(),
            })
        }
    }
}

/// A NaN or infinite origin, axis or limit would make every pose non-finite: refuse the
/// URDF naming the joint and field instead.
fn check_finite_joint(joint: &urdf_rs::Joint) -> Result<(), String> {
    let fields = [
        ("origin xyz", joint.origin.xyz.to_vec()),
        ("origin rpy", joint.origin.rpy.to_vec()),
        ("axis xyz", joint.axis.xyz.to_vec()),
        (
            "limit",
            vec![
                joint.limit.lower,
                joint.limit.upper,
                joint.limit.velocity,
                joint.limit.effort,
            ],
        ),
    ];
    for (field, values) in fields {
        if let Some(v) = values.iter().find(|v| !v.is_finite()) {
            return Err(format!(
                "joint {} has a non-finite {field} ({v} in {values:?})",
                joint.name
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embedded_model_has_paper_limits() {
        let m = ArmModel::embedded();
        let uppers: Vec<f64> = m.limits().iter().map(|l| l.upper).collect();
        assert_eq!(uppers, [2.967, 2.094, 2.967, 2.094, 2.967, 2.094, 3.054]);
        assert!(m.limits().iter().all(|l| l.lower == -l.upper));
        let vel: Vec<f64> = m.limits().iter().map(|l| l.velocity).collect();
        assert_eq!(vel, [1.483, 1.483, 1.745, 1.309, 2.269, 2.321, 2.356]);
        assert_eq!(m.joint_names()[0], "iiwa_joint_1");
        assert_eq!(m.root_link(), "world");
    }

    #[test]
    fn bad_joint_values_name_the_joint() {
        let m = ArmModel::embedded();
        let err = m.check_joints(&[0.0; 5]).unwrap_err().to_string();
        assert!(err.starts_with("expected 7 joint values"), "{err}");
        assert!(err.contains("got 5"), "{err}");
        let err = m
            .check_joints(&[0.0, 2.5, 0.0, 0.0, 0.0, 0.0, -3.1])
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("joint iiwa_joint_2 = 2.5 rad is outside its limits [-2.094, 2.094]"),
            "{err}"
        );
        assert!(err.contains("iiwa_joint_7 = -3.1"), "{err}");
        let err = m
            .check_joints(&[f64::NAN, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
            .unwrap_err()
            .to_string();
        assert!(err.contains("not a finite number"), "{err}");
    }

    #[test]
    fn bad_urdf_is_reported_with_its_origin() {
        let err = ArmModel::from_urdf_file(Path::new("/nonexistent/arm.urdf"))
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("/nonexistent/arm.urdf: cannot read URDF"),
            "{err}"
        );
        let err = ArmModel::from_urdf_str("<robot name='x'><link", "bad.urdf")
            .unwrap_err()
            .to_string();
        assert!(err.starts_with("bad.urdf: malformed URDF"), "{err}");
        let nan = EMBEDDED_IIWA_URDF.replace("xyz=\"0 0.2045 0\"", "xyz=\"0 NaN 0\"");
        let err = ArmModel::from_urdf_str(&nan, "nan.urdf")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("joint iiwa_joint_3 has a non-finite origin xyz (NaN"),
            "{err}"
        );
        let no_ef = EMBEDDED_IIWA_URDF.replace("\"ef\"", "\"tip\"");
        let err = ArmModel::from_urdf_str(&no_ef, "a.urdf")
            .unwrap_err()
            .to_string();
        assert!(err.contains("link \"ef\" not found"), "{err}");
        let six = EMBEDDED_IIWA_URDF.replace(
            "<joint name=\"iiwa_joint_7\" type=\"revolute\">",
            "<joint name=\"iiwa_joint_7\" type=\"fixed\">",
        );
        let err = ArmModel::from_urdf_str(&six, "b.urdf")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("expected 7 revolute joints") && err.contains("found 6"),
            "{err}"
        );
        let prismatic = EMBEDDED_IIWA_URDF.replace(
            "<joint name=\"iiwa_joint_4\" type=\"revolute\">",
            "<joint name=\"iiwa_joint_4\" type=\"prismatic\">",
        );
        let err = ArmModel::from_urdf_str(&prismatic, "c.urdf")
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("c.urdf: joint iiwa_joint_4 is Prismatic"),
            "{err}"
        );
        let no_limits = EMBEDDED_IIWA_URDF.replace(
            "<limit lower=\"-2.094\" upper=\"2.094\" effort=\"40\" velocity=\"2.321\"/>",
            "<limit lower=\"2.094\" upper=\"-2.094\" effort=\"40\" velocity=\"2.321\"/>",
        );
        let err = ArmModel::from_urdf_str(&no_limits, "d.urdf")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("joint iiwa_joint_6 has limits [2.094, -2.094]"),
            "{err}"
        );
    }
}
