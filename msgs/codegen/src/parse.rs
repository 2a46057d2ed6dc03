//! Strict parser of the ROS 2 `.msg` / `.srv` interface language.
//!
//! Strict on purpose: the same files are compiled by `rosidl` for rclpy users, so anything
//! rosidl would reject (or read differently) must fail here too, at build time, with the file
//! and line, instead of producing Rust types that silently disagree with ROS 2.

use std::fmt;

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

const RUST_STYLE_HINT: &str = "a line `TYPE NAME [DEFAULT]` or `TYPE NAME=VALUE`";

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

/// Split a line into (code, comment) at the first `#` outside quotes.
fn split_comment(line: &str) -> (&str, Option<&str>) {
    let mut quote: Option<char> = None;
    let mut escaped = false;
    for (i, c) in line.char_indices() {
        if escaped {
            escaped = false;
            continue;
        }
        match (quote, c) {
            (Some(_), '\\') => escaped = true,
            (Some(q), c) if c == q => quote = None,
            (None, '"' | '\'') => quote = Some(c),
            (None, '#') => return (&line[..i], Some(&line[i + 1..])),
            _ => {}
        }
    }
    (line, None)
}

fn comment_text(c: &str) -> String {
    let c = c.trim_start_matches('#');
    c.strip_prefix(' ').unwrap_or(c).trim_end().to_string()
}

fn parse_section(
    ctx: &Ctx<'_>,
    name: &str,
    lines: &[(usize, &str)],
    text: String,
) -> Result<MessageSpec, ParseError> {
    let mut fields: Vec<Field> = Vec::new();
    let mut constants: Vec<Constant> = Vec::new();
    let mut doc: Vec<String> = Vec::new();
    // The type's doc is the first comment block of the file, up to the first blank line.
    let mut doc_closed = false;
    let mut seen_statement = false;
    let mut pending: Vec<String> = Vec::new();
    for &(lineno, raw) in lines {
        let (code, comment) = split_comment(raw);
        let code = code.trim();
        if code.is_empty() {
            match comment {
                Some(c) => {
                    let c = comment_text(c);
                    if !seen_statement && !doc_closed {
                        doc.push(c.clone());
                    }
                    pending.push(c);
                }
                None => {
                    pending.clear();
                    doc_closed |= !doc.is_empty();
                }
            }
            continue;
        }
        seen_statement = true;
        let mut item_doc = std::mem::take(&mut pending);
        if let Some(c) = comment {
            let c = comment_text(c);
            if !c.is_empty() {
                item_doc.push(c);
            }
        }
        let (type_tok, rest) = match code.split_once(char::is_whitespace) {
            Some((t, r)) => (t, r.trim()),
            None => {
                return Err(ctx.err(
                    lineno,
                    format!("`{code}` has no name: expected {RUST_STYLE_HINT}"),
                ));
            }
        };
        let ty = parse_type(ctx, lineno, type_tok)?;
        // A constant is `NAME=VALUE` (spaces around `=` allowed); a field default may contain `=`
        // only inside its value, which then is not preceded by a bare identifier.
        let constant = rest.split_once('=').filter(|(l, _)| {
            let l = l.trim();
            !l.is_empty() && !l.contains(char::is_whitespace)
        });
        if let Some((cname, cvalue)) = constant {
            let c = parse_constant(
                ctx,
                lineno,
                &ty,
                type_tok,
                cname.trim(),
                cvalue.trim(),
                item_doc,
            )?;
            if constants.iter().any(|k| k.name == c.name) {
                return Err(ctx.err(lineno, format!("constant {} is declared twice", c.name)));
            }
            constants.push(c);
            continue;
        }
        let field = parse_field(ctx, lineno, ty, type_tok, rest, item_doc)?;
        if fields.iter().any(|f| f.name == field.name) {
            return Err(ctx.err(lineno, format!("field {} is declared twice", field.name)));
        }
        fields.push(field);
    }
    Ok(MessageSpec {
        package: ctx.package.to_string(),
        name: name.to_string(),
        fields,
        constants,
        doc,
        text,
    })
}

