//! The `validate` body of emitted messages: the bounds serde cannot enforce (bounded
//! strings and sequences, fixed arrays longer than serde's native ones), nested types included.

use std::fmt::Write as _;

use super::rust::field_ident;
use super::{MAX_NATIVE_ARRAY, Registry, key};
use crate::parse::{ArrayKind, BaseType, Field, FieldType};

impl Registry<'_> {
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

    pub(super) fn validate_body(&mut self, fields: &[Field]) -> String {
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
}
