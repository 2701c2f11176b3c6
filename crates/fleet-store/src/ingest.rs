//! The ingester: subscribes to `spBv1.0/#` at QoS 1 with a persistent session and writes each
//! node's births, seconds, events and probe events to PostgreSQL, acknowledging a message only once its rows
//! are committed. A row that exists already (the same machine and data time) is left as it is,
//! so whatever the broker or a publisher sends again is written once. A message that is not
//! Sparkplug, or NDATA of a node whose birth is unknown, is counted and acknowledged (skipped);
//! a database failure drops the MQTT connection unacknowledged, so the broker keeps the
//! message for the reconnect.

use std::collections::HashMap;
use std::time::{Duration, Instant};

use postgres::{Client, GenericClient, NoTls};
use truepos_fleet::mqtt::{Connection, Incoming};
use truepos_fleet::sparkplug::{Payload, Value};
use truepos_fleet::BrokerUrl;

use crate::schema::{self, Partitions};

/// What a message was, for the summary.
#[derive(Debug, Clone, PartialEq)]
pub enum Outcome {
    /// NBIRTH: the node's names recorded.
    Birth,
    /// NDEATH.
    Death,
    /// A second's row: written, or there already.
    Second {
        /// New.
        written: bool,
    },
    /// An event's row.
    Event {
        /// New.
        written: bool,
    },
    /// A probe event's row.
    Probe {
        /// New.
        written: bool,
    },
    /// Not stored, and why.
    Skipped(String),
}

/// A decoded NDATA as rows.
#[derive(Debug, Clone, PartialEq)]
pub enum Row {
    /// A second of cycles.
    Second {
        /// Data time, ms since the epoch.
        t_ms: i64,
        /// Cycles and active cycles.
        cycles: Option<i64>,
        /// Of those, active.
        active: Option<i64>,
        /// `{"Inputs/t1": [min, mean, max], …}`.
        stats: serde_json::Value,
        /// Sent from the store after an outage.
        historical: bool,
    },
    /// An event.
    Event {
        /// Data time, ms since the epoch.
        t_ms: i64,
        /// Kind, subject, detail.
        fields: [String; 3],
        /// Sent from the store after an outage.
        historical: bool,
    },
    /// An accepted probe event.
    Probe {
        /// Data time, ms since the epoch.
        t_ms: i64,
        /// Its cycle's compensation state.
        state: Option<String>,
        /// `{"probe_dz_um": -3.1, "probe_z_mm": -50.0, "t1": 21.3, …}` (null: no value).
        values: serde_json::Value,
        /// Sent from the store after an outage.
        historical: bool,
    },
}

/// `spBv1.0/<group>/<NBIRTH|NDATA|NDEATH>/<node>` taken apart; anything else is `None`.
pub fn parse_topic(topic: &str) -> Option<(&str, &str, &str)> {
    let mut parts = topic.split('/');
    let (ns, group, kind, node) = (parts.next()?, parts.next()?, parts.next()?, parts.next()?);
    (ns == "spBv1.0" && parts.next().is_none() && !group.is_empty() && !node.is_empty())
        .then_some((group, kind, node))
}

fn number(v: &Value) -> Option<f64> {
    match v {
        Value::Double(x) => Some(*x),
        Value::UInt32(x) => Some(f64::from(*x)),
        Value::UInt64(x) => Some(*x as f64),
        _ => None,
    }
}

/// The first and last instants a stored row may have, ms since the Unix epoch (2000-01-01 and
/// 2200-01-01): beyond them PostgreSQL's timestamps and the day partitions still work, but no
/// machine's clock is right, and a time far beyond them fails the database's conversion.
const TIME_RANGE_MS: (u64, u64) = (946_684_800_000, 7_258_118_400_000);

/// A message's time in ms, if a machine's clock can have read it.
fn plausible_time(t_ms: u64) -> Result<i64, String> {
    if (TIME_RANGE_MS.0..=TIME_RANGE_MS.1).contains(&t_ms) {
        Ok(t_ms as i64)
    } else {
        Err(format!(
            "a time of {t_ms} ms since 1970, outside the years 2000 to 2200"
        ))
    }
}

