//! `truepos sign`: a new Ed25519 key pair, or a signature beside each model file
//! (`MODEL.sig`), which a service started with `--trusted-keys` asks of every model it loads
//! (`truepos_io::model_file::signature`).

use std::io::Write as _;
use std::path::PathBuf;

use truepos_io::model_file::signature::{public_hex, signature_line, signature_path, SecretKey};

use crate::error::CliError;

/// Arguments of `truepos sign`.
#[derive(clap::Args)]
pub struct Args {
    /// Make a new key pair: the secret key written to FILE (readable by its owner only), the
    /// public key to FILE.pub and printed — a line for a service's --trusted-keys list.
    #[arg(long, value_name = "FILE", conflicts_with_all = ["key", "models"])]
    new_key: Option<PathBuf>,
    /// The secret key to sign with.
    #[arg(long, value_name = "FILE", required_unless_present = "new_key")]
    key: Option<PathBuf>,
    /// Model files to sign; each gets MODEL.sig beside it.
    #[arg(required_unless_present = "new_key")]
    models: Vec<PathBuf>,
}

/// Runs `truepos sign`.
pub fn run(args: Args) -> Result<(), CliError> {
    if let Some(path) = &args.new_key {
        return new_key(path);
    }
    let key_path = args.key.as_ref().expect("clap requires --key");
    let key = SecretKey::load(key_path)?;
    for model in &args.models {
        let bytes = truepos_files::read::read(model, truepos_files::MODEL)?;
        let sig = signature_path(model);
        let inputs = [("--key", key_path.as_path()), ("MODEL", model.as_path())];
        crate::write::write_whole(&sig, signature_line(&key, &bytes), &inputs)?;
        println!("{}: signed by {}", sig.display(), public_hex(&key.public()));
    }
    Ok(())
}

fn new_key(path: &std::path::Path) -> Result<(), CliError> {
    let key = SecretKey::generate()
        .map_err(|e| CliError::refused(format!("cannot read the system's random source: {e}")))?;
    let mut public = path.as_os_str().to_owned();
    public.push(".pub");
    let public = PathBuf::from(public);
    let line = format!("{}\n", public_hex(&key.public()));
    // A key already there may be the one a fleet's trust lists name: never replaced.
    for p in [path, public.as_path()] {
        if std::fs::symlink_metadata(p).is_ok() {
            return Err(CliError::refused(format!(
                "--new-key: {} exists; a key is never overwritten (remove it first)",
                p.display()
            )));
        }
    }
    let mut secret = truepos_files::write::Pending::create_private(path, &[])?;
    secret
        .write_all(key.to_text().as_bytes())
        .map_err(|e| CliError::refused(format!("{}: cannot write: {e}", path.display())))?;
    crate::write::write_whole(&public, &line, &[])?;
    secret.commit()?;
    print!("{line}");
    Ok(())
}
