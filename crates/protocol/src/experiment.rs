//! The paper's experiments and their sizes, the keys a dataset bag records about its run,
//! and how a run's seed becomes the simulator's and the babbler's.
//!
//! The generator writes these and the dataset builder, the ground truth and the CLI read
//! them; none of the readers should have to build the generator to learn their names.

/// Which of the paper's experiments.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Experiment {
    /// Kinematics: random joint configurations.
    Exp1,
    /// Intuitive physics: magnet, cube, table.
    Exp2,
}

crate::choice!(Experiment, "experiment", [Experiment::Exp1 => "exp1", Experiment::Exp2 => "exp2"]);

impl Experiment {
    /// Components of its actions: the arm's joints, and the magnet in experiment 2.
    pub const fn action_components(self) -> usize {
        match self {
            Self::Exp1 => crate::ARM_DOF,
            Self::Exp2 => crate::ARM_DOF + 1,
        }
    }
}

/// Size presets: the dataset a run generates ([`RunPlan::for_profile`]) and the epochs the
/// trainer gives each network; one name, so `--profile quick` means the same everywhere.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Profile {
    /// The paper's protocol: 500,000 steps (exp 1), 4,000 episodes × 500 (exp 2); FM 60
    /// (exp 1) / 100 (exp 2) epochs, IM 1,000, base IM 100, pre-network 4,000.
    Paper,
    /// A demo: a dataset in about a minute, a few epochs of each network.
    Quick,
}

crate::choice!(Profile, "profile", [Profile::Paper => "paper", Profile::Quick => "quick"]);

/// How many episodes of how many steps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RunPlan {
    /// Episodes (exp 1 runs one long episode).
    pub episodes: u64,
    /// Steps per episode.
    pub steps_per_episode: u64,
}

impl RunPlan {
    /// The profile's plan for `experiment`.
    pub fn for_profile(experiment: Experiment, profile: Profile) -> Self {
        match (experiment, profile) {
            (Experiment::Exp1, Profile::Paper) => Self {
                episodes: 1,
                steps_per_episode: 500_000,
            },
            (Experiment::Exp1, Profile::Quick) => Self {
                episodes: 1,
                steps_per_episode: 5_000,
            },
            (Experiment::Exp2, Profile::Paper) => Self {
                episodes: 4_000,
                steps_per_episode: 500,
            },
            (Experiment::Exp2, Profile::Quick) => Self {
                episodes: 20,
                steps_per_episode: 500,
            },
        }
    }

    /// Total steps.
    pub fn total_steps(&self) -> u64 {
        self.episodes * self.steps_per_episode
    }

    /// The plans of `count` shards that together run this plan's steps: exp 1's one long
    /// episode is cut into `count` episodes; exp 2's episodes (of fixed length) are dealt
    /// out. Earlier shards take the remainder. A shard with nothing to do is refused,
    /// naming the sizes.
    pub fn shards(&self, experiment: Experiment, count: u64) -> Result<Vec<RunPlan>, String> {
        if count == 0 {
            return Err("--shards must be at least 1, got 0".into());
        }
        let split = |total: u64| -> Vec<u64> {
            (0..count)
                .map(|i| total / count + u64::from(i < total % count))
                .collect()
        };
        let plans: Vec<RunPlan> = if experiment == Experiment::Exp2 || self.episodes > 1 {
            split(self.episodes)
                .into_iter()
                .map(|episodes| RunPlan { episodes, ..*self })
                .collect()
        } else {
            split(self.steps_per_episode)
                .into_iter()
                .map(|steps_per_episode| RunPlan {
                    episodes: self.episodes,
                    steps_per_episode,
                })
                .collect()
        };
        if plans.iter().any(|p| p.total_steps() == 0) {
            return Err(format!(
                "{count} shards for {} episode(s) of {} steps leave a shard without work",
                self.episodes, self.steps_per_episode
            ));
        }
        Ok(plans)
    }
}

/// Seed of shard `index` of a run seeded `seed`: shard 0 keeps the run's seed (so one
/// shard is the unsharded run), the others get decorrelated seeds that no small run seed
/// collides with, below 2^63 so a node's integer `seed` parameter can take them.
pub fn shard_seed(seed: u64, index: u64) -> u64 {
    match index {
        0 => seed,
        i => {
            // splitmix64 of (seed, index)
            let mut z = seed ^ i.wrapping_mul(0x9E37_79B9_7F4A_7C15);
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            (z ^ (z >> 31)) >> 1
        }
    }
}

