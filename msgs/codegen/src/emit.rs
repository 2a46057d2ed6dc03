//! Rust emitter: turns parsed interfaces into serde structs whose `cdr-encoding` bytes are the
//! ROS 2 (XCDR1) bytes, plus the registry the runtime crate dispatches on.
//!
//! The emitted code refers to the runtime crate only through `crate::RosMessage`,
//! `crate::RosService`, `crate::MessageTypeVisitor` and `crate::__rt`, so the generated file is
//! meant to be `include!`d at the root of `causal_arm_msgs`.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::fmt::Write as _;

use crate::parse::{ArrayKind, BaseType, Field, FieldType, MessageSpec, ServiceSpec, Value};
use crate::{Error, Interface, TypeIndex};

/// serde implements `Serialize`/`Deserialize`/`Default` for `[T; N]` only up to this N.
const MAX_NATIVE_ARRAY: usize = 32;

const RUST_KEYWORDS: &[&str] = &[
    "as", "break", "const", "continue", "else", "enum", "extern", "false", "fn", "for", "if",
    "impl", "in", "let", "loop", "match", "mod", "move", "mut", "pub", "ref", "return", "static",
    "struct", "trait", "true", "type", "unsafe", "use", "where", "while", "async", "await", "dyn",
    "abstract", "become", "box", "do", "final", "macro", "override", "priv", "typeof", "unsized",
    "virtual", "yield", "try", "gen",
];
/// Keywords that cannot be written as raw identifiers; fields get a trailing `_` plus a serde rename.
const NON_RAW_KEYWORDS: &[&str] = &["self", "super", "crate"];

struct Registry<'a> {
    own: &'a str,
    /// Rust path of the module the generated file is included in (`crate` normally).
    root: &'a str,
    /// `pkg/Name` → message spec (messages only; service halves are never referenced).
    messages: BTreeMap<String, &'a MessageSpec>,
    needs_validation: HashMap<String, bool>,
    /// `pkg/msg/Name`, `pkg/srv/Name(_Request|_Response)` → its RIHS01 type hash.
    type_hashes: BTreeMap<String, String>,
}

fn key(pkg: &str, name: &str) -> String {
    format!("{pkg}/{name}")
}

/// Rust field identifier and, if it differs from the .msg name, the serde rename.
fn field_ident(name: &str) -> (String, bool) {
    if NON_RAW_KEYWORDS.contains(&name) {
        (format!("{name}_"), true)
    } else if RUST_KEYWORDS.contains(&name) {
        (format!("r#{name}"), false)
    } else {
        (name.to_string(), false)
    }
}

fn doc_attr(out: &mut String, indent: &str, lines: &[String]) {
    for l in lines {
        // Escape what rustdoc would read as links or HTML; the text is plain prose from .msg files.
        let mut esc = String::with_capacity(l.len());
        for c in l.chars() {
            if matches!(c, '[' | ']' | '<' | '>') {
                esc.push('\\');
            }
            esc.push(c);
        }
        let text = if esc.is_empty() {
            String::new()
        } else {
            format!(" {esc}")
        };
        let _ = writeln!(out, "{indent}#[doc = {text:?}]");
    }
}

impl<'a> Registry<'a> {
    fn path_of(&self, pkg: &str, name: &str) -> String {
        if pkg == self.own {
            format!("{}::msg::{name}", self.root)
        } else {
            format!("{}::{pkg}::msg::{name}", self.root)
        }
    }

    fn elem_type(&self, base: &BaseType) -> String {
        match base {
            BaseType::Bool => "bool".into(),
            BaseType::Byte | BaseType::Char | BaseType::U8 => "u8".into(),
            BaseType::I8 => "i8".into(),
            BaseType::I16 => "i16".into(),
            BaseType::U16 => "u16".into(),
            BaseType::I32 => "i32".into(),
            BaseType::U32 => "u32".into(),
            BaseType::I64 => "i64".into(),
            BaseType::U64 => "u64".into(),
            BaseType::F32 => "f32".into(),
            BaseType::F64 => "f64".into(),
            BaseType::String { .. } | BaseType::WString { .. } => "::std::string::String".into(),
            BaseType::Named { package, name } => self.path_of(package, name),
        }
    }

