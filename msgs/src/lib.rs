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
    /// Unbounded arrays appended at the end of the type after it was first published
    /// (the `.msg` marks the first with a comment starting "Appended"): a sample of the
    /// layout before them is still read ([`from_cdr`]), with them empty.
    const APPENDED_SEQUENCES: usize = 0;
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
    let (msg, used) = match decode_body::<M>(header, body)? {
        Ok(decoded) => decoded,
        Err(source) => match read_before_appended::<M>(header, body)? {
            Some(decoded) => decoded,
            None => return Err(CdrError::Codec { ros_type, source }),
        },
    };
    // Writers may pad the end to a multiple of 4; anything more is a type mismatch.
    let extra = body.len().saturating_sub(used);
    if extra >= 4 {
        return Err(CdrError::Trailing { ros_type, extra });
    }
    msg.validate()
        .map_err(|reason| CdrError::Invalid { ros_type, reason })?;
    Ok(msg)
}

/// A sample of `M`'s layout before its last k appended sequences (k = 1 ..=
/// `M::APPENDED_SEQUENCES`): read with those sequences empty, but only where the sample
/// ends exactly where they would begin (up to its padding), so a truncated sample is still
/// an error.
fn read_before_appended<M: RosMessage>(
    header: [u8; 4],
    body: &[u8],
) -> Result<Option<(M, usize)>, CdrError> {
    // Each missing sequence reads as a length of 0, after the padding to 4 bytes.
    let padding = (4 - body.len() % 4) % 4;
    for k in 1..=M::APPENDED_SEQUENCES {
        let mut padded = body.to_vec();
        padded.extend(std::iter::repeat_n(0, padding + 4 * k));
        if let Ok((msg, used)) = decode_body::<M>(header, &padded)?
            && used == padded.len()
        {
            return Ok(Some((msg, body.len())));
        }
    }
    Ok(None)
}

/// The body's message by the encapsulation `header`'s byte order: an unknown
/// encapsulation is the outer error, a body that does not decode the inner one.
fn decode_body<M: RosMessage>(
    header: [u8; 4],
    body: &[u8],
) -> Result<cdr_encoding::Result<(M, usize)>, CdrError> {
    match header {
        [0, 1, _, _] => Ok(cdr_encoding::from_bytes::<M, LittleEndian>(body)),
        [0, 0, _, _] => Ok(cdr_encoding::from_bytes::<M, BigEndian>(body)),
        _ => Err(CdrError::Encapsulation {
            ros_type: M::ROS_TYPE,
            header,
        }),
    }
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
mod tests;