/// Text as PostgreSQL can store it: `text` and `jsonb` refuse the NUL character, which a
/// Sparkplug string may carry.
fn storable(text: &str) -> String {
    text.replace('\0', "\u{fffd}")
}

/// An NDATA's rows, its metrics named through the node's birth (`names`: alias → name).
pub fn rows(p: &Payload, names: &HashMap<u64, String>) -> Result<Row, String> {
    let mut stats = serde_json::Map::new();
    let (mut cycles, mut active) = (None, None);
    let mut event: [Option<String>; 3] = Default::default();
    let mut probe = serde_json::Map::new();
    let mut probe_state = None;
    let mut t_ms = None;
    let mut historical = false;
    for m in &p.metrics {
        let name = if m.name.is_empty() {
            let a = m.alias.ok_or("a metric with neither name nor alias")?;
            names
                .get(&a)
                .ok_or_else(|| format!("alias {a} is not in the node's birth"))?
                .as_str()
        } else {
            m.name.as_str()
        };
        t_ms = t_ms.or(m.timestamp_ms);
        historical |= m.historical;
        match name {
            "Cycles" => cycles = number(&m.value).map(|x| x as i64),
            "Active cycles" => active = number(&m.value).map(|x| x as i64),
            "Event/Kind" | "Event/Subject" | "Event/Detail" => {
                let i = ["Event/Kind", "Event/Subject", "Event/Detail"]
                    .iter()
                    .position(|n| *n == name)
                    .unwrap_or(0);
                if let Value::String(s) = &m.value {
                    event[i] = Some(s.clone());
                }
            }
            "Probe/state" => {
                if let Value::String(s) = &m.value {
                    probe_state = Some(storable(s));
                }
            }
            _ if name.starts_with("Probe/") => {
                let column = &name["Probe/".len()..];
                probe.insert(
                    storable(column),
                    number(&m.value).map_or(serde_json::Value::Null, |x| x.into()),
                );
            }
            _ => {
                let Some((column, stat)) = name.rsplit_once('/') else {
                    continue;
                };
                let k = match stat {
                    "min" => 0,
                    "mean" => 1,
                    "max" => 2,
                    _ => continue,
                };
                let entry = stats
                    .entry(storable(column))
                    .or_insert_with(|| serde_json::json!([null, null, null]));
                entry[k] = number(&m.value).map_or(serde_json::Value::Null, |x| x.into());
            }
        }
    }
    let t_ms = plausible_time(t_ms.unwrap_or(p.timestamp_ms))?;
    if let [Some(k), Some(s), Some(d)] = event {
        return Ok(Row::Event {
            t_ms,
            fields: [k, s, d].map(|f| storable(&f)),
            historical,
        });
    }
    if !probe.is_empty() {
        return Ok(Row::Probe {
            t_ms,
            state: probe_state,
            values: serde_json::Value::Object(probe),
            historical,
        });
    }
    if cycles.is_none() && stats.is_empty() {
        return Err(
            "NDATA with neither a second's aggregates, a whole event nor a probe event".into(),
        );
    }
    Ok(Row::Second {
        t_ms,
        cycles,
        active,
        stats: serde_json::Value::Object(stats),
        historical,
    })
}

/// Whether the database refused a message's values (SQLSTATE classes 22, data exception, and
/// 23, integrity constraint), as opposed to failing itself (a lost connection, a full disk).
fn refused_data(e: &postgres::Error) -> bool {
    e.code()
        .is_some_and(|c| c.code().starts_with("22") || c.code().starts_with("23"))
}

/// The ingester's state between messages.
#[derive(Default)]
pub struct Ingester {
    births: HashMap<(String, String), HashMap<u64, String>>,
    partitions: Partitions,
}

fn seconds_f64(t_ms: i64) -> f64 {
    t_ms as f64 / 1000.0
}

