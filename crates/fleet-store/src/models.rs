//! Models as fleet objects: every generation of a machine's model kept in the store with its
//! bytes, its signature line and its public key, the provenance and validation figures its file
//! carries, and its state — `candidate`, `shadow`, `active` or `retired` (migration
//! `0002_models.sql`). A machine has at most one active model (a partial unique index).
//!
//! - [`register`] adds a candidate, version = the machine's highest + 1, parent = its active
//!   version. The caller has verified the signature and loaded the model (the CLI does both
//!   through `truepos_io`'s loader); the store keeps exactly those bytes and their SHA-256.
//! - [`activate`] makes a candidate or shadow active and retires the active one, whose version
//!   becomes the new one's parent; [`rollback`] retires the active model and makes its parent
//!   active again, refused when it has none. [`shadow`] marks a candidate as run in shadow.
//! - Each change is one transaction holding a lock per machine, and writes a row of
//!   `fleet_model_changes` (who, when, from, to, why).
//! - [`activate_if`] and [`rollback_if`] move only when the active version is still the one
//!   the caller judged (compared under the lock): another, activated in between, is a
//!   [`ModelError::Conflict`] and nothing changes.
//!
//! ```
//! use truepos_fleet_store::models::State;
//! assert_eq!(State::parse("shadow"), Some(State::Shadow));
//! assert_eq!(State::Active.as_str(), "active");
//! assert_eq!(State::parse("running"), None);
//! ```

use postgres::{GenericClient, Row, Transaction};
use sha2::{Digest, Sha256};

/// Largest model the store takes, bytes: the loader's limit for a model file.
pub const MAX_MODEL_BYTES: usize = 16 * 1024 * 1024;

/// A model's state in the fleet.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum State {
    /// Registered, not run.
    Candidate,
    /// Run beside the active model, its predictions logged, never applied.
    Shadow,
    /// The machine's model.
    Active,
    /// Once active (or never), no longer run.
    Retired,
}

impl State {
    /// The word the store keeps.
    pub fn as_str(self) -> &'static str {
        match self {
            State::Candidate => "candidate",
            State::Shadow => "shadow",
            State::Active => "active",
            State::Retired => "retired",
        }
    }

    /// The state a word names.
    pub fn parse(word: &str) -> Option<Self> {
        [
            State::Candidate,
            State::Shadow,
            State::Active,
            State::Retired,
        ]
        .into_iter()
        .find(|s| s.as_str() == word)
    }
}

impl std::fmt::Display for State {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Why a model operation was refused or failed.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// The database failed or refused.
    #[error("PostgreSQL: {0}")]
    Db(#[from] postgres::Error),
    /// What was given cannot be stored (an empty machine, a file name with a `/`, too large).
    #[error("{0}")]
    Invalid(String),
    /// No such version.
    #[error("machine `{machine}` has no model version {version}")]
    NoSuchVersion {
        /// Machine.
        machine: String,
        /// Version asked for.
        version: i32,
    },
    /// No model of that state.
    #[error("machine `{machine}` has no {state} model")]
    NoneInState {
        /// Machine.
        machine: String,
        /// State asked for.
        state: State,
    },
    /// The version is not in a state the move starts from.
    #[error("machine `{machine}`: version {version} is {state}; {rule}")]
    WrongState {
        /// Machine.
        machine: String,
        /// Version.
        version: i32,
        /// Its state.
        state: State,
        /// What the move needs.
        rule: &'static str,
    },
    /// Rollback of an active model that replaced none.
    #[error(
        "machine `{machine}`: the active version {version} has no parent to return to \
         (it was the machine's first active model); nothing changed"
    )]
    NoParent {
        /// Machine.
        machine: String,
        /// The active version.
        version: i32,
    },
    /// The active version is not the one the caller expected (someone moved it in between).
    #[error(
        "machine `{machine}`: the active version is {} now, not {expected} as judged; nothing changed",
        active.map_or("none".to_string(), |v| v.to_string())
    )]
    Conflict {
        /// Machine.
        machine: String,
        /// The active version the caller judged.
        expected: i32,
        /// The active version found.
        active: Option<i32>,
    },
    /// The same bytes are registered already.
    #[error("machine `{machine}`: this model (sha256 {sha256}) is registered already, as version {version}")]
    AlreadyRegistered {
        /// Machine.
        machine: String,
        /// Its version.
        version: i32,
        /// The bytes' hash.
        sha256: String,
    },
}

