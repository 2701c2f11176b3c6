//! The cursor: what one broker acknowledged, kept in a small JSON file beside the log
//! (`LOG.<host>_<port>.mqtt-cursor`), one per broker. A side file and not a table in the log:
//! the logger thread stays the log's only writer (a second writer would take SQLite's one write
//! lock from it every second) and the publisher's connection to the log stays read-only, so
//! the log's tables and `Logger::start`'s check of them are unchanged. Written whole or not at
//! all (temporary file, fsync, rename); a lost or unreadable cursor costs a replay marked
//! historical, never a loss.

use std::path::{Path, PathBuf};

use crate::mqtt::BrokerUrl;
use crate::store::Rows;

/// The cursor file's content.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Cursor {
    /// The broker it belongs to.
    pub broker: String,
    /// Rows the broker acknowledged.
    pub rows: Rows,
    /// The clock time of the service's time 0 for those rows (a log appended to by several runs
    /// restarts its service time at each).
    pub run_start_unix_s: f64,
    /// The last Sparkplug `bdSeq` used, so the next connection takes the next one.
    pub bd_seq: u8,
}

/// The cursor file of `log` for `broker`.
pub fn path_for(log: &Path, broker: &BrokerUrl) -> PathBuf {
    let host: String = broker
        .host
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '.' || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect();
    let mut p = log.as_os_str().to_owned();
    p.push(format!(".{host}_{}.mqtt-cursor", broker.port));
    p.into()
}

/// Reads a cursor file: `Ok(None)` when there is none; a file that is not a cursor is an
/// error naming it (the caller decides; the publisher refuses to start rather than replay
/// a log the operator may not want replayed).
pub fn load(path: &Path) -> Result<Option<Cursor>, String> {
    let text = match truepos_files::read::read_text(path, truepos_files::CONFIG) {
        Ok(t) => t,
        Err(e) if e.is_not_found() => return Ok(None),
        Err(e) => return Err(e.to_string()),
    };
    serde_json::from_str(&text).map(Some).map_err(|e| {
        format!(
            "{}: not a cursor file ({e}); remove it to forward this run again",
            path.display()
        )
    })
}

/// Writes the cursor file whole.
pub fn save(path: &Path, c: &Cursor) -> Result<(), String> {
    let text = serde_json::to_string(c).map_err(|e| e.to_string())?;
    truepos_files::write::write_whole(path, text.as_bytes(), &[]).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::Cursor;

    #[test]
    fn a_cursor_written_before_probes_were_forwarded_still_loads() {
        let old = r#"{"broker":"mqtt://127.0.0.1:1883","rows":{"cycles":120,"events":7},"run_start_unix_s":1764400000.0,"bd_seq":3}"#;
        let c: Cursor = serde_json::from_str(old).unwrap();
        assert_eq!((c.rows.cycles, c.rows.events), (120, 7));
        // Not known: the publisher starts its probes where a new broker's would start.
        assert_eq!(c.rows.probes, -1);
        let new: Cursor = serde_json::from_str(&serde_json::to_string(&c).unwrap()).unwrap();
        assert_eq!(new, c);
    }
}