impl Ingester {
    /// Stores one message. `Err` only for a database failure (the message must not be
    /// acknowledged); anything wrong with the message itself is `Ok(Outcome::Skipped)`.
    pub fn handle(
        &mut self,
        db: &mut impl GenericClient,
        topic: &str,
        payload: &[u8],
    ) -> Result<Outcome, postgres::Error> {
        match self.prepare(db, topic, payload)? {
            Prepared::Done(o) => Ok(o),
            Prepared::Row(group, node, row) => self.write(db, &group, &node, row),
        }
    }

    /// Takes a message apart: a birth or a death is stored at once (a later NDATA of the same
    /// batch is read with that birth's names); NDATA becomes the row to write.
    fn prepare(
        &mut self,
        db: &mut impl GenericClient,
        topic: &str,
        payload: &[u8],
    ) -> Result<Prepared, postgres::Error> {
        let Some((group, kind, node)) = parse_topic(topic) else {
            return Ok(Prepared::Done(Outcome::Skipped(format!(
                "not a Sparkplug node topic: {topic}"
            ))));
        };
        let key = (group.to_string(), node.to_string());
        let p = match Payload::decode(payload) {
            Ok(p) => p,
            Err(e) => return Ok(Prepared::Done(Outcome::Skipped(format!("{topic}: {e}")))),
        };
        match kind {
            "NBIRTH" => self.birth(db, key, &p).map(Prepared::Done),
            "NDEATH" => {
                let Ok(died_ms) = plausible_time(p.timestamp_ms) else {
                    return Ok(Prepared::Done(Outcome::Skipped(format!(
                        "{topic}: an implausible time"
                    ))));
                };
                db.execute(
                    "UPDATE fleet_nodes SET died_at = to_timestamp($3) WHERE group_id = $1 AND node_id = $2",
                    &[&key.0, &key.1, &seconds_f64(died_ms)],
                )?;
                Ok(Prepared::Done(Outcome::Death))
            }
            "NDATA" => self.data(db, key, &p),
            _ => Ok(Prepared::Done(Outcome::Skipped(format!(
                "{topic}: not stored"
            )))),
        }
    }

    fn birth(
        &mut self,
        db: &mut impl GenericClient,
        key: (String, String),
        p: &Payload,
    ) -> Result<Outcome, postgres::Error> {
        let born_ms = match plausible_time(p.timestamp_ms) {
            Ok(t) => t,
            Err(e) => return Ok(Outcome::Skipped(format!("{}/{} birth: {e}", key.0, key.1))),
        };
        let mut names = HashMap::new();
        let text = |n: &str| {
            p.metrics
                .iter()
                .find(|m| m.name == n)
                .and_then(|m| match &m.value {
                    Value::String(s) => Some(storable(s)),
                    _ => None,
                })
        };
        let bd_seq = p
            .metrics
            .iter()
            .find(|m| m.name == "bdSeq")
            .and_then(|m| number(&m.value))
            .map(|x| x as i64);
        for m in &p.metrics {
            if let Some(a) = m.alias {
                names.insert(a, storable(&m.name));
            }
        }
        let aliases: serde_json::Map<String, serde_json::Value> = names
            .iter()
            .map(|(a, n)| (a.to_string(), n.clone().into()))
            .collect();
        db.execute(
            "INSERT INTO fleet_nodes (group_id, node_id, machine, models, bd_seq, aliases, born_at)
             VALUES ($1, $2, $3, $4, $5, $6::text::jsonb, to_timestamp($7))
             ON CONFLICT (group_id, node_id) DO UPDATE SET machine = $3, models = $4, bd_seq = $5,
                 aliases = $6::text::jsonb, born_at = to_timestamp($7)",
            &[
                &key.0,
                &key.1,
                &text("Properties/Machine"),
                &text("Properties/Models"),
                &bd_seq,
                &serde_json::Value::Object(aliases).to_string(),
                &seconds_f64(born_ms),
            ],
        )?;
        self.births.insert(key, names);
        Ok(Outcome::Birth)
    }

