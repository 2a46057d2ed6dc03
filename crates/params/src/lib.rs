//! Node parameters, declared once and checked once.
//!
//! `launch_scripts/graph.toml` declares every parameter; the build makes one typed struct
//! per owner from it ([`RunParams`], [`TrainerParams`], …: [`declared`]), so a node, the
//! CLI and a library read the same fields, and a parameter added to the file is a field
//! everywhere. Values given on the command line (`--ros-args -p name:=value`) are parsed
//! as YAML-like scalars and checked against the declared type and range by
//! [`ParamSpec::parse`], the one verdict on a value: `-p steps:=ten` or a misspelt name
//! stops the node with a message naming the parameter, and a command-line option of the
//! same setting gets the same words. No DDS here: the node plumbing announces these
//! declarations over ROS 2 (`causal_arm_node::params`).

#[cfg(test)]
mod codegen;
pub mod declared;

pub use declared::*;

use std::collections::BTreeMap;
use std::fmt;

use causal_arm_protocol::graph::GraphError;
use causal_arm_protocol::{ParamDecl, ParamDefault};
use thiserror::Error;

/// Type of a declared parameter (the ROS 2 parameter types the project uses).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ParamKind {
    /// `true` / `false`.
    Bool,
    /// 64-bit signed integer.
    Integer,
    /// 64-bit float; integer literals are accepted and widened.
    Double,
    /// Free text.
    String,
    /// `[1.0, 2.0]`.
    DoubleArray,
    /// `[a, "b c"]`; a bare value is a one-element array.
    StringArray,
}

impl fmt::Display for ParamKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ParamKind::Bool => "bool",
            ParamKind::Integer => "integer",
            ParamKind::Double => "double",
            ParamKind::String => "string",
            ParamKind::DoubleArray => "double array",
            ParamKind::StringArray => "string array",
        })
    }
}

/// A typed parameter value.
#[derive(Debug, Clone, PartialEq)]
pub enum ParamValue {
    /// See [`ParamKind::Bool`].
    Bool(bool),
    /// See [`ParamKind::Integer`].
    Integer(i64),
    /// See [`ParamKind::Double`].
    Double(f64),
    /// See [`ParamKind::String`].
    String(String),
    /// See [`ParamKind::DoubleArray`].
    DoubleArray(Vec<f64>),
    /// See [`ParamKind::StringArray`].
    StringArray(Vec<String>),
}

impl ParamValue {
    /// The kind of this value.
    pub fn kind(&self) -> ParamKind {
        match self {
            ParamValue::Bool(_) => ParamKind::Bool,
            ParamValue::Integer(_) => ParamKind::Integer,
            ParamValue::Double(_) => ParamKind::Double,
            ParamValue::String(_) => ParamKind::String,
            ParamValue::DoubleArray(_) => ParamKind::DoubleArray,
            ParamValue::StringArray(_) => ParamKind::StringArray,
        }
    }
}

impl fmt::Display for ParamValue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParamValue::Bool(v) => write!(f, "{v}"),
            ParamValue::Integer(v) => write!(f, "{v}"),
            ParamValue::Double(v) => write!(f, "{v}"),
            ParamValue::String(v) => write!(f, "{v:?}"),
            ParamValue::DoubleArray(v) => write!(f, "{v:?}"),
            ParamValue::StringArray(v) => write!(f, "{v:?}"),
        }
    }
}

/// Declaration of one node parameter.
#[derive(Debug, Clone)]
pub struct ParamSpec {
    /// Name as given after `-p`.
    pub name: &'static str,
    /// Value used when the command line does not set it; also fixes the type.
    pub default: ParamValue,
    /// One line for `--help`-style listings and error messages.
    pub description: &'static str,
    /// Inclusive numeric range for integer and double parameters.
    pub range: Option<(f64, f64)>,
    /// The values a string parameter takes, for `ros2 param describe` (the node's own
    /// parsing refuses others, naming them); empty for any.
    pub choices: Vec<String>,
}

impl ParamSpec {
    /// A parameter without a range.
    pub fn new(name: &'static str, default: ParamValue, description: &'static str) -> Self {
        Self {
            name,
            default,
            description,
            range: None,
            choices: Vec::new(),
        }
    }

    /// Restricts an integer or double parameter to `[min, max]`.
    pub fn with_range(mut self, min: f64, max: f64) -> Self {
        self.range = Some((min, max));
        self
    }

