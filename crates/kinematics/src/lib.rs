//! Kinematics of the iiwa arm straight from its URDF: forward kinematics of every link and
//! of the `ef` frame, the geometric Jacobian, and damped-least-squares inverse kinematics.
//!
//! The simulator, the babbler (reaching for the cube) and the dataset builder all need the
//! same arm model; building it from the URDF file keeps one source of truth, and errors
//! name the file, joint and limits involved so a broken model is fixed at the source.

use std::fmt;
use std::path::{Path, PathBuf};

use causal_arm_protocol::ARM_DOF;
use causal_arm_protocol::frames::EF as EF_FRAME;
use nalgebra::{
    DMatrix, DVector, Isometry3, Matrix3, Matrix6xX, Point3, Rotation3, Translation3, Unit,
    UnitQuaternion, Vector3, Vector6,
};
use rand::{Rng, SeedableRng, rngs::StdRng};
use thiserror::Error;

/// The project's arm (iiwa 14 + magnet tool), compiled in so tools work without a checkout.
pub const EMBEDDED_IIWA_URDF: &str = include_str!("../../../urdf/iiwa14_magnet.urdf");

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
enum Motion {
    Fixed,
    Revolute {
        axis: Unit<Vector3<f64>>,
        index: usize,
    },
}

#[derive(Debug, Clone)]
struct Segment {
    origin: Isometry3<f64>,
    motion: Motion,
    child_link: String,
}

/// A serial chain from the URDF root to `ef`.
#[derive(Debug, Clone)]
pub struct ArmModel {
    segments: Vec<Segment>,
    root_link: String,
    limits: Vec<JointLimits>,
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
        if q.len() != self.limits.len() {
            return Err(KinematicsError::JointCount {
                expected: self.limits.len(),
                names: self.joint_names().join(", "),
                got: q.len(),
            });
        }
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

    fn count_ok(&self, q: &[f64]) -> Result<(), KinematicsError> {
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

    /// Damped-least-squares IK for a position (and optionally an orientation) of `ef`.
    pub fn inverse(
        &self,
        target: &IkTarget,
        options: &IkOptions,
    ) -> Result<IkSolution, KinematicsError> {
        let mut rng = StdRng::seed_from_u64(options.seed);
        let mut best: Option<IkSolution> = None;
        let max_attempts = options.max_attempts.max(1);
        for attempt in 0..max_attempts {
            let start: Vec<f64> = match (attempt, &options.initial) {
                (0, Some(q0)) => {
                    self.count_ok(q0)?;
                    q0.clone()
                }
                (0, None) => self
                    .limits
                    .iter()
                    .map(|l| 0.5 * (l.lower + l.upper))
                    .collect(),
                _ => self
                    .limits
                    .iter()
                    .map(|l| rng.random_range(0.9 * l.lower..0.9 * l.upper))
                    .collect(),
            };
            let solution = self.dls(target, start, options)?;
            let done = solution.position_error_m <= options.tolerance_m
                && solution.orientation_error_rad <= options.tolerance_rad;
            if best.as_ref().is_none_or(|b| solution.cost() < b.cost()) {
                best = Some(IkSolution {
                    attempts: attempt + 1,
                    ..solution
                });
            }
            if done {
                return Ok(best.expect("just set"));
            }
        }
        let best = best.expect("at least one attempt ran");
        Err(KinematicsError::Unreachable {
            target: target.position,
            best_error_m: best.position_error_m,
            attempts: max_attempts,
        })
    }

    fn dls(
        &self,
        target: &IkTarget,
        mut q: Vec<f64>,
        o: &IkOptions,
    ) -> Result<IkSolution, KinematicsError> {
        let rows = if target.orientation.is_some() { 6 } else { 3 };
        let n = q.len();
        let mut lambda = o.damping;
        let error = |q: &[f64]| -> Result<(DVector<f64>, f64, f64), KinematicsError> {
            let pose = self.ef_pose(q)?;
            let dp = target.position.coords - pose.translation.vector;
            let mut e = DVector::zeros(rows);
            e.fixed_rows_mut::<3>(0).copy_from(&dp);
            let mut rot_err = 0.0;
            if let Some(r) = &target.orientation {
                let dr = (r * pose.rotation.inverse()).scaled_axis();
                rot_err = dr.norm();
                e.fixed_rows_mut::<3>(3)
                    .copy_from(&(dr * o.orientation_weight));
            }
            Ok((e, dp.norm(), rot_err))
        };
        let (mut e, mut pos_err, mut rot_err) = error(&q)?;
        for _ in 0..o.max_iterations {
            if pos_err <= o.tolerance_m && rot_err <= o.tolerance_rad {
                break;
            }
            let full = self.jacobian(&q)?;
            let mut j = DMatrix::from_iterator(
                rows,
                n,
                (0..n)
                    .flat_map(|c| (0..rows).map(move |r| (r, c)))
                    .map(|(r, c)| {
                        let v = full[(r, c)];
                        if r >= 3 { v * o.orientation_weight } else { v }
                    }),
            );
            // Joints pinned at a limit and pushed outward are removed from this step.
            let jt = j.transpose();
            let grad = &jt * &e;
            for (c, l) in self.limits.iter().enumerate() {
                if (q[c] <= l.lower && grad[c] < 0.0) || (q[c] >= l.upper && grad[c] > 0.0) {
                    j.column_mut(c).fill(0.0);
                }
            }
            let jjt = &j * j.transpose() + DMatrix::identity(rows, rows) * (lambda * lambda);
            let Some(chol) = jjt.cholesky() else { break };
            let dq = j.transpose() * chol.solve(&e);
            let candidate: Vec<f64> = q
                .iter()
                .zip(dq.iter())
                .zip(&self.limits)
                .map(|((qi, d), l)| {
                    (qi + d.clamp(-o.max_step_rad, o.max_step_rad)).clamp(l.lower, l.upper)
                })
                .collect();
            let (e2, p2, r2) = error(&candidate)?;
            if e2.norm() < e.norm() {
                q = candidate;
                e = e2;
                pos_err = p2;
                rot_err = r2;
                lambda = (lambda * 0.5).max(1e-6);
            } else {
                lambda *= 4.0;
                if lambda > 10.0 {
                    break;
                }
            }
        }
        Ok(IkSolution {
            joints: q,
            position_error_m: pos_err,
            orientation_error_rad: rot_err,
            attempts: 1,
        })
    }
}

/// What IK should reach.
#[derive(Debug, Clone, PartialEq)]
pub struct IkTarget {
    /// Position of `ef` in the world frame.
    pub position: Point3<f64>,
    /// Orientation of `ef`, if it matters (picking from above does).
    pub orientation: Option<UnitQuaternion<f64>>,
}

impl IkTarget {
    /// Position only.
    pub fn position(x: f64, y: f64, z: f64) -> Self {
        Self {
            position: Point3::new(x, y, z),
            orientation: None,
        }
    }

