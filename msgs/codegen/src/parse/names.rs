//! Naming rules of packages, types, fields and constants, kept apart so every
//! identifier is checked against the same rules rosidl applies.

use super::{Ctx, ParseError};

pub(super) fn check_package_name(
    ctx: &Ctx<'_>,
    line: usize,
    pkg: &str,
    elem: &str,
) -> Result<(), ParseError> {
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

pub(super) fn check_type_name(ctx: &Ctx<'_>, line: usize, name: &str) -> Result<(), ParseError> {
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

pub(super) fn check_field_name(ctx: &Ctx<'_>, line: usize, name: &str) -> Result<(), ParseError> {
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

pub(super) fn check_constant_name(
    ctx: &Ctx<'_>,
    line: usize,
    name: &str,
) -> Result<(), ParseError> {
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