    fn field_type(&self, ty: &FieldType) -> String {
        let e = self.elem_type(&ty.base);
        match ty.array {
            ArrayKind::Scalar => e,
            ArrayKind::Fixed(n) if n <= MAX_NATIVE_ARRAY => format!("[{e}; {n}]"),
            _ => format!("::std::vec::Vec<{e}>"),
        }
    }

    fn type_needs_validation(&mut self, k: &str) -> bool {
        if let Some(v) = self.needs_validation.get(k) {
            return *v;
        }
        // Interfaces cannot be recursive (checked in `generate`), so this terminates.
        let spec = self.messages[k];
        let v = spec
            .fields
            .iter()
            .any(|f| self.field_needs_validation(&f.ty));
        self.needs_validation.insert(k.to_string(), v);
        v
    }

    fn elem_needs_validation(&mut self, base: &BaseType) -> bool {
        match base {
            BaseType::String { bound: Some(_) } => true,
            BaseType::Named { package, name } => self.type_needs_validation(&key(package, name)),
            _ => false,
        }
    }

    fn field_needs_validation(&mut self, ty: &FieldType) -> bool {
        matches!(ty.array, ArrayKind::Bounded(_))
            || matches!(ty.array, ArrayKind::Fixed(n) if n > MAX_NATIVE_ARRAY)
            || self.elem_needs_validation(&ty.base)
    }

    fn elem_check(&mut self, base: &BaseType, expr: &str, label: &str, label_args: &str) -> String {
        match base {
            BaseType::String { bound: Some(b) } => format!(
                "if {expr}.len() > {b} {{ return ::std::result::Result::Err(format!(\"{label}: string of {{}} bytes exceeds its bound {b}\"{label_args}, {expr}.len())); }}\n"
            ),
            BaseType::Named { package, name }
                if self.type_needs_validation(&key(package, name)) =>
            {
                format!(
                    "crate::RosMessage::validate({amp}{expr}).map_err(|m| format!(\"{label}.{{m}}\"{label_args}))?;\n",
                    amp = if expr.starts_with("self.") { "&" } else { "" }
                )
            }
            _ => String::new(),
        }
    }

    fn validate_body(&mut self, fields: &[Field]) -> String {
        let mut body = String::new();
        for f in fields {
            let (ident, _) = field_ident(&f.name);
            let acc = format!("self.{ident}");
            let name = &f.name;
            match f.ty.array {
                ArrayKind::Bounded(b) => {
                    let _ = writeln!(
                        body,
                        "if {acc}.len() > {b} {{ return ::std::result::Result::Err(format!(\"{name}: {{}} elements exceed its bound {b}\", {acc}.len())); }}"
                    );
                }
                ArrayKind::Fixed(n) if n > MAX_NATIVE_ARRAY => {
                    let _ = writeln!(
                        body,
                        "if {acc}.len() != {n} {{ return ::std::result::Result::Err(format!(\"{name}: {{}} elements, the array has exactly {n}\", {acc}.len())); }}"
                    );
                }
                _ => {}
            }
            if f.ty.array == ArrayKind::Scalar {
                body += &self.elem_check(&f.ty.base, &acc, name, "");
            } else if self.elem_needs_validation(&f.ty.base) {
                let inner = self.elem_check(&f.ty.base, "e", &format!("{name}[{{}}]"), ", i");
                let _ = writeln!(body, "for (i, e) in {acc}.iter().enumerate() {{\n{inner}}}");
            }
        }
        body
    }

    fn literal(&self, base: &BaseType, v: &Value) -> String {
        let ty = self.elem_type(base);
        match v {
            Value::Bool(b) => b.to_string(),
            Value::Int(i) => format!("{i}_{ty}"),
            Value::Float(x) if x.is_nan() => format!("{ty}::NAN"),
            Value::Float(x) if x.is_infinite() => {
                format!(
                    "{ty}::{}",
                    if *x > 0.0 { "INFINITY" } else { "NEG_INFINITY" }
                )
            }
            Value::Float(x) => format!("{x:?}_{ty}"),
            Value::Str(s) => format!("::std::string::String::from({s:?})"),
            Value::Array(_) => unreachable!("nested array literal"),
        }
    }

