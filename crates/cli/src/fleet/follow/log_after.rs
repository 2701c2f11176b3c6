//! Reads of the service's log after a cursor (a rowid), so that a round of `fleet follow`
//! reads what the log gained rather than all of it — by the runtime's readers
//! (`truepos_runtime::log`), read-only while the service writes the log.

use std::path::Path;

use truepos_runtime::log::{self, LoggedEvent, ProbeTable};

use crate::error::CliError;

/// The largest rowid of the log's probes (0: no log, no table or no rows).
pub fn last_probe_row(path: &Path) -> Result<i64, CliError> {
    Ok(log::last_rows(path).probes)
}

/// The largest rowid of the log's events (0: no log, no table or no rows).
pub fn last_event_row(path: &Path) -> Result<i64, CliError> {
    Ok(log::last_rows(path).events)
}

/// The log's probes rows from rowid `from` on (that row included).
pub fn probes_from(path: &Path, from: i64) -> Result<ProbeTable, CliError> {
    log::read_probes_from(path, from).map_err(CliError::from)
}

/// The log's events after rowid `after`, oldest first, each with its rowid (none from a log
/// without an events table).
pub fn events_after(path: &Path, after: i64) -> Result<Vec<(i64, LoggedEvent)>, CliError> {
    log::read_all_events_after(path, after).map_err(CliError::from)
}
