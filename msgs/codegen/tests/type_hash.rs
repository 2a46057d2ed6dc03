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
