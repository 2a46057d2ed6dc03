//! `causal-arm`: one entry point for every tool and node of the project.

mod bag_cmd;
mod choice;
mod discover_cmd;
mod explain_cmd;
mod generate_cmd;
mod intervene_cmd;
mod kinematics_cmd;
mod launch_cmd;
mod launch_shards;
mod place_cmd;
mod play_cmd;
mod progress;
mod reach_cmd;
mod reach_models;
mod rollout_cmd;
mod security_cmd;
mod service_cmd;
mod topic_cmd;
mod train_cmd;

use causal_arm_node::RosArgs;
use clap::{Parser, Subcommand};

#[derive(Debug, Parser)]
#[command(
    name = "causal-arm",
    version,
    about = "Learn low-level causal relations of a simulated iiwa arm by motor babbling (ROS 2)",
    after_help = "ROS arguments go after --ros-args, e.g. `causal-arm topic echo /joint_states --type sensor_msgs/msg/JointState --ros-args -r __node:=my_echo`.\nEnvironment: ROS_DOMAIN_ID, ROS_AUTOMATIC_DISCOVERY_RANGE, ROS_LOCALHOST_ONLY, RMW_IMPLEMENTATION, ROS_SECURITY_ENABLE, ROS_SECURITY_STRATEGY, ROS_SECURITY_KEYSTORE, ROS_SECURITY_ENCLAVE_OVERRIDE, RUST_LOG."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Forward kinematics: pose of the `ef` frame for a joint configuration.
    Fk(kinematics_cmd::FkArgs),
    /// Inverse kinematics (damped least squares): joints that put `ef` at a position.
    Ik(kinematics_cmd::IkArgs),
    /// Inspect, check and recover bags (topics, counts, integrity).
    Bag(bag_cmd::BagArgs),
    /// Run an experiment in one process (no DDS) and write its dataset bag.
    Generate(generate_cmd::GenerateCmd),
    /// Start the simulator, babbler and recorder nodes over DDS and record the bag.
    Launch(launch_cmd::LaunchArgs),
    /// Republish a bag on its topics (like `ros2 bag play`).
    Play(play_cmd::PlayArgs),
    /// Publish or echo any known message type as JSON (like `ros2 topic`).
    Topic(topic_cmd::TopicArgs),
    /// Cross-validate forward/inverse models on bags and write model files and metrics.
    Train(train_cmd::TrainArgs),
    /// Mental simulation: chain a trained forward model over fresh trajectories.
    Rollout(rollout_cmd::RolloutArgs),
    /// Drive the arm to target effector positions with the Jacobian, a learned inverse
    /// model or babbling, and report success within 1 cm and 5 mm.
    Reach(reach_cmd::ReachArgs),
    /// Move the cube to spots on the table with FM-MPC (exp 2: pick, carry, release).
    Place(place_cmd::PlaceArgs),
    /// SHAP attributions of a forward model: heat map, PDPs and relevance report.
    Explain(explain_cmd::ExplainArgs),
    /// Which action drives which state feature, tested straight on a bag's transitions
    /// (no model), beside the standard linear Granger tests.
    Discover(discover_cmd::DiscoverArgs),
    /// Score causal claims made by any tool against a ground truth (precision, recall, F1,
    /// AUROC, undecided), by the project's scorer.
    Score(discover_cmd::ScoreArgs),
    /// Causal ground truth: intervene on every action in states of a bag, record what changes.
    Intervene(intervene_cmd::InterveneArgs),
    /// Call a service with a JSON request (like `ros2 service call`).
    Service(service_cmd::ServiceArgs),
    /// SROS2 keystores and enclaves (like `ros2 security`).
    Security(security_cmd::SecurityArgs),
}

/// Whether a command that reads bags was given `--salvage` (the others do not take it).
fn salvage_asked(command: &Command) -> bool {
    match command {
        Command::Bag(args) => args.read.salvage,
        Command::Play(args) => args.read.salvage,
        Command::Train(args) => args.read.salvage,
        Command::Rollout(args) => args.read.salvage,
        Command::Explain(args) => args.read.salvage,
        Command::Discover(args) => args.read.salvage,
        Command::Intervene(args) => args.read.salvage,
        _ => false,
    }
}

fn main() -> std::process::ExitCode {
    // Like any Unix tool, end quietly when the reader of stdout goes away (`| head`)
    // rather than panic on EPIPE (Rust ignores SIGPIPE unless told otherwise).
    // SAFETY: sets a signal's default disposition before any other thread exists.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let all: Vec<String> = std::env::args().collect();
    let (ros_args, rest) = match RosArgs::split(&all) {
        Ok(split) => split,
        Err(err) => {
            eprintln!("error: {err}");
            return std::process::ExitCode::FAILURE;
        }
    };
    // The options' defaults come from the graph file: a bad CAUSAL_ARM_GRAPH is named here,
    // not as an empty default.
    if let Err(err) = causal_arm_protocol::graph::graph() {
        eprintln!("error: {err}");
        return std::process::ExitCode::FAILURE;
    }
    let cli = match Cli::try_parse_from(rest) {
        Ok(cli) => cli,
        Err(err) => return usage_exit(&err),
    };
    // Warnings of the commands themselves (a bag cut short, a dataset not cached) are
    // printed, not only those of nodes.
    causal_arm_node::logging::init_with_level(ros_args.log_level.as_deref());
    if salvage_asked(&cli.command) {
        causal_arm_bag::ReadPolicy::Salvage.set_process_default();
    }
    let result = match &cli.command {
        Command::Fk(args) => kinematics_cmd::run_fk(args),
        Command::Ik(args) => kinematics_cmd::run_ik(args),
        Command::Bag(args) => bag_cmd::run(args),
        Command::Generate(args) => generate_cmd::run(args),
        Command::Launch(args) => launch_cmd::run(args, &ros_args),
        Command::Play(args) => play_cmd::run(args, &ros_args),
        Command::Topic(args) => topic_cmd::run(args, &ros_args),
        Command::Train(args) => train_cmd::run(args),
        Command::Rollout(args) => rollout_cmd::run(args),
        Command::Reach(args) => reach_cmd::run(args, &ros_args),
        Command::Place(args) => place_cmd::run(args, &ros_args),
        Command::Explain(args) => explain_cmd::run(args),
        Command::Discover(args) => discover_cmd::run(args),
        Command::Score(args) => discover_cmd::score(args),
        Command::Intervene(args) => intervene_cmd::run(args),
        Command::Service(args) => service_cmd::run(args, &ros_args),
        Command::Security(args) => security_cmd::run(args),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

/// Prints clap's help, version or error. Help and version exit 0; a bad command line exits
/// 1, like every other refused input of this tool.
fn usage_exit(err: &clap::Error) -> std::process::ExitCode {
    use clap::error::ErrorKind;
    let _ = err.print();
    match err.kind() {
        ErrorKind::DisplayHelp | ErrorKind::DisplayVersion => std::process::ExitCode::SUCCESS,
        _ => std::process::ExitCode::FAILURE,
    }
}