    fn default_expr(&self, f: &Field) -> String {
        match (&f.default, f.ty.array) {
            (Some(Value::Array(items)), arr) => {
                let items: Vec<String> =
                    items.iter().map(|v| self.literal(&f.ty.base, v)).collect();
                match arr {
                    ArrayKind::Fixed(n) if n <= MAX_NATIVE_ARRAY => {
                        format!("[{}]", items.join(", "))
                    }
                    _ => format!("vec![{}]", items.join(", ")),
                }
            }
            (Some(v), _) => self.literal(&f.ty.base, v),
            (None, ArrayKind::Fixed(n)) if n > MAX_NATIVE_ARRAY => {
                format!("vec![<{}>::default(); {n}]", self.elem_type(&f.ty.base))
            }
            (None, _) => "::std::default::Default::default()".into(),
        }
    }

    /// Full `ros2msg` definition as rosbag2's LocalMessageDefinitionSource builds it: own text,
    /// then each dependency once, depth first, dependencies of one type in sorted order.
    fn full_definition(&self, spec: &MessageSpec) -> String {
        fn deps(spec: &MessageSpec) -> BTreeSet<String> {
            spec.fields
                .iter()
                .filter_map(|f| match &f.ty.base {
                    BaseType::Named { package, name } => Some(key(package, name)),
                    _ => None,
                })
                .collect()
        }
        fn rec(
            reg: &Registry<'_>,
            spec: &MessageSpec,
            seen: &mut BTreeSet<String>,
            out: &mut String,
        ) {
            out.push_str(&spec.text);
            for d in deps(spec) {
                if seen.insert(d.clone()) {
                    out.push('\n');
                    out.push_str(&"=".repeat(80));
                    out.push('\n');
                    let _ = writeln!(out, "MSG: {d}");
                    rec(reg, reg.messages[&d], seen, out);
                }
            }
        }
        let mut out = String::new();
        rec(self, spec, &mut BTreeSet::new(), &mut out);
        out
    }

    fn emit_struct(&mut self, out: &mut String, spec: &MessageSpec, kind: &str, doc_head: &str) {
        let name = &spec.name;
        let pkg = &spec.package;
        let ros_type = format!("{pkg}/{kind}/{name}");
        let mut doc = vec![doc_head.to_string()];
        if !spec.doc.is_empty() {
            doc.push(String::new());
            doc.extend(spec.doc.iter().cloned());
        }
        doc_attr(out, "", &doc);
        let derivable = spec.fields.iter().all(|f| {
            f.default.is_none()
                && !matches!(f.ty.array, ArrayKind::Fixed(n) if n > MAX_NATIVE_ARRAY)
        });
        let _ = writeln!(
            out,
            "#[derive(Debug, Clone, PartialEq, {}serde::Serialize, serde::Deserialize)]",
            if derivable { "Default, " } else { "" }
        );
        out.push_str("#[serde(default, deny_unknown_fields)]\n");
        if name.contains('_') {
            out.push_str("#[allow(non_camel_case_types)]\n");
        }
        let _ = writeln!(out, "pub struct {name} {{");
        let mut fields = spec.fields.clone();
        if fields.is_empty() {
            // rosidl adds this member to empty structures; the wire carries one octet.
            fields.push(Field {
                name: "structure_needs_at_least_one_member".into(),
                ty: FieldType {
                    base: BaseType::U8,
                    array: ArrayKind::Scalar,
                },
                default: None,
                doc: vec![
                    "Placeholder that rosidl adds to empty structures (one octet on the wire)."
                        .into(),
                ],
                line: 0,
            });
        }
        self.emit_fields(out, &fields, &ros_type);
        if !derivable {
            self.emit_default(out, name, &fields);
        }
        self.emit_constants(out, spec, &ros_type);
        self.emit_message_impl(out, spec, kind, &fields);
    }