/// `custom_data` keys a dataset bag carries (written by datagen's
/// `GenerateOptions::bag_custom_data`, read by the dataset builder and the ground truth).
pub mod bag_keys {
    /// `exp1` or `exp2`.
    pub const EXPERIMENT: &str = "causal_arm.experiment";
    /// Babbling seed.
    pub const SEED: &str = "causal_arm.seed";
    /// Episodes in the run.
    pub const EPISODES: &str = "causal_arm.episodes";
    /// Steps per episode.
    pub const STEPS_PER_EPISODE: &str = "causal_arm.steps_per_episode";
    /// Exp 1 babbling spread, rad.
    pub const SIGMA: &str = "causal_arm.sigma";
    /// Scale of the URDF joint velocity limits.
    pub const VELOCITY_SCALE: &str = "causal_arm.velocity_scale";
    /// How the simulator moved the arm, `kinematic` or `dynamic` (bags written before the
    /// dynamic arm existed lack the key and used the kinematic one).
    pub const ARM: &str = "causal_arm.arm";
    /// Exp 2 babbler moves while switching the magnet (`true`/`false`; bags written before
    /// it became the default lack the key and held the arm still).
    pub const MOVE_WHILE_SWITCHING: &str = "causal_arm.move_while_switching";
    /// A shard's place in its set, `INDEX/COUNT` (absent in unsharded bags).
    pub const SHARD: &str = "causal_arm.shard";
    /// The seed the shard set was asked for (each shard's own is [`SEED`]).
    pub const SHARD_SET_SEED: &str = "causal_arm.shard_set_seed";
    /// How the babbler drew its actions, in words (each action says so itself in
    /// `Action.design`; bags written before lack both and read as the paper's design).
    pub const DESIGN: &str = "causal_arm.design";
}

/// Seed of the simulator for a run seed (decorrelated from the babbler's).
pub fn sim_seed(seed: u64) -> u64 {
    seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0x5151
}

/// Seed of the babbler for a run seed.
pub fn babbler_seed(seed: u64) -> u64 {
    seed.wrapping_mul(0xD1B5_4A32_D192_ED03) ^ 0xBABB
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_parse_back_and_unknown_ones_are_named() {
        for e in [Experiment::Exp1, Experiment::Exp2] {
            assert_eq!(e.to_string().parse::<Experiment>(), Ok(e));
        }
        let err = "exp3".parse::<Experiment>().unwrap_err();
        assert!(
            err.contains("\"exp3\"") && err.contains("exp1 or exp2"),
            "{err}"
        );
        assert_eq!("quick".parse::<Profile>(), Ok(Profile::Quick));
        assert!("fast".parse::<Profile>().is_err());
    }

    #[test]
    fn plans_follow_the_paper() {
        let paper1 = RunPlan::for_profile(Experiment::Exp1, Profile::Paper);
        assert_eq!((paper1.episodes, paper1.total_steps()), (1, 500_000));
        let paper2 = RunPlan::for_profile(Experiment::Exp2, Profile::Paper);
        assert_eq!((paper2.episodes, paper2.steps_per_episode), (4_000, 500));
    }

    /// Every bag's content depends on these; a change would silently change all datasets.
    #[test]
    fn shards_share_out_the_plan_exactly() {
        let exp1 = RunPlan::for_profile(Experiment::Exp1, Profile::Paper);
        let halves = exp1.shards(Experiment::Exp1, 2).unwrap();
        assert_eq!(
            halves,
            vec![
                RunPlan {
                    episodes: 1,
                    steps_per_episode: 250_000
                };
                2
            ]
        );
        let exp2 = RunPlan {
            episodes: 5,
            steps_per_episode: 500,
        };
        let three: Vec<u64> = (exp2.shards(Experiment::Exp2, 3).unwrap().iter())
            .map(|p| p.episodes)
            .collect();
        assert_eq!(three, vec![2, 2, 1]);
        let cases = [
            (exp1, Experiment::Exp1, 3),
            (exp2, Experiment::Exp2, 2),
            (exp2, Experiment::Exp2, 5),
        ];
        for (plan, experiment, n) in cases {
            let shards = plan.shards(experiment, n).unwrap();
            let total: u64 = shards.iter().map(RunPlan::total_steps).sum();
            assert_eq!(total, plan.total_steps());
        }
        assert_eq!(exp1.shards(Experiment::Exp1, 1).unwrap(), vec![exp1]);
        assert!(
            exp2.shards(Experiment::Exp2, 0)
                .unwrap_err()
                .contains("at least 1")
        );
        let err = exp2.shards(Experiment::Exp2, 6).unwrap_err();
        assert!(
            err.contains("6 shards") && err.contains("5 episode"),
            "{err}"
        );
        let one = RunPlan {
            episodes: 1,
            steps_per_episode: 500,
        };
        assert!(
            one.shards(Experiment::Exp2, 2).is_err(),
            "exp 2 episodes are never cut"
        );
    }

    #[test]
    fn shard_zero_keeps_the_run_seed_and_the_rest_differ() {
        assert_eq!(shard_seed(5, 0), 5);
        let seeds: std::collections::BTreeSet<u64> = (0..64).map(|i| shard_seed(5, i)).collect();
        assert_eq!(seeds.len(), 64);
        assert!(
            (1..64).all(|i| shard_seed(5, i) > 1_000_000),
            "no collision with small run seeds"
        );
        assert_ne!(shard_seed(5, 1), shard_seed(6, 1));
    }

    #[test]
    fn seeds_are_stable() {
        assert_eq!(sim_seed(3), 0xdaa6_6d2c_7ddf_256e);
        assert_eq!(babbler_seed(3), 0x751f_de98_74b8_7db2);
    }
}
