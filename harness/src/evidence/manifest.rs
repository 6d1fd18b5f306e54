//! The evidence folder's SHA-256 manifest, its seal and ed25519 signature, and `rig verify`.
//!
//! - `MANIFEST.sha256`: `<hex>  <path>` per file (the `sha256sum -c` format), every regular file
//!   in the folder except the manifest and the seal, sorted by path.
//! - `MANIFEST.sha256.sig` (the seal), three lines: `manifest-sha256 <hex>`, `signature <hex>`
//!   (ed25519 over the manifest's bytes, or `none` when no key was given) and `seal-sha256 <hex>`
//!   (SHA-256 of the first two lines). The two digests are not a security measure (anyone can
//!   recompute them); they let [`verify`] tell *which* file changed: a byte flipped in the seal
//!   breaks its own digest, one flipped in the manifest breaks `manifest-sha256`. The ed25519
//!   signature is what makes the folder tamper-evident to someone who holds the public key.
//! - `signing-key.pub.pem`: the public key (SPKI PEM, as `openssl pkey -pubout` writes it). A
//!   reviewer must compare its fingerprint with the one the team published (or pass the
//!   published key to `rig verify --pubkey`): a key shipped inside the folder proves nothing by
//!   itself.
//!
//! Keys are ed25519 PKCS#8 PEM files, e.g. `openssl genpkey -algorithm ed25519 -out key.pem`
//! (crate `ed25519-dalek`). The signature also checks with openssl:
//! `openssl pkeyutl -verify -pubin -inkey signing-key.pub.pem -rawin -in MANIFEST.sha256
//! -sigfile <(sed -n 's/^signature //p' MANIFEST.sha256.sig | xxd -r -p)`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use ed25519_dalek::pkcs8::spki::der::pem::LineEnding;
use ed25519_dalek::pkcs8::{DecodePrivateKey, DecodePublicKey, EncodePublicKey};
use ed25519_dalek::{Signature, Signer, SigningKey, VerifyingKey};

use crate::record::{sha256_bytes, sha256_file};

/// The manifest's file name.
pub const MANIFEST_FILE: &str = "MANIFEST.sha256";
/// The seal's file name.
pub const SEAL_FILE: &str = "MANIFEST.sha256.sig";
/// The public key's file name.
pub const PUBKEY_FILE: &str = "signing-key.pub.pem";

/// What can be wrong with an evidence folder. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum VerifyError {
    /// The folder has no manifest or seal: not an evidence folder (exit 2).
    #[error("{0}: missing: not an evidence folder, or it was removed")]
    Missing(PathBuf),
    /// A file cannot be read (exit 2).
    #[error("{path}: cannot read: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    /// A file differs from what the manifest (or the seal, for the manifest) says.
    #[error("{path}: changed (sha256 {actual}, expected {expected})")]
    Changed {
        path: String,
        expected: String,
        actual: String,
    },
    /// A line of the manifest or seal is not in its format.
    #[error("{path}:{line}: changed: {what}")]
    Malformed {
        path: String,
        line: usize,
        what: String,
    },
    /// A file the manifest lists is gone.
    #[error("{0}: listed in MANIFEST.sha256 but missing")]
    Removed(String),
    /// A file is in the folder but not in the manifest.
    #[error("{0}: not listed in MANIFEST.sha256 (added after sealing)")]
    Added(String),
    /// The signature does not verify with the key.
    #[error(
        "{SEAL_FILE}: the signature over {MANIFEST_FILE} is not valid for the key {key} ({fingerprint})"
    )]
    BadSignature { key: String, fingerprint: String },
    /// The key file is not an ed25519 public key.
    #[error("{path}: not an ed25519 public key (SPKI PEM): {message}")]
    BadKey { path: String, message: String },
}

impl VerifyError {
    /// `rig verify`'s exit code for this error: 1 evidence changed, 2 not readable as evidence.
    pub fn exit_code(&self) -> u8 {
        match self {
            VerifyError::Missing(_) | VerifyError::Read { .. } => 2,
            _ => 1,
        }
    }
}

/// Errors signing a folder.
#[derive(Debug, thiserror::Error)]
pub enum SealError {
    #[error("{path}: cannot read the signing key: {source}")]
    ReadKey {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error(
        "{path}: not an ed25519 private key in PKCS#8 PEM ({message}); make one with \
         `openssl genpkey -algorithm ed25519 -out {path}`"
    )]
    BadKey { path: PathBuf, message: String },
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
}