/// One `TYPE NAME=VALUE` line: a primitive scalar constant.
fn parse_constant(
    ctx: &Ctx<'_>,
    lineno: usize,
    ty: &FieldType,
    type_tok: &str,
    cname: &str,
    cvalue: &str,
    doc: Vec<String>,
) -> Result<Constant, ParseError> {
    check_constant_name(ctx, lineno, cname)?;
    if ty.array != ArrayKind::Scalar {
        return Err(ctx.err(
            lineno,
            format!(
                "constant {cname} has array type `{type_tok}`: constants must be primitive scalars"
            ),
        ));
    }
    if !ty.base.is_primitive() {
        return Err(ctx.err(lineno, format!("constant {cname} has message type `{type_tok}`: constants must be primitive scalars")));
    }
    if cvalue.is_empty() {
        return Err(ctx.err(lineno, format!("constant {cname} has no value after `=`")));
    }
    let value = parse_scalar(ctx, lineno, &ty.base, cvalue, &format!("constant {cname}"))?;
    Ok(Constant {
        name: cname.to_string(),
        ty: ty.base.clone(),
        value,
        doc,
        line: lineno,
    })
}

/// One `TYPE NAME [DEFAULT]` line (`rest` is what follows the type).
fn parse_field(
    ctx: &Ctx<'_>,
    lineno: usize,
    ty: FieldType,
    type_tok: &str,
    rest: &str,
    doc: Vec<String>,
) -> Result<Field, ParseError> {
    let (fname, default) = match rest.split_once(char::is_whitespace) {
        Some((n, d)) => (n, Some(d.trim())),
        None => (rest, None),
    };
    check_field_name(ctx, lineno, fname)?;
    let default = match default {
        None => None,
        Some(d) => {
            if !ty.base.is_primitive() {
                return Err(ctx.err(
                    lineno,
                    format!(
                        "field {fname} of message type `{type_tok}` cannot have a default value"
                    ),
                ));
            }
            Some(parse_default(ctx, lineno, &ty, d, fname)?)
        }
    };
    if let BaseType::WString { .. } = ty.base {
        return Err(ctx.err(
            lineno,
            format!(
                "field {fname}: `wstring` is not supported by this generator (use `string`, UTF-8)"
            ),
        ));
    }
    Ok(Field {
        name: fname.to_string(),
        ty,
        default,
        doc,
        line: lineno,
    })
}

fn parse_usize(ctx: &Ctx<'_>, line: usize, s: &str, what: &str) -> Result<usize, ParseError> {
    if s.is_empty() || !s.bytes().all(|b| b.is_ascii_digit()) {
        return Err(ctx.err(line, format!("{what} `{s}` is not a non-negative integer")));
    }
    let n: usize = s
        .parse()
        .map_err(|_| ctx.err(line, format!("{what} `{s}` is too large")))?;
    if n == 0 {
        return Err(ctx.err(line, format!("{what} must be at least 1")));
    }
    Ok(n)
}

/// Parse a type token such as `float64[]`, `string<=8[<=3]`, `geometry_msgs/Pose[2]`, `Header`.
fn parse_type(ctx: &Ctx<'_>, line: usize, tok: &str) -> Result<FieldType, ParseError> {
    let (elem, array) = match tok.find('[') {
        None => (tok, ArrayKind::Scalar),
        Some(open) => {
            let Some(inner) = tok[open + 1..].strip_suffix(']') else {
                return Err(ctx.err(
                    line,
                    format!("malformed array type `{tok}`: expected `T[]`, `T[N]` or `T[<=N]`"),
                ));
            };
            let array = if inner.is_empty() {
                ArrayKind::Unbounded
            } else if let Some(b) = inner.strip_prefix("<=") {
                ArrayKind::Bounded(parse_usize(ctx, line, b, "array bound")?)
            } else {
                ArrayKind::Fixed(parse_usize(ctx, line, inner, "array size")?)
            };
            (&tok[..open], array)
        }
    };
    let base = if let Some((word, bound)) = elem.split_once("<=") {
        let bound = Some(parse_usize(ctx, line, bound, "string bound")?);
        match word {
            "string" => BaseType::String { bound },
            "wstring" => BaseType::WString { bound },
            _ => {
                return Err(ctx.err(
                    line,
                    format!("`{elem}`: only `string` and `wstring` can be bounded with `<=`"),
                ));
            }
        }
    } else if let Some(p) = BaseType::from_primitive(elem) {
        p
    } else if let Some((pkg, name)) = elem.split_once('/') {
        let (pkg, name) = match name.split_once('/') {
            Some(("msg", n)) => (pkg, n),
            Some(_) => return Err(ctx.err(line, format!("type `{elem}`: expected `package/Type`"))),
            None => (pkg, name),
        };
        check_package_name(ctx, line, pkg, elem)?;
        check_type_name(ctx, line, name)?;
        BaseType::Named {
            package: pkg.to_string(),
            name: name.to_string(),
        }
    } else if elem == "Header" {
        BaseType::Named {
            package: "std_msgs".into(),
            name: "Header".into(),
        }
    } else if elem.starts_with(|c: char| c.is_ascii_uppercase()) {
        check_type_name(ctx, line, elem)?;
        BaseType::Named {
            package: ctx.package.to_string(),
            name: elem.to_string(),
        }
    } else {
        return Err(ctx.err(
            line,
            format!(
                "unknown type `{elem}`: expected a primitive (bool, byte, char, int8..uint64, float32, float64, string), \
                 `package/Type` or a same-package `Type`"
            ),
        ));
    };
    Ok(FieldType { base, array })
}

