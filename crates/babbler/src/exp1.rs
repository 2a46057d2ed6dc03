//! Experiment 1: every step a joint configuration drawn from N(mean, σ²) per joint,
//! clipped to the joint limits, whatever the state.

use causal_arm_kinematics::ArmModel;
use causal_arm_protocol::{ARM_DOF, Command, Draw, Drawn, SimState};
use rand::{SeedableRng, rngs::StdRng};
use rand_distr::{Distribution, Normal};

use crate::limits_of;

/// Settings of experiment 1.
#[derive(Debug, Clone)]
pub struct Exp1Config {
    /// Mean of the joint distribution, rad.
    pub mean: [f64; ARM_DOF],
    /// Standard deviation per joint, rad (DESIGN.md: 0.35 matches the paper's ablations).
    pub sigma: f64,
    /// Seed.
    pub seed: u64,
}

impl Default for Exp1Config {
    fn default() -> Self {
        Self {
            mean: [0.0; ARM_DOF],
            sigma: causal_arm_protocol::graph::run_default_f64("sigma"),
            seed: 0,
        }
    }
}

impl Exp1Config {
    /// The design in words, for the bag's metadata.
    pub fn design_words(&self) -> String {
        format!(
            "exp1: every step each joint's target ~ clamp(mean + N(0, {}^2), its limits), mean {:?} rad, independent of the state and of the other joints; no scripted steps",
            self.sigma, self.mean
        )
    }
}

/// Random joint configurations (experiment 1).
pub struct Exp1Babbler {
    rng: StdRng,
    normal: Normal<f64>,
    mean: [f64; ARM_DOF],
    lower: [f64; ARM_DOF],
    upper: [f64; ARM_DOF],
}

impl Exp1Babbler {
    /// A babbler for `model` (limits) with `config`.
    pub fn new(model: &ArmModel, config: &Exp1Config) -> Result<Self, String> {
        if !(config.sigma.is_finite() && config.sigma >= 0.0) {
            return Err(format!(
                "sigma must be a finite non-negative number of rad, got {}",
                config.sigma
            ));
        }
        let normal = Normal::new(0.0, config.sigma).map_err(|e| {
            format!(
                "sigma must be a finite non-negative number, got {}: {e}",
                config.sigma
            )
        })?;
        let (lower, upper) = limits_of(model);
        Ok(Self {
            rng: StdRng::seed_from_u64(config.seed),
            normal,
            mean: config.mean,
            lower,
            upper,
        })
    }

    /// The next command.
    pub fn next(&mut self, state: &SimState) -> Command {
        self.next_drawn(state).command
    }

    /// The next command and how it was drawn: each joint's target from N(mean, σ²),
    /// clamped to its limits, whatever the state.
    pub fn next_drawn(&mut self, _state: &SimState) -> Drawn {
        let joint_targets = std::array::from_fn(|i| {
            (self.mean[i] + self.normal.sample(&mut self.rng)).clamp(self.lower[i], self.upper[i])
        });
        let sigma = self.normal.std_dev();
        let design = (0..ARM_DOF)
            .map(|i| match sigma > 0.0 {
                true => Draw::Normal {
                    center: self.mean[i],
                    sigma,
                    lower: self.lower[i],
                    upper: self.upper[i],
                    region: None,
                },
                false => Draw::Scripted,
            })
            .collect();
        Drawn {
            command: Command {
                joint_targets,
                magnet: 0,
            },
            design,
        }
    }
}
