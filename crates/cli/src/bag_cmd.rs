//! `causal-arm bag info BAG`: what a bag holds (like `ros2 bag info`), as JSON, including
//! whether the file was cut short by a crash and how much of it is readable.

use std::path::PathBuf;

use causal_arm_bag::BagReader;
use serde_json::json;

/// `causal-arm bag …`
#[derive(Debug, clap::Args)]
pub struct BagArgs {
    #[command(subcommand)]
    command: BagCommand,
}

#[derive(Debug, clap::Subcommand)]
enum BagCommand {
    /// Topics, types, message counts and integrity of a bag, as JSON.
    Info {
        /// Bag directory or .mcap file.
        bag: PathBuf,
    },
}

/// Runs `causal-arm bag …`.
pub fn run(args: &BagArgs) -> anyhow::Result<()> {
    match &args.command {
        BagCommand::Info { bag } => {
            let reader = BagReader::open(bag)?;
            let mut first = None;
            let mut last = None;
            for raw in reader.messages() {
                let raw = raw?;
                first.get_or_insert(raw.log_time_ns);
                last = Some(raw.log_time_ns);
            }
            let topics: Vec<_> = reader
                .topics()
                .iter()
                .map(|t| json!({"name": t.name, "type": t.ros_type, "message_count": t.message_count}))
                .collect();
            let info = json!({
                "path": reader.path(),
                "message_count": reader.message_count(),
                "start_ns": first,
                "end_ns": last,
                "complete": reader.truncation().is_none(),
                "truncation": reader.truncation(),
                "topics": topics,
            });
            println!("{}", serde_json::to_string_pretty(&info)?);
            Ok(())
        }
    }
}