/// A model to register: the bytes verified and loaded, and what was read from them.
#[derive(Debug, Clone)]
pub struct NewModel<'a> {
    /// The machine (Sparkplug node id, `fleet_nodes.node_id`).
    pub machine: &'a str,
    /// The file's name without directories (its extension tells the loader TOML from JSON).
    pub file_name: &'a str,
    /// The file's bytes.
    pub bytes: &'a [u8],
    /// The signature line of `MODEL.sig`.
    pub signature: &'a str,
    /// The signing public key, 64 hex digits.
    pub public_key: &'a str,
    /// The file's `provenance` table as JSON.
    pub provenance: serde_json::Value,
    /// The file's `validation` table as JSON.
    pub validation: serde_json::Value,
}

/// Who changes a model and why, for `fleet_model_changes`.
#[derive(Debug, Clone)]
pub struct Change<'a> {
    /// Who (`None`: the database role).
    pub by: Option<&'a str>,
    /// Why.
    pub reason: &'a str,
}

/// A stored model generation, without its bytes.
#[derive(Debug, Clone, PartialEq)]
pub struct Model {
    /// Machine.
    pub machine: String,
    /// Generation.
    pub version: i32,
    /// What a rollback returns to.
    pub parent: Option<i32>,
    /// State.
    pub state: State,
    /// The registered file's name.
    pub file_name: String,
    /// SHA-256 of the bytes, hex.
    pub sha256: String,
    /// The signing key, hex.
    pub public_key: String,
    /// Registered at, s since the Unix epoch.
    pub created_unix_s: f64,
    /// State last changed at, s since the Unix epoch.
    pub state_changed_unix_s: f64,
    /// The file's provenance.
    pub provenance: serde_json::Value,
    /// The file's validation figures.
    pub validation: serde_json::Value,
}

impl Model {
    /// The model as JSON (times as seconds since the Unix epoch).
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({
            "machine": self.machine,
            "version": self.version,
            "parent": self.parent,
            "state": self.state.as_str(),
            "file_name": self.file_name,
            "sha256": self.sha256,
            "public_key": self.public_key,
            "created_unix_s": self.created_unix_s,
            "state_changed_unix_s": self.state_changed_unix_s,
            "provenance": self.provenance,
            "validation": self.validation,
        })
    }
}

/// A stored model file: what a service fetches and verifies.
#[derive(Debug, Clone)]
pub struct ModelFile {
    /// Generation.
    pub version: i32,
    /// State.
    pub state: State,
    /// File name.
    pub file_name: String,
    /// The bytes.
    pub bytes: Vec<u8>,
    /// The `MODEL.sig` line.
    pub signature: String,
    /// SHA-256 of the bytes, hex.
    pub sha256: String,
}

/// Which of a machine's models.
#[derive(Debug, Clone, Copy)]
pub enum Which {
    /// That version.
    Version(i32),
    /// The newest in that state (the active one: the only one).
    State(State),
}

/// SHA-256 in hex.
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

const COLUMNS: &str = "machine, version, parent_version, state, file_name, sha256, public_key, \
     extract(epoch FROM created_at)::float8, extract(epoch FROM state_changed_at)::float8, \
     provenance::text, validation::text";

fn model_of(row: &Row) -> Model {
    let json =
        |i: usize| serde_json::from_str(row.get::<_, &str>(i)).unwrap_or(serde_json::Value::Null);
    Model {
        machine: row.get(0),
        version: row.get(1),
        parent: row.get(2),
        state: State::parse(row.get(3)).unwrap_or(State::Retired),
        file_name: row.get(4),
        sha256: row.get(5),
        public_key: row.get(6),
        created_unix_s: row.get(7),
        state_changed_unix_s: row.get(8),
        provenance: json(9),
        validation: json(10),
    }
}

fn check_new(m: &NewModel<'_>) -> Result<(), ModelError> {
    let bad = |why: String| Err(ModelError::Invalid(why));
    if m.machine.is_empty() || m.machine.len() > 200 {
        return bad(format!("machine `{}`: give 1-200 characters", m.machine));
    }
    if m.file_name.is_empty() || m.file_name.len() > 255 || m.file_name.contains('/') {
        return bad(format!(
            "model file name `{}`: give a name of 1-255 bytes without `/`",
            m.file_name
        ));
    }
    if m.bytes.is_empty() || m.bytes.len() > MAX_MODEL_BYTES {
        return bad(format!(
            "{}: {} bytes; a model in the store has 1 to {MAX_MODEL_BYTES}",
            m.file_name,
            m.bytes.len()
        ));
    }
    Ok(())
}

/// Takes the machine's lock for this transaction: its model moves happen one after another.
fn lock(tx: &mut Transaction<'_>, machine: &str) -> Result<(), postgres::Error> {
    tx.execute(
        "SELECT pg_advisory_xact_lock(hashtext('truepos fleet_models'), hashtext($1))",
        &[&machine],
    )?;
    Ok(())
}