/// Reads an ed25519 PKCS#8 PEM private key.
pub fn load_signing_key(path: &Path) -> Result<SigningKey, SealError> {
    let pem = std::fs::read_to_string(path).map_err(|source| SealError::ReadKey {
        path: path.to_owned(),
        source,
    })?;
    SigningKey::from_pkcs8_pem(&pem).map_err(|e| SealError::BadKey {
        path: path.to_owned(),
        message: e.to_string(),
    })
}

/// SHA-256 of the key's raw 32 bytes: what a team publishes so reviewers can check the key.
pub fn fingerprint(key: &VerifyingKey) -> String {
    format!("sha256:{}", sha256_bytes(key.as_bytes()))
}

/// Every regular file under `dir`, as `/`-separated relative paths, sorted. A symbolic link
/// is an error naming it: what it leads to can change after sealing, outside the folder.
fn files(dir: &Path) -> std::io::Result<Vec<String>> {
    fn walk(root: &Path, dir: &Path, out: &mut Vec<String>) -> std::io::Result<()> {
        for entry in std::fs::read_dir(dir)? {
            let entry = entry?;
            let kind = entry.file_type()?;
            let path = entry.path();
            if kind.is_symlink() {
                return Err(std::io::Error::other(format!(
                    "{} is a symbolic link: an evidence folder holds files only",
                    path.display()
                )));
            }
            if kind.is_dir() {
                walk(root, &path, out)?;
            } else {
                let rel = path.strip_prefix(root).expect("walked from root");
                out.push(
                    rel.components()
                        .map(|c| c.as_os_str().to_string_lossy())
                        .collect::<Vec<_>>()
                        .join("/"),
                );
            }
        }
        Ok(())
    }
    let mut out = Vec::new();
    walk(dir, dir, &mut out)?;
    out.sort();
    Ok(out)
}

/// Writes the public key (when signing), the manifest of every file, and the seal.
pub fn seal(dir: &Path, key: Option<&SigningKey>) -> Result<(), SealError> {
    let io = |path: &Path| {
        let path = path.to_owned();
        move |source| SealError::Io { path, source }
    };
    if let Some(key) = key {
        let pem = key
            .verifying_key()
            .to_public_key_pem(LineEnding::LF)
            .expect("an ed25519 key always encodes");
        let p = dir.join(PUBKEY_FILE);
        std::fs::write(&p, pem).map_err(io(&p))?;
    }
    let mut manifest = String::new();
    for rel in files(dir).map_err(io(dir))? {
        if rel == MANIFEST_FILE || rel == SEAL_FILE {
            continue;
        }
        let p = dir.join(&rel);
        let digest = sha256_file(&p).map_err(io(&p))?;
        manifest.push_str(&format!("{digest}  {rel}\n"));
    }
    let p = dir.join(MANIFEST_FILE);
    std::fs::write(&p, &manifest).map_err(io(&p))?;
    let signature = match key {
        Some(key) => hex(&key.sign(manifest.as_bytes()).to_bytes()),
        None => "none".to_owned(),
    };
    let body = format!(
        "manifest-sha256 {}\nsignature {signature}\n",
        sha256_bytes(manifest.as_bytes())
    );
    let seal = format!("{body}seal-sha256 {}\n", sha256_bytes(body.as_bytes()));
    let p = dir.join(SEAL_FILE);
    std::fs::write(&p, seal).map_err(io(&p))?;
    Ok(())
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn unhex(s: &str) -> Option<Vec<u8>> {
    if !s.len().is_multiple_of(2) {
        return None;
    }
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(s.get(i..i + 2)?, 16).ok())
        .collect()
}

/// What a successful [`verify`] found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Verified {
    /// Files checked (the manifest's entries).
    pub files: usize,
    /// The key's fingerprint when the folder is signed and the signature holds; `None` when
    /// unsigned (the digests match, but nothing says who made the folder).
    pub signed_by: Option<String>,
}