    /// The node's names by alias: this process's, else the last birth the store holds (an
    /// ingester restarted in the middle of a node's session).
    fn names(
        &mut self,
        db: &mut impl GenericClient,
        key: &(String, String),
    ) -> Result<Option<&HashMap<u64, String>>, postgres::Error> {
        if !self.births.contains_key(key) {
            let row = db.query_opt(
                "SELECT aliases::text FROM fleet_nodes WHERE group_id = $1 AND node_id = $2",
                &[&key.0, &key.1],
            )?;
            let stored: Option<String> = row.and_then(|r| r.get(0));
            if let Some(Ok(serde_json::Value::Object(m))) = stored.map(|s| serde_json::from_str(&s))
            {
                let names = m
                    .into_iter()
                    .filter_map(|(a, n)| Some((a.parse().ok()?, n.as_str()?.to_string())))
                    .collect();
                self.births.insert(key.clone(), names);
            }
        }
        Ok(self.births.get(key))
    }

    fn data(
        &mut self,
        db: &mut impl GenericClient,
        key: (String, String),
        p: &Payload,
    ) -> Result<Prepared, postgres::Error> {
        let Some(names) = self.names(db, &key)? else {
            return Ok(Prepared::Done(Outcome::Skipped(format!(
                "NDATA of {}/{} before any birth",
                key.0, key.1
            ))));
        };
        Ok(match rows(p, names) {
            Ok(r) => Prepared::Row(key.0, key.1, r),
            Err(e) => Prepared::Done(Outcome::Skipped(format!("{}/{}: {e}", key.0, key.1))),
        })
    }

    /// Writes one row (a message alone: the path that undoes a refused message by itself), with
    /// the same statements as a batch.
    fn write(
        &mut self,
        db: &mut impl GenericClient,
        group: &str,
        node: &str,
        row: Row,
    ) -> Result<Outcome, postgres::Error> {
        let outcome: fn(bool) -> Outcome = match row {
            Row::Second { .. } => |written| Outcome::Second { written },
            Row::Event { .. } => |written| Outcome::Event { written },
            Row::Probe { .. } => |written| Outcome::Probe { written },
        };
        let (_, _, _, duplicates) = self.write_all(db, vec![(group.into(), node.into(), row)])?;
        Ok(outcome(duplicates == 0))
    }

    /// Writes many rows with one statement per table (`unnest` of arrays): a batch costs the
    /// database a few round trips instead of three per message. Returns the seconds, the
    /// events and the probe events written; the rest of `rows` were there already.
    fn write_all(
        &mut self,
        db: &mut impl GenericClient,
        rows: Vec<(String, String, Row)>,
    ) -> Result<(u64, u64, u64, u64), postgres::Error> {
        let mut s = SecondColumns::default();
        let mut e = EventColumns::default();
        let mut p = ProbeColumns::default();
        for (group, node, row) in rows {
            match row {
                Row::Second {
                    t_ms,
                    cycles,
                    active,
                    stats,
                    historical,
                } => {
                    self.partitions.ensure(db, "fleet_seconds", t_ms)?;
                    s.group.push(group);
                    s.node.push(node);
                    s.t.push(seconds_f64(t_ms));
                    s.cycles.push(cycles.map(|c| c as i32));
                    s.active.push(active.map(|c| c as i32));
                    s.stats.push(stats.to_string());
                    s.historical.push(historical);
                }
                Row::Event {
                    t_ms,
                    fields: [kind, subject, detail],
                    historical,
                } => {
                    self.partitions.ensure(db, "fleet_events", t_ms)?;
                    e.group.push(group);
                    e.node.push(node);
                    e.t.push(seconds_f64(t_ms));
                    e.kind.push(kind);
                    e.subject.push(subject);
                    e.detail.push(detail);
                    e.historical.push(historical);
                }
                Row::Probe {
                    t_ms,
                    state,
                    values,
                    historical,
                } => {
                    self.partitions.ensure(db, "fleet_probes", t_ms)?;
                    p.group.push(group);
                    p.node.push(node);
                    p.t.push(seconds_f64(t_ms));
                    p.state.push(state);
                    p.values.push(values.to_string());
                    p.historical.push(historical);
                }
            }
        }
        let offered = (s.t.len() + e.t.len() + p.t.len()) as u64;
        let mut seconds = 0;
        if !s.t.is_empty() {
            seconds = db.execute(
                "INSERT INTO fleet_seconds (group_id, node_id, t, cycles, active_cycles, stats, historical)
                 SELECT g, n, to_timestamp(t), c, a, st::jsonb, h
                 FROM unnest($1::text[], $2::text[], $3::float8[], $4::int4[], $5::int4[], $6::text[], $7::bool[])
                     AS r(g, n, t, c, a, st, h)
                 ON CONFLICT DO NOTHING",
                &[&s.group, &s.node, &s.t, &s.cycles, &s.active, &s.stats, &s.historical],
            )?;
        }
        let mut events = 0;
        if !e.t.is_empty() {
            events = db.execute(
                "INSERT INTO fleet_events (group_id, node_id, t, kind, subject, detail, historical)
                 SELECT g, n, to_timestamp(t), k, s, d, h
                 FROM unnest($1::text[], $2::text[], $3::float8[], $4::text[], $5::text[], $6::text[], $7::bool[])
                     AS r(g, n, t, k, s, d, h)
                 ON CONFLICT DO NOTHING",
                &[&e.group, &e.node, &e.t, &e.kind, &e.subject, &e.detail, &e.historical],
            )?;
        }
        let mut probes = 0;
        if !p.t.is_empty() {
            probes = db.execute(
                "INSERT INTO fleet_probes (group_id, node_id, t, state, \"values\", historical)
                 SELECT g, n, to_timestamp(t), st, v::jsonb, h
                 FROM unnest($1::text[], $2::text[], $3::float8[], $4::text[], $5::text[], $6::bool[])
                     AS r(g, n, t, st, v, h)
                 ON CONFLICT DO NOTHING",
                &[&p.group, &p.node, &p.t, &p.state, &p.values, &p.historical],
            )?;
        }
        Ok((seconds, events, probes, offered - seconds - events - probes))
    }
}

