//! Named QoS profiles, so every node picks delivery guarantees by intent, not by knob.

use std::time::Duration;

use ros2_client::{
    QosProfile,
    qos::{Durability, History, Reliability, WhenFull},
};

/// Data that is recorded into bags: reliable, keep-all, a publisher blocks rather than
/// dropping when a reader lags (keep-last would silently lose samples).
pub fn recorded() -> QosProfile {
    QosProfile::publisher_default()
        .reliability(Reliability::Reliable {
            when_full: WhenFull::Wait(Duration::from_secs(10)),
        })
        .history(History::KeepAll)
}

/// `/clock`, as rclcpp's `ClockQoS`: best effort, keep last 1, only the newest time matters.
pub fn clock() -> QosProfile {
    QosProfile::subscription_default()
        .reliability(Reliability::BestEffort)
        .history(History::KeepLast { depth: 1 })
}

/// Latched topics such as `/robot_description` and reports: late joiners get the last value.
pub fn latched() -> QosProfile {
    QosProfile::publisher_default()
        .durability(Durability::TransientLocal)
        .history(History::KeepLast { depth: 1 })
}

/// `ros_discovery_info`, as rmw writes it (reliable, transient local), read with a deep
/// history: one topic instance carries every participant's announcements.
pub fn discovery_info() -> QosProfile {
    QosProfile::subscription_default()
        .reliability(Reliability::Reliable {
            when_full: WhenFull::Wait(Duration::ZERO),
        })
        .durability(Durability::TransientLocal)
        .history(History::KeepLast { depth: 256 })
}

/// Live monitoring streams for humans (`ros2 topic echo`): reliable, keep last 10,
/// like rclcpp's default profile.
pub fn default_reliable() -> QosProfile {
    QosProfile::publisher_default().history(History::KeepLast { depth: 10 })
}

/// Service request and reply topics, as rmw's `rmw_qos_profile_services_default`.
pub fn services() -> QosProfile {
    default_reliable()
}

/// Looks a profile up by the name users give on the command line.
pub fn by_name(name: &str) -> Option<QosProfile> {
    Some(match name {
        "recorded" => recorded(),
        "clock" => clock(),
        "latched" => latched(),
        "default" => default_reliable(),
        "services" => services(),
        "best_effort" => {
            QosProfile::subscription_default().history(History::KeepLast { depth: 10 })
        }
        _ => return None,
    })
}

/// Profile names accepted by [`by_name`], for error messages and `--help`.
pub const PROFILE_NAMES: &[&str] = &[
    "recorded",
    "clock",
    "latched",
    "default",
    "services",
    "best_effort",
];

/// `qos` with the USER_DATA an Iron-and-later rmw gives an endpoint of a type whose
/// REP-2011 hash is `type_hash`: `typehash=RIHS01_<hex>;`. Peers read it to tell types of
/// the same name apart (rmw_cyclonedds warns about endpoints without it).
pub fn with_type_hash(qos: QosProfile, type_hash: &str) -> QosProfile {
    qos.user_data(format!("typehash={type_hash};").into_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ros2-client's own endpoints (patched to announce their hashes) carry the hashes our
    /// generator computes from the vendored Jazzy definitions.
    #[test]
    fn ros2_clients_builtin_endpoints_announce_our_hashes() {
        use causal_arm_msgs::{RosMessage, RosService, rcl_interfaces, rmw_dds_common};
        use ros2_client::builtin_topics as builtin;
        let pairs = [
            (
                builtin::ros_discovery::TYPE_HASH,
                rmw_dds_common::msg::ParticipantEntitiesInfo::TYPE_HASH,
            ),
            (
                builtin::rosout::TYPE_HASH,
                rcl_interfaces::msg::Log::TYPE_HASH,
            ),
            (
                builtin::parameter_events::TYPE_HASH,
                rcl_interfaces::msg::ParameterEvent::TYPE_HASH,
            ),
            (
                builtin::clock::TYPE_HASH,
                causal_arm_msgs::rosgraph_msgs::msg::Clock::TYPE_HASH,
            ),
            (
                builtin::parameter_services::GET_PARAMETERS.0,
                <rcl_interfaces::srv::GetParameters as RosService>::Request::TYPE_HASH,
            ),
            (
                builtin::parameter_services::GET_PARAMETERS.1,
                <rcl_interfaces::srv::GetParameters as RosService>::Response::TYPE_HASH,
            ),
            (
                builtin::parameter_services::GET_PARAMETER_TYPES.0,
                <rcl_interfaces::srv::GetParameterTypes as RosService>::Request::TYPE_HASH,
            ),
            (
                builtin::parameter_services::GET_PARAMETER_TYPES.1,
                <rcl_interfaces::srv::GetParameterTypes as RosService>::Response::TYPE_HASH,
            ),
            (
                builtin::parameter_services::SET_PARAMETERS.0,
                <rcl_interfaces::srv::SetParameters as RosService>::Request::TYPE_HASH,
            ),
            (
                builtin::parameter_services::SET_PARAMETERS.1,
                <rcl_interfaces::srv::SetParameters as RosService>::Response::TYPE_HASH,
            ),
            (
                builtin::parameter_services::SET_PARAMETERS_ATOMICALLY.0,
                <rcl_interfaces::srv::SetParametersAtomically as RosService>::Request::TYPE_HASH,
            ),
            (
                builtin::parameter_services::SET_PARAMETERS_ATOMICALLY.1,
                <rcl_interfaces::srv::SetParametersAtomically as RosService>::Response::TYPE_HASH,
            ),
            (
                builtin::parameter_services::LIST_PARAMETERS.0,
                <rcl_interfaces::srv::ListParameters as RosService>::Request::TYPE_HASH,
            ),
            (
                builtin::parameter_services::LIST_PARAMETERS.1,
                <rcl_interfaces::srv::ListParameters as RosService>::Response::TYPE_HASH,
            ),
            (
                builtin::parameter_services::DESCRIBE_PARAMETERS.0,
                <rcl_interfaces::srv::DescribeParameters as RosService>::Request::TYPE_HASH,
            ),
            (
                builtin::parameter_services::DESCRIBE_PARAMETERS.1,
                <rcl_interfaces::srv::DescribeParameters as RosService>::Response::TYPE_HASH,
            ),
        ];
        for (theirs, ours) in pairs {
            assert_eq!(theirs, ours);
        }
    }

    #[test]
    fn type_hash_user_data_is_rmws_text() {
        let q = with_type_hash(default_reliable(), "RIHS01_ab");
        assert_eq!(q.user_data, b"typehash=RIHS01_ab;");
    }

    #[test]
    fn recorded_never_drops() {
        let q = recorded();
        assert_eq!(q.history, History::KeepAll);
        assert!(matches!(q.reliability, Reliability::Reliable { .. }));
    }

    #[test]
    fn every_named_profile_resolves() {
        for name in PROFILE_NAMES {
            assert!(by_name(name).is_some(), "{name}");
        }
        assert!(by_name("fast").is_none());
        assert_eq!(latched().durability, Durability::TransientLocal);
    }
}
