//! REP-2011 type hashes (`RIHS01_<sha256>`): since Iron every ROS 2 endpoint announces the
//! hash of its type's description, and tools (rmw, rosbag2) use it to tell types of the same
//! name apart. The hash is the SHA-256 of the type description (its fields and every type it
//! refers to, default values left out) in the exact JSON text rosidl hashes, so it must be
//! computed from the same `.msg`/`.srv` definitions, byte for byte.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use sha2::{Digest, Sha256};

use crate::{ArrayKind, BaseType, Field, FieldType, Interface, MessageSpec};

/// `type_description_interfaces/msg/FieldType` ids of the element types.
mod field_type {
    pub const NESTED_TYPE: u8 = 1;
    pub const INT8: u8 = 2;
    pub const UINT8: u8 = 3;
    pub const INT16: u8 = 4;
    pub const UINT16: u8 = 5;
    pub const INT32: u8 = 6;
    pub const UINT32: u8 = 7;
    pub const INT64: u8 = 8;
    pub const UINT64: u8 = 9;
    pub const FLOAT: u8 = 10;
    pub const DOUBLE: u8 = 11;
    pub const BOOLEAN: u8 = 15;
    pub const BYTE: u8 = 16;
    pub const STRING: u8 = 17;
    pub const WSTRING: u8 = 18;
    pub const BOUNDED_STRING: u8 = 21;
    pub const BOUNDED_WSTRING: u8 = 22;
    /// Added to the element id for `T[N]`.
    pub const ARRAY: u8 = 48;
    /// Added to the element id for `T[<=N]`.
    pub const BOUNDED_SEQUENCE: u8 = 96;
    /// Added to the element id for `T[]`.
    pub const UNBOUNDED_SEQUENCE: u8 = 144;
}

/// The field rosidl gives a message without fields (IDL structs need one member).
const EMPTY_MESSAGE_FIELD: &str = "structure_needs_at_least_one_member";

/// One field as the type description holds it (its default value is not hashed).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FieldDescription {
    /// Field name.
    pub name: String,
    /// `FieldType` id of the element type plus the array offset.
    pub type_id: u8,
    /// Array length or sequence bound (0 for scalars and unbounded sequences).
    pub capacity: u64,
    /// String bound (0 when unbounded).
    pub string_capacity: u64,
    /// `pkg/msg/Name` of a nested type, else empty.
    pub nested_type_name: String,
}

/// Every type the build knows, by its full name (`pkg/msg/Name`, `pkg/srv/Name_Request`,
/// `pkg/srv/Name`), as type descriptions.
#[derive(Debug, Default)]
pub struct TypeIndex {
    types: BTreeMap<String, Vec<FieldDescription>>,
}

/// A type hash could not be computed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum TypeHashError {
    /// `type_name` (or a type it refers to, `missing`) is not among the interfaces given.
    Unknown {
        /// The type whose hash was asked for.
        type_name: String,
        /// The type that has no description.
        missing: String,
    },
}

impl std::fmt::Display for TypeHashError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            TypeHashError::Unknown { type_name, missing } => write!(
                f,
                "type hash of {type_name}: no definition of {missing} among the interfaces given"
            ),
        }
    }
}

impl std::error::Error for TypeHashError {}

impl TypeIndex {
    /// Describes every message and service of `interfaces` (services with their request,
    /// response and event message, as rosidl does; the event refers to
    /// `service_msgs/msg/ServiceEventInfo`, which must be among the interfaces).
    pub fn new(interfaces: &[Interface]) -> Self {
        let mut index = TypeIndex::default();
        for interface in interfaces {
            match interface {
                Interface::Message { spec, .. } => index.add_message("msg", spec),
                Interface::Service { spec, .. } => {
                    let base = format!("{}/srv/{}", spec.package, spec.name);
                    index.add_message("srv", &spec.request);
                    index.add_message("srv", &spec.response);
                    let nested = |name: &str, type_name: String, capacity| FieldDescription {
                        name: name.to_string(),
                        type_id: field_type::NESTED_TYPE
                            + if capacity > 0 {
                                field_type::BOUNDED_SEQUENCE
                            } else {
                                0
                            },
                        capacity,
                        string_capacity: 0,
                        nested_type_name: type_name,
                    };
                    let event = vec![
                        nested("info", "service_msgs/msg/ServiceEventInfo".into(), 0),
                        nested("request", format!("{base}_Request"), 1),
                        nested("response", format!("{base}_Response"), 1),
                    ];
                    index.types.insert(format!("{base}_Event"), event);
                    let service = vec![
                        nested("request_message", format!("{base}_Request"), 0),
                        nested("response_message", format!("{base}_Response"), 0),
                        nested("event_message", format!("{base}_Event"), 0),
                    ];
                    index.types.insert(base, service);
                }
            }
        }
        index
    }

    fn add_message(&mut self, kind: &str, spec: &MessageSpec) {
        let mut fields: Vec<FieldDescription> = spec.fields.iter().map(describe).collect();
        if fields.is_empty() {
            fields.push(FieldDescription {
                name: EMPTY_MESSAGE_FIELD.to_string(),
                type_id: field_type::UINT8,
                capacity: 0,
                string_capacity: 0,
                nested_type_name: String::new(),
            });
        }
        self.types
            .insert(format!("{}/{kind}/{}", spec.package, spec.name), fields);
    }

    /// Every type described, by full name (service events included).
    pub fn type_names(&self) -> impl Iterator<Item = &str> {
        self.types.keys().map(String::as_str)
    }