fn check_package_name(ctx: &Ctx<'_>, line: usize, pkg: &str, elem: &str) -> Result<(), ParseError> {
    let ok = pkg.starts_with(|c: char| c.is_ascii_lowercase())
        && pkg
            .bytes()
            .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_')
        && !pkg.contains("__")
        && !pkg.ends_with('_');
    if ok {
        Ok(())
    } else {
        Err(ctx.err(
            line,
            format!("type `{elem}`: package `{pkg}` must match [a-z][a-z0-9_]*"),
        ))
    }
}

fn check_type_name(ctx: &Ctx<'_>, line: usize, name: &str) -> Result<(), ParseError> {
    // `_Request` / `_Response` suffixes are produced by us, not written by users.
    let base = name
        .strip_suffix("_Request")
        .or_else(|| name.strip_suffix("_Response"))
        .unwrap_or(name);
    let ok = base.starts_with(|c: char| c.is_ascii_uppercase())
        && base.bytes().all(|b| b.is_ascii_alphanumeric());
    if ok {
        Ok(())
    } else {
        Err(ctx.err(
            line,
            format!("type name `{name}` must be CamelCase ([A-Z][A-Za-z0-9]*)"),
        ))
    }
}

fn check_field_name(ctx: &Ctx<'_>, line: usize, name: &str) -> Result<(), ParseError> {
    let ok = name.starts_with(|c: char| c.is_ascii_lowercase())
        && name
            .bytes()
            .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_')
        && !name.contains("__")
        && !name.ends_with('_');
    if ok {
        Ok(())
    } else {
        Err(ctx.err(
            line,
            format!(
                "field name `{name}` must be snake_case ([a-z][a-z0-9_]*, no `__`, no trailing `_`)"
            ),
        ))
    }
}

fn check_constant_name(ctx: &Ctx<'_>, line: usize, name: &str) -> Result<(), ParseError> {
    let ok = name.starts_with(|c: char| c.is_ascii_uppercase())
        && name
            .bytes()
            .all(|b| b.is_ascii_uppercase() || b.is_ascii_digit() || b == b'_')
        && !name.contains("__")
        && !name.ends_with('_');
    if ok {
        Ok(())
    } else {
        Err(ctx.err(
            line,
            format!("constant name `{name}` must be UPPER_CASE ([A-Z][A-Z0-9_]*)"),
        ))
    }
}

fn int_range(base: &BaseType) -> Option<(i128, i128)> {
    Some(match base {
        BaseType::Byte | BaseType::Char | BaseType::U8 => (0, u8::MAX as i128),
        BaseType::I8 => (i8::MIN as i128, i8::MAX as i128),
        BaseType::I16 => (i16::MIN as i128, i16::MAX as i128),
        BaseType::U16 => (0, u16::MAX as i128),
        BaseType::I32 => (i32::MIN as i128, i32::MAX as i128),
        BaseType::U32 => (0, u32::MAX as i128),
        BaseType::I64 => (i64::MIN as i128, i64::MAX as i128),
        BaseType::U64 => (0, u64::MAX as i128),
        _ => return None,
    })
}

