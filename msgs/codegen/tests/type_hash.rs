//! RIHS01 hashes computed from the vendored Jazzy definitions equal the hashes Jazzy
//! publishes (as `ros2 topic info -v` and rosbag2's metadata show them).

use std::path::Path;

use causal_arm_msgs_codegen::{Interface, TypeIndex, load_package};

fn jazzy_index() -> TypeIndex {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../ros_interfaces");
    let mut interfaces: Vec<Interface> = Vec::new();
    for entry in std::fs::read_dir(&root).unwrap() {
        let dir = entry.unwrap().path();
        let package = dir.file_name().unwrap().to_str().unwrap().to_string();
        interfaces.extend(load_package(&package, &dir).unwrap());
    }
    TypeIndex::new(&interfaces)
}

#[test]
fn standard_types_hash_as_jazzy_publishes_them() {
    let index = jazzy_index();
    for (type_name, published) in [
        (
            "std_msgs/msg/String",
            "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18",
        ),
        (
            "sensor_msgs/msg/JointState",
            "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e",
        ),
        (
            "geometry_msgs/msg/PoseStamped",
            "RIHS01_10f3786d7d40fd2b54367835614bff85d4ad3b5dab62bf8bca0cc232d73b4cd8",
        ),
        (
            "tf2_msgs/msg/TFMessage",
            "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087",
        ),
        // As rosbags' Jazzy type store hashes it (Typestore.hash_rihs01), which agrees
        // with Jazzy on the four types above.
        (
            "visualization_msgs/msg/MarkerArray",
            "RIHS01_86cb8800b6fb05b5eff1abd7a56f62a5641d3ae9a1c29e78e67e704f1d067dcf",
        ),
    ] {
        assert_eq!(index.rihs01(type_name).unwrap(), published, "{type_name}");
    }
}

#[test]
fn the_hashed_text_is_rosidls_json() {
    let json = jazzy_index().hashed_json("std_msgs/msg/String").unwrap();
    assert_eq!(
        json,
        "{\"type_description\": {\"type_name\": \"std_msgs/msg/String\", \"fields\": \
         [{\"name\": \"data\", \"type\": {\"type_id\": 17, \"capacity\": 0, \
         \"string_capacity\": 0, \"nested_type_name\": \"\"}}]}, \
         \"referenced_type_descriptions\": []}"
    );
}

#[test]
fn an_unknown_reference_is_named() {
    let err = TypeIndex::new(&[])
        .rihs01("std_msgs/msg/String")
        .unwrap_err();
    assert!(
        err.to_string()
            .contains("no definition of std_msgs/msg/String"),
        "{err}"
    );
}

/// The types ros2-client's own endpoints carry (rosout, parameter events, discovery info,
/// clock, parameter services): message hashes as rosbags' Jazzy type store computes them.
#[test]
fn node_infrastructure_types_hash_as_rosbags_jazzy_store() {
    let index = jazzy_index();
    for (type_name, rosbags) in [
        (
            "rcl_interfaces/msg/Log",
            "RIHS01_e28ce254ca8abc06abf92773b74602cdbf116ed34fbaf294fb9f81da9f318eac",
        ),
        (
            "rcl_interfaces/msg/ParameterEvent",
            "RIHS01_043e627780fcad87a22d225bc2a037361dba713fca6a6b9f4b869a5aa0393204",
        ),
        (
            "rcl_interfaces/msg/ParameterDescriptor",
            "RIHS01_52175dbfda6c51153101d33d2a9da05743f66f02d5ab2ca9ec4709b46b73d704",
        ),
        (
            "rcl_interfaces/msg/ListParametersResult",
            "RIHS01_237ae3428413dcbcfb452b510c42355f3a2b021dc091afa3e18526d57022f1cd",
        ),
        (
            "rcl_interfaces/msg/SetParametersResult",
            "RIHS01_cfcc0fb0371ee5159b403960ef4300f8f9d2f1fd6117c8666b7f9654d528a9b1",
        ),
        (
            "rcl_interfaces/msg/ParameterType",
            "RIHS01_df29ed057a834862187be24dd187d981790ff3ea6502f4cd27b432cbc42c6d46",
        ),
        (
            "rosgraph_msgs/msg/Clock",
            "RIHS01_692f7a66e93a3c83e71765d033b60349ba68023a8c689a79e48078bcb5c58564",
        ),
    ] {
        assert_eq!(index.rihs01(type_name).unwrap(), rosbags, "{type_name}");
    }
    // rosbags hashes `char` as FIELD_TYPE_CHAR (e725f4a5…); rosidl turns a .msg `char` into
    // uint8 before hashing, and this is the hash Jazzy's rmw and zenoh-plugin-ros2dds
    // announce for ros_discovery_info.
    assert_eq!(
        index
            .rihs01("rmw_dds_common/msg/ParticipantEntitiesInfo")
            .unwrap(),
        "RIHS01_91a0593bacdcc50ea9bdcf849a938b128412cc1ea821245c663bcd26f83c295e"
    );
}

/// Service hashes hash the request, response and event messages (REP-2011); these are the
/// values Jazzy's share/rcl_interfaces/srv/*.json carry, as independent ROS 2 clients
/// (zenoh-plugin-ros2dds, rclgo-style and rosbags-style generators) publish them.
#[test]
fn parameter_services_hash_as_jazzy_publishes_them() {
    let index = jazzy_index();
    for (type_name, published) in [
        (
            "rcl_interfaces/srv/GetParameters",
            "RIHS01_bf9803d5c74cf989a5de3e0c2e99444599a627c7ff75f97b8c05b01003675cbc",
        ),
        (
            "rcl_interfaces/srv/GetParameterTypes",
            "RIHS01_da199c878688b3e530bdfe3ca8f74cb9fa0c303101e980a9e8f260e25e1c80ca",
        ),
        (
            "rcl_interfaces/srv/SetParameters",
            "RIHS01_56eed9a67e169f9cb6c1f987bc88f868c14a8fc9f743a263bc734c154015d7e0",
        ),
        (
            "rcl_interfaces/srv/SetParametersAtomically",
            "RIHS01_0e192ef259c07fc3c07a13191d27002222e65e00ccec653ca05e856f79285fcd",
        ),
        (
            "rcl_interfaces/srv/ListParameters",
            "RIHS01_3e6062bfbb27bfb8730d4cef2558221f51a11646d78e7bb30a1e83afac3aad9d",
        ),
        (
            "rcl_interfaces/srv/DescribeParameters",
            "RIHS01_845b484d71eb0673dae682f2e3ba3c4851a65a3dcfb97bddd82c5b57e91e4cff",
        ),
    ] {
        assert_eq!(index.rihs01(type_name).unwrap(), published, "{type_name}");
    }
}
