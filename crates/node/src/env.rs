//! The ROS 2 environment variables that decide which DDS peers a node can see.
//!
//! Read once, validated strictly: a typo in `ROS_DOMAIN_ID` must stop the node with a
//! clear message instead of silently joining domain 0 next to somebody else's robot.

use std::net::{IpAddr, Ipv4Addr};

use causal_arm_security::{SecurityEnv, SecurityError, SecurityMode};
use ros2_client::ServiceMapping;
use thiserror::Error;

/// Highest domain id ROS 2 accepts (DDS port arithmetic overflows above it on Linux).
pub const MAX_DOMAIN_ID: u16 = 232;

/// How far automatic discovery reaches (`ROS_AUTOMATIC_DISCOVERY_RANGE`, ROS 2 Iron+).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DiscoveryRange {
    /// Only peers on this host: we bind and announce on loopback only.
    Localhost,
    /// Peers on the local subnet (the DDS default).
    Subnet,
    /// No automatic discovery of other hosts. rustdds cannot switch discovery off
    /// entirely, so this is the strictest thing it can do: loopback only, and no
    /// localhost unicast peer list (processes on the host still meet via loopback
    /// multicast). Documented, not silently treated as `Subnet`.
    Off,
}

/// Why the environment was rejected; each variant names the variable and the value.
#[derive(Debug, Error)]
pub enum EnvError {
    /// `ROS_DOMAIN_ID` is not an integer in 0..=232.
    #[error("ROS_DOMAIN_ID={value:?} is invalid: expected an integer from 0 to {MAX_DOMAIN_ID}")]
    DomainId {
        /// The offending value as found in the environment.
        value: String,
    },
    /// `ROS_AUTOMATIC_DISCOVERY_RANGE` is not one of the ROS 2 values.
    #[error(
        "ROS_AUTOMATIC_DISCOVERY_RANGE={value:?} is invalid: expected LOCALHOST, SUBNET, OFF or SYSTEM_DEFAULT"
    )]
    DiscoveryRange {
        /// The offending value.
        value: String,
    },
    /// `ROS_LOCALHOST_ONLY` is not 0 or 1.
    #[error("ROS_LOCALHOST_ONLY={value:?} is invalid: expected 0 or 1")]
    LocalhostOnly {
        /// The offending value.
        value: String,
    },
    /// A `ROS_SECURITY_*` variable is invalid, or Enforce finds no usable enclave.
    #[error(transparent)]
    Security(#[from] SecurityError),
}

/// `EnvError` is compared in tests; security errors carry I/O and OpenSSL errors, which
/// are not comparable, so they compare by message.
impl PartialEq for EnvError {
    fn eq(&self, other: &Self) -> bool {
        self.to_string() == other.to_string()
    }
}
impl Eq for EnvError {}

/// The validated ROS 2 environment of one process.
#[derive(Debug, Clone, PartialEq)]
pub struct RosEnv {
    /// DDS domain (`ROS_DOMAIN_ID`, default 0).
    pub domain_id: u16,
    /// Discovery reach, from `ROS_AUTOMATIC_DISCOVERY_RANGE` or legacy `ROS_LOCALHOST_ONLY`.
    pub discovery_range: DiscoveryRange,
    /// How services map onto DDS topics, chosen from `RMW_IMPLEMENTATION` so our services
    /// talk to the rmw the user runs (rmw_cyclonedds_cpp → Cyclone, otherwise Enhanced as
    /// rmw_fastrtps uses).
    pub service_mapping: ServiceMapping,
    /// `ROS_SECURITY_ENABLE`, `_STRATEGY`, `_KEYSTORE`, `_ENCLAVE_OVERRIDE` (SROS2).
    pub security: SecurityEnv,
}

impl RosEnv {
    /// Reads the process environment.
    pub fn from_env() -> Result<Self, EnvError> {
        Self::from_lookup(|key| std::env::var(key).ok())
    }

    /// Reads variables through `lookup`, so tests need not mutate the process environment.
    pub fn from_lookup(lookup: impl Fn(&str) -> Option<String>) -> Result<Self, EnvError> {
        let non_empty = |key: &str| lookup(key).filter(|v| !v.trim().is_empty());
        let domain_id = match non_empty("ROS_DOMAIN_ID") {
            None => 0,
            Some(value) => match value.trim().parse::<u16>() {
                Ok(id) if id <= MAX_DOMAIN_ID => id,
                _ => return Err(EnvError::DomainId { value }),
            },
        };
        let localhost_only = match non_empty("ROS_LOCALHOST_ONLY").as_deref().map(str::trim) {
            None | Some("0") => false,
            Some("1") => true,
            Some(other) => {
                return Err(EnvError::LocalhostOnly {
                    value: other.to_owned(),
                });
            }
        };
        let discovery_range = match non_empty("ROS_AUTOMATIC_DISCOVERY_RANGE") {
            None => {
                if localhost_only {
                    DiscoveryRange::Localhost
                } else {
                    DiscoveryRange::Subnet
                }
            }
            Some(value) => match value.trim().to_ascii_uppercase().as_str() {
                "LOCALHOST" => DiscoveryRange::Localhost,
                "SUBNET" | "SYSTEM_DEFAULT" => DiscoveryRange::Subnet,
                "OFF" => DiscoveryRange::Off,
                _ => return Err(EnvError::DiscoveryRange { value }),
            },
        };
        let service_mapping = match non_empty("RMW_IMPLEMENTATION").as_deref() {
            Some(rmw) if rmw.contains("cyclonedds") => ServiceMapping::Cyclone,
            _ => ServiceMapping::Enhanced,
        };
        let security = SecurityEnv::from_lookup(&lookup)?;
        Ok(Self {
            domain_id,
            discovery_range,
            service_mapping,
            security,
        })
    }

