//! Signed model files: who made a model, and that not one byte changed since.
//!
//! A model that moves axes should come from someone the machine's owner trusts, and a model
//! copied across a network or a fleet can be damaged or replaced on the way. A model file is
//! signed with Ed25519 (RFC 8032) over its exact bytes; the signature lives beside it in
//! `<model>.sig`, one line:
//!
//! ```text
//! ed25519 <public key, 64 hex digits> <signature, 128 hex digits>
//! ```
//!
//! A service started with a list of trusted public keys ([`TrustedKeys`], a text file of one
//! key in hex a line, `#` comments) loads a model only when its signature verifies under one of
//! them — at start and at every hot reload — and the bytes it verified are the bytes it parses
//! ([`super::load_entry_trusted`]). A secret key is a file of 64 hex digits
//! (the 32-byte seed), written readable by its owner only.
//!
//! ```
//! use truepos_io::model_file::signature::{signature_line, verify_line, SecretKey};
//! let key = SecretKey::from_seed([7; 32]);
//! let line = signature_line(&key, b"format = \"truepos-model\"\n");
//! assert!(verify_line(&line, b"format = \"truepos-model\"\n", &[key.public()]).is_ok());
//! assert!(verify_line(&line, b"format = \"truepos-model\" \n", &[key.public()]).is_err());
//! ```

use std::path::{Path, PathBuf};

use ed25519_dalek::{Signature, Signer, SigningKey, Verifier, VerifyingKey};

use crate::error::read_text;
use truepos_files::InputError;

/// A public key, as the trust list and the signature line write it.
pub type PublicKey = VerifyingKey;

/// A secret signing key.
pub struct SecretKey(SigningKey);

impl SecretKey {
    /// The key of a 32-byte seed.
    pub fn from_seed(seed: [u8; 32]) -> Self {
        Self(SigningKey::from_bytes(&seed))
    }

    /// A new key from the operating system's random source.
    pub fn generate() -> std::io::Result<Self> {
        use std::io::Read;
        let mut seed = [0u8; 32];
        std::fs::File::open("/dev/urandom")?.read_exact(&mut seed)?;
        Ok(Self::from_seed(seed))
    }

    /// Reads a secret key file: 64 hex digits, surrounding white space allowed.
    pub fn load(path: &Path) -> Result<Self, InputError> {
        let text = read_text(path, truepos_files::CONFIG)?;
        let seed = hex_array::<32>(text.trim()).ok_or_else(|| {
            InputError::at(
                path,
                1,
                1,
                "",
                "expected 64 hex digits (an Ed25519 secret key)",
            )
        })?;
        Ok(Self::from_seed(seed))
    }

    /// The file's text: the seed in hex.
    pub fn to_text(&self) -> String {
        format!("{}\n", hex(self.0.as_bytes()))
    }

    /// Its public key.
    pub fn public(&self) -> PublicKey {
        self.0.verifying_key()
    }
}

/// The public key in hex, as a trust list holds it.
pub fn public_hex(key: &PublicKey) -> String {
    hex(key.as_bytes())
}

/// Where a model's signature lives: the model's path with `.sig` added.
pub fn signature_path(model: &Path) -> PathBuf {
    let mut p = model.as_os_str().to_owned();
    p.push(".sig");
    PathBuf::from(p)
}

/// The signature line of `bytes` under `key`.
pub fn signature_line(key: &SecretKey, bytes: &[u8]) -> String {
    let sig = key.0.sign(bytes);
    format!(
        "ed25519 {} {}\n",
        public_hex(&key.public()),
        hex(&sig.to_bytes())
    )
}

/// Checks a signature line against `bytes` and the trusted keys; the error says what is wrong
/// in words (not the form, a key not trusted, a signature that does not verify).
pub fn verify_line(line: &str, bytes: &[u8], trusted: &[PublicKey]) -> Result<(), String> {
    let mut words = line.split_whitespace();
    let (Some("ed25519"), Some(key), Some(sig), None) =
        (words.next(), words.next(), words.next(), words.next())
    else {
        return Err("expected `ed25519 <public key> <signature>`".into());
    };
    let key = hex_array::<32>(key)
        .and_then(|k| VerifyingKey::from_bytes(&k).ok())
        .ok_or("the public key is not 64 hex digits of an Ed25519 key")?;
    let sig = hex_array::<64>(sig).ok_or("the signature is not 128 hex digits")?;
    if !trusted.contains(&key) {
        return Err(format!(
            "signed by {}, a key not in the trust list",
            public_hex(&key)
        ));
    }
    key.verify(bytes, &Signature::from_bytes(&sig))
        .map_err(|_| "the signature does not match the file: it was changed after signing, or signed by another key".into())
}

