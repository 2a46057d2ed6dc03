//! `causal-arm bag info|check|recover|stats`: what a bag holds (like `ros2 bag info`),
//! whether it is sound (like `mcap doctor`), a new bag from what is intact (like `mcap
//! recover` and `ros2 bag reindex`), and the physics its data shows (`stats`).

use std::path::{Path, PathBuf};

use anyhow::{Context as _, bail};
use causal_arm_bag::{BagOptions, BagReader, BagWriter, ReadPolicy};
use causal_arm_msgs::{MessageTypeVisitor, RosMessage, visit_message_type};
use serde_json::json;

/// `causal-arm bag …`
#[derive(Debug, clap::Args)]
pub struct BagArgs {
    #[command(subcommand)]
    command: BagCommand,
    /// How to treat damage in the bags read (for every `bag` subcommand).
    #[command(flatten)]
    pub read: ReadArgs,
}

/// `--salvage`, for the commands that read bags (only they take it).
#[derive(Debug, Clone, Copy, clap::Args)]
pub struct ReadArgs {
    /// Read damaged bags anyway: skip damaged chunks with a warning instead of refusing the
    /// bag (a crash tail is always read up to its last complete chunk).
    #[arg(long, global = true)]
    pub salvage: bool,
}

#[derive(Debug, clap::Subcommand)]
enum BagCommand {
    /// Topics, types, message counts and integrity of a bag, as JSON (for a shard set, a
    /// JSON array with one entry per shard).
    Info {
        /// Bag directory, .mcap file or shard set.
        bag: PathBuf,
    },
    /// Checks everything (record framing, chunk sizes and CRCs, message indexes, section
    /// CRCs, summary and metadata.yaml counts, step completeness); prints a JSON report and
    /// exits 1 unless the bag (every shard of a shard set) is sound and finished.
    Check {
        /// Bag directory, .mcap file or shard set.
        bag: PathBuf,
    },
    /// Writes a new bag (MCAP with summary, and metadata.yaml) from every intact chunk of
    /// BAG, and reports what was lost.
    Recover {
        /// Damaged or cut-short bag directory or .mcap file.
        bag: PathBuf,
        /// New bag directory.
        #[arg(long)]
        out: PathBuf,
        /// Replace a bag already at --out.
        #[arg(long)]
        overwrite: bool,
        /// Split the new bag as `ros2 bag record --max-bag-size` does (bytes; 0: one file).
        #[arg(long, value_name = "BYTES", default_value_t = 0)]
        max_bag_size: u64,
        /// Split the new bag as `ros2 bag record --max-bag-duration` does (s; 0: one file).
        #[arg(long, value_name = "SECONDS", default_value_t = 0)]
        max_bag_duration: u64,
    },
    /// Physical statistics of the data, as JSON: commanded and realized joint changes, how
    /// deep and how often the arm's links went into the table, and in exp 2 how often the
    /// cube lay on the floor and how often switching the magnet on caught it. Several bags
    /// (or a shard set) are described as one dataset.
    Stats {
        /// Bag directories or shard sets.
        #[arg(required = true)]
        bags: Vec<PathBuf>,
    },
}

/// Runs `causal-arm bag …`.
pub fn run(args: &BagArgs) -> anyhow::Result<()> {
    match &args.command {
        BagCommand::Info { bag } => each_bag(bag, info_report),
        BagCommand::Check { bag } => each_bag(bag, check_report),
        BagCommand::Recover {
            bag,
            out,
            overwrite,
            max_bag_size,
            max_bag_duration,
        } => {
            let split =
                causal_arm_bag::SplitLimits::from_ros2_units(*max_bag_size, *max_bag_duration);
            recover(bag, out, *overwrite, split)
        }
        BagCommand::Stats { bags } => stats(bags),
    }
}

/// Prints the physical statistics of `bags` (one dataset) as JSON.
fn stats(bags: &[PathBuf]) -> anyhow::Result<()> {
    let (data, loaded) = causal_arm_dataset::load_bags(
        bags,
        None,
        causal_arm_dataset::ActionSource::Commanded,
        None,
    )?;
    let config = causal_arm_sim::SimConfig {
        velocity_scale: recorded_velocity_scale(loaded.iter().map(|(bag, _)| bag.as_path()))?,
        ..causal_arm_sim::SimConfig::default()
    };
    let stats = causal_arm_datastats::describe(&data, &config).context("describing the data")?;
    println!("{}", serde_json::to_string_pretty(&stats)?);
    Ok(())
}