/// What [`Ingester::prepare`] made of a message.
enum Prepared {
    /// Stored already (a birth, a death) or skipped.
    Done(Outcome),
    /// A row to write: group, node, row.
    Row(String, String, Row),
}

/// `fleet_seconds` rows as columns, for one `unnest` insert.
#[derive(Default)]
struct SecondColumns {
    group: Vec<String>,
    node: Vec<String>,
    t: Vec<f64>,
    cycles: Vec<Option<i32>>,
    active: Vec<Option<i32>>,
    stats: Vec<String>,
    historical: Vec<bool>,
}

/// `fleet_events` rows as columns.
#[derive(Default)]
struct EventColumns {
    group: Vec<String>,
    node: Vec<String>,
    t: Vec<f64>,
    kind: Vec<String>,
    subject: Vec<String>,
    detail: Vec<String>,
    historical: Vec<bool>,
}

/// `fleet_probes` rows as columns.
#[derive(Default)]
struct ProbeColumns {
    group: Vec<String>,
    node: Vec<String>,
    t: Vec<f64>,
    state: Vec<Option<String>>,
    values: Vec<String>,
    historical: Vec<bool>,
}

/// How to ingest.
#[derive(Debug, Clone)]
pub struct Config {
    /// The broker.
    pub broker: BrokerUrl,
    /// PostgreSQL, `postgres://USER@HOST:PORT/DB` (or a libpq key=value string).
    pub db: String,
    /// MQTT client id: the broker keeps this session's subscription and queue.
    pub client_id: String,
    /// Stop after this long without a message (`None`: run until the deadline).
    pub idle_exit: Option<Duration>,
    /// Stop after this long in all (`None`: never).
    pub deadline: Option<Duration>,
}

/// What the ingester did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Summary {
    /// Messages received (a redelivery counts again).
    pub messages: u64,
    /// Seconds and events written.
    pub seconds: u64,
    /// Events written.
    pub events: u64,
    /// Probe events written.
    pub probes: u64,
    /// Rows that were there already (sent again).
    pub duplicates: u64,
    /// Messages skipped, and the last reason.
    pub skipped: u64,
    /// Why the last one was skipped.
    pub last_skip: Option<String>,
    /// Times the database failed and was connected again.
    pub db_failures: u64,
    /// MQTT connections made.
    pub connects: u64,
    /// The last error, if any.
    pub last_error: Option<String>,
}

