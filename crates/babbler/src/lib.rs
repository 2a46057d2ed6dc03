//! Motor babbling: what the robot does to collect data, for both experiments of the paper.
//!
//! A babbler sees the simulator's state and answers with one [`Command`]; it is seeded
//! and deterministic, so the same seed produces the same dataset whether the graph runs
//! over DDS or in one process.
//!
//! - Experiment 1 ([`Exp1Babbler`]): every step a joint configuration drawn from
//!   N(mean, σ²) per joint, clipped to the joint limits.
//! - Experiment 2 ([`Exp2Babbler`]): babbles empty-handed; at random switches the magnet
//!   on, then reaches the cube (IK, from above), picks it, manoeuvres randomly for a random
//!   number of steps, switches the magnet off (the cube drops) and babbles again.

mod exp1;
mod exp2;

pub use exp1::{Exp1Babbler, Exp1Config};
pub use exp2::{Exp2Babbler, Exp2Config, Phase};

use causal_arm_kinematics::ArmModel;
use causal_arm_protocol::ARM_DOF;

/// The arm's joint limits, lower and upper, in joint order.
fn limits_of(model: &ArmModel) -> ([f64; ARM_DOF], [f64; ARM_DOF]) {
    let l = model.limits();
    (
        std::array::from_fn(|i| l[i].lower),
        std::array::from_fn(|i| l[i].upper),
    )
}