/// The velocity scale the bags were recorded with (their joints' speed limits), which
/// must be one for all of them.
fn recorded_velocity_scale<'a>(bags: impl Iterator<Item = &'a Path>) -> anyhow::Result<f64> {
    let key = causal_arm_protocol::bag_keys::VELOCITY_SCALE;
    let mut scale: Option<(f64, PathBuf)> = None;
    for bag in bags {
        let data = BagReader::open(bag)?.custom_data();
        let text = data.get(key).with_context(|| {
            format!("{}: the bag records no {key} (custom_data)", bag.display())
        })?;
        let value: f64 = text.parse().map_err(|_| {
            anyhow::anyhow!(
                "{}: custom_data {key}={text:?} is not a number",
                bag.display()
            )
        })?;
        match &scale {
            Some((first, first_bag)) if *first != value => bail!(
                "{} was recorded with {key}={first}, {} with {value}: describe them apart",
                first_bag.display(),
                bag.display()
            ),
            Some(_) => {}
            None => scale = Some((value, bag.to_owned())),
        }
    }
    scale.map(|(value, _)| value).context("no bags to describe")
}

/// Prints `report` of `path` as JSON, or for a shard set a JSON array of its shards'
/// reports; fails when any report failed, after printing them all.
fn each_bag(
    path: &Path,
    report: fn(&Path) -> (Option<serde_json::Value>, anyhow::Result<()>),
) -> anyhow::Result<()> {
    if causal_arm_bag::ShardSet::read(path)?.is_none() {
        let (json, verdict) = report(path);
        if let Some(json) = json {
            println!("{}", serde_json::to_string_pretty(&json)?);
        }
        return verdict;
    }
    let (mut reports, mut failed) = (Vec::new(), Vec::new());
    for bag in causal_arm_bag::bags_in(path)? {
        let (json, verdict) = report(&bag);
        reports.push(json.unwrap_or_else(|| json!({"path": bag})));
        if let Err(e) = verdict {
            failed.push(format!("{e:#}"));
        }
    }
    println!("{}", serde_json::to_string_pretty(&reports)?);
    match failed.is_empty() {
        true => Ok(()),
        false => bail!(
            "{} of {} shards failed: {}",
            failed.len(),
            reports.len(),
            failed.join("; ")
        ),
    }
}

fn info_report(bag: &Path) -> (Option<serde_json::Value>, anyhow::Result<()>) {
    match info(bag) {
        Ok(json) => (Some(json), Ok(())),
        Err(e) => (None, Err(e)),
    }
}

fn info(bag: &Path) -> anyhow::Result<serde_json::Value> {
    let reader = BagReader::open(bag)?;
    let mut first = None;
    let mut last = None;
    for raw in reader.messages() {
        let raw = raw?;
        first.get_or_insert(raw.log_time_ns);
        last = Some(raw.log_time_ns);
    }
    let info = json!({
        "path": reader.path(),
        "files": files_json(&reader),
        "message_count": reader.message_count(),
        "start_ns": first,
        "end_ns": last,
        "complete": reader.truncation().is_none() && reader.damage().is_empty(),
        "truncation": reader.truncation(),
        "damage": damage_json(&reader),
        "topics": topics_json(&reader),
    });
    Ok(info)
}

fn topics_json(reader: &BagReader) -> Vec<serde_json::Value> {
    reader
        .topics()
        .iter()
        .map(|t| json!({"name": t.name, "type": t.ros_type, "message_count": t.message_count}))
        .collect()
}

fn damage_json(reader: &BagReader) -> Vec<serde_json::Value> {
    reader
        .damage()
        .iter()
        .map(
            |d| json!({"file": d.file, "offset": d.offset, "chunk": d.chunk, "problem": d.problem}),
        )
        .collect()
}

