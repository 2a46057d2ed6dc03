//! Continuing a run that was cut short (`generate --resume`, `launch --resume`).
//!
//! A killed or stopped run leaves a bag whose complete steps are sound (the recorder lands
//! whole chunks; a crash tail is read up to its last one). Resuming keeps those steps: the
//! bag is moved aside as `<bag>.interrupted`, its first steps are copied into a new bag in
//! its place, and the aside copy is removed once they have landed. The simulator and the
//! babbler are re-run to the same step ([`crate::fast_forward`]), so the finished bag is
//! the one an uninterrupted run of the seed writes.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use causal_arm_bag::{BagReader, RawMessage};
use causal_arm_protocol::{bag_keys, topics};

use crate::{BagSink, GenerateError, GenerateOptions};

/// Where a bag is kept while its steps are copied into its replacement.
pub fn interrupted_dir(dir: &Path) -> PathBuf {
    let mut name = dir.file_name().unwrap_or_default().to_os_string();
    name.push(".interrupted");
    dir.with_file_name(name)
}

/// A bag to resume: its messages up to its last complete step.
struct Resumable {
    /// The robot description and the messages of the complete steps, in file order.
    messages: Vec<RawMessage>,
    /// Stamp of each complete step, in order.
    steps: Vec<u64>,
}

/// Reads the bag at `dir` as a cut-short run of `options`: refuses a bag of another run
/// (naming the setting that differs) and damage other than a crash tail.
fn read_resumable(dir: &Path, options: &GenerateOptions) -> Result<Resumable, GenerateError> {
    let aside = interrupted_dir(dir);
    if aside.exists() {
        return Err(GenerateError::Options(format!(
            "{} exists: an earlier --resume stopped while copying; it holds the original bag: move it back to {} and resume again",
            aside.display(),
            dir.display()
        )));
    }
    let reader = BagReader::open(dir)?;
    let recorded = reader.custom_data();
    for (key, want) in options.bag_custom_data() {
        // Bags written before the dynamic arm existed used the kinematic one.
        let unrecorded = match key == bag_keys::ARM {
            true => "kinematic",
            false => "(none)",
        };
        let got = recorded.get(&key).map(String::as_str).unwrap_or(unrecorded);
        if got != want {
            return Err(GenerateError::Options(format!(
                "{}: cannot resume another run: the bag has {key} = {got}, this run {key} = {want}",
                dir.display()
            )));
        }
    }
    let all = reader.messages().collect::<Result<Vec<_>, _>>()?;
    let mut topics_at: BTreeMap<u64, Vec<&str>> = BTreeMap::new();
    for m in all
        .iter()
        .filter(|m| topics::RECORDED_STEP.contains(&m.topic.as_str()))
    {
        topics_at.entry(m.log_time_ns).or_default().push(&m.topic);
    }
    let complete = |topics: &Vec<&str>| {
        topics.len() == topics::RECORDED_STEP.len()
            && topics::RECORDED_STEP.iter().all(|t| topics.contains(t))
    };
    let steps: Vec<u64> = topics_at
        .iter()
        .take_while(|(_, topics)| complete(topics))
        .map(|(&stamp, _)| stamp)
        .collect();
    let last = steps.last().copied();
    let messages = all
        .into_iter()
        .filter(|m| {
            topics::LATCHED.contains(&m.topic.as_str()) || last.is_some_and(|l| m.log_time_ns <= l)
        })
        .collect();
    Ok(Resumable { messages, steps })
}

/// The complete steps of the bag at `dir`, a cut-short run of `options`: the step a resumed
/// run starts at. A bag that already holds the whole run has nothing to resume.
pub fn resume_point(dir: &Path, options: &GenerateOptions) -> Result<u64, GenerateError> {
    unfinished(dir, options, &read_resumable(dir, options)?)
}

/// The steps `old` holds, or an error if they are the whole run of `options`.
fn unfinished(
    dir: &Path,
    options: &GenerateOptions,
    old: &Resumable,
) -> Result<u64, GenerateError> {
    let (have, total) = (old.steps.len() as u64, options.plan.total_steps());
    match have < total {
        true => Ok(have),
        false => Err(GenerateError::Options(format!(
            "{} already holds all {total} steps: nothing to resume",
            dir.display()
        ))),
    }
}

impl BagSink {
    /// Replaces the bag at `dir`, a run of `options` cut short, by one holding its first
    /// `keep` steps (all its complete steps if `None`) and its robot description, ready
    /// for the next step. Returns the sink and the steps kept.
    pub fn resume(
        dir: &Path,
        options: &GenerateOptions,
        keep: Option<u64>,
    ) -> Result<(BagSink, u64), GenerateError> {
        Self::resume_from(dir, options, read_resumable(dir, options)?, keep)
    }

    /// [`BagSink::resume`] with the cut-short bag already read.
    fn resume_from(
        dir: &Path,
        options: &GenerateOptions,
        mut old: Resumable,
        keep: Option<u64>,
    ) -> Result<(BagSink, u64), GenerateError> {
        let have = old.steps.len() as u64;
        let keep = keep.unwrap_or(have);
        if keep > have {
            return Err(GenerateError::Options(format!(
                "{}: cannot resume at step {keep}: the bag holds {have} complete steps",
                dir.display()
            )));
        }
        if let Some(&first_dropped) = old.steps.get(keep as usize) {
            old.messages.retain(|m| {
                topics::LATCHED.contains(&m.topic.as_str()) || m.log_time_ns < first_dropped
            });
        }
        let aside = interrupted_dir(dir);
        std::fs::rename(dir, &aside)
            .map_err(|e| GenerateError::Options(format!("moving {} aside: {e}", dir.display())))?;
        let mut sink = BagSink::create(dir, false, options)?;
        for m in &old.messages {
            sink.writer
                .write_cdr(&m.topic, m.log_time_ns, m.publish_time_ns, &m.data)?;
        }
        sink.messages = old.messages.len() as u64;
        // Killed before its first chunk landed, the bag lost even the latched messages (a
        // bag from before `/tf_static` was recorded lacks that one).
        let has = |topic: &str| old.messages.iter().any(|m| m.topic == topic);
        let (description, tf_static) = (has(topics::ROBOT_DESCRIPTION), has(topics::TF_STATIC));
        if !description || !tf_static {
            let latched = crate::simulator(options)?.latched_messages();
            if !description {
                sink.writer
                    .write(topics::ROBOT_DESCRIPTION, 0, &latched.robot_description)?;
                sink.messages += 1;
            }
            if !tf_static {
                sink.writer
                    .write(topics::TF_STATIC, 0, &latched.tf_static)?;
                sink.messages += 1;
            }
        }
        sink.writer.land()?;
        sink.landed_stamp = keep.checked_sub(1).map(|i| old.steps[i as usize]);
        std::fs::remove_dir_all(&aside)
            .map_err(|e| GenerateError::Options(format!("removing {}: {e}", aside.display())))?;
        Ok((sink, keep))
    }
}

/// Continues the cut-short run of `options` in its bag, reading the bag once: the sink
/// holding its complete steps, and the step to go on from.
pub(crate) fn resume_unfinished(
    options: &GenerateOptions,
) -> Result<(BagSink, u64), GenerateError> {
    let dir = &options.out;
    let old = read_resumable(dir, options)?;
    let start = unfinished(dir, options, &old)?;
    BagSink::resume_from(dir, options, old, Some(start))
}
