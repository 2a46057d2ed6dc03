//! The sros2 keystore on disk: `public/` and `private/` hold one CA that serves as both
//! identity and permissions CA (the role names are symlinks to it), `enclaves/` holds the
//! signed governance document and one directory per enclave with what a participant
//! needs (the six files of [`ENCLAVE_FILES`]).

use std::fs;
use std::io::Write;
use std::os::unix::fs::{OpenOptionsExt, symlink};
use std::path::{Path, PathBuf};

use openssl::pkey::PKey;
use openssl::x509::X509;

use crate::SecurityError;
use crate::documents::{governance_xml, permissions_xml};
use crate::names::validate_enclave_name;
use crate::pki::{self, Identity};

/// The files one enclave directory must hold, with the names rmw_dds_common looks for.
pub const ENCLAVE_FILES: [&str; 6] = [
    "identity_ca.cert.pem",
    "cert.pem",
    "key.pem",
    "permissions_ca.cert.pem",
    "governance.p7s",
    "permissions.p7s",
];

/// What `is_valid_keystore` requires in sros2, relative to the keystore root.
const KEYSTORE_FILES: [&str; 5] = [
    "public/permissions_ca.cert.pem",
    "public/identity_ca.cert.pem",
    "private/permissions_ca.key.pem",
    "private/identity_ca.key.pem",
    "enclaves/governance.p7s",
];

/// sros2's CA common name, kept so keystores look the same from either tool.
const CA_COMMON_NAME: &str = "sros2CA";

/// A complete keystore directory.
#[derive(Debug, Clone)]
pub struct Keystore {
    root: PathBuf,
}

impl Keystore {
    /// Creates a keystore in `dir` (made if absent) for `domain_id`, as
    /// `ros2 security create-keystore` does; refuses a directory that already holds one.
    pub fn create(dir: &Path, domain_id: u16) -> Result<Self, SecurityError> {
        let dir = &absolute(dir)?;
        if Self::first_missing(dir).is_none() {
            return Err(SecurityError::KeystoreExists(dir.to_owned()));
        }
        let keystore = Self {
            root: dir.to_owned(),
        };
        for sub in ["public", "private", "enclaves"] {
            create_dir(&dir.join(sub))?;
        }
        set_mode(&dir.join("private"), 0o700)?;
        let ca = pki::issue(CA_COMMON_NAME, None, pki::validity_now())?;
        let pem = ca
            .cert
            .to_pem()
            .map_err(SecurityError::crypto("writing the CA certificate"))?;
        write_file(&dir.join("public/ca.cert.pem"), &pem, 0o644)?;
        write_key(&dir.join("private/ca.key.pem"), &ca)?;
        for role in ["identity_ca", "permissions_ca"] {
            relink("ca.cert.pem", &dir.join(format!("public/{role}.cert.pem")))?;
            relink("ca.key.pem", &dir.join(format!("private/{role}.key.pem")))?;
        }
        let governance = governance_xml(domain_id);
        write_file(
            &dir.join("enclaves/governance.xml"),
            governance.as_bytes(),
            0o644,
        )?;
        let signed = pki::smime_sign(&ca, governance.as_bytes())?;
        write_file(&dir.join("enclaves/governance.p7s"), &signed, 0o644)?;
        Ok(keystore)
    }

    /// Opens an existing keystore, naming the first required file it lacks.
    pub fn open(dir: &Path) -> Result<Self, SecurityError> {
        let dir = &absolute(dir)?;
        match Self::first_missing(dir) {
            Some(missing) => Err(SecurityError::NotAKeystore {
                dir: dir.to_owned(),
                missing,
            }),
            None => Ok(Self {
                root: dir.to_owned(),
            }),
        }
    }

    fn first_missing(dir: &Path) -> Option<PathBuf> {
        KEYSTORE_FILES
            .iter()
            .map(|f| dir.join(f))
            .find(|p| !p.is_file())
    }