    /// Parses and checks a raw value (`-p name:=raw`) as the node does: the one verdict
    /// on a parameter's value, for the node and for a command-line option alike.
    pub fn parse(&self, raw: &str) -> Result<ParamValue, ParamError> {
        parse_value(self, raw)
    }

    /// The range error for `value`; an integer parameter's bounds as the int64 bounds its
    /// descriptor declares (2⁶³ − 1, not the f64 2⁶³).
    fn out_of_range(&self, value: String) -> ParamError {
        let (min, max) = self.range.unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
        let (min, max) = match self.default {
            ParamValue::Integer(_) => (
                (min.ceil().max(i64::MIN as f64) as i64).to_string(),
                (max.floor().min(i64::MAX as f64) as i64).to_string(),
            ),
            _ => (min.to_string(), max.to_string()),
        };
        ParamError::OutOfRange {
            name: self.name.to_owned(),
            value,
            min,
            max,
        }
    }

    /// Names the values a string parameter takes.
    pub fn with_choices(mut self, choices: impl IntoIterator<Item = impl Into<String>>) -> Self {
        self.choices = choices.into_iter().map(Into::into).collect();
        self
    }
}

impl From<&'static ParamDecl> for ParamSpec {
    /// A declaration of the graph file (launch_scripts/graph.toml), as a node declares it.
    fn from(decl: &'static ParamDecl) -> Self {
        let default = match &decl.default {
            ParamDefault::Bool(v) => ParamValue::Bool(*v),
            ParamDefault::Integer(v) => ParamValue::Integer(*v),
            ParamDefault::Double(v) => ParamValue::Double(*v),
            ParamDefault::String(v) => ParamValue::String(v.clone()),
            ParamDefault::StringArray(v) => ParamValue::StringArray(v.clone()),
        };
        let spec = Self::new(&decl.name, default, &decl.description).with_choices(&decl.choices);
        match decl.range {
            Some([lo, hi]) => spec.with_range(lo, hi),
            None => spec,
        }
    }
}

/// Every node has `use_sim_time`, as in ROS 2.
pub fn use_sim_time_spec() -> ParamSpec {
    ParamSpec::new(
        "use_sim_time",
        ParamValue::Bool(false),
        "take time from /clock instead of the wall clock",
    )
}

/// Why command-line arguments or parameters were rejected.
#[derive(Debug, Error, PartialEq)]
pub enum ParamError {
    /// `-p` names a parameter the node does not declare.
    #[error("unknown parameter {name:?} for node {node}; declared parameters: {known}")]
    Unknown {
        /// Parameter name as given.
        name: String,
        /// Node that rejected it.
        node: String,
        /// Comma-separated declared names.
        known: String,
    },
    /// The value does not parse as the declared type.
    #[error("parameter {name:?}: expected {expected}, got {got:?}")]
    WrongType {
        /// Parameter name.
        name: String,
        /// Declared type.
        expected: ParamKind,
        /// Raw value from the command line.
        got: String,
    },
    /// The value is outside the declared range.
    #[error("parameter {name:?} = {value} is outside its range [{min}, {max}]")]
    OutOfRange {
        /// Parameter name.
        name: String,
        /// The value as given (an integer beyond int64 has no other form).
        value: String,
        /// Lower bound (an integer parameter's as an integer).
        min: String,
        /// Upper bound.
        max: String,
    },
    /// The graph file in use cannot be read, or declares what this program was not
    /// built with.
    #[error(transparent)]
    Graph(#[from] GraphError),
    /// A parameter read under another type or name than declared (a programming error
    /// or a graph file given at run time).
    #[error("parameter {name:?} {problem}")]
    Declared {
        /// Parameter name.
        name: String,
        /// What is wrong.
        problem: String,
    },
    /// A `--ros-args` item is malformed or not supported.
    #[error("invalid --ros-args: {0}")]
    Syntax(String),
}

/// What `--ros-args … [--]` asked for.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RosArgs {
    /// `-p name:=value`, in order, raw.
    pub params: Vec<(String, String)>,
    /// `-r __node:=name`.
    pub node_name: Option<String>,
    /// `-r __ns:=/namespace`.
    pub namespace: Option<String>,
    /// `-r from:=to` topic remappings other than `__node`/`__ns`.
    pub remaps: Vec<(String, String)>,
    /// `--log-level LEVEL`.
    pub log_level: Option<String>,
    /// `-e/--enclave /NAME`: the keystore enclave used when security is enabled.
    pub enclave: Option<String>,
}

