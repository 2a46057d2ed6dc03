//! Tests of the crate root.

use super::*;
use crate::sensor_msgs::msg::JointState;

#[test]
fn joint_state_round_trips_with_ros_layout() {
    let mut js = JointState::default();
    js.header.stamp.sec = 3;
    js.header.frame_id = "w".into();
    js.name = vec!["a".into()];
    js.position = vec![1.5];
    let bytes = to_cdr(&js).unwrap();
    // header 00 01 00 00, sec, nanosec, frame_id "w\0" (len 2), pad to 4,
    // name count 1, "a\0", pad, position count 1, pad to 8, 1.5
    assert_eq!(&bytes[..4], &[0, 1, 0, 0]);
    assert_eq!(&bytes[4..8], &3i32.to_le_bytes());
    assert_eq!(&bytes[12..16], &2u32.to_le_bytes());
    assert_eq!(from_cdr::<JointState>(&bytes).unwrap(), js);
}

#[test]
fn definitions_carry_dependencies_once() {
    let def = JointState::definition();
    assert!(def.starts_with("# This is a message that holds data"));
    assert_eq!(def.matches("MSG: std_msgs/Header").count(), 1);
    assert_eq!(def.matches("MSG: builtin_interfaces/Time").count(), 1);
    assert_eq!(
        JointState::dds_type_name(),
        "sensor_msgs::msg::dds_::JointState_"
    );
}

#[test]
fn type_hashes_are_built_from_the_definitions() {
    // Jazzy's published hash (codegen's tests check three more standard types).
    assert_eq!(
        JointState::TYPE_HASH,
        "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e"
    );
    let ours = [
        crate::srv::PredictNextState::TYPE_HASH,
        <crate::srv::PredictNextState as RosService>::Request::TYPE_HASH,
        <crate::srv::PredictNextState as RosService>::Response::TYPE_HASH,
        crate::srv::Explain::TYPE_HASH,
        crate::msg::Action::TYPE_HASH,
    ];
    for hash in ours {
        assert!(
            hash.starts_with("RIHS01_") && hash.len() == 7 + 64,
            "{hash}"
        );
    }
    let distinct: std::collections::BTreeSet<_> = ours.iter().collect();
    assert_eq!(distinct.len(), ours.len(), "every type has its own hash");
}

#[test]
fn defaults_and_constants_follow_the_msg_files() {
    assert_eq!(crate::geometry_msgs::msg::Quaternion::default().w, 1.0);
    assert_eq!(crate::msg::Action::MAGNET_OFF, -1);
    assert_eq!(crate::rcl_interfaces::msg::Log::FATAL, 50);
    assert_eq!(
        <crate::srv::PredictNextState as RosService>::dds_request_type_name(),
        "causal_arm_msgs::srv::dds_::PredictNextState_Request_"
    );
}

#[test]
fn registry_knows_every_type_and_rejects_others() {
    assert!(message_types().contains(&"causal_arm_msgs/msg/Action"));
    assert!(message_types().contains(&"causal_arm_msgs/srv/Explain_Response"));
    let json = serde_json::json!({"on": true});
    let bytes = json_to_cdr("causal_arm_msgs/MagnetState", &json).unwrap();
    assert_eq!(
        cdr_to_json("causal_arm_msgs/msg/MagnetState", &bytes).unwrap()["on"],
        true
    );
    let err = json_to_cdr("sensor_msgs/msg/JointStat", &json).unwrap_err();
    assert!(err.to_string().contains("JointStat\""), "{err}");
    let err = json_to_cdr(
        "causal_arm_msgs/msg/MagnetState",
        &serde_json::json!({"onn": 1}),
    )
    .unwrap_err();
    assert!(err.to_string().contains("onn"), "{err}");
}

#[test]
fn bad_cdr_is_a_clear_error() {
    let err = from_cdr::<JointState>(&[0, 1]).unwrap_err();
    assert!(err.to_string().contains("too short"), "{err}");
    let err = from_cdr::<JointState>(&[0, 7, 0, 0, 1, 2, 3]).unwrap_err();
    assert!(err.to_string().contains("encapsulation"), "{err}");
    let err = from_cdr::<JointState>(&[0, 1, 0, 0, 1, 0, 0, 0]).unwrap_err();
    assert!(
        err.to_string().contains("sensor_msgs/msg/JointState"),
        "{err}"
    );
}

