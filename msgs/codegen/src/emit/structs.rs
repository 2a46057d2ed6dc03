//! One emitted type per message, service half and service: the struct with its docs,
//! serde attributes, `Default`, constants and the `RosMessage` / `RosService` impls.

use std::collections::BTreeSet;
use std::fmt::Write as _;

use super::rust::{doc_attr, field_ident};
use super::{MAX_NATIVE_ARRAY, Registry, key};
use crate::parse::{ArrayKind, BaseType, Field, FieldType, MessageSpec, ServiceSpec, Value};

impl Registry<'_> {
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

    pub(super) fn emit_struct(
        &mut self,
        out: &mut String,
        spec: &MessageSpec,
        kind: &str,
        doc_head: &str,
    ) {
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
        let appended = appended_sequences(fields);
        if appended > 0 {
            let _ = writeln!(out, "    const APPENDED_SEQUENCES: usize = {appended};");
        }
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

    pub(super) fn emit_service(&mut self, out: &mut String, srv: &ServiceSpec) {
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

/// The trailing fields appended to a message in its latest change: from the last field
/// whose comment starts with "Appended" to the end, when all are unbounded arrays (a
/// layout before them ends where they begin, and they read as empty); else none.
pub(crate) fn appended_sequences(fields: &[Field]) -> usize {
    let Some(first) = fields.iter().rposition(|f| {
        f.doc
            .first()
            .is_some_and(|line| line.trim_start().starts_with("Appended"))
    }) else {
        return 0;
    };
    let appended = &fields[first..];
    match appended.iter().all(|f| f.ty.array == ArrayKind::Unbounded) {
        true => appended.len(),
        false => 0,
    }
}
