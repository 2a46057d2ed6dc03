//! Line-level parsing of one message section: comments, the type token, and the
//! constant and field declarations built from it.

use super::literals::{parse_default, parse_scalar};
use super::names::{check_constant_name, check_field_name, check_package_name, check_type_name};
use super::{ArrayKind, BaseType, Constant, Ctx, Field, FieldType, MessageSpec, ParseError};

const RUST_STYLE_HINT: &str = "a line `TYPE NAME [DEFAULT]` or `TYPE NAME=VALUE`";

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

pub(super) fn parse_section(
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