    /// The struct's fields with their docs and serde attributes, and its closing brace.
    fn emit_fields(&mut self, out: &mut String, fields: &[Field], ros_type: &str) {
        for f in fields {
            let mut fdoc = f.doc.clone();
            if fdoc.is_empty() {
                fdoc.push(format!(
                    "`{}` field `{}` (undocumented in the .msg).",
                    ros_type, f.name
                ));
            }
            doc_attr(out, "    ", &fdoc);
            let (ident, renamed) = field_ident(&f.name);
            if renamed {
                let _ = writeln!(out, "    #[serde(rename = {:?})]", f.name);
            }
            if let ArrayKind::Fixed(n) = f.ty.array
                && n > MAX_NATIVE_ARRAY
            {
                let _ = writeln!(
                    out,
                    "    #[serde(serialize_with = \"crate::__rt::ser_fixed::<_, _, {n}>\", deserialize_with = \"crate::__rt::de_fixed::<_, _, {n}>\")]"
                );
            }
            let _ = writeln!(out, "    pub {ident}: {},", self.field_type(&f.ty));
        }
        out.push_str("}\n\n");
    }

    /// `Default` by hand, for structs with .msg defaults or arrays serde cannot default
    /// (a .msg default may equal the type's own, e.g. `bool read_only false`, hence the
    /// `allow`).
    fn emit_default(&mut self, out: &mut String, name: &str, fields: &[Field]) {
        let _ = writeln!(
            out,
            "#[allow(clippy::derivable_impls)]\nimpl ::std::default::Default for {name} {{\n    fn default() -> Self {{\n        Self {{"
        );
        for f in fields {
            let (ident, _) = field_ident(&f.name);
            let _ = writeln!(out, "            {ident}: {},", self.default_expr(f));
        }
        out.push_str("        }\n    }\n}\n\n");
    }

    /// The .msg's constants as associated consts.
    fn emit_constants(&mut self, out: &mut String, spec: &MessageSpec, ros_type: &str) {
        let name = &spec.name;
        if !spec.constants.is_empty() {
            let _ = writeln!(out, "impl {name} {{");
            for c in &spec.constants {
                let mut cdoc = c.doc.clone();
                if cdoc.is_empty() {
                    cdoc.push(format!("Constant `{}` of `{ros_type}`.", c.name));
                }
                doc_attr(out, "    ", &cdoc);
                let (ty, val) = match (&c.ty, &c.value) {
                    (BaseType::String { .. } | BaseType::WString { .. }, Value::Str(s)) => {
                        ("&'static str".to_string(), format!("{s:?}"))
                    }
                    (b, v) => (self.elem_type(b), self.literal(b, v)),
                };
                let _ = writeln!(out, "    pub const {}: {ty} = {val};", c.name);
            }
            out.push_str("}\n\n");
        }
    }

    /// `RosMessage` (type names, full definition, validation) and ros2-client's `Message`.
    fn emit_message_impl(
        &mut self,
        out: &mut String,
        spec: &MessageSpec,
        kind: &str,
        fields: &[Field],
    ) {
        let name = &spec.name;
        let pkg = &spec.package;
        let ros_type = format!("{pkg}/{kind}/{name}");
        let definition = self.full_definition(spec);
        let _ = writeln!(out, "impl crate::RosMessage for {name} {{");
        let _ = writeln!(out, "    const PACKAGE: &'static str = {pkg:?};");
        let _ = writeln!(out, "    const NAME: &'static str = {name:?};");
        let _ = writeln!(out, "    const ROS_TYPE: &'static str = {ros_type:?};");
        let _ = writeln!(
            out,
            "    const TYPE_HASH: &'static str = {:?};",
            self.type_hashes[&ros_type]
        );
        let _ = writeln!(
            out,
            "    fn dds_type_name() -> ::std::string::String {{\n        ::std::string::String::from({:?})\n    }}",
            format!("{pkg}::{kind}::dds_::{name}_")
        );
        let _ = writeln!(
            out,
            "    fn definition() -> &'static str {{\n        {definition:?}\n    }}"
        );
        let body = self.validate_body(fields);
        if !body.is_empty() {
            let _ = writeln!(
                out,
                "    fn validate(&self) -> ::std::result::Result<(), ::std::string::String> {{\n{body}::std::result::Result::Ok(())\n    }}"
            );
        }
        out.push_str("}\n\n");
        let _ = writeln!(
            out,
            "#[cfg(feature = \"ros2\")]\nimpl ros2_client::Message for {name} {{}}\n"
        );
    }

