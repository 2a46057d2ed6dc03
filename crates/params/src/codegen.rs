//! Typed parameter structs from the graph file, as `msgs/codegen` makes message types from
//! `.msg` files: one struct per owner (the run, each node, stand-in and server), one field
//! per declared parameter, its Rust type that of the TOML default. Used by this crate's
//! build script, so a parameter added to launch_scripts/graph.toml is a field everywhere,
//! and a default of another type (`1` for `1.0`) is a compile error where the field is
//! used, not a panic at run time.

use std::fmt::Write as _;

/// A parameter's type as its TOML default gives it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FieldType {
    /// `true` / `false`.
    Bool,
    /// A whole number.
    Integer,
    /// A number with a point or exponent.
    Double,
    /// Text.
    String,
    /// A list of texts (also the empty list).
    StringArray,
}

impl FieldType {
    fn of(value: &toml::Value, place: &str) -> Result<Self, String> {
        Ok(match value {
            toml::Value::Boolean(_) => Self::Bool,
            toml::Value::Integer(_) => Self::Integer,
            toml::Value::Float(_) => Self::Double,
            toml::Value::String(_) => Self::String,
            toml::Value::Array(items) if items.iter().all(|i| i.is_str()) => Self::StringArray,
            other => {
                return Err(format!(
                    "{place}: default {other:?} has no parameter type (expected a bool, integer, float, string or list of strings)"
                ));
            }
        })
    }

    fn rust(self) -> &'static str {
        match self {
            Self::Bool => "bool",
            Self::Integer => "i64",
            Self::Double => "f64",
            Self::String => "String",
            Self::StringArray => "Vec<String>",
        }
    }

    fn kind(self) -> &'static str {
        match self {
            Self::Bool => "Bool",
            Self::Integer => "Integer",
            Self::Double => "Double",
            Self::String => "String",
            Self::StringArray => "StringArray",
        }
    }

    fn literal(self, value: &toml::Value) -> String {
        match (self, value) {
            (Self::Double, toml::Value::Float(v)) => format!("{v:?}_f64"),
            (Self::String, toml::Value::String(v)) => format!("{v:?}.to_owned()"),
            (Self::StringArray, toml::Value::Array(items)) => {
                let items: Vec<String> = items
                    .iter()
                    .filter_map(|i| i.as_str().map(|s| format!("{s:?}.to_owned()")))
                    .collect();
                format!("vec![{}]", items.join(", "))
            }
            (_, toml::Value::Integer(v)) => format!("{v}_i64"),
            (_, toml::Value::Boolean(v)) => v.to_string(),
            (_, other) => format!("compile_error!({:?})", format!("{other:?}")),
        }
    }
}

/// One declared parameter.
#[derive(Debug, Clone)]
pub struct Field {
    /// Name as given after `-p`, and the field's name.
    pub name: String,
    /// Its type.
    pub ty: FieldType,
    default: toml::Value,
    description: String,
}

/// The parameters of one owner.
#[derive(Debug, Clone)]
pub struct Owner {
    /// "" for the run's parameters, else the node's name.
    pub node: String,
    /// The module of its parameters' modules (`run`, `recorder`, …): the node's name
    /// without `causal_arm_`.
    pub module: String,
    /// The struct's name, from the module's (`RunParams`, `RecorderParams`, …).
    pub type_name: String,
    /// Whether the node also takes the run's parameters (run nodes and stand-ins).
    pub takes_run: bool,
    /// Its own parameters, in file order.
    pub fields: Vec<Field>,
}

/// Rust keywords a parameter cannot be named (the field and module would not compile).
const KEYWORDS: &[&str] = &[
    "as", "break", "const", "continue", "crate", "else", "enum", "extern", "false", "fn", "for",
    "if", "impl", "in", "let", "loop", "match", "mod", "move", "mut", "pub", "ref", "return",
    "self", "static", "struct", "super", "trait", "true", "type", "unsafe", "use", "where",
    "while", "async", "await", "dyn", "gen", "try",
];

/// Reads every owner's declarations from the graph file's text.
pub fn owners(text: &str) -> Result<Vec<Owner>, String> {
    let table: toml::Table = text.parse().map_err(|e| format!("{e}"))?;
    let mut owners = vec![owner("", "run", false, table.get("run_params"))?];
    for (section, takes_run) in [("nodes", true), ("stand_ins", true), ("servers", false)] {
        let nodes = table.get(section).and_then(|v| v.as_array());
        for node in nodes.into_iter().flatten() {
            let name = node
                .get("name")
                .and_then(|v| v.as_str())
                .unwrap_or_default();
            let module = name.strip_prefix("causal_arm_").unwrap_or(name);
            owners.push(owner(name, module, takes_run, node.get("params"))?);
        }
    }
    Ok(owners)
}

fn owner(
    node: &str,
    module: &str,
    takes_run: bool,
    params: Option<&toml::Value>,
) -> Result<Owner, String> {
    let mut fields = Vec::new();
    for param in params.and_then(|v| v.as_array()).into_iter().flatten() {
        let name = param
            .get("name")
            .and_then(|v| v.as_str())
            .unwrap_or_default();
        let place = format!(
            "{} parameter {name}",
            if node.is_empty() { "run" } else { node }
        );
        if KEYWORDS.contains(&name) || !is_identifier(name) {
            return Err(format!(
                "{place}: not a usable name (a Rust identifier, no keyword)"
            ));
        }
        let default = param.get("default").ok_or(format!("{place}: no default"))?;
        fields.push(Field {
            name: name.to_owned(),
            ty: FieldType::of(default, &place)?,
            default: default.clone(),
            description: param
                .get("description")
                .and_then(|v| v.as_str())
                .unwrap_or_default()
                .to_owned(),
        });
    }
    Ok(Owner {
        node: node.to_owned(),
        module: module.to_owned(),
        type_name: format!("{}Params", camel(module)),
        takes_run,
        fields,
    })
}

