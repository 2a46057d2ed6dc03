use rustdds::{policy::*, *};

/// REP-2011: ROS 2 endpoints announce their type's hash in USER_DATA as
/// `typehash=RIHS01_<hex>;` (rmw_fastrtps and rmw_cyclonedds since Iron).
pub fn type_hash_user_data(type_hash: &str) -> UserData {
  UserData {
    value: format!("typehash={type_hash};").into_bytes(),
  }
}

pub mod ros_discovery {
  use super::*;

  lazy_static! {
    pub static ref QOS_PUB: QosPolicies = QosPolicyBuilder::new()
      .durability(Durability::TransientLocal)
      .deadline(Deadline(Duration::INFINITE))
      .ownership(Ownership::Shared)
      .reliable(Duration::ZERO)
      .history(History::KeepLast { depth: 1 })
      .lifespan(Lifespan {
        duration: Duration::INFINITE
      })
      .build()
      .with_user_data(type_hash_user_data(TYPE_HASH));
    pub static ref QOS_SUB: QosPolicies = QosPolicyBuilder::new()
      .durability(Durability::Volatile)
      .ownership(Ownership::Shared)
      .reliable(Duration::ZERO)
      .history(History::KeepLast { depth: 1 })
      .lifespan(Lifespan {
        duration: Duration::INFINITE
      })
      .build()
      .with_user_data(type_hash_user_data(TYPE_HASH));
  }

  pub const TOPIC_NAME: &str = "ros_discovery_info";

  pub const TYPE_NAME: &str = "rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_";

  /// RIHS01 of rmw_dds_common/msg/ParticipantEntitiesInfo (Iron, Jazzy).
  pub const TYPE_HASH: &str =
    "RIHS01_91a0593bacdcc50ea9bdcf849a938b128412cc1ea821245c663bcd26f83c295e";
}

pub mod parameter_events {
  use super::*;

  lazy_static! {
    /// rcl's `rmw_qos_profile_parameter_events`: reliable, volatile, keep last 1000.
    pub static ref QOS: QosPolicies = QosPolicyBuilder::new()
      .durability(Durability::Volatile)
      .reliable(Duration::ZERO)
      .history(History::KeepLast { depth: 1000 })
      .build()
      .with_user_data(type_hash_user_data(TYPE_HASH));
  }

  pub const TOPIC_NAME: &str = "rt/parameter_events";

  pub const TYPE_NAME: &str = "rcl_interfaces::msg::dds_::ParameterEvent_";

  /// RIHS01 of rcl_interfaces/msg/ParameterEvent (Jazzy).
  pub const TYPE_HASH: &str =
    "RIHS01_043e627780fcad87a22d225bc2a037361dba713fca6a6b9f4b869a5aa0393204";
}

pub mod rosout {
  use super::*;

  lazy_static! {
    /// rcl's `rcl_qos_profile_rosout_default`: reliable, transient local, keep
    /// last 1000, lifespan 10 s, so a late `ros2 topic echo /rosout` or
    /// rqt_console gets the last 10 s of a node's log, not its last line.
    pub static ref QOS: QosPolicies = QosPolicyBuilder::new()
      .durability(Durability::TransientLocal)
      .deadline(Deadline(Duration::INFINITE))
      .ownership(Ownership::Shared)
      .reliable(Duration::ZERO)
      .history(History::KeepLast { depth: 1000 })
      .lifespan(Lifespan {
        duration: Duration::from_secs(10)
      })
      .build()
      .with_user_data(type_hash_user_data(TYPE_HASH));
  }

  pub const TOPIC_NAME: &str = "rt/rosout";

  pub const TYPE_NAME: &str = "rcl_interfaces::msg::dds_::Log_";

  /// RIHS01 of rcl_interfaces/msg/Log (Jazzy).
  pub const TYPE_HASH: &str =
    "RIHS01_e28ce254ca8abc06abf92773b74602cdbf116ed34fbaf294fb9f81da9f318eac";
}

/// The `/clock` every node reads for sim time: rosgraph_msgs/msg/Clock, as ROS 2
/// publishes it (its CDR is that of the builtin_interfaces/msg/Time it wraps).
pub mod clock {
  /// RIHS01 of rosgraph_msgs/msg/Clock (Jazzy).
  pub const TYPE_HASH: &str =
    "RIHS01_692f7a66e93a3c83e71765d033b60349ba68023a8c689a79e48078bcb5c58564";
}

/// The parameter services' RIHS01 hashes (Jazzy, Kilted) as (request, response):
/// rmw_fastrtps announces the request message's hash on the `rq/` topic and the
/// response message's on `rr/`, not the service's.
pub mod parameter_services {
  pub const GET_PARAMETERS: (&str, &str) = (
    "RIHS01_135a9e1c3d7cebef792f6687d7ddf99949b21a0bd9a320d863a9110a3f5cf4d6",
    "RIHS01_9fa773b46e39cc5d02db6224d8fd520bb9caeeffc2b27c96c1e59431baba9f2a",
  );
  pub const GET_PARAMETER_TYPES: (&str, &str) = (
    "RIHS01_87d7ec5ef545d4daa289d500025d31fb2437bc8b8365ca367161c4dac4be33fd",
    "RIHS01_ac1335dce67c478e669434f6ac2fbff34fcd529580f272d3006785ba8b54e47f",
  );
  pub const SET_PARAMETERS: (&str, &str) = (
    "RIHS01_130d46386b7e84ea9ecf60608a4d83cbe5e5cb7c6cc5b712b7a4e3a6c254e932",
    "RIHS01_7a0e8140a0b8d98308fa81a5403a766e610af29a239caf54b7553227906fc266",
  );
  pub const SET_PARAMETERS_ATOMICALLY: (&str, &str) = (
    "RIHS01_db0bd950ed5ed867a0e90b225e44dea382d762c0762ff3e0ee842190042a59e5",
    "RIHS01_31b1a38c5b0b9d893ee24da45f69638f4561c78461d82d52750f429b534502b8",
  );
  pub const LIST_PARAMETERS: (&str, &str) = (
    "RIHS01_a1b0b5d6b967a5b8ac5bc8563c3ea678f349e312a6a4967227c5a96bc5ce38df",
    "RIHS01_31b937b82de3612426be79f231e386259f97e8dc843e3f2845288b4bfa296bdd",
  );
  pub const DESCRIBE_PARAMETERS: (&str, &str) = (
    "RIHS01_05dd1c2bc87dec2627105c8070d6f9725c781a4f2ab852975bf105462b82b644",
    "RIHS01_ad6747319613c6131589e062e095b469a46cc764f7d0f12a001a49e6cd893995",
  );
}

#[cfg(test)]
mod tests {
  use super::*;

  // rcl's profiles: `rmw_qos_profile_parameter_events` (rmw/qos_profiles.h) and
  // `rcl_qos_profile_rosout_default` (rcl/logging_rosout.h).
  #[test]
  fn parameter_events_and_rosout_have_rcls_qos() {
    let events = &*parameter_events::QOS;
    assert!(events.is_reliable());
    assert_eq!(events.durability(), Some(Durability::Volatile));
    assert_eq!(events.history(), Some(History::KeepLast { depth: 1000 }));

    let rosout = &*rosout::QOS;
    assert!(rosout.is_reliable());
    assert_eq!(rosout.durability(), Some(Durability::TransientLocal));
    assert_eq!(rosout.history(), Some(History::KeepLast { depth: 1000 }));
    assert_eq!(
      rosout.lifespan(),
      Some(Lifespan {
        duration: Duration::from_secs(10)
      })
    );
  }
}
