//! Keys, certificates and S/MIME signatures as sros2 makes them: prime256v1 (the curve
//! DDS-Security 9.3.1 calls for), SHA-256, ten years, valid from a day ago (Connext
//! rejects a grant that starts "in the future" by clock skew), PKCS#8 keys, and detached
//! `text/plain` S/MIME signatures.

use openssl::asn1::{Asn1Integer, Asn1Time};
use openssl::bn::{BigNum, MsbOption};
use openssl::ec::{EcGroup, EcKey};
use openssl::hash::MessageDigest;
use openssl::nid::Nid;
use openssl::pkcs7::{Pkcs7, Pkcs7Flags};
use openssl::pkey::{PKey, Private};
use openssl::stack::Stack;
use openssl::x509::extension::BasicConstraints;
use openssl::x509::{X509, X509Name};

use crate::SecurityError;

const VALID_DAYS: i64 = 3650;

/// A certificate with its private key.
pub(crate) struct Identity {
    pub cert: X509,
    pub key: PKey<Private>,
}

/// When a new certificate starts and stops being valid (Unix seconds).
pub(crate) fn validity_now() -> (i64, i64) {
    let now = chrono::Utc::now().timestamp();
    (now - 86_400, now + VALID_DAYS * 86_400)
}

/// ISO 8601 UTC, as permissions documents want a certificate's validity.
pub(crate) fn iso8601(unix_seconds: i64) -> String {
    chrono::DateTime::from_timestamp(unix_seconds, 0)
        .unwrap_or_default()
        .format("%Y-%m-%dT%H:%M:%S")
        .to_string()
}

fn new_key() -> Result<PKey<Private>, openssl::error::ErrorStack> {
    let group = EcGroup::from_curve_name(Nid::X9_62_PRIME256V1)?;
    PKey::from_ec_key(EcKey::generate(&group)?)
}

fn random_serial() -> Result<Asn1Integer, openssl::error::ErrorStack> {
    let mut serial = BigNum::new()?;
    serial.rand(159, MsbOption::MAYBE_ZERO, false)?;
    serial.to_asn1_integer()
}

fn common_name(cn: &str) -> Result<X509Name, openssl::error::ErrorStack> {
    let mut name = X509Name::builder()?;
    name.append_entry_by_nid(Nid::COMMONNAME, cn)?;
    Ok(name.build())
}

/// Issues a certificate for `cn`: self-signed CA when `issuer` is `None`, else an end
/// entity signed by `issuer`.
pub(crate) fn issue(
    cn: &str,
    issuer: Option<&Identity>,
    validity: (i64, i64),
) -> Result<Identity, SecurityError> {
    let build = || -> Result<Identity, openssl::error::ErrorStack> {
        let key = new_key()?;
        let subject = common_name(cn)?;
        let mut cert = X509::builder()?;
        cert.set_version(2)?;
        let serial = random_serial()?;
        cert.set_serial_number(&serial)?;
        cert.set_subject_name(&subject)?;
        cert.set_issuer_name(issuer.map_or(&subject, |i| i.cert.subject_name()))?;
        cert.set_pubkey(&key)?;
        let (not_before, not_after) = (
            Asn1Time::from_unix(validity.0)?,
            Asn1Time::from_unix(validity.1)?,
        );
        cert.set_not_before(&not_before)?;
        cert.set_not_after(&not_after)?;
        let constraints = match issuer {
            None => BasicConstraints::new().critical().ca().pathlen(1).build()?,
            Some(_) => BasicConstraints::new().build()?,
        };
        cert.append_extension(constraints)?;
        cert.sign(issuer.map_or(&key, |i| &i.key), MessageDigest::sha256())?;
        Ok(Identity {
            cert: cert.build(),
            key,
        })
    };
    build().map_err(SecurityError::crypto(format!(
        "issuing a certificate for CN={cn}"
    )))
}

/// Signs `document` as `openssl smime -sign -text` (detached, text/plain), the `.p7s`
/// form DDS Security reads governance and permissions from.
pub(crate) fn smime_sign(signer: &Identity, document: &[u8]) -> Result<Vec<u8>, SecurityError> {
    let flags = Pkcs7Flags::DETACHED | Pkcs7Flags::TEXT;
    let sign = || -> Result<Vec<u8>, openssl::error::ErrorStack> {
        let no_extra_certs: Stack<X509> = Stack::new()?;
        let pkcs7 = Pkcs7::sign(&signer.cert, &signer.key, &no_extra_certs, document, flags)?;
        pkcs7.to_smime(document, flags)
    };
    sign().map_err(SecurityError::crypto("signing a document"))
}

/// Verifies a `.p7s` against `ca` and returns the signed content.
pub(crate) fn smime_verify(ca: &X509, smime: &[u8]) -> Result<Vec<u8>, SecurityError> {
    let verify = || -> Result<Vec<u8>, openssl::error::ErrorStack> {
        let (pkcs7, content) = Pkcs7::from_smime(smime)?;
        let mut store = openssl::x509::store::X509StoreBuilder::new()?;
        store.add_cert(ca.clone())?;
        let store = store.build();
        let mut certs = Stack::new()?;
        certs.push(ca.clone())?;
        let mut out = Vec::new();
        pkcs7.verify(
            &certs,
            &store,
            content.as_deref(),
            Some(&mut out),
            Pkcs7Flags::TEXT,
        )?;
        Ok(out)
    };
    verify().map_err(SecurityError::crypto("verifying a signed document"))
}