    fn emit_service(&mut self, out: &mut String, srv: &ServiceSpec) {
        let name = &srv.name;
        let pkg = &srv.package;
        let ros_type = format!("{pkg}/srv/{name}");
        self.emit_struct(
            out,
            &srv.request,
            "srv",
            &format!("Request of service `{ros_type}`."),
        );
        self.emit_struct(
            out,
            &srv.response,
            "srv",
            &format!("Response of service `{ros_type}`."),
        );
        let mut doc = vec![format!(
            "Service `{ros_type}`: a zero-sized marker tying request and response types to the service name."
        )];
        if !srv.doc.is_empty() {
            doc.push(String::new());
            doc.extend(srv.doc.iter().cloned());
        }
        doc_attr(out, "", &doc);
        let _ = writeln!(
            out,
            "#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]\npub struct {name};\n"
        );
        let _ = writeln!(out, "impl crate::RosService for {name} {{");
        let _ = writeln!(
            out,
            "    type Request = {name}_Request;\n    type Response = {name}_Response;"
        );
        let _ = writeln!(out, "    const ROS_TYPE: &'static str = {ros_type:?};");
        let _ = writeln!(
            out,
            "    const TYPE_HASH: &'static str = {:?};",
            self.type_hashes[&ros_type]
        );
        let _ = writeln!(
            out,
            "    fn dds_request_type_name() -> ::std::string::String {{\n        ::std::string::String::from({:?})\n    }}",
            format!("{pkg}::srv::dds_::{name}_Request_")
        );
        let _ = writeln!(
            out,
            "    fn dds_response_type_name() -> ::std::string::String {{\n        ::std::string::String::from({:?})\n    }}",
            format!("{pkg}::srv::dds_::{name}_Response_")
        );
        out.push_str("}\n\n");
    }
}

fn check_references(
    interfaces: &[Interface],
    messages: &BTreeMap<String, &MessageSpec>,
) -> Result<(), Error> {
    for i in interfaces {
        let (file, specs): (&str, Vec<&MessageSpec>) = match i {
            Interface::Message { file, spec } => (file, vec![spec]),
            Interface::Service { file, spec } => (file, vec![&spec.request, &spec.response]),
        };
        for spec in specs {
            for f in &spec.fields {
                if let BaseType::Named { package, name } = &f.ty.base
                    && !messages.contains_key(&key(package, name))
                {
                    return Err(Error::Parse(crate::ParseError {
                        file: file.to_string(),
                        line: f.line,
                        message: format!(
                            "field {}: unknown message type `{package}/{name}` (known: {})",
                            f.name,
                            messages.keys().cloned().collect::<Vec<_>>().join(", ")
                        ),
                    }));
                }
            }
        }
    }
    // Reject recursive definitions (ROS 2 cannot represent them either).
    fn visit(
        k: &str,
        messages: &BTreeMap<String, &MessageSpec>,
        stack: &mut Vec<String>,
        done: &mut BTreeSet<String>,
    ) -> Result<(), Error> {
        if done.contains(k) {
            return Ok(());
        }
        if stack.iter().any(|s| s == k) {
            stack.push(k.to_string());
            return Err(Error::Recursive(stack.join(" -> ")));
        }
        stack.push(k.to_string());
        for f in &messages[k].fields {
            if let BaseType::Named { package, name } = &f.ty.base {
                visit(&key(package, name), messages, stack, done)?;
            }
        }
        stack.pop();
        done.insert(k.to_string());
        Ok(())
    }
    let mut done = BTreeSet::new();
    for k in messages.keys() {
        visit(k, messages, &mut Vec::new(), &mut done)?;
    }
    Ok(())
}