/// Value and bytes produced by Python `rosbags` (tests/fixtures, see the golden pytest).
const FIXTURE_JSON: &str = r#"{"flag": true, "b": 127, "c": 66, "i8v": -128, "u8v": 200, "i16v": -300, "u16v": 60000, "i32v": -70000, "u32v": 4000000000, "i64v": -5000000000, "u64v": 18446744073709551615, "f32v": 1.5, "f64v": -2.25, "s": "h\u00e9llo", "bs": "abc", "fixed3": [1, -2, 3], "fixed40": [-7.0, -6.5, -6.0, -5.5, -5.0, -4.5, -4.0, -3.5, -3.0, -2.5, -2.0, -1.5, -1.0, -0.5, 0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0, 5.5, 6.0, 6.5, 7.0, 7.5, 8.0, 8.5, 9.0, 9.5, 10.0, 10.5, 11.0, 11.5, 12.0, 12.5], "bounded_bytes": [1, 2, 3], "bounded_strings": ["\u00e9", "xyz"], "raw": [9, 8, 7, 6, 5], "type": -7, "inners": [{"tag": "a", "value": 1.25}, {"tag": "bc", "value": -0.5}], "inner_seq": [{"tag": "", "value": 3.0}], "header": {"stamp": {"sec": -3, "nanosec": 7}, "frame_id": "w"}}"#;
const FIXTURE_HEX: &str = "00010000017f4280c800d4fe60ea000090eefeff00286bee00000000000efad5feffffffffffffffffffffff0000c03f0000000000000000000002c00700000068c3a96c6c6f0000040000006162630001000000feffffff030000000000000000001cc00000000000001ac000000000000018c000000000000016c000000000000014c000000000000012c000000000000010c00000000000000cc000000000000008c000000000000004c000000000000000c0000000000000f8bf000000000000f0bf000000000000e0bf0000000000000000000000000000e03f000000000000f03f000000000000f83f0000000000000040000000000000044000000000000008400000000000000c40000000000000104000000000000012400000000000001440000000000000164000000000000018400000000000001a400000000000001c400000000000001e40000000000000204000000000000021400000000000002240000000000000234000000000000024400000000000002540000000000000264000000000000027400000000000002840000000000000294003000000010203000200000003000000c3a900000400000078797a00050000000908070605000000f9ffffff020000006100000000000000000000000000f43f0300000062630000000000000000e0bf010000000100000000000000000000000000000000000840fdffffff07000000020000007700";

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