fn active(
    tx: &mut Transaction<'_>,
    machine: &str,
) -> Result<Option<(i32, Option<i32>)>, postgres::Error> {
    Ok(tx
        .query_opt(
            "SELECT version, parent_version FROM fleet_models WHERE machine = $1 AND state = 'active'",
            &[&machine],
        )?
        .map(|r| (r.get(0), r.get(1))))
}

fn state_of(tx: &mut Transaction<'_>, machine: &str, version: i32) -> Result<State, ModelError> {
    let row = tx.query_opt(
        "SELECT state FROM fleet_models WHERE machine = $1 AND version = $2",
        &[&machine, &version],
    )?;
    let row = row.ok_or_else(|| ModelError::NoSuchVersion {
        machine: machine.to_string(),
        version,
    })?;
    Ok(State::parse(row.get(0)).unwrap_or(State::Retired))
}

/// The version's state, refused with `rule` unless it is one of `allowed`.
fn state_among(
    tx: &mut Transaction<'_>,
    machine: &str,
    version: i32,
    allowed: &[State],
    rule: &'static str,
) -> Result<State, ModelError> {
    let state = state_of(tx, machine, version)?;
    if !allowed.contains(&state) {
        return Err(ModelError::WrongState {
            machine: machine.to_string(),
            version,
            state,
            rule,
        });
    }
    Ok(state)
}

/// Moves one version to `to` and writes its history row.
fn set_state(
    tx: &mut Transaction<'_>,
    machine: &str,
    version: i32,
    from: Option<State>,
    to: State,
    change: &Change<'_>,
) -> Result<(), postgres::Error> {
    if from.is_some() {
        tx.execute(
            "UPDATE fleet_models SET state = $3, state_changed_at = now() WHERE machine = $1 AND version = $2",
            &[&machine, &version, &to.as_str()],
        )?;
    }
    tx.execute(
        "INSERT INTO fleet_model_changes (machine, version, from_state, to_state, reason, changed_by)
         VALUES ($1, $2, $3, $4, $5, COALESCE($6, current_user))",
        &[
            &machine,
            &version,
            &from.map(State::as_str),
            &to.as_str(),
            &change.reason,
            &change.by,
        ],
    )?;
    Ok(())
}

/// Registers a candidate: version = the machine's highest + 1, parent = its active version.
/// The same bytes twice for a machine are refused, naming the version they are.
pub fn register(
    db: &mut impl GenericClient,
    m: &NewModel<'_>,
    change: &Change<'_>,
) -> Result<Model, ModelError> {
    check_new(m)?;
    let sha256 = sha256_hex(m.bytes);
    let mut tx = db.transaction()?;
    lock(&mut tx, m.machine)?;
    if let Some(r) = tx.query_opt(
        "SELECT version FROM fleet_models WHERE machine = $1 AND sha256 = $2",
        &[&m.machine, &sha256],
    )? {
        return Err(ModelError::AlreadyRegistered {
            machine: m.machine.to_string(),
            version: r.get(0),
            sha256,
        });
    }
    let parent = active(&mut tx, m.machine)?.map(|(v, _)| v);
    let version: i32 = tx
        .query_one(
            "SELECT COALESCE(MAX(version), 0) + 1 FROM fleet_models WHERE machine = $1",
            &[&m.machine],
        )?
        .get(0);
    let row = tx.query_one(
        &format!(
            "INSERT INTO fleet_models (machine, version, parent_version, file_name, sha256, model,
                 signature, public_key, provenance, validation)
             VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9::text::jsonb, $10::text::jsonb)
             RETURNING {COLUMNS}"
        ),
        &[
            &m.machine,
            &version,
            &parent,
            &m.file_name,
            &sha256,
            &m.bytes,
            &m.signature.trim(),
            &m.public_key,
            &m.provenance.to_string(),
            &m.validation.to_string(),
        ],
    )?;
    set_state(&mut tx, m.machine, version, None, State::Candidate, change)?;
    tx.commit()?;
    Ok(model_of(&row))
}

/// Makes a candidate or shadow version active; the active one, if any, is retired and becomes
/// the new one's parent. Returns the version retired.
pub fn activate(
    db: &mut impl GenericClient,
    machine: &str,
    version: i32,
    change: &Change<'_>,
) -> Result<Option<i32>, ModelError> {
    activate_if(db, machine, version, None, change)
}