/// Emit the Rust source for all `interfaces`; those of `own_package` go to the crate-root
/// modules `msg` / `srv`, every other package to `<package>::msg`.
pub fn generate(own_package: &str, interfaces: &[Interface]) -> Result<String, Error> {
    generate_at(own_package, interfaces, "crate")
}

/// Like [`generate`], for a file included in module `root` (e.g. `crate::fixture`) instead of
/// the crate root; used to compile test-only interface sets next to the real ones.
pub fn generate_at(
    own_package: &str,
    interfaces: &[Interface],
    root: &str,
) -> Result<String, Error> {
    let messages = index_messages(interfaces)?;
    check_references(interfaces, &messages)?;
    let mut reg = Registry {
        own: own_package,
        root,
        messages,
        needs_validation: HashMap::new(),
        type_hashes: type_hashes(interfaces)?,
    };

    // package → (messages, services), sorted for a stable output.
    let mut by_pkg: BTreeMap<&str, (Vec<&MessageSpec>, Vec<&ServiceSpec>)> = BTreeMap::new();
    for i in interfaces {
        match i {
            Interface::Message { spec, .. } => {
                by_pkg.entry(&spec.package).or_default().0.push(spec)
            }
            Interface::Service { spec, .. } => {
                by_pkg.entry(&spec.package).or_default().1.push(spec)
            }
        }
    }
    let mut out = String::from(
        "// @generated by causal_arm_msgs_codegen from the .msg/.srv files. Do not edit.\n\n",
    );
    let mut tables = TypeTables::default();
    for (pkg, (msgs, srvs)) in &mut by_pkg {
        msgs.sort_by(|a, b| a.name.cmp(&b.name));
        srvs.sort_by(|a, b| a.name.cmp(&b.name));
        reg.emit_package(&mut out, pkg, msgs, srvs, &mut tables);
    }
    tables.emit(&mut out);
    Ok(out)
}

/// The RIHS01 hash of every message, service and service half of `interfaces`.
fn type_hashes(interfaces: &[Interface]) -> Result<BTreeMap<String, String>, Error> {
    let index = TypeIndex::new(interfaces);
    index
        .type_names()
        .map(|name| {
            let hash = index.rihs01(name).map_err(Error::TypeHash)?;
            Ok((name.to_string(), hash))
        })
        .collect()
}

/// Every message by `pkg/msg/Name`; a type declared twice is an error.
fn index_messages(interfaces: &[Interface]) -> Result<BTreeMap<String, &MessageSpec>, Error> {
    let mut messages: BTreeMap<String, &MessageSpec> = BTreeMap::new();
    for i in interfaces {
        let (k, file) = match i {
            Interface::Message { spec, file } => (key(&spec.package, &spec.name), file),
            Interface::Service { spec, file } => {
                (format!("{}/srv/{}", spec.package, spec.name), file)
            }
        };
        let dup = match i {
            Interface::Message { spec, .. } => messages.insert(k.clone(), spec).is_some(),
            Interface::Service { .. } => false,
        };
        if dup {
            return Err(Error::Duplicate {
                ros_type: k,
                file: file.clone(),
            });
        }
    }
    Ok(messages)
}

/// What the generated registry lists: (ROS_TYPE, Rust path) of every message type and
/// service half, and every service type.
#[derive(Default)]
struct TypeTables {
    types: Vec<(String, String)>,
    services: Vec<String>,
}

