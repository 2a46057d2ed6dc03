//! SROS2-compatible DDS Security material for causal-arm.
//!
//! `ros2 security create-keystore` / `create-enclave` are Python tools from a ROS 2
//! install, which this product must not need. This crate writes the same keystore layout
//! and files (one self-signed CA acting as identity and permissions CA, a signed
//! governance document, and per enclave an identity certificate, its key and signed
//! permissions), so a keystore made here works with rmw_fastrtps/rmw_cyclonedds and one
//! made by `ros2 security` works with our nodes. It also holds rcl's rules for which
//! enclave a process uses, so every node decides the same way.
//!
//! No DDS here: the nodes hand the enclave directory to rustdds' DDS Security.

mod documents;
mod enclave;
mod keystore;
mod names;
mod pki;

pub use documents::{governance_xml, permissions_xml};
pub use enclave::{SecurityEnv, SecurityMode, Strategy};
pub use keystore::{ENCLAVE_FILES, Keystore};
pub use names::validate_enclave_name;

use std::path::PathBuf;

/// Why a keystore, an enclave or the security environment was refused.
#[derive(Debug, thiserror::Error)]
pub enum SecurityError {
    /// A file could not be read, written or linked.
    #[error("{path}: {source}")]
    Io {
        /// The file or directory involved.
        path: PathBuf,
        /// The operating system's reason.
        source: std::io::Error,
    },
    /// OpenSSL refused to generate, sign or parse something.
    #[error("{what}: {source}")]
    Crypto {
        /// What was being done.
        what: String,
        /// OpenSSL's error stack.
        source: openssl::error::ErrorStack,
    },
    /// `create-keystore` on a directory that already holds a keystore.
    #[error("{0} already holds a keystore; remove it or pick another directory")]
    KeystoreExists(PathBuf),
    /// The directory is not a complete keystore; names the first missing file.
    #[error(
        "{dir} is not a keystore: {missing} is missing (create one with `causal-arm security create-keystore`)"
    )]
    NotAKeystore {
        /// The directory given.
        dir: PathBuf,
        /// The first required file not found.
        missing: PathBuf,
    },
    /// An enclave name breaks the ROS namespace rules.
    #[error("invalid enclave name {name:?}: {reason}")]
    EnclaveName {
        /// The name given.
        name: String,
        /// Which rule it breaks.
        reason: &'static str,
    },
    /// A `ROS_SECURITY_*` variable holds a value rcl would silently misread.
    #[error("{variable}={value:?} is invalid: expected {expected}")]
    Variable {
        /// The environment variable.
        variable: &'static str,
        /// Its value.
        value: String,
        /// The accepted values.
        expected: &'static str,
    },
    /// Security is enforced but this process has no usable enclave.
    #[error("ROS_SECURITY_STRATEGY=Enforce: {0}")]
    Enforced(String),
}

impl SecurityError {
    fn io(path: impl Into<PathBuf>) -> impl FnOnce(std::io::Error) -> Self {
        let path = path.into();
        move |source| Self::Io { path, source }
    }

    fn crypto(what: impl Into<String>) -> impl FnOnce(openssl::error::ErrorStack) -> Self {
        let what = what.into();
        move |source| Self::Crypto { what, source }
    }
}