fn connect_db(url: &str) -> Result<Client, String> {
    let mut db = Client::connect(url, NoTls).map_err(|e| format!("PostgreSQL: {e}"))?;
    schema::migrate(&mut db).map_err(|e| format!("PostgreSQL: migrations: {e}"))?;
    Ok(db)
}

/// Stores what one poll brought in one transaction and returns the packet ids to acknowledge
/// (a commit per message would bound the ingester to the disk's syncs per second). The counts
/// go into the summary only once committed: a batch the database refused comes again.
fn store_batch(
    ingester: &mut Ingester,
    db: &mut Client,
    incoming: Vec<Incoming>,
    s: &mut Summary,
) -> Result<Vec<u16>, postgres::Error> {
    let mut ids = Vec::new();
    let mut messages = Vec::new();
    for p in incoming {
        if let Incoming::Publish {
            topic,
            packet_id,
            payload,
        } = p
        {
            ids.extend(packet_id);
            messages.push((topic, payload));
        }
    }
    if messages.is_empty() {
        return Ok(ids);
    }
    let batch = ingester.store(db, &messages)?;
    s.messages += batch.messages;
    s.seconds += batch.seconds;
    s.events += batch.events;
    s.probes += batch.probes;
    s.duplicates += batch.duplicates;
    s.skipped += batch.skipped;
    if batch.last_skip.is_some() {
        s.last_skip = batch.last_skip;
    }
    Ok(ids)
}

impl Ingester {
    /// Stores messages (topic, payload) in one transaction and says what became of them; `Err`
    /// only for a database failure, after which nothing of them is stored.
    ///
    /// The rows are written together, one statement per table, inside a savepoint. Should the
    /// database refuse a value of any of them (SQLSTATE 22 or 23), that savepoint is undone
    /// and the messages are written again one by one, each in a savepoint of its own, so that
    /// only the refused message is skipped.
    pub fn store(
        &mut self,
        db: &mut Client,
        messages: &[(String, Vec<u8>)],
    ) -> Result<Summary, postgres::Error> {
        let mut tx = db.transaction()?;
        let mut bulk = tx.transaction()?;
        let batch = match store_together(self, &mut bulk, messages) {
            Ok(b) => {
                bulk.commit()?;
                b
            }
            Err(e) if refused_data(&e) => {
                drop(bulk);
                // Partitions made inside the undone savepoint are gone again.
                self.partitions.forget();
                store_one_by_one(self, &mut tx, messages)?
            }
            Err(e) => return Err(e),
        };
        tx.commit()?;
        Ok(batch)
    }
}

/// A batch's rows written together ([`Ingester::write_all`]).
fn store_together(
    ingester: &mut Ingester,
    db: &mut impl GenericClient,
    messages: &[(String, Vec<u8>)],
) -> Result<Summary, postgres::Error> {
    let mut batch = Summary::default();
    let mut rows = Vec::with_capacity(messages.len());
    for (topic, payload) in messages {
        batch.messages += 1;
        match ingester.prepare(db, topic, payload)? {
            Prepared::Row(g, n, r) => rows.push((g, n, r)),
            Prepared::Done(Outcome::Skipped(why)) => {
                batch.skipped += 1;
                batch.last_skip = Some(why);
            }
            Prepared::Done(_) => {}
        }
    }
    let (seconds, events, probes, duplicates) = ingester.write_all(db, rows)?;
    batch.seconds = seconds;
    batch.events = events;
    batch.probes = probes;
    batch.duplicates = duplicates;
    Ok(batch)
}

