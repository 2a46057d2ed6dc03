//! The graph file's parameters as typed structs (generated at build time by
//! `codegen.rs`), and the few functions the generated code calls: a typed read of a
//! resolved parameter, its `-p` rendering, the declarations a node announces, and the one
//! check of a raw value.

use causal_arm_protocol::graph::{GraphError, graph};
use causal_arm_protocol::{NodeDecl, ParamDecl};

use crate::{ParamError, ParamKind, ParamSpec, ParamValue, Params};

include!(concat!(env!("OUT_DIR"), "/declared.rs"));

/// A Rust type a parameter of one [`ParamKind`] is read as.
pub trait Typed: Sized {
    /// The kind it is read from.
    const KIND: ParamKind;
    /// The value, if `value` is of [`Self::KIND`].
    fn from_value(value: &ParamValue) -> Option<Self>;
    /// The value back, as [`ParamSpec::parse`] reads it from `-p name:=TEXT`.
    fn to_text(&self) -> String;
}

macro_rules! typed {
    ($ty:ty, $kind:ident, |$v:ident| $text:expr) => {
        impl Typed for $ty {
            const KIND: ParamKind = ParamKind::$kind;
            fn from_value(value: &ParamValue) -> Option<Self> {
                match value {
                    ParamValue::$kind(v) => Some(v.clone()),
                    _ => None,
                }
            }
            fn to_text(&self) -> String {
                let $v = self;
                $text
            }
        }
    };
}

typed!(bool, Bool, |v| v.to_string());
typed!(i64, Integer, |v| v.to_string());
typed!(f64, Double, |v| format!("{v:?}"));
typed!(String, String, |v| v.clone());
typed!(Vec<String>, StringArray, |v| format!("[{}]", v.join(", ")));
typed!(Vec<f64>, DoubleArray, |v| format!("{v:?}"));

impl Params {
    /// Parameter `name` as `T`; an error (not a panic) if it was declared as another type,
    /// which only a graph file given at run time (`CAUSAL_ARM_GRAPH`) can do.
    pub fn typed<T: Typed>(&self, name: &str) -> Result<T, ParamError> {
        let value = self.value(name).ok_or_else(|| ParamError::Declared {
            name: name.to_owned(),
            problem: "is not declared".into(),
        })?;
        read_as(name, value)
    }
}

/// `value` of parameter `name` as `T`, or why not (it was declared as another type).
fn read_as<T: Typed>(name: &str, value: &ParamValue) -> Result<T, ParamError> {
    T::from_value(value).ok_or_else(|| ParamError::Declared {
        name: name.to_owned(),
        problem: format!(
            "is declared {}, but this program reads a {}",
            value.kind(),
            T::KIND
        ),
    })
}

/// A fault of the graph file in use (which has loaded, or this is not reached).
fn graph_error(problem: String) -> ParamError {
    let source_name = graph().map_or_else(|e| e.source_name, |g| g.source_name().to_owned());
    ParamError::Graph(GraphError {
        source_name,
        problem,
    })
}

/// `name:=value`, as the launcher passes a parameter after `-p`.
pub fn ros_arg<T: Typed>(name: &str, value: &T) -> String {
    format!("{name}:={}", value.to_text())
}

/// The parameter declarations of `node` ("" for the run's alone) in the graph file in use,
/// the run's first if `takes_run`, each checked against the name and type this program was
/// built with: a graph file given at run time that lacks one, adds one or changes a type
/// is refused here, naming the parameter, instead of failing when it is read.
pub fn declared_specs(
    node: &str,
    declared: &[(&str, ParamKind)],
    takes_run: bool,
) -> Result<Vec<ParamSpec>, ParamError> {
    let own = decls_of(node)?;
    let mut specs: Vec<ParamSpec> = match takes_run {
        true => RunParams::specs()?,
        false => Vec::new(),
    };
    if own.len() != declared.len() {
        let names = |d: &[&str]| d.join(", ");
        return Err(graph_error(format!(
            "{} declares parameters [{}]; this program was built with [{}]",
            owner_name(node),
            names(&own.iter().map(|p| p.name.as_str()).collect::<Vec<_>>()),
            names(&declared.iter().map(|(n, _)| *n).collect::<Vec<_>>())
        )));
    }
    for (decl, (name, kind)) in own.iter().zip(declared) {
        let spec = ParamSpec::from(decl);
        if decl.name != *name || spec.default.kind() != *kind {
            return Err(graph_error(format!(
                "{} parameter {}: default of type {}; this program was built with {name} of type {kind}",
                owner_name(node),
                decl.name,
                spec.default.kind()
            )));
        }
        specs.push(spec);
    }
    Ok(specs)
}

/// The declaration of parameter `name` of `node` ("" for a run parameter) in the graph
/// file in use: its default, range and choices.
pub fn declared_spec(node: &str, name: &str) -> Result<ParamSpec, ParamError> {
    let decl = decls_of(node)?
        .iter()
        .find(|p| p.name == name)
        .ok_or_else(|| ParamError::Declared {
            name: name.to_owned(),
            problem: format!("is not declared for {}", owner_name(node)),
        })?;
    Ok(ParamSpec::from(decl))
}

/// Parses and checks `raw` for parameter `name` of `node` as the node does, so a
/// command-line option and `-p` get the same verdict in the same words.
pub fn parse_declared<T: Typed>(node: &str, name: &str, raw: &str) -> Result<T, ParamError> {
    read_as(name, &declared_spec(node, name)?.parse(raw)?)
}

fn decls_of(node: &str) -> Result<&'static [ParamDecl], ParamError> {
    let graph = graph()?;
    if node.is_empty() {
        return Ok(&graph.run_params);
    }
    let server = || graph.servers.iter().find(|n| n.name == node);
    let decl: &NodeDecl = graph.node(node).or_else(server).ok_or_else(|| {
        graph_error(format!(
            "it declares no node {node}, which this program was built with"
        ))
    })?;
    Ok(&decl.params)
}

fn owner_name(node: &str) -> &str {
    match node {
        "" => "the run",
        node => node,
    }
}
