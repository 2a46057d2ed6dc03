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
    pub static ref QOS: QosPolicies = QosPolicyBuilder::new()
      .durability(Durability::TransientLocal)
      .reliable(Duration::ZERO)
      .history(History::KeepLast { depth: 1 })
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
    pub static ref QOS: QosPolicies = QosPolicyBuilder::new()
      .durability(Durability::TransientLocal)
      .deadline(Deadline(Duration::INFINITE))
      .ownership(Ownership::Shared)
      .reliable(Duration::ZERO)
      .history(History::KeepLast { depth: 1 })
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

/// The parameter services of a node: (service name suffix, type, RIHS01 of the
/// rcl_interfaces/srv type in Jazzy).
pub mod parameter_services {
  pub const GET_PARAMETERS: &str =
    "RIHS01_bf9803d5c74cf989a5de3e0c2e99444599a627c7ff75f97b8c05b01003675cbc";
  pub const GET_PARAMETER_TYPES: &str =
    "RIHS01_da199c878688b3e530bdfe3ca8f74cb9fa0c303101e980a9e8f260e25e1c80ca";
  pub const SET_PARAMETERS: &str =
    "RIHS01_56eed9a67e169f9cb6c1f987bc88f868c14a8fc9f743a263bc734c154015d7e0";
  pub const SET_PARAMETERS_ATOMICALLY: &str =
    "RIHS01_0e192ef259c07fc3c07a13191d27002222e65e00ccec653ca05e856f79285fcd";
  pub const LIST_PARAMETERS: &str =
    "RIHS01_3e6062bfbb27bfb8730d4cef2558221f51a11646d78e7bb30a1e83afac3aad9d";
  pub const DESCRIBE_PARAMETERS: &str =
    "RIHS01_845b484d71eb0673dae682f2e3ba3c4851a65a3dcfb97bddd82c5b57e91e4cff";
}