    /// Position with the tool pointing straight down (ef z axis = −world z), as for picking.
    pub fn pointing_down(x: f64, y: f64, z: f64) -> Self {
        Self {
            position: Point3::new(x, y, z),
            orientation: Some(UnitQuaternion::from_rotation_matrix(
                &Rotation3::from_matrix_unchecked(Matrix3::new(
                    1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0,
                )),
            )),
        }
    }
}

/// Solver settings; the defaults reach sub-millimetre accuracy on the iiwa.
#[derive(Debug, Clone)]
pub struct IkOptions {
    /// Start of the first attempt (default: mid-range of every joint).
    pub initial: Option<Vec<f64>>,
    /// Seed of the random restarts.
    pub seed: u64,
    /// Attempts (first start + random restarts) before giving up; 0 counts as 1.
    pub max_attempts: usize,
    /// Iterations per attempt.
    pub max_iterations: usize,
    /// Position tolerance, m.
    pub tolerance_m: f64,
    /// Orientation tolerance, rad.
    pub tolerance_rad: f64,
    /// Initial damping λ (adapted Levenberg–Marquardt style).
    pub damping: f64,
    /// Largest joint change per iteration, rad.
    pub max_step_rad: f64,
    /// Metres per radian when weighing orientation against position error.
    pub orientation_weight: f64,
}

impl Default for IkOptions {
    fn default() -> Self {
        Self {
            initial: None,
            seed: 0,
            max_attempts: 20,
            max_iterations: 200,
            tolerance_m: 1e-5,
            tolerance_rad: 1e-4,
            damping: 0.05,
            max_step_rad: 0.5,
            orientation_weight: 0.3,
        }
    }
}

/// An IK result.
#[derive(Debug, Clone, PartialEq)]
pub struct IkSolution {
    /// Joint values, within limits.
    pub joints: Vec<f64>,
    /// Remaining position error, m.
    pub position_error_m: f64,
    /// Remaining orientation error, rad (0 without an orientation target).
    pub orientation_error_rad: f64,
    /// Attempts used.
    pub attempts: usize,
}

impl IkSolution {
    fn cost(&self) -> f64 {
        self.position_error_m + 0.3 * self.orientation_error_rad
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

    fn random_q(model: &ArmModel, rng: &mut StdRng) -> Vec<f64> {
        model
            .limits()
            .iter()
            .map(|l| rng.random_range(l.lower..l.upper))
            .collect()
    }

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
    fn ik_reaches_1000_reachable_targets_below_1mm() {
        let m = ArmModel::embedded();
        let mut rng = StdRng::seed_from_u64(42);
        let mut worst: f64 = 0.0;
        let mut total_error = 0.0;
        let mut attempts = Vec::new();
        let started = std::time::Instant::now();
        for i in 0..1000 {
            let q = random_q(&m, &mut rng);
            let p = m.ef_pose(&q).unwrap().translation.vector;
            let target = IkTarget::position(p.x, p.y, p.z);
            let sol = m
                .inverse(
                    &target,
                    &IkOptions {
                        seed: i,
                        ..IkOptions::default()
                    },
                )
                .unwrap_or_else(|e| panic!("target {i}: {e}"));
            m.check_joints(&sol.joints).unwrap();
            let reached = m.ef_pose(&sol.joints).unwrap().translation.vector;
            let error = (reached - p).norm();
            assert!(
                (error - sol.position_error_m).abs() < 1e-12,
                "reported error"
            );
            worst = worst.max(error);
            total_error += error;
            attempts.push(sol.attempts);
        }
        let elapsed = started.elapsed();
        let restarted = attempts.iter().filter(|&&a| a > 1).count();
        println!(
            "IK, 1000 targets: worst {worst:.2e} m, mean {:.2e} m, {restarted} needed restarts (max {} attempts), {:.1} ms total",
            total_error / 1000.0,
            attempts.iter().max().unwrap(),
            elapsed.as_secs_f64() * 1e3
        );
        assert!(worst < 1e-3, "worst error {worst} m");
    }

    #[test]
    fn ik_reaches_table_targets_pointing_down() {
        let m = ArmModel::embedded();
        for (x, y) in [(0.45, -0.2), (0.6, 0.0), (0.75, 0.3)] {
            let sol = m
                .inverse(&IkTarget::pointing_down(x, y, 0.25), &IkOptions::default())
                .unwrap();
            assert!(
                sol.position_error_m < 1e-3 && sol.orientation_error_rad < 1e-2,
                "{sol:?}"
            );
        }
    }

    /// The cube spawn area documented in urdf/README.md and urdf/table.urdf: table top at
    /// z = 0.20 m, cube positions x 0.43..0.73 m, y -0.25..0.25 m. `ef` must reach every one
    /// pointing down, from touching the 5 cm cube (top + 5 mm) to 0.2 m above it.
    #[test]
    fn pick_area_is_reachable_from_above() {
        let m = ArmModel::embedded();
        let cube_top = 0.20 + 0.05;
        let mut worst: f64 = 0.0;
        let mut checked = 0;
        for ix in 0..=12 {
            let x = 0.43 + 0.30 * ix as f64 / 12.0;
            for iy in 0..=10 {
                let y = -0.25 + 0.50 * iy as f64 / 10.0;
                for dz in [0.005, 0.12, 0.2] {
                    let target = IkTarget::pointing_down(x, y, cube_top + dz);
                    let sol = m
                        .inverse(&target, &IkOptions::default())
                        .unwrap_or_else(|e| panic!("({x:.3}, {y:.3}, +{dz}): {e}"));
                    assert!(sol.orientation_error_rad < 1e-3, "{sol:?}");
                    worst = worst.max(sol.position_error_m);
                    checked += 1;
                }
            }
        }
        assert!(worst < 1e-4, "worst {worst}");
        assert_eq!(checked, 13 * 11 * 3);
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

    #[test]
    fn zero_attempts_still_tries_once() {
        let m = ArmModel::embedded();
        let sol = m
            .inverse(
                &IkTarget::position(0.5, 0.1, 0.6),
                &IkOptions {
                    max_attempts: 0,
                    ..Default::default()
                },
            )
            .unwrap();
        assert!(sol.position_error_m < 1e-4);
    }

    #[test]
    fn unreachable_target_is_reported() {
        let m = ArmModel::embedded();
        let err = m
            .inverse(
                &IkTarget::position(5.0, 0.0, 0.5),
                &IkOptions {
                    max_attempts: 3,
                    ..Default::default()
                },
            )
            .unwrap_err();
        let text = err.to_string();
        assert!(
            text.contains("unreachable") && text.contains("(5.0000, 0.0000, 0.5000)"),
            "{text}"
        );
        let KinematicsError::Unreachable { best_error_m, .. } = err else {
            panic!()
        };
        assert!(best_error_m > 3.0);
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