    /// The keystore's root directory.
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// Where enclave `name` lives (whether or not it exists yet).
    pub fn enclave_dir(&self, name: &str) -> PathBuf {
        enclave_dir(&self.root, name)
    }

    /// Creates (or refreshes the permissions of) enclave `name` for `domain_id`, as
    /// `ros2 security create-enclave` does: an identity certificate with CN=`name`
    /// signed by the identity CA, and permissions for sros2's default policy signed by
    /// the permissions CA. An existing certificate and key are kept.
    pub fn create_enclave(&self, name: &str, domain_id: u16) -> Result<PathBuf, SecurityError> {
        validate_enclave_name(name)?;
        let dir = self.enclave_dir(name);
        create_dir(&dir)?;
        for file in ["identity_ca.cert.pem", "permissions_ca.cert.pem"] {
            relink_relative(&self.root.join("public").join(file), &dir.join(file))?;
        }
        relink_relative(
            &self.root.join("enclaves/governance.p7s"),
            &dir.join("governance.p7s"),
        )?;
        let (cert_path, key_path) = (dir.join("cert.pem"), dir.join("key.pem"));
        if !cert_path.is_file() || !key_path.is_file() {
            let ca = self.load_ca("identity_ca")?;
            let identity = pki::issue(name, Some(&ca), pki::validity_now())?;
            let pem = identity
                .cert
                .to_pem()
                .map_err(SecurityError::crypto("writing cert.pem"))?;
            write_file(&cert_path, &pem, 0o644)?;
            write_key(&key_path, &identity)?;
        }
        let cert = load_cert(&cert_path)?;
        let not_before = asn1_to_unix(cert.not_before(), &cert_path)?;
        let not_after = asn1_to_unix(cert.not_after(), &cert_path)?;
        let permissions = permissions_xml(
            name,
            domain_id,
            &pki::iso8601(not_before),
            &pki::iso8601(not_after),
        );
        write_file(&dir.join("permissions.xml"), permissions.as_bytes(), 0o644)?;
        let signer = self.load_ca("permissions_ca")?;
        let signed = pki::smime_sign(&signer, permissions.as_bytes())?;
        write_file(&dir.join("permissions.p7s"), &signed, 0o644)?;
        Ok(dir)
    }

    /// The enclaves of this keystore (directories holding a `key.pem`), sorted.
    pub fn enclaves(&self) -> Result<Vec<String>, SecurityError> {
        let mut found = Vec::new();
        collect_enclaves(&self.root.join("enclaves"), "", &mut found)?;
        found.sort();
        Ok(found)
    }

    /// Checks a signed document of this keystore against its permissions CA and returns
    /// the signed text: how tests and users confirm a `.p7s` is what it claims.
    pub fn verify_signed(&self, p7s: &Path) -> Result<String, SecurityError> {
        let ca = load_cert(&self.root.join("public/permissions_ca.cert.pem"))?;
        let smime = fs::read(p7s).map_err(SecurityError::io(p7s))?;
        let content = pki::smime_verify(&ca, &smime)?;
        Ok(String::from_utf8_lossy(&content).into_owned())
    }

    fn load_ca(&self, role: &str) -> Result<Identity, SecurityError> {
        let cert = load_cert(&self.root.join(format!("public/{role}.cert.pem")))?;
        let key_path = self.root.join(format!("private/{role}.key.pem"));
        let pem = fs::read(&key_path).map_err(SecurityError::io(&key_path))?;
        let key = PKey::private_key_from_pem(&pem).map_err(SecurityError::crypto(format!(
            "reading {}",
            key_path.display()
        )))?;
        Ok(Identity { cert, key })
    }
}

/// `keystore/enclaves/<name without its leading slash>`.
pub(crate) fn enclave_dir(root: &Path, name: &str) -> PathBuf {
    root.join("enclaves").join(name.trim_start_matches('/'))
}

