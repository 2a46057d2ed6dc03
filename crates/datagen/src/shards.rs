//! `generate --shards N`: one run cut into N shards simulated side by side, one thread
//! each, written as a shard set (see `causal_arm_bag::ShardSet`). Every shard is an
//! ordinary seeded run of its share of the plan, so it is deterministic on its own and
//! the set is the same for the same seed and count whatever the thread timing.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Duration;

use causal_arm_bag::ShardSet;
use causal_arm_protocol::{bag_keys, shard_seed};

use crate::{GenerateError, GenerateOptions, GenerateSummary, generate};

/// A shard's place in its set, recorded in its bag's `custom_data`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// 0-based index.
    pub index: u64,
    /// Shards in the set.
    pub count: u64,
    /// The seed the set was asked for (the shard runs on `shard_seed(set_seed, index)`).
    pub set_seed: u64,
}

/// The options of every shard of `options` cut `count` ways: each its share of the plan,
/// its own seed and `OUT/shard-i`.
pub fn shard_options(
    options: &GenerateOptions,
    count: u64,
) -> Result<Vec<GenerateOptions>, GenerateError> {
    let plans = (options.plan)
        .shards(options.experiment, count)
        .map_err(GenerateError::Options)?;
    let set = ShardSet::numbered(plans.len(), BTreeMap::new());
    Ok(plans
        .into_iter()
        .zip(&set.shards)
        .enumerate()
        .map(|(i, (plan, name))| {
            let index = i as u64;
            let mut shard = options.clone();
            shard.plan = plan;
            shard.seed = shard_seed(options.seed, index);
            shard.out = options.out.join(name);
            shard.shard = Some(Shard {
                index,
                count,
                set_seed: options.seed,
            });
            shard
        })
        .collect())
}

/// Runs the shards of `options` in parallel into the shard set `options.out`; calls
/// `progress(steps done, steps in all)` from this thread about ten times a second.
pub fn generate_shards(
    options: &GenerateOptions,
    count: u64,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Vec<GenerateSummary>, GenerateError> {
    let shards = shard_options(options, count)?;
    for shard in &shards {
        crate::validate(shard)?;
    }
    shard_set_manifest(options, &shards).create(&options.out, options.overwrite)?;
    let total = options.plan.total_steps();
    let done: Vec<AtomicU64> = shards.iter().map(|_| AtomicU64::new(0)).collect();
    let running = AtomicU64::new(shards.len() as u64);
    let failed = AtomicBool::new(false);
    let results = std::thread::scope(|scope| {
        let workers: Vec<_> = shards
            .iter()
            .zip(&done)
            .map(|(shard, done)| {
                let (running, failed) = (&running, &failed);
                scope.spawn(move || {
                    // Every 256 steps: the shards' counters share a cache line.
                    let mut report = |steps: u64, total: u64| {
                        if steps.is_multiple_of(256) || steps == total {
                            done.store(steps, Ordering::Relaxed);
                        }
                    };
                    let result = generate(shard, &mut report);
                    failed.fetch_or(result.is_err(), Ordering::Relaxed);
                    running.fetch_sub(1, Ordering::Release);
                    result
                })
            })
            .collect();
        while running.load(Ordering::Acquire) > 0 {
            std::thread::sleep(Duration::from_millis(100));
            progress(done.iter().map(|d| d.load(Ordering::Relaxed)).sum(), total);
        }
        workers
            .into_iter()
            .map(|w| w.join().expect("a shard thread panicked"))
            .collect::<Vec<_>>()
    });
    progress(done.iter().map(|d| d.load(Ordering::Relaxed)).sum(), total);
    results.into_iter().collect()
}

/// The set's manifest: the run it splits and each shard's seed.
pub fn shard_set_manifest(options: &GenerateOptions, shards: &[GenerateOptions]) -> ShardSet {
    let mut data = BTreeMap::from([
        (
            bag_keys::EXPERIMENT.to_owned(),
            options.experiment.to_string(),
        ),
        (
            bag_keys::SHARD_SET_SEED.to_owned(),
            options.seed.to_string(),
        ),
    ]);
    for shard in shards {
        let name = shard.out.file_name().unwrap_or_default().to_string_lossy();
        data.insert(format!("{}.{name}", bag_keys::SEED), shard.seed.to_string());
    }
    ShardSet::numbered(shards.len(), data)
}

#[cfg(test)]
mod tests {
    use super::*;
    use causal_arm_protocol::{Experiment, RunPlan};

    #[test]
    fn shards_split_the_plan_and_name_their_place_and_seed() {
        let plan = RunPlan {
            episodes: 1,
            steps_per_episode: 101,
        };
        let options = GenerateOptions::new(Experiment::Exp1, plan, 7, "/tmp/set");
        let shards = shard_options(&options, 2).unwrap();
        let steps: Vec<u64> = shards.iter().map(|s| s.plan.total_steps()).collect();
        assert_eq!(steps, [51, 50]);
        assert_eq!(shards[0].seed, 7);
        assert_eq!(shards[1].seed, shard_seed(7, 1));
        assert!(shards[1].out.ends_with("shard-1"));
        let data = shards[1].bag_custom_data();
        assert_eq!(data[bag_keys::SHARD], "1/2");
        assert_eq!(data[bag_keys::SHARD_SET_SEED], "7");
        assert_eq!(data[bag_keys::SEED], shard_seed(7, 1).to_string());
        assert!(shard_options(&options, 0).is_err());
    }
}