/// Each MCAP file of the bag (several for a split bag), as `ros2 bag info` lists them.
fn files_json(reader: &BagReader) -> Vec<serde_json::Value> {
    reader
        .files()
        .iter()
        .map(|f| {
            json!({
                "path": f.path,
                "message_count": f.message_count,
                "finished": f.finished,
                "truncation": f.truncation,
            })
        })
        .collect()
}

fn check_report(bag: &Path) -> (Option<serde_json::Value>, anyhow::Result<()>) {
    let reader = match BagReader::open_unchecked(bag) {
        Ok(reader) => reader,
        Err(e) => return (None, Err(e.into())),
    };
    // metadata.yaml and the file's own damage, as a strict reader judges them.
    let verdict = reader.judge(bag, ReadPolicy::Strict).err();
    let steps = if verdict.is_none() {
        match causal_arm_dataset::from_bag(bag, None, causal_arm_dataset::ActionSource::Realized) {
            Ok(data) => json!({"transitions": data.rows()}),
            Err(e) => json!({"error": format!("{e:#}")}),
        }
    } else {
        serde_json::Value::Null
    };
    let sound = verdict.is_none() && reader.finished() && steps.get("error").is_none();
    let report = json!({
        "path": reader.path(),
        "files": files_json(&reader),
        "sound": sound,
        "finished": reader.finished(),
        "chunks": reader.chunk_count(),
        "readable_messages": reader.message_count(),
        "messages_in_damaged_chunks": reader.lost_known(),
        "truncation": reader.truncation(),
        "damage": damage_json(&reader),
        "error": verdict.as_ref().map(|e| e.to_string()),
        "steps": steps,
        "topics": topics_json(&reader),
    });
    (Some(report), check_verdict(&reader, verdict, &steps))
}

fn check_verdict(
    reader: &BagReader,
    verdict: Option<causal_arm_bag::BagError>,
    steps: &serde_json::Value,
) -> anyhow::Result<()> {
    if let Some(e) = verdict {
        bail!("{e}");
    }
    if let Some(e) = steps.get("error") {
        bail!(
            "{}: steps: {}",
            reader.path().display(),
            e.as_str().unwrap_or_default()
        );
    }
    if let Some(t) = reader.truncation() {
        bail!(
            "{}: not finished ({t}); `causal-arm bag recover` writes a finished copy",
            reader.last_path().display()
        );
    }
    Ok(())
}

/// Registers one topic of the recovered bag with its type's full definition.
struct AddTopic<'a> {
    writer: &'a mut BagWriter,
    topic: &'a str,
    qos: &'a str,
}

impl MessageTypeVisitor for AddTopic<'_> {
    type Output = Result<(), causal_arm_bag::BagError>;
    fn visit<M: RosMessage>(self) -> Self::Output {
        self.writer.add_topic::<M>(self.topic, self.qos)
    }
}

fn recover(
    bag: &Path,
    out: &Path,
    overwrite: bool,
    split: causal_arm_bag::SplitLimits,
) -> anyhow::Result<()> {
    let reader = BagReader::open_unchecked(bag)?;
    if reader.message_count() == 0 {
        bail!("{}: nothing intact to recover", reader.path().display());
    }
    let mut writer = BagWriter::create(
        out,
        BagOptions {
            custom_data: reader.custom_data(),
            overwrite,
            split,
            ..BagOptions::default()
        },
    )?;
    for topic in reader.topics() {
        let add = AddTopic {
            writer: &mut writer,
            topic: &topic.name,
            qos: &topic.offered_qos,
        };
        visit_message_type(&topic.ros_type, add)
            .map_err(|e| anyhow::anyhow!("{}: topic {}: {e}", bag.display(), topic.name))??;
    }
    let mut messages = reader.messages().collect::<Result<Vec<_>, _>>()?;
    let dropped = if reader.truncation().is_some() {
        drop_partial_last_stamp(&mut messages)
    } else {
        0
    };
    for raw in &messages {
        writer
            .write_cdr(&raw.topic, raw.log_time_ns, raw.publish_time_ns, &raw.data)
            .with_context(|| format!("writing {}", out.display()))?;
    }
    let summary = writer.finish()?;
    let report = json!({
        "from": reader.path(),
        "to": summary.mcap_path,
        "to_files": summary.files,
        "recovered_messages": summary.message_count,
        "recovered_per_topic": summary.per_topic,
        "messages_in_damaged_chunks": reader.lost_known(),
        "dropped_partial_last_stamp": dropped,
        "truncation": reader.truncation(),
        "damage": damage_json(&reader),
    });
    println!("{}", serde_json::to_string_pretty(&report)?);
    Ok(())
}

