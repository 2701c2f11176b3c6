//! `truepos fleet status --http ADDR`: the fleet's status as a page (`truepos_live::fleet`),
//! read from the store once per request of the page's JSON, until Ctrl-C or `--duration-s`.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use truepos_fleet_store::postgres::{Client, NoTls};
use truepos_fleet_store::status::MachineStatus;
use truepos_live::fleet::FleetServer;
use truepos_live::host::HttpArgs;

use crate::error::CliError;

/// Serves the page until a signal or `duration`.
pub fn serve(db: &str, http: HttpArgs, duration: Option<Duration>) -> Result<(), CliError> {
    // One connection, kept while it works and made again after it failed: a page read every
    // few seconds needs no pool.
    let conn: Mutex<Option<Client>> = Mutex::new(None);
    let db = db.to_string();
    let status = Arc::new(move || {
        let mut guard = conn
            .lock()
            .map_err(|_| "the store's connection was poisoned")?;
        if guard.is_none() {
            *guard = Some(Client::connect(&db, NoTls).map_err(|e| format!("PostgreSQL: {e}"))?);
        }
        let client = guard.as_mut().ok_or("no connection")?;
        match truepos_fleet_store::status::fleet(client) {
            Ok(all) => {
                let v: Vec<serde_json::Value> = all.iter().map(MachineStatus::to_json).collect();
                Ok(serde_json::json!({ "machines": v }))
            }
            Err(e) => {
                *guard = None;
                Err(format!("PostgreSQL: {e}"))
            }
        }
    });
    let server = FleetServer::start(http, status).map_err(CliError::refused)?;
    eprintln!("fleet view on http://{}/", server.addr());
    let stop = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGTERM, signal_hook::consts::SIGINT] {
        signal_hook::flag::register(signal, Arc::clone(&stop))
            .map_err(CliError::context("cannot install the signal handler: "))?;
    }
    let end = duration.map(|d| Instant::now() + d);
    while !stop.load(Ordering::Relaxed) && end.is_none_or(|e| Instant::now() < e) {
        std::thread::sleep(Duration::from_millis(100));
    }
    server.stop();
    Ok(())
}