#[test]
fn every_generator_feature_matches_rosbags_bytes() {
    use crate::fixture::codegen_test_msgs::msg::{Everything, Inner};
    let value: Everything = serde_json::from_str(FIXTURE_JSON).unwrap();
    assert_eq!(value.fixed3, [1, -2, 3]);
    assert_eq!(value.r#type, -7);
    assert_eq!(value.fixed40.len(), 40);
    let bytes = to_cdr(&value).unwrap();
    assert_eq!(hex(&bytes), FIXTURE_HEX);
    assert_eq!(from_cdr::<Everything>(&bytes).unwrap(), value);
    // JSON round trip keeps field names (`type`, not `r#type`).
    let json = serde_json::to_value(&value).unwrap();
    assert_eq!(json["type"], -7);
    assert_eq!(serde_json::from_value::<Everything>(json).unwrap(), value);
    // Big-endian input decodes to the same value.
    assert_eq!(
        Everything::definition()
            .matches("MSG: codegen_test_msgs/Inner")
            .count(),
        1
    );
    let _ = Inner::default();
}

#[test]
fn defaults_constants_and_bounds_of_the_fixture() {
    use crate::fixture::codegen_test_msgs::msg::{Everything, Inner};
    let d = Everything::default();
    assert!(d.flag);
    assert_eq!(
        (d.b, d.c, d.i8v, d.u8v, d.u64v),
        (3, 66, -3, 200, 10_000_000_000)
    );
    assert_eq!((d.f32v, d.f64v, d.s.as_str()), (1.5, -2.25, "quoted"));
    assert_eq!(d.fixed3, [1, -2, 3]);
    assert_eq!(d.fixed40, vec![0.0; 40]);
    assert_eq!(Everything::NEG, -5);
    assert_eq!(Everything::BIG, u64::MAX);
    assert_eq!(Everything::HALF, 0.5f32);
    const { assert!(Everything::YES) };
    assert_eq!(Everything::GREETING, "hi # there");
    assert_eq!((Everything::B, Everything::C), (7u8, 65u8));
    to_cdr(&d).unwrap();

    let mut v = d.clone();
    v.bs = "toolong".into();
    let e = to_cdr(&v).unwrap_err().to_string();
    assert_eq!(
        e,
        "codegen_test_msgs/msg/Everything: bs: string of 7 bytes exceeds its bound 4"
    );
    let mut v = d.clone();
    v.bounded_bytes = vec![0; 6];
    assert!(
        to_cdr(&v)
            .unwrap_err()
            .to_string()
            .contains("bounded_bytes: 6 elements exceed its bound 5")
    );
    let mut v = d.clone();
    v.bounded_strings = vec!["a".into(), "abcd".into()];
    assert!(
        to_cdr(&v)
            .unwrap_err()
            .to_string()
            .contains("bounded_strings[1]: string of 4 bytes")
    );
    let mut v = d.clone();
    v.inner_seq = vec![Inner {
        tag: "xyz".into(),
        value: 0.0,
    }];
    assert!(
        to_cdr(&v)
            .unwrap_err()
            .to_string()
            .contains("inner_seq[0].tag: string of 3 bytes")
    );
    let mut v = d.clone();
    v.fixed40.pop();
    assert!(
        to_cdr(&v)
            .unwrap_err()
            .to_string()
            .contains("fixed40: 39 elements, the array has exactly 40")
    );
    // A too-long bounded string on the wire is rejected on decode too.
    let mut bytes = vec![0, 1, 0, 0, 4, 0, 0, 0];
    bytes.extend_from_slice(b"abc\0");
    bytes.extend_from_slice(&1.5f64.to_le_bytes());
    let e = from_cdr::<Inner>(&bytes).unwrap_err().to_string();
    assert_eq!(
        e,
        "codegen_test_msgs/msg/Inner: tag: string of 3 bytes exceeds its bound 2"
    );
}

#[test]
fn big_endian_and_short_names() {
    use crate::std_msgs::msg::Header;
    let h = Header {
        stamp: crate::builtin_interfaces::msg::Time {
            sec: -2,
            nanosec: 5,
        },
        frame_id: "map".into(),
    };
    let mut be = vec![0, 0, 0, 0];
    be.extend_from_slice(&(-2i32).to_be_bytes());
    be.extend_from_slice(&5u32.to_be_bytes());
    be.extend_from_slice(&4u32.to_be_bytes());
    be.extend_from_slice(b"map\0");
    assert_eq!(from_cdr::<Header>(&be).unwrap(), h);
    assert_eq!(
        hex(&to_cdr(&h).unwrap()),
        "00010000feffffff05000000040000006d617000"
    );
    assert!(visit_message_type("std_msgs/Header", Definition).is_ok());
    assert!(visit_message_type("causal_arm_msgs/PredictNextState_Request", Definition).is_ok());
    assert!(visit_message_type("causal_arm_msgs/srv/PredictNextState", Definition).is_err());
    assert_eq!(service_types().len(), 11);
    assert_eq!(message_types().len(), 61);
    let mut trailing = to_cdr(&h).unwrap();
    trailing.extend_from_slice(&[0; 8]);
    assert!(
        from_cdr::<Header>(&trailing)
            .unwrap_err()
            .to_string()
            .contains("trailing")
    );
}

#[test]
fn service_markers_name_dds_types() {
    use crate::srv::{Explain, GetModelInfo, PredictAction, PredictNextState, Rollout};
    fn names<S: RosService>() -> (String, String, &'static str, &'static str) {
        (
            S::dds_request_type_name(),
            S::dds_response_type_name(),
            S::ROS_TYPE,
            <S::Request as RosMessage>::ROS_TYPE,
        )
    }
    assert_eq!(
        names::<PredictNextState>(),
        (
            "causal_arm_msgs::srv::dds_::PredictNextState_Request_".to_string(),
            "causal_arm_msgs::srv::dds_::PredictNextState_Response_".to_string(),
            "causal_arm_msgs/srv/PredictNextState",
            "causal_arm_msgs/srv/PredictNextState_Request"
        )
    );
    assert_eq!(
        names::<PredictAction>().2,
        "causal_arm_msgs/srv/PredictAction"
    );
    assert_eq!(names::<Rollout>().2, "causal_arm_msgs/srv/Rollout");
    assert_eq!(
        names::<GetModelInfo>().2,
        "causal_arm_msgs/srv/GetModelInfo"
    );
    assert_eq!(names::<Explain>().2, "causal_arm_msgs/srv/Explain");
    assert_eq!(
        crate::srv::PredictNextState_Request::NAME,
        "PredictNextState_Request"
    );
    assert!(crate::srv::Explain_Response::definition().starts_with("# False when"));
}

#[cfg(feature = "ros2")]
#[test]
fn ros2_client_marker_is_implied() {
    fn needs_message<M: ros2_client::Message>() {}
    fn generic<M: RosMessage>() {
        needs_message::<M>();
    }
    generic::<crate::msg::Action>();
}

/// A sample written before `Action.design` was appended (a bag of an earlier release) is
/// read with the design empty, with or without its writer's end padding; a sample cut
/// inside its old fields is still an error.
#[test]
fn a_sample_of_the_layout_before_an_appended_field_still_reads() {
    use crate::msg::{Action, Draw};
    assert_eq!(Action::APPENDED_SEQUENCES, 1);
    assert_eq!(crate::msg::Relevance::APPENDED_SEQUENCES, 3);
    assert_eq!(JointState::APPENDED_SEQUENCES, 0);
    let old = Action {
        step: 3,
        joint_deltas: vec![0.1; 7],
        joint_targets: vec![0.2; 7],
        magnet: 1,
        ..Default::default()
    };
    let bytes = to_cdr(&old).unwrap();
    // The design's length was the last 4 bytes; before it, the padding after `magnet`.
    let padded = &bytes[..bytes.len() - 4];
    let unpadded = &bytes[..bytes.len() - 7];
    assert_eq!(unpadded.last(), Some(&1u8), "ends with the magnet");
    for layout in [padded, unpadded] {
        assert_eq!(from_cdr::<Action>(layout).unwrap(), old);
    }
    let cut = &bytes[..bytes.len() - 20];
    assert!(from_cdr::<Action>(cut).is_err(), "a cut sample still fails");
    let new = Action {
        design: vec![Draw {
            family: Draw::NORMAL,
            scale: 0.35,
            ..Default::default()
        }],
        ..old
    };
    assert_eq!(from_cdr::<Action>(&to_cdr(&new).unwrap()).unwrap(), new);
}
