//! ROS 2 messages and services of causal-arm, with CDR (de)serialisation.
//!
//! Every struct here is generated at build time from the `.msg`/`.srv` text — our own
//! package in `msg/` and `srv/`, and the standard ROS 2 Jazzy definitions the graph uses,
//! vendored in `ros_interfaces/` — so the Rust types and the interface package a ROS 2
//! user builds cannot drift. Types live where ROS puts them:
//! `causal_arm_msgs::sensor_msgs::msg::JointState`, `causal_arm_msgs::msg::Action`,
//! `causal_arm_msgs::srv::PredictNextState` (with `PredictNextState_Request`/`_Response`).

// Generated docs quote the .msg comments verbatim, bare URLs included.
#![allow(rustdoc::bare_urls)]

use byteorder::{BigEndian, LittleEndian};
use thiserror::Error;

include!(concat!(env!("OUT_DIR"), "/interfaces.rs"));

/// With the `ros2` feature every [`RosMessage`] is also a `ros2_client::Message`, so code
/// generic over `M: RosMessage` can hand `M` to ros2-client publishers, servers and clients
/// without repeating the bound.
#[cfg(feature = "ros2")]
pub trait Ros2Compat: ros2_client::Message {}
#[cfg(feature = "ros2")]
impl<T: ros2_client::Message> Ros2Compat for T {}
/// Without the `ros2` feature there is nothing to add (the crate is then DDS-free).
#[cfg(not(feature = "ros2"))]
pub trait Ros2Compat {}
#[cfg(not(feature = "ros2"))]
impl<T> Ros2Compat for T {}

/// A ROS 2 message type: what DDS, MCAP and the registry need to know about it.
pub trait RosMessage:
    Ros2Compat
    + serde::Serialize
    + serde::de::DeserializeOwned
    + Clone
    + std::fmt::Debug
    + Default
    + PartialEq
    + Send
    + Sync
    + 'static
{
    /// Package, e.g. `sensor_msgs`.
    const PACKAGE: &'static str;
    /// Type name, e.g. `JointState` (service parts: `PredictNextState_Request`).
    const NAME: &'static str;
    /// Full ROS name, e.g. `sensor_msgs/msg/JointState`.
    const ROS_TYPE: &'static str;
    /// REP-2011 hash of the type's description (`RIHS01_<64 hex>`), computed from the
    /// `.msg` at build time, as Iron-and-later endpoints and bags carry it.
    const TYPE_HASH: &'static str;
    /// DDS type name as rmw uses it, e.g. `sensor_msgs::msg::dds_::JointState_`.
    fn dds_type_name() -> String;
    /// Schema text as rosbag2 writes it into MCAP (`ros2msg` encoding): the definition,
    /// then each dependency once after a line of 80 `=` and `MSG: pkg/Name`.
    fn definition() -> &'static str;
    /// Checks what serde cannot express: bounded strings (`string<=N`), bounded sequences
    /// (`T[<=N]`) and fixed arrays longer than 32 (held in a `Vec`). [`to_cdr`] and
    /// [`from_cdr`] call it so a value rclcpp would reject never reaches the wire. The error
    /// names the field path, e.g. `header.frame_id: string of 9 bytes exceeds its bound 8`.
    fn validate(&self) -> Result<(), String> {
        Ok(())
    }
}

/// A ROS 2 service type.
pub trait RosService {
    /// Request message.
    type Request: RosMessage;
    /// Response message.
    type Response: RosMessage;
    /// Full ROS name, e.g. `causal_arm_msgs/srv/PredictNextState`.
    const ROS_TYPE: &'static str;
    /// REP-2011 hash of the service's description (request, response and event).
    const TYPE_HASH: &'static str;
    /// DDS type of requests, e.g. `causal_arm_msgs::srv::dds_::PredictNextState_Request_`.
    fn dds_request_type_name() -> String;
    /// DDS type of responses.
    fn dds_response_type_name() -> String;
}

