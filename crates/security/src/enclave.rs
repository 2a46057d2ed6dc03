//! Which enclave a process uses, and whether it runs secured at all: rcl's rules
//! (`rcl_get_security_options_from_environment`, `rcl_get_secure_root`) and
//! rmw_dds_common's file check, with one change: values rcl would silently read as
//! "off" (`ROS_SECURITY_ENABLE=True`, `ROS_SECURITY_STRATEGY=enforce`) are refused, since
//! a typo must not turn security off.

use std::path::{Path, PathBuf};

use crate::SecurityError;
use crate::keystore::{ENCLAVE_FILES, enclave_dir};
use crate::names::validate_enclave_name;

/// What happens when security is enabled but the enclave is missing or incomplete.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Strategy {
    /// Run unsecured, with a warning (rcl's default).
    #[default]
    Permissive,
    /// Refuse to start.
    Enforce,
}

/// The `ROS_SECURITY_*` variables of one process, validated.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct SecurityEnv {
    /// `ROS_SECURITY_ENABLE=true`.
    pub enable: bool,
    /// `ROS_SECURITY_STRATEGY`.
    pub strategy: Strategy,
    /// `ROS_SECURITY_KEYSTORE`.
    pub keystore: Option<PathBuf>,
    /// `ROS_SECURITY_ENCLAVE_OVERRIDE`: wins over `--ros-args --enclave`.
    pub enclave_override: Option<String>,
}

/// How this process joins DDS.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SecurityMode {
    /// Security not asked for.
    Off,
    /// Authenticated, access-controlled and encrypted with the files in `dir`.
    Secured {
        /// The enclave name.
        enclave: String,
        /// Its directory in the keystore.
        dir: PathBuf,
    },
    /// Asked for, but permissive and the enclave is unusable: runs unsecured.
    Unsecured {
        /// Why, for the warning the node logs.
        reason: String,
    },
}

impl SecurityEnv {
    /// Reads the variables through `lookup` (the process environment in production).
    pub fn from_lookup(lookup: impl Fn(&str) -> Option<String>) -> Result<Self, SecurityError> {
        let non_empty = |key: &str| lookup(key).filter(|v| !v.is_empty());
        let enable = match non_empty("ROS_SECURITY_ENABLE").as_deref() {
            None | Some("false") => false,
            Some("true") => true,
            Some(other) => return Err(variable("ROS_SECURITY_ENABLE", other, "true or false")),
        };
        let strategy = match non_empty("ROS_SECURITY_STRATEGY").as_deref() {
            None | Some("Permissive") => Strategy::Permissive,
            Some("Enforce") => Strategy::Enforce,
            Some(other) => {
                return Err(variable(
                    "ROS_SECURITY_STRATEGY",
                    other,
                    "Enforce or Permissive",
                ));
            }
        };
        let enclave_override = non_empty("ROS_SECURITY_ENCLAVE_OVERRIDE");
        if let Some(name) = &enclave_override {
            validate_enclave_name(name)?;
        }
        Ok(Self {
            enable,
            strategy,
            keystore: non_empty("ROS_SECURITY_KEYSTORE").map(PathBuf::from),
            enclave_override,
        })
    }

    /// Decides how to join DDS, given the `--enclave` argument (default `/`).
    pub fn resolve(&self, enclave_arg: Option<&str>) -> Result<SecurityMode, SecurityError> {
        if !self.enable {
            return Ok(SecurityMode::Off);
        }
        let enclave = self
            .enclave_override
            .as_deref()
            .or(enclave_arg)
            .unwrap_or("/")
            .to_owned();
        validate_enclave_name(&enclave)?;
        let problem = match &self.keystore {
            None => Err("ROS_SECURITY_ENABLE=true but ROS_SECURITY_KEYSTORE is not set".to_owned()),
            Some(root) => check_enclave(root, &enclave),
        };
        match (problem, self.strategy) {
            (Ok(dir), _) => Ok(SecurityMode::Secured { enclave, dir }),
            (Err(reason), Strategy::Enforce) => Err(SecurityError::Enforced(reason)),
            (Err(reason), Strategy::Permissive) => Ok(SecurityMode::Unsecured {
                reason: format!(
                    "{reason}; running WITHOUT security (ROS_SECURITY_STRATEGY=Permissive)"
                ),
            }),
        }
    }
}

/// The enclave's directory if it holds every file DDS Security needs, else which is missing.
fn check_enclave(root: &Path, enclave: &str) -> Result<PathBuf, String> {
    let dir = enclave_dir(root, enclave);
    if !dir.is_dir() {
        return Err(format!(
            "enclave {enclave:?} not found: no directory {}",
            dir.display()
        ));
    }
    match ENCLAVE_FILES
        .iter()
        .map(|f| dir.join(f))
        .find(|p| !p.is_file())
    {
        Some(missing) => Err(format!(
            "enclave {enclave:?} is incomplete: {} is missing",
            missing.display()
        )),
        None => Ok(dir),
    }
}

fn variable(variable: &'static str, value: &str, expected: &'static str) -> SecurityError {
    SecurityError::Variable {
        variable,
        value: value.to_owned(),
        expected,
    }
}

impl std::fmt::Display for SecurityMode {
    /// One phrase for logs: "security off", "secured as enclave /x", "UNSECURED: …".
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SecurityMode::Off => write!(f, "security off"),
            SecurityMode::Secured { enclave, .. } => write!(f, "secured as enclave {enclave}"),
            SecurityMode::Unsecured { .. } => write!(f, "UNSECURED (permissive fallback)"),
        }
    }
}
