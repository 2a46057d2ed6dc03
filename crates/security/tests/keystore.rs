//! Keystores as sros2 lays them out, checked with the `openssl` command-line tool as an
//! independent verifier of certificates and S/MIME signatures.

use std::path::Path;
use std::process::Command;

use causal_arm_security::{
    ENCLAVE_FILES, Keystore, SecurityEnv, SecurityError, SecurityMode, Strategy,
};

fn openssl(args: &[&str], dir: &Path) -> String {
    let out = Command::new("openssl")
        .args(args)
        .current_dir(dir)
        .output()
        .expect("openssl runs");
    assert!(
        out.status.success(),
        "openssl {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr)
}

#[test]
fn keystore_layout_matches_sros2_and_openssl_verifies_it() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().join("keystore");
    let ks = Keystore::create(&root, 7).unwrap();
    for link in [
        "public/identity_ca.cert.pem",
        "public/permissions_ca.cert.pem",
    ] {
        assert_eq!(
            std::fs::read_link(root.join(link)).unwrap(),
            Path::new("ca.cert.pem")
        );
    }
    for link in [
        "private/identity_ca.key.pem",
        "private/permissions_ca.key.pem",
    ] {
        assert_eq!(
            std::fs::read_link(root.join(link)).unwrap(),
            Path::new("ca.key.pem")
        );
    }
    let dir = ks.create_enclave("/causal_arm/sim", 7).unwrap();
    assert_eq!(dir, root.join("enclaves/causal_arm/sim"));
    for file in ENCLAVE_FILES {
        assert!(dir.join(file).is_file(), "{file}");
    }
    assert_eq!(
        std::fs::read_link(dir.join("governance.p7s")).unwrap(),
        Path::new("../../governance.p7s")
    );
    use std::os::unix::fs::PermissionsExt;
    let mode = std::fs::metadata(dir.join("key.pem"))
        .unwrap()
        .permissions()
        .mode();
    assert_eq!(mode & 0o077, 0, "key.pem readable by others: {mode:o}");

    // The identity certificate chains to the CA and names the enclave.
    let verified = openssl(
        &["verify", "-CAfile", "identity_ca.cert.pem", "cert.pem"],
        &dir,
    );
    assert!(verified.contains("cert.pem: OK"), "{verified}");
    let subject = openssl(&["x509", "-in", "cert.pem", "-noout", "-subject"], &dir);
    assert!(subject.contains("CN = /causal_arm/sim"), "{subject}");
    let text = openssl(&["x509", "-in", "cert.pem", "-noout", "-text"], &dir);
    assert!(
        text.contains("prime256v1") && text.contains("ecdsa-with-SHA256"),
        "{text}"
    );

    // Both documents verify against the permissions CA, and say what they should.
    for doc in ["governance.p7s", "permissions.p7s"] {
        let out = openssl(
            &[
                "smime",
                "-verify",
                "-in",
                doc,
                "-CAfile",
                "permissions_ca.cert.pem",
                "-text",
            ],
            &dir,
        );
        assert!(out.contains("Verification successful"), "{doc}: {out}");
    }
    let governance = ks.verify_signed(&dir.join("governance.p7s")).unwrap();
    assert!(
        governance.contains("<id>7</id>") && governance.contains("<data_protection_kind>ENCRYPT")
    );
    let permissions = ks.verify_signed(&dir.join("permissions.p7s")).unwrap();
    assert!(
        permissions.contains("<subject_name>CN=/causal_arm/sim</subject_name>"),
        "{permissions}"
    );
    assert!(
        permissions.contains("<topic>rt/*</topic>") && permissions.contains("ros_discovery_info")
    );

    assert_eq!(ks.enclaves().unwrap(), vec!["/causal_arm/sim".to_string()]);
}

#[test]
fn a_tampered_document_fails_verification() {
    let tmp = tempfile::tempdir().unwrap();
    let ks = Keystore::create(tmp.path(), 0).unwrap();
    let dir = ks.create_enclave("/a", 0).unwrap();
    let p7s = dir.join("permissions.p7s");
    let text = std::fs::read_to_string(&p7s)
        .unwrap()
        .replace("rt/*", "rt/x");
    std::fs::write(&p7s, text).unwrap();
    assert!(matches!(
        ks.verify_signed(&p7s),
        Err(SecurityError::Crypto { .. })
    ));
}

