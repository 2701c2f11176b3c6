//! Signature lines and trust lists are read from files anyone may have written: any text gives
//! an answer, never a panic, and only the exact signed bytes verify.

use proptest::prelude::*;
use truepos_io::model_file::signature::{signature_line, verify_line, SecretKey, TrustedKeys};

proptest! {
    #[test]
    fn any_signature_line_is_refused_or_verifies_only_the_signed_bytes(
        line in "\\PC{0,300}", bytes in proptest::collection::vec(any::<u8>(), 0..64),
    ) {
        let key = SecretKey::from_seed([3; 32]);
        let _ = verify_line(&line, &bytes, &[key.public()]);
    }

    #[test]
    fn a_changed_byte_never_verifies(
        bytes in proptest::collection::vec(any::<u8>(), 1..256), at in any::<prop::sample::Index>(),
        flip in 1u8..=255,
    ) {
        let key = SecretKey::from_seed([5; 32]);
        let line = signature_line(&key, &bytes);
        prop_assert!(verify_line(&line, &bytes, &[key.public()]).is_ok());
        let mut changed = bytes.clone();
        let i = at.index(changed.len());
        changed[i] ^= flip;
        prop_assert!(verify_line(&line, &changed, &[key.public()]).is_err());
    }

    #[test]
    fn any_trust_list_is_read_or_refused_by_line(text in "(\\PC|\n|#){0,400}") {
        let dir = std::env::temp_dir().join(format!("truepos-trust-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("keys.pub");
        std::fs::write(&path, &text).unwrap();
        match TrustedKeys::load(&path) {
            Ok(k) => prop_assert!(!k.keys.is_empty()),
            Err(e) => prop_assert!(e.to_string().contains("keys.pub"), "{e}"),
        }
    }
}
