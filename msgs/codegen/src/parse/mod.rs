//! Strict parser of the ROS 2 `.msg` / `.srv` interface language.
//!
//! Strict on purpose: the same files are compiled by `rosidl` for rclpy users, so anything
//! rosidl would reject (or read differently) must fail here too, at build time, with the file
//! and line, instead of producing Rust types that silently disagree with ROS 2.

use std::fmt;

mod literals;
mod names;
mod section;

use names::check_type_name;
use section::parse_section;

/// A parse failure, located so the author can jump straight to it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ParseError {
    /// Path (or name) of the interface file as given to the parser.
    pub file: String,
    /// 1-based line number; 0 when the problem concerns the whole file.
    pub line: usize,
    /// What was wrong and what was expected.
    pub message: String,
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}: {}", self.file, self.line, self.message)
    }
}

impl std::error::Error for ParseError {}

/// Primitive and named element types of the interface language.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum BaseType {
    /// `bool`
    Bool,
    /// `byte` (an opaque octet; `uint8` on the wire)
    Byte,
    /// `char` (ROS 2 maps it to `uint8`)
    Char,
    /// `int8`
    I8,
    /// `uint8`
    U8,
    /// `int16`
    I16,
    /// `uint16`
    U16,
    /// `int32`
    I32,
    /// `uint32`
    U32,
    /// `int64`
    I64,
    /// `uint64`
    U64,
    /// `float32`
    F32,
    /// `float64`
    F64,
    /// `string` or `string<=N`
    String {
        /// Maximum length in bytes, if bounded.
        bound: Option<usize>,
    },
    /// `wstring` or `wstring<=N` (parsed so the error can be precise; not emitted)
    WString {
        /// Maximum length in characters, if bounded.
        bound: Option<usize>,
    },
    /// A message type `package/Name` (same-package and `Header` references already resolved).
    Named {
        /// ROS package of the type.
        package: String,
        /// Message name within the package.
        name: String,
    },
}

impl BaseType {
    /// Whether this is a built-in (non-message) type; only those may be constants.
    pub fn is_primitive(&self) -> bool {
        !matches!(self, BaseType::Named { .. })
    }

    fn from_primitive(word: &str) -> Option<BaseType> {
        Some(match word {
            "bool" => BaseType::Bool,
            "byte" => BaseType::Byte,
            "char" => BaseType::Char,
            "int8" => BaseType::I8,
            "uint8" => BaseType::U8,
            "int16" => BaseType::I16,
            "uint16" => BaseType::U16,
            "int32" => BaseType::I32,
            "uint32" => BaseType::U32,
            "int64" => BaseType::I64,
            "uint64" => BaseType::U64,
            "float32" => BaseType::F32,
            "float64" => BaseType::F64,
            "string" => BaseType::String { bound: None },
            "wstring" => BaseType::WString { bound: None },
            _ => return None,
        })
    }
}

/// How many elements a field holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ArrayKind {
    /// A single value.
    Scalar,
    /// `T[]`
    Unbounded,
    /// `T[N]`
    Fixed(usize),
    /// `T[<=N]`
    Bounded(usize),
}

/// Element type plus array shape of a field or constant.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FieldType {
    /// Element type.
    pub base: BaseType,
    /// Array shape.
    pub array: ArrayKind,
}

/// One field of a message.
#[derive(Debug, Clone, PartialEq)]
pub struct Field {
    /// Field name exactly as in the file.
    pub name: String,
    /// Its type.
    pub ty: FieldType,
    /// Default value, already validated against the type.
    pub default: Option<Value>,
    /// Comment lines directly above the field plus its trailing comment.
    pub doc: Vec<String>,
    /// 1-based line of the declaration.
    pub line: usize,
}

/// One constant of a message.
#[derive(Debug, Clone, PartialEq)]
pub struct Constant {
    /// Constant name (upper case).
    pub name: String,
    /// Its primitive type.
    pub ty: BaseType,
    /// Its value, validated against the type.
    pub value: Value,
    /// Comment lines directly above plus the trailing comment.
    pub doc: Vec<String>,
    /// 1-based line of the declaration.
    pub line: usize,
}

