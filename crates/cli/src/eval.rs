//! `truepos eval`: a model on a recorded run.

/// Arguments of `truepos eval`.
#[derive(clap::Args)]
pub struct Args {}

pub fn run(_args: Args) -> Result<(), String> {
    Err("not yet".into())
}