    /// Builds the DDS participant this environment asks for; with
    /// [`SecurityMode::Secured`] it authenticates, checks permissions and encrypts with
    /// the enclave's files through rustdds' DDS Security plugins.
    pub fn domain_participant(
        &self,
        security: &SecurityMode,
    ) -> rustdds::dds::CreateResult<rustdds::DomainParticipant> {
        let loopback = [IpAddr::V4(Ipv4Addr::LOCALHOST)];
        let builder = rustdds::DomainParticipantBuilder::new(self.domain_id);
        let builder = match self.discovery_range {
            DiscoveryRange::Subnet => builder,
            DiscoveryRange::Localhost => builder
                .with_only_networks(loopback)
                .same_host_loopback(true),
            DiscoveryRange::Off => builder
                .with_only_networks(loopback)
                .same_host_loopback(false),
        };
        let builder = match security {
            SecurityMode::Secured { dir, .. } => builder.builtin_security(
                // sros2 keys are unencrypted PKCS#8, so no password.
                rustdds::DomainParticipantSecurityConfigFiles::with_ros_default_names(
                    dir,
                    String::new(),
                ),
            ),
            SecurityMode::Off | SecurityMode::Unsecured { .. } => builder,
        };
        builder.build()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env(pairs: &[(&str, &str)]) -> Result<RosEnv, EnvError> {
        let pairs: Vec<(String, String)> = pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        RosEnv::from_lookup(move |key| pairs.iter().find(|(k, _)| k == key).map(|(_, v)| v.clone()))
    }

    #[test]
    fn defaults_match_ros2() {
        let e = env(&[]).unwrap();
        assert_eq!(e.domain_id, 0);
        assert_eq!(e.discovery_range, DiscoveryRange::Subnet);
        assert!(matches!(e.service_mapping, ServiceMapping::Enhanced));
    }

    #[test]
    fn domain_id_is_validated() {
        assert_eq!(env(&[("ROS_DOMAIN_ID", "42")]).unwrap().domain_id, 42);
        let err = env(&[("ROS_DOMAIN_ID", "abc")]).unwrap_err();
        assert_eq!(
            err,
            EnvError::DomainId {
                value: "abc".into()
            }
        );
        assert!(err.to_string().contains("ROS_DOMAIN_ID=\"abc\""), "{err}");
        assert!(env(&[("ROS_DOMAIN_ID", "233")]).is_err());
        assert!(env(&[("ROS_DOMAIN_ID", "-1")]).is_err());
    }

    #[test]
    fn discovery_range_and_legacy_localhost_only() {
        let range = |pairs: &[(&str, &str)]| env(pairs).unwrap().discovery_range;
        assert_eq!(
            range(&[("ROS_LOCALHOST_ONLY", "1")]),
            DiscoveryRange::Localhost
        );
        assert_eq!(
            range(&[("ROS_AUTOMATIC_DISCOVERY_RANGE", "localhost")]),
            DiscoveryRange::Localhost
        );
        assert_eq!(
            range(&[("ROS_AUTOMATIC_DISCOVERY_RANGE", "OFF")]),
            DiscoveryRange::Off
        );
        // The new variable wins over the deprecated one, as in rmw.
        assert_eq!(
            range(&[
                ("ROS_LOCALHOST_ONLY", "1"),
                ("ROS_AUTOMATIC_DISCOVERY_RANGE", "SUBNET")
            ]),
            DiscoveryRange::Subnet
        );
        assert!(env(&[("ROS_AUTOMATIC_DISCOVERY_RANGE", "LAN")]).is_err());
        assert!(env(&[("ROS_LOCALHOST_ONLY", "yes")]).is_err());
    }

    #[test]
    fn service_mapping_follows_rmw() {
        let e = env(&[("RMW_IMPLEMENTATION", "rmw_cyclonedds_cpp")]).unwrap();
        assert!(matches!(e.service_mapping, ServiceMapping::Cyclone));
    }
}