impl RosArgs {
    /// Splits `args` into the ROS part and the rest (the program's own arguments),
    /// following rcl: everything between `--ros-args` and `--` (or the end) is ROS's.
    pub fn split(args: &[String]) -> Result<(RosArgs, Vec<String>), ParamError> {
        let mut ros = RosArgs::default();
        let mut rest = Vec::new();
        let mut iter = args.iter();
        while let Some(arg) = iter.next() {
            if arg != "--ros-args" {
                rest.push(arg.clone());
                continue;
            }
            while let Some(item) = iter.next() {
                let mut value_of = |flag: &str| {
                    iter.next()
                        .cloned()
                        .ok_or_else(|| ParamError::Syntax(format!("{flag} needs a value")))
                };
                match item.as_str() {
                    "--" => break,
                    "--ros-args" => {}
                    "-p" | "--param" => {
                        let pair = value_of(item)?;
                        ros.params.push(split_assignment(&pair, item)?);
                    }
                    "-r" | "--remap" => {
                        let (from, to) = split_assignment(&value_of(item)?, item)?;
                        if to.is_empty() {
                            return Err(ParamError::Syntax(format!(
                                "{item} {from}:= needs a name after :="
                            )));
                        }
                        match from.as_str() {
                            "__node" | "__name" => ros.node_name = Some(to),
                            "__ns" => ros.namespace = Some(to),
                            _ => ros.remaps.push((from, to)),
                        }
                    }
                    "--log-level" => ros.log_level = Some(value_of(item)?),
                    "-e" | "--enclave" => ros.enclave = Some(value_of(item)?),
                    other => {
                        return Err(ParamError::Syntax(format!(
                            "unsupported item {other:?} (supported: -p/--param NAME:=VALUE, -r/--remap FROM:=TO, --log-level LEVEL, -e/--enclave NAME)"
                        )));
                    }
                }
            }
        }
        Ok((ros, rest))
    }
}

fn split_assignment(pair: &str, flag: &str) -> Result<(String, String), ParamError> {
    match pair.split_once(":=") {
        Some((name, value)) if !name.is_empty() => Ok((name.to_owned(), value.to_owned())),
        _ => Err(ParamError::Syntax(format!(
            "{flag} expects NAME:=VALUE, got {pair:?}"
        ))),
    }
}

/// The validated parameters of one node.
#[derive(Debug, Clone)]
pub struct Params {
    values: BTreeMap<&'static str, ParamValue>,
}

impl Params {
    /// Applies `overrides` (name, raw value) to the declared `specs`; `use_sim_time` is
    /// declared implicitly.
    pub fn resolve(
        node: &str,
        specs: &[ParamSpec],
        overrides: &[(String, String)],
    ) -> Result<Self, ParamError> {
        let mut all: Vec<ParamSpec> = specs.to_vec();
        if !all.iter().any(|s| s.name == "use_sim_time") {
            all.push(use_sim_time_spec());
        }
        let mut values: BTreeMap<&'static str, ParamValue> =
            all.iter().map(|s| (s.name, s.default.clone())).collect();
        for (name, raw) in overrides {
            let Some(spec) = all.iter().find(|s| s.name == name) else {
                return Err(ParamError::Unknown {
                    name: name.clone(),
                    node: node.to_owned(),
                    known: all.iter().map(|s| s.name).collect::<Vec<_>>().join(", "),
                });
            };
            values.insert(spec.name, parse_value(spec, raw)?);
        }
        Ok(Self { values })
    }

    /// All values, by name.
    pub fn iter(&self) -> impl Iterator<Item = (&'static str, &ParamValue)> {
        self.values.iter().map(|(k, v)| (*k, v))
    }

    /// The value of `name`, if declared.
    pub fn value(&self, name: &str) -> Option<&ParamValue> {
        self.values.get(name)
    }

    fn get(&self, name: &str) -> &ParamValue {
        self.values
            .get(name)
            .unwrap_or_else(|| panic!("parameter {name:?} was never declared (programming error)"))
    }

    /// A declared bool parameter. Panics only on a programming error (undeclared or
    /// differently typed name), never on user input, which [`Params::resolve`] validated.
    pub fn bool(&self, name: &str) -> bool {
        match self.get(name) {
            ParamValue::Bool(v) => *v,
            other => panic!("parameter {name:?} is {}, not bool", other.kind()),
        }
    }

