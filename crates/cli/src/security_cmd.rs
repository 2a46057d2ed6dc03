//! `causal-arm security create-keystore|create-enclave|list-enclaves`: the SROS2 keystore
//! tools (`ros2 security …`) without a ROS 2 install. The keystores are interchangeable
//! with sros2's; nodes use them through `ROS_SECURITY_*` (see README, "Security").

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use causal_arm_node::RosEnv;
use causal_arm_security::Keystore;

/// `causal-arm security …`
#[derive(Debug, clap::Args)]
pub struct SecurityArgs {
    #[command(subcommand)]
    command: SecurityCommand,
}

#[derive(Debug, clap::Subcommand)]
enum SecurityCommand {
    /// Creates a keystore: one CA (identity and permissions) and the governance document,
    /// signed, for ROS_DOMAIN_ID (like `ros2 security create-keystore`).
    CreateKeystore {
        /// Keystore directory (created).
        keystore: PathBuf,
    },
    /// Creates an enclave: identity certificate and key, and permissions for every ROS
    /// topic and service, signed (like `ros2 security create-enclave`).
    CreateEnclave {
        /// Keystore directory.
        keystore: PathBuf,
        /// Enclave name, a ROS namespace such as /causal_arm.
        enclave: String,
    },
    /// Lists a keystore's enclaves (like `ros2 security list-enclaves`).
    ListEnclaves {
        /// Keystore directory.
        keystore: PathBuf,
    },
}

/// Runs `causal-arm security …`.
pub fn run(args: &SecurityArgs) -> anyhow::Result<()> {
    match &args.command {
        SecurityCommand::CreateKeystore { keystore } => {
            let domain_id = domain_id()?;
            let created = Keystore::create(keystore, domain_id)?;
            println!(
                "created keystore {} for ROS_DOMAIN_ID {domain_id}",
                created.root().display()
            );
        }
        SecurityCommand::CreateEnclave { keystore, enclave } => {
            let dir = open(keystore)?.create_enclave(enclave, domain_id()?)?;
            println!("created enclave {enclave} in {}", dir.display());
        }
        SecurityCommand::ListEnclaves { keystore } => {
            for enclave in open(keystore)?.enclaves()? {
                println!("{enclave}");
            }
        }
    }
    Ok(())
}

fn open(keystore: &Path) -> anyhow::Result<Keystore> {
    Ok(Keystore::open(keystore)?)
}

/// The domain the documents grant, from ROS_DOMAIN_ID as sros2 takes it.
fn domain_id() -> anyhow::Result<u16> {
    let env = RosEnv::from_env().context("reading the ROS environment")?;
    Ok(env.domain_id)
}