fn is_identifier(name: &str) -> bool {
    let mut chars = name.chars();
    chars
        .next()
        .is_some_and(|c| c.is_ascii_lowercase() || c == '_')
        && chars.all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_')
}

fn camel(snake: &str) -> String {
    snake
        .split('_')
        .map(|w| {
            let mut c = w.chars();
            c.next()
                .map(|f| f.to_ascii_uppercase().to_string() + c.as_str())
                .unwrap_or_default()
        })
        .collect()
}

/// The Rust source of every owner's struct.
pub fn generate(text: &str) -> Result<String, String> {
    let mut out = String::from(
        "// Generated by crates/params/build.rs from launch_scripts/graph.toml. Do not edit.\n",
    );
    for owner in owners(text)? {
        emit_struct(&mut out, &owner);
        emit_impl(&mut out, &owner);
        emit_field_modules(&mut out, &owner);
    }
    Ok(out)
}

fn emit_struct(out: &mut String, owner: &Owner) {
    let whose = match owner.node.as_str() {
        "" => "The run's parameters, which every node of the graph takes".to_owned(),
        node => format!("The parameters of {node}"),
    };
    let _ = writeln!(
        out,
        "\n/// {whose}, as launch_scripts/graph.toml declares them.\n#[derive(Debug, Clone, PartialEq)]\npub struct {} {{",
        owner.type_name
    );
    for f in &owner.fields {
        let _ = writeln!(
            out,
            "    /// {}\n    pub {}: {},",
            f.description,
            f.name,
            f.ty.rust()
        );
    }
    let _ = writeln!(out, "}}\n\nimpl Default for {} {{", owner.type_name);
    let _ = writeln!(
        out,
        "    /// The defaults of the graph file this program was built with.\n    fn default() -> Self {{\n        Self {{"
    );
    for f in &owner.fields {
        let _ = writeln!(out, "            {}: {},", f.name, f.ty.literal(&f.default));
    }
    let _ = writeln!(out, "        }}\n    }}\n}}");
}

fn emit_impl(out: &mut String, owner: &Owner) {
    let names: Vec<String> = (owner.fields.iter())
        .map(|f| format!("({:?}, crate::ParamKind::{})", f.name, f.ty.kind()))
        .collect();
    let _ = writeln!(out, "\nimpl {} {{", owner.type_name);
    let _ = writeln!(
        out,
        "    /// The node declaring them in the graph file (\"\" for the run's).\n    pub const NODE: &'static str = {:?};",
        owner.node
    );
    let _ = writeln!(
        out,
        "    /// Each parameter's name and type, as this program was built.\n    pub const DECLARED: &'static [(&'static str, crate::ParamKind)] = &[{}];",
        names.join(", ")
    );
    let _ = writeln!(
        out,
        "    /// Whether the node also takes the run's parameters.\n    pub const TAKES_RUN: bool = {};",
        owner.takes_run
    );
    let _ = writeln!(
        out,
        "\n    /// Reads every field from parameters a node resolved (or the defaults).\n    pub fn from_params(params: &crate::Params) -> Result<Self, crate::ParamError> {{\n        Ok(Self {{"
    );
    for f in &owner.fields {
        let _ = writeln!(out, "            {0}: params.typed({0:?})?,", f.name);
    }
    let _ = writeln!(out, "        }})\n    }}");
    let _ = writeln!(
        out,
        "\n    /// `name:=value` for each field, which [`Self::from_params`] reads back unchanged.\n    pub fn to_ros_args(&self) -> Vec<String> {{\n        vec!["
    );
    for f in &owner.fields {
        let _ = writeln!(out, "            crate::ros_arg({0:?}, &self.{0}),", f.name);
    }
    let _ = writeln!(out, "        ]\n    }}");
    let _ = writeln!(
        out,
        "\n    /// The declarations a node announces (with the run's, if it takes them), from the\n    /// graph file in use, checked against the types this program was built with.\n    pub fn specs() -> Result<Vec<crate::ParamSpec>, crate::ParamError> {{\n        crate::declared_specs(Self::NODE, Self::DECLARED, Self::TAKES_RUN)\n    }}\n}}"
    );
}

fn emit_field_modules(out: &mut String, owner: &Owner) {
    let _ = writeln!(
        out,
        "\n/// One module per parameter of [`{}`]: its `--help` default and its one check.\npub mod {} {{",
        owner.type_name, owner.module
    );
    for f in &owner.fields {
        let _ = writeln!(
            out,
            "    /// `{0}`: {1}\n    pub mod {0} {{\n        /// The name after `-p`.\n        pub const NAME: &str = {0:?};\n        /// The default in the graph file in use, as text (a command-line option's default).\n        pub fn default_text() -> &'static str {{\n            causal_arm_protocol::graph::default_text({2:?}, NAME)\n        }}\n        /// Its declaration in the graph file in use (default, range, choices).\n        pub fn spec() -> Result<crate::ParamSpec, crate::ParamError> {{\n            crate::declared_spec({2:?}, NAME)\n        }}\n        /// Parses and checks `raw` as the node does: the verdict of the CLI and the node alike.\n        pub fn parse(raw: &str) -> Result<{3}, crate::ParamError> {{\n            crate::parse_declared({2:?}, NAME, raw)\n        }}\n    }}",
            f.name,
            f.description.replace('\n', " "),
            owner.node,
            f.ty.rust()
        );
    }
    let _ = writeln!(out, "}}");
}
