//! Output files go through the one door ([`truepos_files::write`]): written whole or not at
//! all (an exclusive temporary file beside the output, synced, renamed), and never over one of
//! the command's inputs, a device, a FIFO, a directory or a symbolic link. The functions here
//! only turn its errors into the CLI's.

use std::path::Path;

use crate::error::CliError;

pub use truepos_files::write::{Inputs, Pending};

/// Checks an output before the command does any work, so that a refusal comes at once; the
/// write checks it again.
pub fn check(path: &Path, inputs: Inputs<'_>) -> Result<(), CliError> {
    Ok(truepos_files::write::check_output(path, inputs)?)
}

/// Writes `bytes` as `path`, whole or not at all; `inputs` are the command's input files with
/// the options that named them.
pub fn write_whole(
    path: &Path,
    bytes: impl AsRef<[u8]>,
    inputs: Inputs<'_>,
) -> Result<(), CliError> {
    Ok(truepos_files::write::write_whole(
        path,
        bytes.as_ref(),
        inputs,
    )?)
}

/// Writes several files that belong together: all of them or none of this call's.
pub fn write_all_whole(files: &[(&Path, &[u8])], inputs: Inputs<'_>) -> Result<(), CliError> {
    Ok(truepos_files::write::write_all_whole(files, inputs)?)
}

/// An output written while the command runs (a CSV of many rows), renamed into place by
/// [`Pending::commit`] once complete.
pub fn create(path: &Path, inputs: Inputs<'_>) -> Result<Pending, CliError> {
    Ok(Pending::create(path, inputs)?)
}

/// Reads a whole text file of one kind through the one door for reading.
pub fn read_text(path: &Path, limit: truepos_files::Limit) -> Result<String, CliError> {
    Ok(truepos_files::read::read_text(path, limit)?)
}

/// Reads a whole file of one kind through the one door for reading.
pub fn read(path: &Path, limit: truepos_files::Limit) -> Result<Vec<u8>, CliError> {
    Ok(truepos_files::read::read(path, limit)?)
}
