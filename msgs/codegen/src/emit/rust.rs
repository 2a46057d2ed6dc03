//! How interface types, names, literals and comments are spelled in the emitted Rust:
//! the one place that knows Rust's keywords and type paths.

use std::fmt::Write as _;

use super::{MAX_NATIVE_ARRAY, Registry};
use crate::parse::{ArrayKind, BaseType, Field, FieldType, Value};

const RUST_KEYWORDS: &[&str] = &[
    "as", "break", "const", "continue", "else", "enum", "extern", "false", "fn", "for", "if",
    "impl", "in", "let", "loop", "match", "mod", "move", "mut", "pub", "ref", "return", "static",
    "struct", "trait", "true", "type", "unsafe", "use", "where", "while", "async", "await", "dyn",
    "abstract", "become", "box", "do", "final", "macro", "override", "priv", "typeof", "unsized",
    "virtual", "yield", "try", "gen",
];
/// Keywords that cannot be written as raw identifiers; fields get a trailing `_` plus a serde rename.
const NON_RAW_KEYWORDS: &[&str] = &["self", "super", "crate"];

/// Rust field identifier and, if it differs from the .msg name, the serde rename.
pub(super) fn field_ident(name: &str) -> (String, bool) {
    if NON_RAW_KEYWORDS.contains(&name) {
        (format!("{name}_"), true)
    } else if RUST_KEYWORDS.contains(&name) {
        (format!("r#{name}"), false)
    } else {
        (name.to_string(), false)
    }
}

pub(super) fn doc_attr(out: &mut String, indent: &str, lines: &[String]) {
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

impl Registry<'_> {
    fn path_of(&self, pkg: &str, name: &str) -> String {
        if pkg == self.own {
            format!("{}::msg::{name}", self.root)
        } else {
            format!("{}::{pkg}::msg::{name}", self.root)
        }
    }

    pub(super) fn elem_type(&self, base: &BaseType) -> String {
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

    pub(super) fn field_type(&self, ty: &FieldType) -> String {
        let e = self.elem_type(&ty.base);
        match ty.array {
            ArrayKind::Scalar => e,
            ArrayKind::Fixed(n) if n <= MAX_NATIVE_ARRAY => format!("[{e}; {n}]"),
            _ => format!("::std::vec::Vec<{e}>"),
        }
    }

    pub(super) fn literal(&self, base: &BaseType, v: &Value) -> String {
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

    pub(super) fn default_expr(&self, f: &Field) -> String {
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
}
