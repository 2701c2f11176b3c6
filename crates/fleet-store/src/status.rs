//! The fleet at a glance, from the store: per machine whether it is online (its last birth came
//! after its last death), when its last message came, which model generation it runs and which
//! wait (candidates, shadows), whether it compensated in its last stored second, and how many
//! faults it logged in the last hour. `truepos fleet status` prints it.
//!
//! A machine is a node of `fleet_nodes` or a machine of `fleet_models` (models may be
//! registered before the machine first reports). Each machine costs a handful of indexed
//! queries (the last second and event by the time key), fine for hundreds of machines.
//!
//! ```
//! use truepos_fleet_store::status::{compensating, Compensating, utc_text};
//! assert_eq!(compensating(Some(10), Some(10)), Compensating::Yes);
//! assert_eq!(compensating(Some(10), Some(4)), Compensating::Partly);
//! assert_eq!(compensating(Some(10), Some(0)), Compensating::No);
//! assert_eq!(compensating(None, None), Compensating::Unknown);
//! assert_eq!(utc_text(1_764_417_600.0), "2025-11-29 12:00:00Z");
//! ```

use std::collections::BTreeMap;

use postgres::GenericClient;

use crate::models::State;
use crate::schema::civil_date;

/// The event kinds that count as faults: what the service logs when a sensor, a position, a
/// source, a sink or the log fails, when it holds or has no model, when a reload is refused
/// and when a cycle runs late (`truepos_runtime::log`'s event names).
pub const FAULT_KINDS: &[&str] = &[
    "sensor-fault",
    "position-fault",
    "source-lost",
    "sink-failed",
    "log-failed",
    "holding",
    "no-model",
    "model-reload-failed",
    "overrun",
    "events-dropped",
];

/// Whether a machine compensated in its last stored second.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Compensating {
    /// Every cycle of the second applied compensation.
    Yes,
    /// Some did.
    Partly,
    /// None did.
    No,
    /// No second stored, or it carried no counts.
    Unknown,
}

impl Compensating {
    /// The word printed.
    pub fn as_str(self) -> &'static str {
        match self {
            Compensating::Yes => "yes",
            Compensating::Partly => "partly",
            Compensating::No => "no",
            Compensating::Unknown => "unknown",
        }
    }
}

/// Compensation in a second from its cycles and active cycles.
pub fn compensating(cycles: Option<i64>, active: Option<i64>) -> Compensating {
    match (cycles, active) {
        (Some(c), Some(a)) if c > 0 && a >= c => Compensating::Yes,
        (Some(c), Some(a)) if c > 0 && a > 0 => Compensating::Partly,
        (Some(c), Some(_)) if c > 0 => Compensating::No,
        _ => Compensating::Unknown,
    }
}

/// A machine's status.
#[derive(Debug, Clone, PartialEq)]
pub struct MachineStatus {
    /// Sparkplug group (`None`: a machine known only by its models).
    pub group: Option<String>,
    /// Machine (Sparkplug node id).
    pub machine: String,
    /// Online: born after its last death (`None`: never born).
    pub online: Option<bool>,
    /// When its last message arrived (birth, death, second or event), s since the epoch.
    pub last_message_unix_s: Option<f64>,
    /// The data time of its last stored second.
    pub last_second_unix_s: Option<f64>,
    /// That second's cycles and active cycles.
    pub cycles: Option<i64>,
    /// Of them, with compensation applied.
    pub active_cycles: Option<i64>,
    /// Faults among its events of the last hour (data time).
    pub faults_last_hour: i64,
    /// Its active model version.
    pub active_model: Option<i32>,
    /// Its candidates and shadows, by version.
    pub waiting: Vec<(i32, State)>,
}

impl MachineStatus {
    /// Whether it compensated in its last stored second.
    pub fn compensating(&self) -> Compensating {
        compensating(self.cycles, self.active_cycles)
    }

    /// As JSON (times as seconds since the epoch and as UTC text).
    pub fn to_json(&self) -> serde_json::Value {
        let utc = |t: Option<f64>| t.map(utc_text);
        serde_json::json!({
            "group": self.group,
            "machine": self.machine,
            "online": self.online,
            "last_message_unix_s": self.last_message_unix_s,
            "last_message_utc": utc(self.last_message_unix_s),
            "last_second_unix_s": self.last_second_unix_s,
            "cycles": self.cycles,
            "active_cycles": self.active_cycles,
            "compensating": self.compensating().as_str(),
            "faults_last_hour": self.faults_last_hour,
            "active_model": self.active_model,
            "waiting_models": self.waiting.iter()
                .map(|(v, s)| serde_json::json!({"version": v, "state": s.as_str()}))
                .collect::<Vec<_>>(),
        })
    }
}