/// The public keys a service trusts to sign its models.
#[derive(Debug, Clone)]
pub struct TrustedKeys {
    /// The trust list's file, for messages.
    pub file: PathBuf,
    /// The keys.
    pub keys: Vec<PublicKey>,
}

impl TrustedKeys {
    /// Reads a trust list: one public key in hex a line; blank lines and `#` comments skipped;
    /// at least one key. A line that is not a key is named at its line.
    pub fn load(path: &Path) -> Result<Self, InputError> {
        let text = read_text(path, truepos_files::CONFIG)?;
        let mut keys = Vec::new();
        for (i, line) in text.lines().enumerate() {
            let word = line.split('#').next().unwrap_or("").trim();
            if word.is_empty() {
                continue;
            }
            let key = hex_array::<32>(word)
                .and_then(|k| VerifyingKey::from_bytes(&k).ok())
                .ok_or_else(|| {
                    InputError::at(
                        path,
                        i + 1,
                        1,
                        "",
                        format!("expected an Ed25519 public key (64 hex digits), got `{word}`"),
                    )
                })?;
            keys.push(key);
        }
        if keys.is_empty() {
            return Err(InputError::file(
                path,
                "expected at least one public key (64 hex digits a line)",
            ));
        }
        Ok(Self {
            file: path.to_path_buf(),
            keys,
        })
    }

    /// Checks that `bytes`, the text of `model`, carry a signature from a trusted key in
    /// [`signature_path`]; the error names the model and the signature file.
    pub fn verify(&self, model: &Path, bytes: &[u8]) -> Result<(), InputError> {
        let sig_path = signature_path(model);
        let line = read_text(&sig_path, truepos_files::CONFIG).map_err(|e| {
            InputError::file(
                model,
                format!(
                    "refused: no signature readable at {} (the trust list {} asks for one): {}",
                    sig_path.display(),
                    self.file.display(),
                    e.message
                ),
            )
        })?;
        verify_line(&line, bytes, &self.keys).map_err(|why| {
            InputError::file(model, format!("refused: {}: {why}", sig_path.display()))
        })
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn hex_array<const N: usize>(text: &str) -> Option<[u8; N]> {
    if text.len() != 2 * N || !text.is_ascii() {
        return None;
    }
    let mut out = [0u8; N];
    for (i, o) in out.iter_mut().enumerate() {
        *o = u8::from_str_radix(&text[2 * i..2 * i + 2], 16).ok()?;
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_changed_byte_an_unknown_key_or_a_broken_line_is_refused() {
        let key = SecretKey::from_seed([1; 32]);
        let other = SecretKey::from_seed([2; 32]);
        let text = b"k0_um_per_k = 2.0\n";
        let line = signature_line(&key, text);
        assert_eq!(
            verify_line(&line, text, &[other.public(), key.public()]),
            Ok(())
        );
        assert!(verify_line(&line, b"k0_um_per_k = 2.5\n", &[key.public()])
            .unwrap_err()
            .contains("does not match"));
        assert!(verify_line(&line, text, &[other.public()])
            .unwrap_err()
            .contains("not in the trust list"));
        for bad in [
            "",
            "ed25519",
            "rsa a b",
            &line.replace("ed25519 ", "ed25519 zz"),
            &format!("{} x", line.trim()),
        ] {
            assert!(verify_line(bad, text, &[key.public()]).is_err(), "{bad}");
        }
        // A signature by the trusted key, moved onto another file.
        let line2 = signature_line(&key, b"other\n");
        assert!(verify_line(&line2, text, &[key.public()]).is_err());
    }

    #[test]
    fn keys_read_back_and_hex_is_checked() {
        let key = SecretKey::from_seed([9; 32]);
        assert_eq!(hex_array::<32>(key.to_text().trim()), Some([9; 32]));
        assert_eq!(hex_array::<2>("0g00"), None);
        assert_eq!(hex_array::<2>("ééé"), None);
        assert_eq!(hex_array::<2>("00ff"), Some([0, 255]));
        assert_eq!(
            signature_path(Path::new("a/m.toml")),
            PathBuf::from("a/m.toml.sig")
        );
    }
}