impl TypeTables {
    /// `MESSAGE_TYPES`, `SERVICE_TYPES`, `dispatch` and `visit_known`.
    fn emit(&self, out: &mut String) {
        out.push_str(
            "/// Every `ROS_TYPE` of the generated message types (service halves included).\n",
        );
        out.push_str("pub(crate) const MESSAGE_TYPES: &[&str] = &[\n");
        for (t, _) in &self.types {
            let _ = writeln!(out, "    {t:?},");
        }
        out.push_str("];\n\n/// Every generated service `ROS_TYPE`.\npub(crate) const SERVICE_TYPES: &[&str] = &[\n");
        for t in &self.services {
            let _ = writeln!(out, "    {t:?},");
        }
        out.push_str("];\n\n");
        out.push_str(
            "/// Call `v.visit::<M>()` for the type whose `ROS_TYPE` is exactly `ros_type`; give `v` back otherwise.\n\
             pub(crate) fn dispatch<V: crate::MessageTypeVisitor>(ros_type: &str, v: V) -> Result<V::Output, V> {\n    match ros_type {\n",
        );
        for (t, path) in &self.types {
            let _ = writeln!(out, "        {t:?} => Ok(v.visit::<{path}>()),");
        }
        out.push_str("        _ => Err(v),\n    }\n}\n\n");
        out.push_str(
            "/// Like `dispatch`, but also accepts the short form `pkg/Name` (message first, then service half).\n\
             pub(crate) fn visit_known<V: crate::MessageTypeVisitor>(ros_type: &str, v: V) -> Option<V::Output> {\n\
             \x20   let v = match dispatch(ros_type, v) {\n\
             \x20       Ok(out) => return Some(out),\n\
             \x20       Err(v) => v,\n\
             \x20   };\n\
             \x20   let (pkg, name) = ros_type.split_once('/')?;\n\
             \x20   if name.contains('/') {\n\
             \x20       return None;\n\
             \x20   }\n\
             \x20   let v = match dispatch(&format!(\"{pkg}/msg/{name}\"), v) {\n\
             \x20       Ok(out) => return Some(out),\n\
             \x20       Err(v) => v,\n\
             \x20   };\n\
             \x20   dispatch(&format!(\"{pkg}/srv/{name}\"), v).ok()\n\
             }\n",
        );
    }
}

impl Registry<'_> {
    /// One package's module: its messages and services, recorded in `tables`.
    fn emit_package(
        &mut self,
        out: &mut String,
        pkg: &str,
        msgs: &[&MessageSpec],
        srvs: &[&ServiceSpec],
        tables: &mut TypeTables,
    ) {
        let own = pkg == self.own;
        let root = self.root;
        if !own {
            doc_attr(
                out,
                "",
                &[format!(
                    "Types of the ROS 2 package `{pkg}` (copied .msg files, Jazzy)."
                )],
            );
            let _ = writeln!(out, "pub mod {pkg} {{");
        }
        if !msgs.is_empty() {
            doc_attr(out, "", &[format!("Messages of `{pkg}` (`{pkg}/msg/*`).")]);
            out.push_str("pub mod msg {\n");
            for m in msgs.iter() {
                self.emit_struct(
                    out,
                    m,
                    "msg",
                    &format!("ROS 2 message `{}/msg/{}`.", m.package, m.name),
                );
                let path = if own {
                    format!("{root}::msg::{}", m.name)
                } else {
                    format!("{root}::{pkg}::msg::{}", m.name)
                };
                tables.types.push((format!("{pkg}/msg/{}", m.name), path));
            }
            out.push_str("}\n\n");
        }
        if !srvs.is_empty() {
            doc_attr(out, "", &[format!("Services of `{pkg}` (`{pkg}/srv/*`).")]);
            out.push_str("pub mod srv {\n");
            for s in srvs.iter() {
                self.emit_service(out, s);
                let base = if own {
                    format!("{root}::srv")
                } else {
                    format!("{root}::{pkg}::srv")
                };
                for half in ["Request", "Response"] {
                    tables.types.push((
                        format!("{pkg}/srv/{}_{half}", s.name),
                        format!("{base}::{}_{half}", s.name),
                    ));
                }
                tables.services.push(format!("{pkg}/srv/{}", s.name));
            }
            out.push_str("}\n\n");
        }
        if !own {
            out.push_str("}\n\n");
        }
    }
}