fn collect_enclaves(
    dir: &Path,
    prefix: &str,
    found: &mut Vec<String>,
) -> Result<(), SecurityError> {
    if dir.join("key.pem").is_file() {
        found.push(if prefix.is_empty() {
            "/".into()
        } else {
            prefix.to_owned()
        });
    }
    for entry in fs::read_dir(dir).map_err(SecurityError::io(dir))? {
        let entry = entry.map_err(SecurityError::io(dir))?;
        let is_dir = entry
            .file_type()
            .map_err(SecurityError::io(entry.path()))?
            .is_dir();
        if is_dir {
            let name = format!("{prefix}/{}", entry.file_name().to_string_lossy());
            collect_enclaves(&entry.path(), &name, found)?;
        }
    }
    Ok(())
}

fn load_cert(path: &Path) -> Result<X509, SecurityError> {
    let pem = fs::read(path).map_err(SecurityError::io(path))?;
    X509::from_pem(&pem).map_err(SecurityError::crypto(format!("reading {}", path.display())))
}

fn asn1_to_unix(time: &openssl::asn1::Asn1TimeRef, path: &Path) -> Result<i64, SecurityError> {
    let epoch = openssl::asn1::Asn1Time::from_unix(0)
        .map_err(SecurityError::crypto("building the epoch"))?;
    let diff = epoch.diff(time).map_err(SecurityError::crypto(format!(
        "reading the validity of {}",
        path.display()
    )))?;
    Ok(i64::from(diff.days) * 86_400 + i64::from(diff.secs))
}

fn absolute(dir: &Path) -> Result<PathBuf, SecurityError> {
    std::path::absolute(dir).map_err(SecurityError::io(dir))
}

fn create_dir(dir: &Path) -> Result<(), SecurityError> {
    fs::create_dir_all(dir).map_err(SecurityError::io(dir))
}

fn set_mode(path: &Path, mode: u32) -> Result<(), SecurityError> {
    use std::os::unix::fs::PermissionsExt;
    fs::set_permissions(path, fs::Permissions::from_mode(mode)).map_err(SecurityError::io(path))
}

fn write_file(path: &Path, bytes: &[u8], mode: u32) -> Result<(), SecurityError> {
    let mut file = fs::OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(true)
        .mode(mode)
        .open(path)
        .map_err(SecurityError::io(path))?;
    file.write_all(bytes).map_err(SecurityError::io(path))?;
    file.sync_all().map_err(SecurityError::io(path))
}

/// Private keys are PKCS#8 PEM, unencrypted as sros2 writes them, readable by the owner only.
fn write_key(path: &Path, identity: &Identity) -> Result<(), SecurityError> {
    let pem = identity
        .key
        .private_key_to_pem_pkcs8()
        .map_err(SecurityError::crypto(format!("writing {}", path.display())))?;
    write_file(path, &pem, 0o600)
}

/// Points `link` at `target` (a name relative to the link's directory), replacing a stale link.
fn relink(target: impl AsRef<Path>, link: &Path) -> Result<(), SecurityError> {
    if link.symlink_metadata().is_ok() {
        fs::remove_file(link).map_err(SecurityError::io(link))?;
    }
    symlink(target, link).map_err(SecurityError::io(link))
}

/// Links `link` to `target` by a relative path, so a keystore can be moved as a whole.
fn relink_relative(target: &Path, link: &Path) -> Result<(), SecurityError> {
    if link == target {
        return Ok(()); // the root enclave "/" is `enclaves/` itself, as in sros2
    }
    let from = link.parent().unwrap_or(Path::new("/"));
    relink(relative_path(from, target), link)
}

/// `target` relative to the directory `from`; both are absolute (the keystore root is).
fn relative_path(from: &Path, target: &Path) -> PathBuf {
    let common = from
        .components()
        .zip(target.components())
        .take_while(|(a, b)| a == b)
        .count();
    let mut path = PathBuf::new();
    for _ in from.components().skip(common) {
        path.push("..");
    }
    for part in target.components().skip(common) {
        path.push(part);
    }
    path
}