/// Refuses with [`ModelError::Conflict`] when `expected` is given and the active version is
/// not it; called under the machine's lock.
fn check_active(
    tx: &mut Transaction<'_>,
    machine: &str,
    expected: Option<i32>,
) -> Result<(), ModelError> {
    if let Some(expected) = expected {
        let now = active(tx, machine)?.map(|(v, _)| v);
        if now != Some(expected) {
            return Err(ModelError::Conflict {
                machine: machine.to_string(),
                expected,
                active: now,
            });
        }
    }
    Ok(())
}

/// [`activate`], only while the active version is `expected_active` (when given): compared
/// under the machine's lock, a [`ModelError::Conflict`] otherwise, nothing changed.
pub fn activate_if(
    db: &mut impl GenericClient,
    machine: &str,
    version: i32,
    expected_active: Option<i32>,
    change: &Change<'_>,
) -> Result<Option<i32>, ModelError> {
    let mut tx = db.transaction()?;
    lock(&mut tx, machine)?;
    check_active(&mut tx, machine, expected_active)?;
    let state = state_among(
        &mut tx,
        machine,
        version,
        &[State::Candidate, State::Shadow],
        "only a candidate or a shadow model can be activated (a retired one comes back by `fleet rollback`, or registered again)",
    )?;
    let old = active(&mut tx, machine)?.map(|(v, _)| v);
    if let Some(old) = old {
        let why = format!("replaced by version {version}: {}", change.reason);
        let retire = Change {
            by: change.by,
            reason: &why,
        };
        set_state(
            &mut tx,
            machine,
            old,
            Some(State::Active),
            State::Retired,
            &retire,
        )?;
        tx.execute(
            "UPDATE fleet_models SET parent_version = $3 WHERE machine = $1 AND version = $2",
            &[&machine, &version, &old],
        )?;
    }
    set_state(
        &mut tx,
        machine,
        version,
        Some(state),
        State::Active,
        change,
    )?;
    tx.commit()?;
    Ok(old)
}

/// Retires the active model and makes its parent active again; returns (retired, now active).
/// Refused, changing nothing, when there is no active model or it has no parent.
pub fn rollback(
    db: &mut impl GenericClient,
    machine: &str,
    change: &Change<'_>,
) -> Result<(i32, i32), ModelError> {
    rollback_if(db, machine, None, change)
}

/// [`rollback`], only while the active version is `expected_active` (when given): compared
/// under the machine's lock, a [`ModelError::Conflict`] otherwise, nothing changed.
pub fn rollback_if(
    db: &mut impl GenericClient,
    machine: &str,
    expected_active: Option<i32>,
    change: &Change<'_>,
) -> Result<(i32, i32), ModelError> {
    let mut tx = db.transaction()?;
    lock(&mut tx, machine)?;
    check_active(&mut tx, machine, expected_active)?;
    let (current, parent) = active(&mut tx, machine)?.ok_or_else(|| ModelError::NoneInState {
        machine: machine.to_string(),
        state: State::Active,
    })?;
    let parent = parent.ok_or_else(|| ModelError::NoParent {
        machine: machine.to_string(),
        version: current,
    })?;
    let parent_state = state_of(&mut tx, machine, parent)?;
    let why = format!("rolled back to version {parent}: {}", change.reason);
    let retire = Change {
        by: change.by,
        reason: &why,
    };
    set_state(
        &mut tx,
        machine,
        current,
        Some(State::Active),
        State::Retired,
        &retire,
    )?;
    set_state(
        &mut tx,
        machine,
        parent,
        Some(parent_state),
        State::Active,
        change,
    )?;
    tx.commit()?;
    Ok((current, parent))
}

/// Marks a candidate as run in shadow.
pub fn shadow(
    db: &mut impl GenericClient,
    machine: &str,
    version: i32,
    change: &Change<'_>,
) -> Result<(), ModelError> {
    move_one(
        db,
        (machine, version),
        &[State::Candidate],
        State::Shadow,
        "only a candidate can go into shadow",
        change,
    )
}

/// Retires a candidate or shadow model that will not run (refused by a service, or not better
/// than the active model), with the reason in its history row.
pub fn retire(
    db: &mut impl GenericClient,
    machine: &str,
    version: i32,
    change: &Change<'_>,
) -> Result<(), ModelError> {
    move_one(
        db,
        (machine, version),
        &[State::Candidate, State::Shadow],
        State::Retired,
        "only a candidate or a shadow model is retired this way (an active one by `fleet rollback` or by activating another)",
        change,
    )
}