    /// A declared integer parameter (see [`Params::bool`] on panics).
    pub fn integer(&self, name: &str) -> i64 {
        match self.get(name) {
            ParamValue::Integer(v) => *v,
            other => panic!("parameter {name:?} is {}, not integer", other.kind()),
        }
    }

    /// A declared double parameter (see [`Params::bool`] on panics).
    pub fn double(&self, name: &str) -> f64 {
        match self.get(name) {
            ParamValue::Double(v) => *v,
            other => panic!("parameter {name:?} is {}, not double", other.kind()),
        }
    }

    /// A declared string parameter (see [`Params::bool`] on panics).
    pub fn string(&self, name: &str) -> &str {
        match self.get(name) {
            ParamValue::String(v) => v,
            other => panic!("parameter {name:?} is {}, not string", other.kind()),
        }
    }

    /// A declared double-array parameter (see [`Params::bool`] on panics).
    pub fn double_array(&self, name: &str) -> &[f64] {
        match self.get(name) {
            ParamValue::DoubleArray(v) => v,
            other => panic!("parameter {name:?} is {}, not double array", other.kind()),
        }
    }

    /// A declared string-array parameter (see [`Params::bool`] on panics).
    pub fn string_array(&self, name: &str) -> &[String] {
        match self.get(name) {
            ParamValue::StringArray(v) => v,
            other => panic!("parameter {name:?} is {}, not string array", other.kind()),
        }
    }

    /// Whether the node runs on simulated time.
    pub fn use_sim_time(&self) -> bool {
        self.bool("use_sim_time")
    }
}

fn parse_value(spec: &ParamSpec, raw: &str) -> Result<ParamValue, ParamError> {
    let expected = spec.default.kind();
    let wrong = || ParamError::WrongType {
        name: spec.name.to_owned(),
        expected,
        got: raw.to_owned(),
    };
    let text = raw.trim();
    let value = match expected {
        ParamKind::Bool => match text.to_ascii_lowercase().as_str() {
            "true" => ParamValue::Bool(true),
            "false" => ParamValue::Bool(false),
            _ => return Err(wrong()),
        },
        ParamKind::Integer => match text.parse() {
            Ok(v) => ParamValue::Integer(v),
            // An integer beyond int64 (a u64 seed) is out of any range, not of the wrong type.
            Err(_) if text.parse::<i128>().is_ok() => {
                return Err(spec.out_of_range(text.to_owned()));
            }
            Err(_) => return Err(wrong()),
        },
        ParamKind::Double => ParamValue::Double(parse_finite(text).ok_or_else(wrong)?),
        ParamKind::String => ParamValue::String(unquote(text).to_owned()),
        ParamKind::DoubleArray => {
            let inner = text
                .strip_prefix('[')
                .and_then(|t| t.strip_suffix(']'))
                .ok_or_else(wrong)?;
            let items: Option<Vec<f64>> = if inner.trim().is_empty() {
                Some(Vec::new())
            } else {
                inner.split(',').map(|t| parse_finite(t.trim())).collect()
            };
            ParamValue::DoubleArray(items.ok_or_else(wrong)?)
        }
        ParamKind::StringArray => match text.strip_prefix('[').and_then(|t| t.strip_suffix(']')) {
            Some(inner) if inner.trim().is_empty() => ParamValue::StringArray(Vec::new()),
            Some(inner) => ParamValue::StringArray(
                inner
                    .split(',')
                    .map(|t| unquote(t.trim()).to_owned())
                    .collect(),
            ),
            None if text.is_empty() => ParamValue::StringArray(Vec::new()),
            None => ParamValue::StringArray(vec![unquote(text).to_owned()]),
        },
    };
    if let Some((min, max)) = spec.range {
        let numbers: Vec<f64> = match &value {
            ParamValue::Integer(v) => vec![*v as f64],
            ParamValue::Double(v) => vec![*v],
            ParamValue::DoubleArray(v) => v.clone(),
            _ => Vec::new(),
        };
        if let Some(bad) = numbers.into_iter().find(|v| *v < min || *v > max) {
            return Err(spec.out_of_range(bad.to_string()));
        }
    }
    Ok(value)
}

fn parse_finite(text: &str) -> Option<f64> {
    text.parse::<f64>().ok().filter(|v| v.is_finite())
}

fn unquote(text: &str) -> &str {
    for q in ['"', '\''] {
        if let Some(inner) = text.strip_prefix(q).and_then(|t| t.strip_suffix(q)) {
            return inner;
        }
    }
    text
}

#[cfg(test)]
mod tests;
