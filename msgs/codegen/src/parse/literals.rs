//! Literal values of constants and field defaults: scalars range-checked against their
//! type, quoted strings and array literals.

use super::{ArrayKind, BaseType, Ctx, FieldType, ParseError, Value};

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

pub(super) fn parse_scalar(
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

pub(super) fn parse_default(
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