/// Re-checks every digest and the signature of the evidence folder `dir`. `pubkey` pins the
/// key (else the folder's own `signing-key.pub.pem` is used and its fingerprint reported).
pub fn verify(dir: &Path, pubkey: Option<&Path>) -> Result<Verified, VerifyError> {
    let read = |rel: &str| {
        let p = dir.join(rel);
        if !p.exists() {
            return Err(VerifyError::Missing(p));
        }
        std::fs::read(&p).map_err(|source| VerifyError::Read { path: p, source })
    };
    let seal = read(SEAL_FILE)?;
    let manifest = read(MANIFEST_FILE)?;

    // The seal first: its own digest says whether it is intact.
    let seal_text = String::from_utf8_lossy(&seal);
    let lines: Vec<&str> = seal_text.split_inclusive('\n').collect();
    let malformed = |line: usize, what: &str| VerifyError::Malformed {
        path: SEAL_FILE.into(),
        line,
        what: what.into(),
    };
    if lines.len() != 3 || !seal_text.ends_with('\n') {
        return Err(malformed(lines.len(), "not the three lines of a seal"));
    }
    let field = |n: usize, key: &str| {
        lines[n]
            .strip_prefix(key)
            .and_then(|r| r.strip_prefix(' '))
            .map(|r| r.trim_end_matches('\n'))
            .ok_or_else(|| malformed(n + 1, &format!("expected `{key} ...`")))
    };
    let seal_digest = field(2, "seal-sha256")?;
    let body = format!("{}{}", lines[0], lines[1]);
    if sha256_bytes(body.as_bytes()) != seal_digest {
        return Err(VerifyError::Changed {
            path: SEAL_FILE.into(),
            expected: seal_digest.into(),
            actual: sha256_bytes(body.as_bytes()),
        });
    }
    let manifest_digest = field(0, "manifest-sha256")?;
    let signature = field(1, "signature")?;
    if sha256_bytes(&manifest) != manifest_digest {
        return Err(VerifyError::Changed {
            path: MANIFEST_FILE.into(),
            expected: manifest_digest.into(),
            actual: sha256_bytes(&manifest),
        });
    }

    // Then every file against the manifest, and nothing more in the folder.
    let text = String::from_utf8_lossy(&manifest);
    let mut listed = BTreeMap::new();
    for (i, line) in text.lines().enumerate() {
        let bad = || VerifyError::Malformed {
            path: MANIFEST_FILE.into(),
            line: i + 1,
            what: format!("not `<sha256>  <path>`: {line:?}"),
        };
        let (digest, rel) = line.split_once("  ").ok_or_else(bad)?;
        if digest.len() != 64 || unhex(digest).is_none() || rel.is_empty() {
            return Err(bad());
        }
        listed.insert(rel.to_owned(), digest.to_owned());
    }
    for (rel, expected) in &listed {
        let p = dir.join(rel);
        if !p.is_file() {
            return Err(VerifyError::Removed(rel.clone()));
        }
        let actual = sha256_file(&p).map_err(|source| VerifyError::Read { path: p, source })?;
        if &actual != expected {
            return Err(VerifyError::Changed {
                path: rel.clone(),
                expected: expected.clone(),
                actual,
            });
        }
    }
    let present = files(dir).map_err(|source| VerifyError::Read {
        path: dir.to_owned(),
        source,
    })?;
    if let Some(extra) = present
        .into_iter()
        .find(|f| f != MANIFEST_FILE && f != SEAL_FILE && !listed.contains_key(f))
    {
        return Err(VerifyError::Added(extra));
    }

    // Last, the signature over the manifest.
    if signature == "none" {
        return Ok(Verified {
            files: listed.len(),
            signed_by: None,
        });
    }
    let sig = unhex(signature)
        .and_then(|b| <[u8; 64]>::try_from(b).ok())
        .map(|b| Signature::from_bytes(&b))
        .ok_or_else(|| malformed(2, "the signature is not 64 bytes of hex"))?;
    let key_path = pubkey
        .map(Path::to_path_buf)
        .unwrap_or_else(|| dir.join(PUBKEY_FILE));
    let pem = std::fs::read_to_string(&key_path).map_err(|source| VerifyError::Read {
        path: key_path.clone(),
        source,
    })?;
    let key = VerifyingKey::from_public_key_pem(&pem).map_err(|e| VerifyError::BadKey {
        path: key_path.display().to_string(),
        message: e.to_string(),
    })?;
    key.verify_strict(&manifest, &sig)
        .map_err(|_| VerifyError::BadSignature {
            key: key_path.display().to_string(),
            fingerprint: fingerprint(&key),
        })?;
    Ok(Verified {
        files: listed.len(),
        signed_by: Some(fingerprint(&key)),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fixed test key (RFC 8032 test 1 secret), so the tests need no randomness.
    fn key() -> SigningKey {
        SigningKey::from_bytes(&[
            0x9d, 0x61, 0xb1, 0x9d, 0xef, 0xfd, 0x5a, 0x60, 0xba, 0x84, 0x4a, 0xf4, 0x92, 0xec,
            0x2c, 0xc4, 0x44, 0x49, 0xc5, 0x69, 0x7b, 0x38, 0x69, 0x19, 0x70, 0x3b, 0xac, 0x03,
            0x1c, 0xae, 0x7f, 0x60,
        ])
    }

    fn folder(signed: bool) -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("report.html"),
            "<html>verdict PASS</html>\n",
        )
        .unwrap();
        std::fs::write(
            dir.path().join("provenance.intoto.json"),
            "{\"_type\":\"https://in-toto.io/Statement/v1\"}\n",
        )
        .unwrap();
        std::fs::create_dir(dir.path().join("phase")).unwrap();
        std::fs::write(dir.path().join("phase/fc-frames.csv"), "t_ms,gap_ms\n1,7\n").unwrap();
        seal(dir.path(), signed.then(key).as_ref()).unwrap();
        dir
    }

    fn flip(path: &Path, at: usize) {
        let mut bytes = std::fs::read(path).unwrap();
        bytes[at] ^= 0x01;
        std::fs::write(path, bytes).unwrap();
    }

    #[test]
    fn a_sealed_folder_verifies_and_names_its_key() {
        let dir = folder(true);
        let v = verify(dir.path(), None).unwrap();
        assert_eq!(v.files, 4, "three files and the public key");
        assert_eq!(v.signed_by, Some(fingerprint(&key().verifying_key())));
        let unsigned = folder(false);
        assert_eq!(verify(unsigned.path(), None).unwrap().signed_by, None);
    }

    /// Every byte of every file, flipped one at a time: each is caught and the error names the
    /// file that changed (the manifest, a report, the statement, the seal, the key).
    #[test]
    fn every_single_flipped_byte_is_caught_and_the_file_named() {
        let dir = folder(true);
        for rel in [
            MANIFEST_FILE,
            "report.html",
            "provenance.intoto.json",
            "phase/fc-frames.csv",
            SEAL_FILE,
            PUBKEY_FILE,
        ] {
            let path = dir.path().join(rel);
            let len = std::fs::metadata(&path).unwrap().len() as usize;
            for at in 0..len {
                flip(&path, at);
                let err = verify(dir.path(), None).expect_err(&format!("{rel}[{at}] flipped"));
                let msg = err.to_string();
                assert!(msg.starts_with(&format!("{rel}:")), "{rel}[{at}]: {msg}");
                assert_eq!(err.exit_code(), 1, "{msg}");
                flip(&path, at);
            }
            verify(dir.path(), None).unwrap();
        }
    }

    #[test]
    fn a_resigned_manifest_fails_against_the_published_key() {
        // Someone edits a report, re-seals with their own key: the folder is consistent, but the
        // team's published key rejects it.
        let dir = folder(true);
        let published = dir.path().join("../published.pem");
        std::fs::copy(dir.path().join(PUBKEY_FILE), &published).unwrap();
        std::fs::write(
            dir.path().join("report.html"),
            "<html>verdict FAIL</html>\n",
        )
        .unwrap();
        let other = SigningKey::from_bytes(&[7; 32]);
        seal(dir.path(), Some(&other)).unwrap();
        verify(dir.path(), None).unwrap();
        let err = verify(dir.path(), Some(&published))
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with(SEAL_FILE) && err.contains("not valid"),
            "{err}"
        );
        std::fs::remove_file(published).unwrap();
    }

    #[test]
    fn added_and_removed_files_are_named() {
        let dir = folder(false);
        std::fs::write(dir.path().join("extra.txt"), "x").unwrap();
        let err = verify(dir.path(), None).unwrap_err().to_string();
        assert!(err.starts_with("extra.txt: not listed"), "{err}");
        std::fs::remove_file(dir.path().join("extra.txt")).unwrap();
        std::fs::remove_file(dir.path().join("phase/fc-frames.csv")).unwrap();
        let err = verify(dir.path(), None).unwrap_err().to_string();
        assert!(err.starts_with("phase/fc-frames.csv: listed"), "{err}");
        let empty = tempfile::tempdir().unwrap();
        assert_eq!(verify(empty.path(), None).unwrap_err().exit_code(), 2);
    }

    #[test]
    fn a_symbolic_link_is_refused_by_name() {
        let refused = |err: String, name: &str| {
            assert!(err.contains(name) && err.contains("symbolic link"), "{err}");
        };
        // sealing a folder with one
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("results.json"), "{}\n").unwrap();
        std::os::unix::fs::symlink("/dev/pts/2", dir.path().join("radio-air")).unwrap();
        let err = anyhow::Error::from(seal(dir.path(), None).unwrap_err());
        refused(format!("{err:#}"), "radio-air");
        // one added to a sealed folder
        let dir = folder(false);
        std::os::unix::fs::symlink("/etc/passwd", dir.path().join("phase/trace.csv")).unwrap();
        let err = anyhow::Error::from(verify(dir.path(), None).unwrap_err());
        refused(format!("{err:#}"), "trace.csv");
    }

    #[test]
    fn a_key_that_is_not_pkcs8_is_a_clear_error() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("key.pem");
        std::fs::write(&p, "not a key").unwrap();
        let err = load_signing_key(&p).unwrap_err().to_string();
        assert!(err.contains("openssl genpkey -algorithm ed25519"), "{err}");
    }
}
