//! `causal-arm`: one entry point for every tool and node of the project.

mod kinematics_cmd;

use clap::{Parser, Subcommand};

#[derive(Debug, Parser)]
#[command(name = "causal-arm", version, about = "Learn low-level causal relations of a simulated iiwa arm by motor babbling (ROS 2)")]
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
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Fk(args) => kinematics_cmd::run_fk(args),
        Command::Ik(args) => kinematics_cmd::run_ik(args),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