#[test]
fn keystores_are_not_overwritten_and_incomplete_ones_are_named() {
    let tmp = tempfile::tempdir().unwrap();
    Keystore::create(tmp.path(), 0).unwrap();
    let err = Keystore::create(tmp.path(), 0).unwrap_err();
    assert!(
        err.to_string().contains("already holds a keystore"),
        "{err}"
    );
    std::fs::remove_file(tmp.path().join("enclaves/governance.p7s")).unwrap();
    let err = Keystore::open(tmp.path()).unwrap_err().to_string();
    assert!(err.contains("governance.p7s is missing"), "{err}");
    let empty = tempfile::tempdir().unwrap();
    let err = Keystore::open(empty.path()).unwrap_err().to_string();
    assert!(err.contains("is not a keystore"), "{err}");
}

#[test]
fn re_creating_an_enclave_keeps_its_identity() {
    let tmp = tempfile::tempdir().unwrap();
    let ks = Keystore::create(tmp.path(), 0).unwrap();
    let dir = ks.create_enclave("/a", 0).unwrap();
    let cert = std::fs::read(dir.join("cert.pem")).unwrap();
    ks.create_enclave("/a", 3).unwrap();
    assert_eq!(std::fs::read(dir.join("cert.pem")).unwrap(), cert);
    assert!(
        ks.verify_signed(&dir.join("permissions.p7s"))
            .unwrap()
            .contains("<id>3</id>")
    );
    assert!(ks.create_enclave("/../escape", 0).is_err());
}

fn env(pairs: &[(&str, &str)]) -> Result<SecurityEnv, SecurityError> {
    let pairs: Vec<(String, String)> = pairs
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    SecurityEnv::from_lookup(move |key| {
        pairs.iter().find(|(k, _)| k == key).map(|(_, v)| v.clone())
    })
}

#[test]
fn enclave_resolution_follows_rcl() {
    let tmp = tempfile::tempdir().unwrap();
    let ks = Keystore::create(tmp.path(), 0).unwrap();
    let dir = ks.create_enclave("/graph", 0).unwrap();
    ks.create_enclave("/other", 0).unwrap();
    let keystore = ks.root().to_str().unwrap();

    assert_eq!(
        env(&[]).unwrap().resolve(Some("/graph")).unwrap(),
        SecurityMode::Off
    );
    let on = env(&[
        ("ROS_SECURITY_ENABLE", "true"),
        ("ROS_SECURITY_KEYSTORE", keystore),
    ])
    .unwrap();
    assert_eq!(
        on.resolve(Some("/graph")).unwrap(),
        SecurityMode::Secured {
            enclave: "/graph".into(),
            dir: dir.clone()
        }
    );
    // The override wins over --enclave.
    let overridden = env(&[
        ("ROS_SECURITY_ENABLE", "true"),
        ("ROS_SECURITY_KEYSTORE", keystore),
        ("ROS_SECURITY_ENCLAVE_OVERRIDE", "/graph"),
    ])
    .unwrap();
    assert!(
        matches!(overridden.resolve(Some("/other")).unwrap(), SecurityMode::Secured { enclave, .. } if enclave == "/graph")
    );
    // Permissive: a missing enclave runs unsecured, saying why.
    match on.resolve(Some("/absent")).unwrap() {
        SecurityMode::Unsecured { reason } => {
            assert!(reason.contains("\"/absent\" not found"), "{reason}")
        }
        other => panic!("{other:?}"),
    }
    // Enforce: the root enclave "/" has no identity, so a node without --enclave cannot start.
    let enforce = env(&[
        ("ROS_SECURITY_ENABLE", "true"),
        ("ROS_SECURITY_KEYSTORE", keystore),
        ("ROS_SECURITY_STRATEGY", "Enforce"),
    ])
    .unwrap();
    assert_eq!(enforce.strategy, Strategy::Enforce);
    let err = enforce.resolve(None).unwrap_err().to_string();
    assert!(
        err.contains("Enforce") && err.contains("key.pem is missing")
            || err.contains("identity_ca.cert.pem is missing"),
        "{err}"
    );
    let no_keystore = env(&[
        ("ROS_SECURITY_ENABLE", "true"),
        ("ROS_SECURITY_STRATEGY", "Enforce"),
    ])
    .unwrap();
    assert!(
        no_keystore
            .resolve(Some("/graph"))
            .unwrap_err()
            .to_string()
            .contains("ROS_SECURITY_KEYSTORE is not set")
    );
}

#[test]
fn values_rcl_would_misread_as_off_are_refused() {
    let err = env(&[("ROS_SECURITY_ENABLE", "True")])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("ROS_SECURITY_ENABLE=\"True\"") && err.contains("true or false"),
        "{err}"
    );
    let err = env(&[("ROS_SECURITY_STRATEGY", "enforce")])
        .unwrap_err()
        .to_string();
    assert!(err.contains("Enforce or Permissive"), "{err}");
    assert!(env(&[("ROS_SECURITY_ENCLAVE_OVERRIDE", "graph")]).is_err());
}