/// `YYYY-MM-DD HH:MM:SSZ` of seconds since the Unix epoch.
pub fn utc_text(unix_s: f64) -> String {
    let s = unix_s.floor() as i64;
    let (y, m, d) = civil_date(s.div_euclid(86_400));
    let t = s.rem_euclid(86_400);
    format!(
        "{y:04}-{m:02}-{d:02} {:02}:{:02}:{:02}Z",
        t / 3600,
        t / 60 % 60,
        t % 60
    )
}

fn later(a: Option<f64>, b: Option<f64>) -> Option<f64> {
    match (a, b) {
        (Some(x), Some(y)) => Some(x.max(y)),
        (x, y) => x.or(y),
    }
}

/// Fills in a node's telemetry: last second, last event, faults of the last hour.
fn telemetry(db: &mut impl GenericClient, s: &mut MachineStatus) -> Result<(), postgres::Error> {
    let group = s.group.clone().unwrap_or_default();
    let key: [&(dyn postgres::types::ToSql + Sync); 2] = [&group, &s.machine];
    if let Some(r) = db.query_opt(
        "SELECT extract(epoch FROM t)::float8, cycles::int8, active_cycles::int8,
                extract(epoch FROM received_at)::float8
         FROM fleet_seconds WHERE group_id = $1 AND node_id = $2 ORDER BY t DESC LIMIT 1",
        &key,
    )? {
        s.last_second_unix_s = r.get(0);
        s.cycles = r.get(1);
        s.active_cycles = r.get(2);
        s.last_message_unix_s = later(s.last_message_unix_s, r.get(3));
    }
    if let Some(r) = db.query_opt(
        "SELECT extract(epoch FROM received_at)::float8 FROM fleet_events
         WHERE group_id = $1 AND node_id = $2 ORDER BY t DESC LIMIT 1",
        &key,
    )? {
        s.last_message_unix_s = later(s.last_message_unix_s, r.get(0));
    }
    let kinds: Vec<&str> = FAULT_KINDS.to_vec();
    s.faults_last_hour = db
        .query_one(
            "SELECT count(*) FROM fleet_events WHERE group_id = $1 AND node_id = $2
             AND t > now() - interval '1 hour' AND kind = ANY($3)",
            &[&group, &s.machine, &kinds],
        )?
        .get(0);
    Ok(())
}

/// Fills in a machine's models: the active version, the candidates and shadows.
fn models(db: &mut impl GenericClient, s: &mut MachineStatus) -> Result<(), postgres::Error> {
    for r in db.query(
        "SELECT version, state FROM fleet_models
         WHERE machine = $1 AND state IN ('active', 'candidate', 'shadow') ORDER BY version",
        &[&s.machine],
    )? {
        let version: i32 = r.get(0);
        match State::parse(r.get(1)) {
            Some(State::Active) => s.active_model = Some(version),
            Some(state) => s.waiting.push((version, state)),
            None => {}
        }
    }
    Ok(())
}

fn blank(group: Option<String>, machine: String) -> MachineStatus {
    MachineStatus {
        group,
        machine,
        online: None,
        last_message_unix_s: None,
        last_second_unix_s: None,
        cycles: None,
        active_cycles: None,
        faults_last_hour: 0,
        active_model: None,
        waiting: Vec::new(),
    }
}

/// The status of every machine the store knows, by machine name.
pub fn fleet(db: &mut impl GenericClient) -> Result<Vec<MachineStatus>, postgres::Error> {
    let mut all: BTreeMap<(String, String), MachineStatus> = BTreeMap::new();
    for r in db.query(
        "SELECT group_id, node_id, extract(epoch FROM born_at)::float8,
                extract(epoch FROM died_at)::float8 FROM fleet_nodes",
        &[],
    )? {
        let (group, node): (String, String) = (r.get(0), r.get(1));
        let (born, died): (Option<f64>, Option<f64>) = (r.get(2), r.get(3));
        let mut s = blank(Some(group.clone()), node.clone());
        s.online = born.map(|b| died.is_none_or(|d| b > d));
        s.last_message_unix_s = later(born, died);
        all.insert((node, group), s);
    }
    for r in db.query("SELECT DISTINCT machine FROM fleet_models", &[])? {
        let machine: String = r.get(0);
        if !all.keys().any(|(m, _)| *m == machine) {
            all.insert((machine.clone(), String::new()), blank(None, machine));
        }
    }
    let mut out: Vec<MachineStatus> = all.into_values().collect();
    for s in &mut out {
        if s.group.is_some() {
            telemetry(db, s)?;
        }
        models(db, s)?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_are_utc_text_and_the_later_of_two_is_taken() {
        assert_eq!(utc_text(0.0), "1970-01-01 00:00:00Z");
        assert_eq!(utc_text(86_399.9), "1970-01-01 23:59:59Z");
        assert_eq!(later(None, Some(2.0)), Some(2.0));
        assert_eq!(later(Some(3.0), Some(2.0)), Some(3.0));
        assert_eq!(later(None, None), None);
    }
}