/// A literal from a constant or default value.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// `true` / `false` (also `1` / `0`).
    Bool(bool),
    /// Any integer, range-checked against its type.
    Int(i128),
    /// Any float (finite or not).
    Float(f64),
    /// A string (quotes removed, escapes resolved).
    Str(String),
    /// An array default `[a, b, c]`.
    Array(Vec<Value>),
}

/// A parsed message (or one half of a service).
#[derive(Debug, Clone, PartialEq)]
pub struct MessageSpec {
    /// ROS package.
    pub package: String,
    /// Type name, e.g. `JointState` or `PredictNextState_Request`.
    pub name: String,
    /// Fields in wire order.
    pub fields: Vec<Field>,
    /// Constants in file order.
    pub constants: Vec<Constant>,
    /// The leading comment block of the file (or of the section).
    pub doc: Vec<String>,
    /// The source text exactly as ROS 2 tools embed it in bags.
    pub text: String,
}

/// A parsed service.
#[derive(Debug, Clone, PartialEq)]
pub struct ServiceSpec {
    /// ROS package.
    pub package: String,
    /// Service name, e.g. `PredictNextState`.
    pub name: String,
    /// `Name_Request`
    pub request: MessageSpec,
    /// `Name_Response`
    pub response: MessageSpec,
    /// Leading comment block of the file.
    pub doc: Vec<String>,
}

struct Ctx<'a> {
    file: &'a str,
    package: &'a str,
}

impl Ctx<'_> {
    fn err(&self, line: usize, message: impl Into<String>) -> ParseError {
        ParseError {
            file: self.file.to_string(),
            line,
            message: message.into(),
        }
    }
}

/// Parse a `.msg` file. `file` is only used in error messages.
pub fn parse_message(
    package: &str,
    name: &str,
    file: &str,
    text: &str,
) -> Result<MessageSpec, ParseError> {
    let ctx = Ctx { file, package };
    check_type_name(&ctx, 0, name)?;
    let lines: Vec<(usize, &str)> = text.lines().enumerate().map(|(i, l)| (i + 1, l)).collect();
    parse_section(&ctx, name, &lines, text.to_string())
}

/// Parse a `.srv` file into its request and response halves (split at the `---` line).
pub fn parse_service(
    package: &str,
    name: &str,
    file: &str,
    text: &str,
) -> Result<ServiceSpec, ParseError> {
    let ctx = Ctx { file, package };
    check_type_name(&ctx, 0, name)?;
    let lines: Vec<(usize, &str)> = text.lines().enumerate().map(|(i, l)| (i + 1, l)).collect();
    let seps: Vec<usize> = lines
        .iter()
        .filter(|(_, l)| l.trim() == "---")
        .map(|(n, _)| *n)
        .collect();
    let sep = match seps.as_slice() {
        [one] => *one,
        [] => {
            return Err(ctx.err(
                0,
                "service has no `---` line separating request and response",
            ));
        }
        [_, second, ..] => {
            return Err(ctx.err(
                *second,
                "second `---` separator (a .srv has exactly one; actions are not supported)",
            ));
        }
    };
    let (req_lines, rest) = lines.split_at(sep - 1);
    let resp_lines = &rest[1..];
    let section_text = |ls: &[(usize, &str)]| -> String {
        let mut s = ls.iter().map(|(_, l)| *l).collect::<Vec<_>>().join("\n");
        if !ls.is_empty() {
            s.push('\n');
        }
        s
    };
    let request = parse_section(
        &ctx,
        &format!("{name}_Request"),
        req_lines,
        section_text(req_lines),
    )?;
    let response = parse_section(
        &ctx,
        &format!("{name}_Response"),
        resp_lines,
        section_text(resp_lines),
    )?;
    Ok(ServiceSpec {
        package: package.to_string(),
        name: name.to_string(),
        doc: request.doc.clone(),
        request,
        response,
    })
}