    /// `RIHS01_<64 hex>` of `type_name` (`pkg/msg/Name`, `pkg/srv/Name`, `pkg/srv/Name_Request`).
    pub fn rihs01(&self, type_name: &str) -> Result<String, TypeHashError> {
        let json = self.hashed_json(type_name)?;
        let digest = Sha256::digest(json.as_bytes());
        let mut out = String::from("RIHS01_");
        for byte in digest {
            let _ = write!(out, "{byte:02x}");
        }
        Ok(out)
    }

    /// The JSON text rosidl hashes: the type's description, then every type it refers to
    /// (transitively, once each, sorted by name), formatted as Python's
    /// `json.dumps(..., separators=(", ", ": "))`.
    pub fn hashed_json(&self, type_name: &str) -> Result<String, TypeHashError> {
        let fields_of = |name: &str| {
            self.types.get(name).ok_or_else(|| TypeHashError::Unknown {
                type_name: type_name.to_string(),
                missing: name.to_string(),
            })
        };
        let own = fields_of(type_name)?;
        let mut referenced = BTreeMap::new();
        let mut pending: Vec<&str> = nested_names(own).collect();
        while let Some(name) = pending.pop() {
            if referenced.contains_key(name) {
                continue;
            }
            let fields = fields_of(name)?;
            pending.extend(nested_names(fields));
            referenced.insert(name, fields);
        }
        let mut json = String::from("{\"type_description\": ");
        write_description(&mut json, type_name, own);
        json.push_str(", \"referenced_type_descriptions\": [");
        for (i, (name, fields)) in referenced.iter().enumerate() {
            if i > 0 {
                json.push_str(", ");
            }
            write_description(&mut json, name, fields);
        }
        json.push_str("]}");
        Ok(json)
    }
}

fn nested_names(fields: &[FieldDescription]) -> impl Iterator<Item = &str> {
    fields
        .iter()
        .filter(|f| !f.nested_type_name.is_empty())
        .map(|f| f.nested_type_name.as_str())
}

fn describe(field: &Field) -> FieldDescription {
    let FieldType { base, array } = &field.ty;
    let (element, string_capacity, nested_type_name) = match base {
        BaseType::Bool => (field_type::BOOLEAN, 0, String::new()),
        BaseType::Byte => (field_type::BYTE, 0, String::new()),
        // rosidl maps `char` of the .msg language to uint8.
        BaseType::Char | BaseType::U8 => (field_type::UINT8, 0, String::new()),
        BaseType::I8 => (field_type::INT8, 0, String::new()),
        BaseType::I16 => (field_type::INT16, 0, String::new()),
        BaseType::U16 => (field_type::UINT16, 0, String::new()),
        BaseType::I32 => (field_type::INT32, 0, String::new()),
        BaseType::U32 => (field_type::UINT32, 0, String::new()),
        BaseType::I64 => (field_type::INT64, 0, String::new()),
        BaseType::U64 => (field_type::UINT64, 0, String::new()),
        BaseType::F32 => (field_type::FLOAT, 0, String::new()),
        BaseType::F64 => (field_type::DOUBLE, 0, String::new()),
        BaseType::String { bound: None } => (field_type::STRING, 0, String::new()),
        BaseType::String { bound: Some(n) } => (field_type::BOUNDED_STRING, *n, String::new()),
        BaseType::WString { bound: None } => (field_type::WSTRING, 0, String::new()),
        BaseType::WString { bound: Some(n) } => (field_type::BOUNDED_WSTRING, *n, String::new()),
        BaseType::Named { package, name } => {
            (field_type::NESTED_TYPE, 0, format!("{package}/msg/{name}"))
        }
    };
    let (offset, capacity) = match array {
        ArrayKind::Scalar => (0, 0),
        ArrayKind::Fixed(n) => (field_type::ARRAY, *n),
        ArrayKind::Bounded(n) => (field_type::BOUNDED_SEQUENCE, *n),
        ArrayKind::Unbounded => (field_type::UNBOUNDED_SEQUENCE, 0),
    };
    FieldDescription {
        name: field.name.clone(),
        type_id: element + offset,
        capacity: capacity as u64,
        string_capacity: string_capacity as u64,
        nested_type_name,
    }
}

fn write_description(json: &mut String, type_name: &str, fields: &[FieldDescription]) {
    json.push_str("{\"type_name\": ");
    write_string(json, type_name);
    json.push_str(", \"fields\": [");
    for (i, f) in fields.iter().enumerate() {
        if i > 0 {
            json.push_str(", ");
        }
        json.push_str("{\"name\": ");
        write_string(json, &f.name);
        let _ = write!(
            json,
            ", \"type\": {{\"type_id\": {}, \"capacity\": {}, \"string_capacity\": {}, \"nested_type_name\": ",
            f.type_id, f.capacity, f.string_capacity
        );
        write_string(json, &f.nested_type_name);
        json.push_str("}}");
    }
    json.push_str("]}");
}

/// A JSON string as Python writes it with `ensure_ascii=True`.
fn write_string(json: &mut String, text: &str) {
    json.push('"');
    for c in text.chars() {
        match c {
            '"' => json.push_str("\\\""),
            '\\' => json.push_str("\\\\"),
            '\n' => json.push_str("\\n"),
            '\r' => json.push_str("\\r"),
            '\t' => json.push_str("\\t"),
            c if c.is_ascii() && !c.is_ascii_control() => json.push(c),
            c => {
                let mut units = [0u16; 2];
                for unit in c.encode_utf16(&mut units) {
                    let _ = write!(json, "\\u{unit:04x}");
                }
            }
        }
    }
    json.push('"');
}