/// A crash cuts the run mid-step: when the last log time carries fewer topics than the
/// one before it, its messages are half a step, and a finished bag must not end in one.
/// Returns how many messages were dropped.
fn drop_partial_last_stamp(messages: &mut Vec<causal_arm_bag::RawMessage>) -> usize {
    let topics_at = |t: u64, all: &[causal_arm_bag::RawMessage]| {
        let mut topics: Vec<&str> = all
            .iter()
            .rev()
            .skip_while(|m| m.log_time_ns != t)
            .take_while(|m| m.log_time_ns == t)
            .map(|m| m.topic.as_str())
            .collect();
        topics.sort_unstable();
        topics.dedup();
        topics.len()
    };
    let Some(last) = messages.last().map(|m| m.log_time_ns) else {
        return 0;
    };
    let Some(before) = messages
        .iter()
        .rev()
        .map(|m| m.log_time_ns)
        .find(|t| *t != last)
    else {
        return 0;
    };
    if topics_at(last, messages) >= topics_at(before, messages) {
        return 0;
    }
    let keep = messages
        .iter()
        .rposition(|m| m.log_time_ns != last)
        .map_or(0, |i| i + 1);
    let dropped = messages.len() - keep;
    messages.truncate(keep);
    dropped
}

#[cfg(test)]
mod tests {
    use super::*;
    use causal_arm_protocol::bag_keys::VELOCITY_SCALE;

    /// An empty bag whose custom_data holds `velocity_scale` (none when `None`).
    fn bag_recorded_with(dir: &Path, velocity_scale: Option<&str>) -> PathBuf {
        let mut options = BagOptions::default();
        if let Some(value) = velocity_scale {
            options
                .custom_data
                .insert(VELOCITY_SCALE.to_owned(), value.to_owned());
        }
        BagWriter::create(dir, options).unwrap().finish().unwrap();
        dir.to_owned()
    }

    fn scale_of(bags: &[PathBuf]) -> anyhow::Result<f64> {
        recorded_velocity_scale(bags.iter().map(PathBuf::as_path))
    }

    #[test]
    fn stats_take_the_one_velocity_scale_the_bags_were_recorded_with() {
        let tmp = tempfile::tempdir().unwrap();
        let a = bag_recorded_with(&tmp.path().join("a"), Some("0.5"));
        let b = bag_recorded_with(&tmp.path().join("b"), Some("0.5"));
        assert_eq!(scale_of(&[a, b]).unwrap(), 0.5);
    }

    #[test]
    fn stats_refuse_bags_recorded_with_different_velocity_scales() {
        let tmp = tempfile::tempdir().unwrap();
        let a = bag_recorded_with(&tmp.path().join("a"), Some("1"));
        let b = bag_recorded_with(&tmp.path().join("b"), Some("2"));
        let message = scale_of(&[a.clone(), b.clone()]).unwrap_err().to_string();
        assert!(message.contains(&a.display().to_string()), "{message}");
        assert!(message.contains(&b.display().to_string()), "{message}");
        assert!(
            message.contains("=1, ") && message.contains("with 2"),
            "{message}"
        );
    }

    #[test]
    fn stats_refuse_a_bag_without_or_with_a_garbled_velocity_scale() {
        let tmp = tempfile::tempdir().unwrap();
        let missing = bag_recorded_with(&tmp.path().join("missing"), None);
        let message = scale_of(std::slice::from_ref(&missing))
            .unwrap_err()
            .to_string();
        assert!(
            message.contains("records no") && message.contains("missing"),
            "{message}"
        );
        let garbled = bag_recorded_with(&tmp.path().join("garbled"), Some("fast"));
        let message = scale_of(&[garbled]).unwrap_err().to_string();
        assert!(message.contains("\"fast\" is not a number"), "{message}");
        assert!(scale_of(&[]).is_err(), "no bags, no scale");
    }
}
