//! Enclave names follow the ROS namespace rules (`rcl_validate_enclave_name`): a name
//! becomes a directory under the keystore and the CN of a certificate, so anything
//! looser could escape the keystore (`/../x`) or fail to match its permissions grant.

use crate::SecurityError;

/// Checks `name` against the ROS 2 namespace rules sros2 applies to enclaves.
pub fn validate_enclave_name(name: &str) -> Result<(), SecurityError> {
    let fail = |reason| {
        Err(SecurityError::EnclaveName {
            name: name.to_owned(),
            reason,
        })
    };
    if !name.starts_with('/') {
        return fail("must start with '/'");
    }
    if name == "/" {
        return Ok(());
    }
    if name.ends_with('/') {
        return fail("must not end with '/'");
    }
    if name.len() > 255 {
        return fail("longer than 255 characters");
    }
    for token in name[1..].split('/') {
        if token.is_empty() {
            return fail("contains '//'");
        }
        if token.starts_with(|c: char| c.is_ascii_digit()) {
            return fail("a part starts with a digit");
        }
        if !token.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
            return fail("only letters, digits, '_' and '/' are allowed");
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ros_namespace_rules() {
        for good in ["/", "/causal_arm", "/a/b_c/d9"] {
            assert!(validate_enclave_name(good).is_ok(), "{good}");
        }
        for (bad, why) in [
            ("causal_arm", "start with"),
            ("/a/", "end with"),
            ("/a//b", "'//'"),
            ("/9a", "digit"),
            ("/a/../b", "only letters"),
            ("/a b", "only letters"),
        ] {
            let err = validate_enclave_name(bad).unwrap_err().to_string();
            assert!(err.contains(why) && err.contains(bad), "{bad}: {err}");
        }
    }
}