/// A batch written message by message, a savepoint each: a message the database refuses (a
/// value it cannot hold) undoes itself alone and is skipped and acknowledged, instead of
/// failing the batch, which the broker would send again and again and stall every machine
/// behind it.
fn store_one_by_one(
    ingester: &mut Ingester,
    tx: &mut postgres::Transaction<'_>,
    messages: &[(String, Vec<u8>)],
) -> Result<Summary, postgres::Error> {
    let mut batch = Summary::default();
    for (topic, payload) in messages {
        batch.messages += 1;
        let mut one = tx.transaction()?;
        let outcome = match ingester.handle(&mut one, topic, payload) {
            Ok(o) => {
                one.commit()?;
                o
            }
            Err(e) if refused_data(&e) => {
                drop(one);
                ingester.partitions.forget();
                Outcome::Skipped(format!("{topic}: refused by the database: {e}"))
            }
            Err(e) => return Err(e),
        };
        match outcome {
            Outcome::Second { written: true } => batch.seconds += 1,
            Outcome::Event { written: true } => batch.events += 1,
            Outcome::Probe { written: true } => batch.probes += 1,
            Outcome::Second { written: false }
            | Outcome::Event { written: false }
            | Outcome::Probe { written: false } => batch.duplicates += 1,
            Outcome::Skipped(why) => {
                batch.skipped += 1;
                batch.last_skip = Some(why);
            }
            Outcome::Birth | Outcome::Death => {}
        }
    }
    Ok(batch)
}

/// Ingests until idle or the deadline: the database first (no message is taken while it is
/// away, so the broker keeps them), then the broker.
pub fn run(config: &Config) -> Summary {
    let start = Instant::now();
    let mut last_message = Instant::now();
    let mut s = Summary::default();
    let mut ingester = Ingester::default();
    let mut db: Option<Client> = None;
    let mut mq: Option<Connection> = None;
    let mut backoff = Duration::from_millis(250);
    let mut last_ping = Instant::now();
    loop {
        if config.deadline.is_some_and(|d| start.elapsed() >= d)
            || config
                .idle_exit
                .is_some_and(|d| last_message.elapsed() >= d)
        {
            break;
        }
        if db.is_none() {
            match connect_db(&config.db) {
                Ok(c) => {
                    db = Some(c);
                    ingester.partitions.forget();
                    backoff = Duration::from_millis(250);
                }
                Err(e) => {
                    s.last_error = Some(e);
                    std::thread::sleep(backoff);
                    backoff = (backoff * 2).min(Duration::from_secs(2));
                    continue;
                }
            }
        }
        if mq.is_none() {
            let c = Connection::connect_subscriber(
                &config.broker,
                &config.client_id,
                30,
                Duration::from_secs(5),
            )
            .and_then(|mut c| {
                c.set_max_incoming(4 << 20);
                c.subscribe(1, "spBv1.0/#").map(|()| c)
            });
            match c {
                Ok(c) => {
                    mq = Some(c);
                    s.connects += 1;
                    last_ping = Instant::now();
                }
                Err(e) => {
                    s.last_error = Some(e);
                    std::thread::sleep(backoff);
                    backoff = (backoff * 2).min(Duration::from_secs(2));
                    continue;
                }
            }
        }
        let (Some(c), Some(d)) = (mq.as_mut(), db.as_mut()) else {
            continue;
        };
        let mut incoming = Vec::new();
        let polled = c.poll(Duration::from_millis(100), &mut incoming);
        let mut drop_mq = polled.is_err();
        if let Err(e) = polled {
            s.last_error = Some(e);
        }
        if !incoming.is_empty() {
            last_message = Instant::now();
        }
        match store_batch(&mut ingester, d, incoming, &mut s) {
            Ok(ids) => {
                // Acknowledged only now that the batch is committed.
                if !ids.is_empty() && c.pubacks(&ids).is_err() {
                    drop_mq = true;
                }
            }
            Err(e) => {
                // Unacknowledged, the batch stays with the broker for the reconnect.
                s.db_failures += 1;
                s.last_error = Some(format!("PostgreSQL: {e}"));
                db = None;
                drop_mq = true;
            }
        }
        if !drop_mq && last_ping.elapsed() >= Duration::from_secs(10) {
            drop_mq = c.ping().is_err();
            last_ping = Instant::now();
        }
        if drop_mq {
            mq = None;
        }
    }
    if let Some(c) = mq {
        c.disconnect();
    }
    s
}