fn parse_scalar(
    ctx: &Ctx<'_>,
    line: usize,
    base: &BaseType,
    s: &str,
    what: &str,
) -> Result<Value, ParseError> {
    if let Some((lo, hi)) = int_range(base) {
        let parsed = if let Some(hex) = s.strip_prefix("0x").or_else(|| s.strip_prefix("0X")) {
            i128::from_str_radix(hex, 16).ok()
        } else {
            s.parse::<i128>().ok()
        };
        let Some(v) = parsed else {
            return Err(ctx.err(line, format!("{what}: `{s}` is not an integer")));
        };
        if v < lo || v > hi {
            return Err(ctx.err(line, format!("{what}: {v} is out of range [{lo}, {hi}]")));
        }
        return Ok(Value::Int(v));
    }
    match base {
        BaseType::Bool => match s {
            "true" | "True" | "1" => Ok(Value::Bool(true)),
            "false" | "False" | "0" => Ok(Value::Bool(false)),
            _ => Err(ctx.err(
                line,
                format!("{what}: `{s}` is not a bool (expected true, false, 1 or 0)"),
            )),
        },
        BaseType::F32 | BaseType::F64 => match s.parse::<f64>() {
            Ok(v) => Ok(Value::Float(v)),
            Err(_) => Err(ctx.err(line, format!("{what}: `{s}` is not a number"))),
        },
        BaseType::String { bound } | BaseType::WString { bound } => {
            let v = unquote(s).ok_or_else(|| {
                ctx.err(line, format!("{what}: unterminated string literal `{s}`"))
            })?;
            if let Some(b) = bound
                && v.len() > *b
            {
                return Err(ctx.err(
                    line,
                    format!("{what}: string of {} bytes exceeds its bound {b}", v.len()),
                ));
            }
            Ok(Value::Str(v))
        }
        _ => Err(ctx.err(
            line,
            format!("{what}: message types cannot have literal values"),
        )),
    }
}

/// Remove matching quotes (resolving `\"`, `\'`, `\\`); unquoted text is taken verbatim.
fn unquote(s: &str) -> Option<String> {
    let q = s.chars().next()?;
    if q != '"' && q != '\'' {
        return Some(s.to_string());
    }
    if s.len() < 2 || !s.ends_with(q) {
        return None;
    }
    let inner = &s[1..s.len() - 1];
    let mut out = String::new();
    let mut chars = inner.chars();
    while let Some(c) = chars.next() {
        if c == '\\' {
            match chars.next() {
                Some(n) => out.push(n),
                None => return None,
            }
        } else if c == q {
            return None;
        } else {
            out.push(c);
        }
    }
    Some(out)
}

/// Split `a, "b,c", d` at top-level commas.
fn split_list(s: &str) -> Option<Vec<String>> {
    let mut items = Vec::new();
    let mut cur = String::new();
    let mut quote: Option<char> = None;
    let mut escaped = false;
    for c in s.chars() {
        if escaped {
            cur.push(c);
            escaped = false;
            continue;
        }
        match (quote, c) {
            (Some(_), '\\') => {
                cur.push(c);
                escaped = true;
            }
            (Some(q), c) if c == q => {
                cur.push(c);
                quote = None;
            }
            (None, '"' | '\'') => {
                cur.push(c);
                quote = Some(c);
            }
            (None, ',') => items.push(std::mem::take(&mut cur).trim().to_string()),
            _ => cur.push(c),
        }
    }
    if quote.is_some() {
        return None;
    }
    let last = cur.trim().to_string();
    if !last.is_empty() || !items.is_empty() {
        items.push(last);
    }
    Some(items)
}

fn parse_default(
    ctx: &Ctx<'_>,
    line: usize,
    ty: &FieldType,
    s: &str,
    fname: &str,
) -> Result<Value, ParseError> {
    let what = format!("default of field {fname}");
    if ty.array == ArrayKind::Scalar {
        return parse_scalar(ctx, line, &ty.base, s, &what);
    }
    let Some(inner) = s.strip_prefix('[').and_then(|r| r.strip_suffix(']')) else {
        return Err(ctx.err(
            line,
            format!("{what}: `{s}` is not an array literal `[a, b, ...]`"),
        ));
    };
    let items = split_list(inner)
        .ok_or_else(|| ctx.err(line, format!("{what}: unterminated string in `{s}`")))?;
    if items.iter().any(|i| i.is_empty()) {
        return Err(ctx.err(line, format!("{what}: empty element in `{s}`")));
    }
    let n = items.len();
    match ty.array {
        ArrayKind::Fixed(size) if n != size => {
            return Err(ctx.err(
                line,
                format!("{what}: {n} elements given, the array has exactly {size}"),
            ));
        }
        ArrayKind::Bounded(b) if n > b => {
            return Err(ctx.err(line, format!("{what}: {n} elements exceed the bound {b}")));
        }
        _ => {}
    }
    let values = items
        .iter()
        .map(|i| parse_scalar(ctx, line, &ty.base, i, &what))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Value::Array(values))
}