/// CDR encoding or decoding failed.
#[derive(Debug, Error)]
pub enum CdrError {
    /// The buffer is shorter than the 4-byte encapsulation header.
    #[error("{ros_type}: CDR buffer of {len} bytes is too short for the encapsulation header")]
    TooShort {
        /// Type being decoded.
        ros_type: &'static str,
        /// Buffer length.
        len: usize,
    },
    /// The encapsulation is not plain CDR (XCDR1) little or big endian.
    #[error(
        "{ros_type}: unsupported CDR encapsulation {header:02x?} (expected 00 01 00 00 or 00 00 00 00)"
    )]
    Encapsulation {
        /// Type being decoded.
        ros_type: &'static str,
        /// The first four bytes.
        header: [u8; 4],
    },
    /// The payload does not match the type.
    #[error("{ros_type}: {source}")]
    Codec {
        /// Type being (de)coded.
        ros_type: &'static str,
        /// What cdr-encoding said.
        source: cdr_encoding::Error,
    },
    /// The value breaks a bound of its .msg definition (see [`RosMessage::validate`]).
    #[error("{ros_type}: {reason}")]
    Invalid {
        /// Type being (de)coded.
        ros_type: &'static str,
        /// Which field and which bound.
        reason: String,
    },
    /// Bytes left over after a complete message (beyond alignment padding).
    #[error("{ros_type}: {extra} unexpected trailing bytes after the message")]
    Trailing {
        /// Type being decoded.
        ros_type: &'static str,
        /// Number of extra bytes.
        extra: usize,
    },
}

/// Serialises `msg` as ROS 2 does on the wire and in bags: CDR little endian with the
/// 4-byte encapsulation header `00 01 00 00`.
pub fn to_cdr<M: RosMessage>(msg: &M) -> Result<Vec<u8>, CdrError> {
    msg.validate().map_err(|reason| CdrError::Invalid {
        ros_type: M::ROS_TYPE,
        reason,
    })?;
    let body = cdr_encoding::to_vec::<M, LittleEndian>(msg).map_err(|source| CdrError::Codec {
        ros_type: M::ROS_TYPE,
        source,
    })?;
    let mut out = Vec::with_capacity(body.len() + 4);
    out.extend_from_slice(&[0, 1, 0, 0]);
    out.extend_from_slice(&body);
    Ok(out)
}

/// Parses CDR bytes with encapsulation header (little or big endian).
pub fn from_cdr<M: RosMessage>(bytes: &[u8]) -> Result<M, CdrError> {
    let ros_type = M::ROS_TYPE;
    if bytes.len() < 4 {
        return Err(CdrError::TooShort {
            ros_type,
            len: bytes.len(),
        });
    }
    let header = [bytes[0], bytes[1], bytes[2], bytes[3]];
    let body = &bytes[4..];
    let decoded = match header {
        [0, 1, _, _] => cdr_encoding::from_bytes::<M, LittleEndian>(body),
        [0, 0, _, _] => cdr_encoding::from_bytes::<M, BigEndian>(body),
        _ => return Err(CdrError::Encapsulation { ros_type, header }),
    };
    let (msg, used) = decoded.map_err(|source| CdrError::Codec { ros_type, source })?;
    // Writers may pad the end to a multiple of 4; anything more is a type mismatch.
    let extra = body.len().saturating_sub(used);
    if extra >= 4 {
        return Err(CdrError::Trailing { ros_type, extra });
    }
    msg.validate()
        .map_err(|reason| CdrError::Invalid { ros_type, reason })?;
    Ok(msg)
}

/// Something generic over a message type, run by [`visit_message_type`] for a type
/// known only by name at run time (CLI tools, bag readers).
pub trait MessageTypeVisitor {
    /// What the visit returns.
    type Output;
    /// Called with the concrete type.
    fn visit<M: RosMessage>(self) -> Self::Output;
}

/// The type name is not one this crate defines.
#[derive(Debug, Error, PartialEq, Eq)]
#[error("unknown message type {0:?} (known: {known})", known = MESSAGE_TYPES.join(", "))]
pub struct UnknownMessageType(pub String);

/// Runs `visitor` with the Rust type of `ros_type` (`pkg/msg/Name` or `pkg/Name`).
pub fn visit_message_type<V: MessageTypeVisitor>(
    ros_type: &str,
    visitor: V,
) -> Result<V::Output, UnknownMessageType> {
    visit_known(ros_type.trim(), visitor).ok_or_else(|| UnknownMessageType(ros_type.to_owned()))
}

/// Every ROS type name the crate defines (messages and service requests/responses).
pub fn message_types() -> &'static [&'static str] {
    MESSAGE_TYPES
}

/// Every service type the crate defines (`pkg/srv/Name`); their halves are in [`message_types`].
pub fn service_types() -> &'static [&'static str] {
    SERVICE_TYPES
}

/// Serde helpers the generated code refers to; not part of the API.
#[doc(hidden)]
pub mod __rt {
    use serde::de::{Deserializer, Error as _, SeqAccess, Visitor};
    use serde::ser::{Error as _, SerializeTuple, Serializer};
    use serde::{Deserialize, Serialize};
    use std::marker::PhantomData;