/// Moves one version, under the machine's lock, from one of `allowed` to `to`; refused with
/// `rule`, changing nothing, from any other state.
fn move_one(
    db: &mut impl GenericClient,
    (machine, version): (&str, i32),
    allowed: &[State],
    to: State,
    rule: &'static str,
    change: &Change<'_>,
) -> Result<(), ModelError> {
    let mut tx = db.transaction()?;
    lock(&mut tx, machine)?;
    let state = state_among(&mut tx, machine, version, allowed, rule)?;
    set_state(&mut tx, machine, version, Some(state), to, change)?;
    tx.commit()?;
    Ok(())
}

/// The models, of one machine or all, by machine and version.
pub fn list(db: &mut impl GenericClient, machine: Option<&str>) -> Result<Vec<Model>, ModelError> {
    let rows = db.query(
        &format!(
            "SELECT {COLUMNS} FROM fleet_models WHERE $1::text IS NULL OR machine = $1
             ORDER BY machine, version"
        ),
        &[&machine],
    )?;
    Ok(rows.iter().map(model_of).collect())
}

/// A row of a machine's history: a state a model entered.
#[derive(Debug, Clone, PartialEq)]
pub struct Changed {
    /// The version.
    pub version: i32,
    /// The state it left (`None`: registered).
    pub from: Option<State>,
    /// The state it entered.
    pub to: State,
    /// Why.
    pub reason: String,
    /// Who.
    pub by: String,
    /// When, s since the Unix epoch.
    pub unix_s: f64,
}

impl Changed {
    /// The row as JSON.
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({
            "version": self.version,
            "from": self.from.map(State::as_str),
            "to": self.to.as_str(),
            "reason": self.reason,
            "by": self.by,
            "unix_s": self.unix_s,
        })
    }
}

/// A machine's history, oldest first.
pub fn history(db: &mut impl GenericClient, machine: &str) -> Result<Vec<Changed>, ModelError> {
    let rows = db.query(
        "SELECT version, from_state, to_state, reason, changed_by,
                extract(epoch FROM changed_at)::float8
         FROM fleet_model_changes WHERE machine = $1 ORDER BY id",
        &[&machine],
    )?;
    Ok(rows
        .iter()
        .map(|r| Changed {
            version: r.get(0),
            from: r.get::<_, Option<&str>>(1).and_then(State::parse),
            to: State::parse(r.get(2)).unwrap_or(State::Retired),
            reason: r.get(3),
            by: r.get(4),
            unix_s: r.get(5),
        })
        .collect())
}

/// One model's file and signature: a version, or the newest in a state.
pub fn fetch(
    db: &mut impl GenericClient,
    machine: &str,
    which: Which,
) -> Result<ModelFile, ModelError> {
    const SELECT: &str =
        "SELECT version, state, file_name, model, signature, sha256 FROM fleet_models";
    let row = match which {
        Which::Version(v) => db.query_opt(
            &format!("{SELECT} WHERE machine = $1 AND version = $2"),
            &[&machine, &v],
        )?,
        Which::State(s) => db.query_opt(
            &format!("{SELECT} WHERE machine = $1 AND state = $2 ORDER BY version DESC LIMIT 1"),
            &[&machine, &s.as_str()],
        )?,
    };
    let row = row.ok_or_else(|| match which {
        Which::Version(version) => ModelError::NoSuchVersion {
            machine: machine.to_string(),
            version,
        },
        Which::State(state) => ModelError::NoneInState {
            machine: machine.to_string(),
            state,
        },
    })?;
    Ok(ModelFile {
        version: row.get(0),
        state: State::parse(row.get(1)).unwrap_or(State::Retired),
        file_name: row.get(2),
        bytes: row.get(3),
        signature: row.get(4),
        sha256: row.get(5),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn states_read_back_and_hashes_are_sha256() {
        for s in [
            State::Candidate,
            State::Shadow,
            State::Active,
            State::Retired,
        ] {
            assert_eq!(State::parse(s.as_str()), Some(s));
        }
        assert_eq!(
            sha256_hex(b"abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
    }

    #[test]
    fn what_cannot_be_stored_is_refused_before_the_database() {
        let m = NewModel {
            machine: "vmc",
            file_name: "a/model.toml",
            bytes: b"x",
            signature: "",
            public_key: "",
            provenance: serde_json::json!({}),
            validation: serde_json::json!({}),
        };
        assert!(check_new(&m)
            .unwrap_err()
            .to_string()
            .contains("without `/`"));
        let empty = NewModel {
            file_name: "model.toml",
            bytes: b"",
            ..m.clone()
        };
        assert!(check_new(&empty).is_err());
        let ok = NewModel {
            file_name: "model.toml",
            ..m
        };
        assert!(check_new(&ok).is_ok());
    }
}