    /// `T[N]` with N > 32 is held in a `Vec` (serde stops at 32); on the wire it must still be
    /// N elements without a length prefix, which is what a serde tuple gives in CDR.
    pub fn ser_fixed<S: Serializer, T: Serialize, const N: usize>(
        v: &[T],
        s: S,
    ) -> Result<S::Ok, S::Error> {
        if v.len() != N {
            return Err(S::Error::custom(format!(
                "fixed array needs exactly {N} elements, got {}",
                v.len()
            )));
        }
        let mut t = s.serialize_tuple(N)?;
        for e in v {
            t.serialize_element(e)?;
        }
        t.end()
    }

    /// Reads what [`ser_fixed`] writes.
    pub fn de_fixed<'de, D: Deserializer<'de>, T: Deserialize<'de>, const N: usize>(
        d: D,
    ) -> Result<Vec<T>, D::Error> {
        struct V<T, const N: usize>(PhantomData<T>);
        impl<'de, T: Deserialize<'de>, const N: usize> Visitor<'de> for V<T, N> {
            type Value = Vec<T>;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                write!(f, "an array of exactly {N} elements")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Vec<T>, A::Error> {
                let mut out = Vec::with_capacity(N);
                while let Some(e) = seq.next_element()? {
                    out.push(e);
                    if out.len() > N {
                        return Err(A::Error::invalid_length(out.len(), &self));
                    }
                }
                if out.len() != N {
                    return Err(A::Error::invalid_length(out.len(), &self));
                }
                Ok(out)
            }
        }
        d.deserialize_tuple(N, V::<T, N>(PhantomData))
    }
}

/// JSON ↔ CDR conversion failed.
#[derive(Debug, Error)]
pub enum JsonCdrError {
    /// Unknown type name.
    #[error(transparent)]
    UnknownType(#[from] UnknownMessageType),
    /// The JSON does not fit the type.
    #[error("{ros_type}: JSON does not match the message: {source}")]
    Json {
        /// Target type.
        ros_type: String,
        /// What serde_json said.
        source: serde_json::Error,
    },
    /// CDR failure.
    #[error(transparent)]
    Cdr(#[from] CdrError),
}

struct JsonToCdr<'a>(&'a serde_json::Value);

impl MessageTypeVisitor for JsonToCdr<'_> {
    type Output = Result<Vec<u8>, JsonCdrError>;
    fn visit<M: RosMessage>(self) -> Self::Output {
        let msg: M =
            serde_json::from_value(self.0.clone()).map_err(|source| JsonCdrError::Json {
                ros_type: M::ROS_TYPE.to_owned(),
                source,
            })?;
        Ok(to_cdr(&msg)?)
    }
}

struct CdrToJson<'a>(&'a [u8]);

impl MessageTypeVisitor for CdrToJson<'_> {
    type Output = Result<serde_json::Value, JsonCdrError>;
    fn visit<M: RosMessage>(self) -> Self::Output {
        let msg: M = from_cdr(self.0)?;
        serde_json::to_value(&msg).map_err(|source| JsonCdrError::Json {
            ros_type: M::ROS_TYPE.to_owned(),
            source,
        })
    }
}

/// Encodes a JSON value (field names as in the .msg) as CDR of `ros_type`.
pub fn json_to_cdr(ros_type: &str, json: &serde_json::Value) -> Result<Vec<u8>, JsonCdrError> {
    visit_message_type(ros_type, JsonToCdr(json))?
}

/// Decodes CDR of `ros_type` into JSON.
pub fn cdr_to_json(ros_type: &str, bytes: &[u8]) -> Result<serde_json::Value, JsonCdrError> {
    visit_message_type(ros_type, CdrToJson(bytes))?
}

struct Definition;

impl MessageTypeVisitor for Definition {
    type Output = &'static str;
    fn visit<M: RosMessage>(self) -> &'static str {
        M::definition()
    }
}

/// The MCAP schema text of `ros_type`.
pub fn definition_of(ros_type: &str) -> Result<&'static str, UnknownMessageType> {
    visit_message_type(ros_type, Definition)
}

/// Types generated from `tests/fixtures/` (every generator feature), for the unit tests only.
#[cfg(test)]
#[allow(dead_code)]
mod fixture {
    include!(concat!(env!("OUT_DIR"), "/fixture.rs"));
}

#[cfg(test)]
mod tests {
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
        assert_eq!(message_types().len(), 60);
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
}
