//! `truepos run --mqtt URL` (the publisher beside the service), `truepos fleet publish`
//! (forward a log that is already written, e.g. after the service was killed), `truepos
//! fleet ingest` (the broker into PostgreSQL), `truepos fleet models …`, `activate`,
//! `rollback` (model generations in the store), `status` (the fleet per machine) and `follow`
//! (the sidecar that shadows, activates and rolls back a service's models, [`follow`]) and
//! `refit` (a model fitted again from the store, signed, registered, [`refit`]): options
//! into `truepos_fleet`'s and `truepos_fleet_store`'s values, the summary or table printed.

use std::path::{Path, PathBuf};
use std::time::Duration;

use truepos_fleet::{BrokerUrl, Config, Publisher, Summary};
use truepos_fleet_store::models::{self, Change, Model, ModelError, NewModel, State, Which};
use truepos_fleet_store::postgres::{Client, NoTls};
use truepos_fleet_store::status::{utc_text, MachineStatus};
use truepos_io::model_file::signature::{signature_path, verify_line, TrustedKeys};

use crate::error::CliError;

mod follow;
mod refit;
mod view;

/// How long `truepos run` forwards what is left after the service stopped, at most; what is not
/// acknowledged by then stays in the log and goes with the next start.
const DRAIN_AT_STOP: Duration = Duration::from_secs(10);

/// Starts the publisher of a service's `--mqtt` (after the service, which creates the log).
pub fn start(config: Config) -> Result<Publisher, CliError> {
    Publisher::start(config).map_err(|e| CliError::refused(format!("--mqtt: {e}")))
}

/// Stops the publisher after the service and says what it did.
pub fn finish(publisher: Publisher) {
    let s = publisher.stop(DRAIN_AT_STOP);
    eprintln!("{}", describe(&s));
}

fn describe(s: &Summary) -> String {
    let mut line = format!(
        "mqtt: {} messages acknowledged of {} sent ({} historical, {} payload bytes), {} connection(s)",
        s.acknowledged, s.published, s.historical, s.bytes, s.connects
    );
    if !s.caught_up {
        line.push_str("; not caught up: the rest stays in the log for the next start");
    }
    if let Some(e) = &s.last_error {
        line.push_str(&format!("; last error: {e}"));
    }
    line
}

/// Arguments of `truepos fleet`.
#[derive(clap::Args)]
pub struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(clap::Subcommand)]
enum Command {
    /// Forward a service's log to an MQTT broker as Sparkplug B from this broker's cursor, then
    /// exit: what a killed service left unsent goes out, marked historical.
    Publish(PublishArgs),
    /// Take the fleet's Sparkplug B telemetry from an MQTT broker into PostgreSQL (migrations
    /// applied first; a message sent twice is written once; docs/fleet.md).
    Ingest(IngestArgs),
    /// Models as fleet objects: register a signed model, list, fetch, mark as shadow.
    #[command(subcommand)]
    Models(ModelsCommand),
    /// Make a candidate or shadow model a machine's active one; the active one is retired.
    Activate(ActivateArgs),
    /// Retire a machine's active model and make the one it replaced active again.
    Rollback(RollbackArgs),
    /// Per machine: online, last message, model generation and state, compensating, faults in
    /// the last hour.
    Status(StatusArgs),
    /// Beside a service: write the store's active model into its model file, shadow its
    /// candidates on the probe events of its log, activate a better one, roll back a worse one
    /// (docs/fleet.md, "The service follows the store").
    Follow(follow::FollowArgs),
    /// Fit a machine's model again from its seconds and probe events in the store (the
    /// defaults of `truepos fit --machine`), refuse it where the fit's checks fail, sign it
    /// and register it as a candidate (docs/fleet.md, "Refit from the store").
    Refit(refit::RefitArgs),
}

#[derive(clap::Subcommand)]
enum ModelsCommand {
    /// Register a signed model as a machine's candidate (signature verified, model loaded and
    /// admitted for the machine file first; nothing written if any of it fails).
    Register(RegisterArgs),
    /// The models in the store, of one machine or all.
    List(ListArgs),
    /// Write a stored model and its signature (MODEL.sig) into a directory.
    Get(GetArgs),
    /// Mark a candidate as run in shadow.
    Shadow(ActivateArgs),
    /// Every state a machine's models entered: when, which version, from, to, who, why.
    History(HistoryArgs),
}

/// The store, common to the model and status commands.
#[derive(clap::Args)]
struct Store {
    /// PostgreSQL, `postgres://USER@HOST:PORT/DB`.
    #[arg(long, value_name = "URL")]
    db: String,
}

/// Who changes a model and why, for the history (`fleet_model_changes`).
#[derive(clap::Args)]
struct Why {
    /// Why (kept in the history; default: the command's name).
    #[arg(long)]
    reason: Option<String>,
    /// Who (default: $USER, else the database role).
    #[arg(long)]
    by: Option<String>,
}

#[derive(clap::Args)]
struct RegisterArgs {
    #[command(flatten)]
    store: Store,
    /// The machine (its Sparkplug node id: the machine file's name with `/`, `+`, `#` as `_`).
    #[arg(long)]
    machine: String,
    /// The model file; its signature is MODEL.sig beside it.
    #[arg(long)]
    model: PathBuf,
    /// The public keys trusted to sign models (one in hex a line).
    #[arg(long, value_name = "FILE")]
    trusted_keys: PathBuf,
    /// The machine description the model is loaded and admitted for.
    #[arg(long, value_name = "FILE")]
    machine_file: PathBuf,
    /// The cycle period the model must fit, ms (as `truepos run --period-ms`).
    #[arg(long, default_value_t = 1.0)]
    period_ms: f64,
    #[command(flatten)]
    why: Why,
}

#[derive(clap::Args)]
struct ListArgs {
    #[command(flatten)]
    store: Store,
    /// Only this machine's.
    #[arg(long)]
    machine: Option<String>,
    /// JSON instead of the table.
    #[arg(long)]
    json: bool,
}

#[derive(clap::Args)]
struct GetArgs {
    #[command(flatten)]
    store: Store,
    /// The machine.
    #[arg(long)]
    machine: String,
    /// The newest model in this state (candidate, shadow, active, retired).
    #[arg(long, default_value = "active", conflicts_with = "version")]
    state: String,
    /// This version instead.
    #[arg(long)]
    version: Option<i32>,
    /// The directory the model file and its MODEL.sig are written to (each whole).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Write only a model whose signature verifies under one of these keys (the store is not
    /// trusted: a row changed in it is refused here, as the service would refuse it).
    #[arg(long, value_name = "FILE")]
    trusted_keys: Option<PathBuf>,
}

#[derive(clap::Args)]
struct HistoryArgs {
    #[command(flatten)]
    store: Store,
    /// The machine.
    #[arg(long)]
    machine: String,
    /// JSON instead of the table.
    #[arg(long)]
    json: bool,
}

#[derive(clap::Args)]
struct ActivateArgs {
    #[command(flatten)]
    store: Store,
    /// The machine.
    #[arg(long)]
    machine: String,
    /// The version.
    #[arg(long)]
    version: i32,
    #[command(flatten)]
    why: Why,
}

#[derive(clap::Args)]
struct RollbackArgs {
    #[command(flatten)]
    store: Store,
    /// The machine.
    #[arg(long)]
    machine: String,
    #[command(flatten)]
    why: Why,
}

#[derive(clap::Args)]
struct StatusArgs {
    #[command(flatten)]
    store: Store,
    /// JSON instead of the table.
    #[arg(long)]
    json: bool,
    /// Serve the status as a page that reads it again every 5 s (and as JSON, `/api/fleet`) on
    /// ADDR until Ctrl-C: `127.0.0.1:8090`, or a port alone for loopback; beyond loopback a
    /// token is needed, as for the live view (docs/live_view.md).
    #[arg(long, value_name = "ADDR")]
    http: Option<String>,
    /// The page's token: the first line of FILE (at least 16 characters).
    #[arg(long, value_name = "FILE")]
    http_token_file: Option<PathBuf>,
    /// With --http, stop after this many seconds.
    #[arg(long)]
    duration_s: Option<f64>,
}

#[derive(clap::Args)]
struct IngestArgs {
    /// The broker, `mqtt://HOST[:PORT]`.
    #[arg(long, value_name = "URL")]
    mqtt: String,
    /// PostgreSQL, `postgres://USER@HOST:PORT/DB`.
    #[arg(long, value_name = "URL")]
    db: String,
    /// MQTT client id: the broker keeps this id's subscription and queues for it while away.
    #[arg(long, default_value = "truepos-fleet-ingest")]
    client_id: String,
    /// Stop after this many seconds without a message (default: run until stopped or
    /// --duration-s).
    #[arg(long)]
    idle_exit_s: Option<f64>,
    /// Stop after this many seconds.
    #[arg(long)]
    duration_s: Option<f64>,
}

#[derive(clap::Args)]
struct PublishArgs {
    /// The service's log.
    #[arg(long)]
    log: PathBuf,
    /// The broker, `mqtt://HOST[:PORT]`.
    #[arg(long, value_name = "URL")]
    mqtt: String,
    /// Sparkplug group id.
    #[arg(long, default_value = "truepos")]
    mqtt_group: String,
    /// Sparkplug edge node id (default: the machine's name in the log): the one the service
    /// published under with --mqtt-node.
    #[arg(long, value_name = "NAME")]
    mqtt_node: Option<String>,
    /// Give up after this many seconds (what is not acknowledged stays for the next time).
    #[arg(long, default_value_t = 60.0)]
    timeout_s: f64,
    /// Historical messages per second at most.
    #[arg(long, default_value_t = 100.0)]
    replay_per_s: f64,
}

/// `truepos fleet …`.
pub fn run(args: Args) -> Result<(), CliError> {
    match args.command {
        Command::Publish(a) => publish(a),
        Command::Ingest(a) => ingest(a),
        Command::Models(ModelsCommand::Register(a)) => register(a),
        Command::Models(ModelsCommand::List(a)) => list(a),
        Command::Models(ModelsCommand::Get(a)) => get(a),
        Command::Models(ModelsCommand::Shadow(a)) => shadow(a),
        Command::Models(ModelsCommand::History(a)) => history(a),
        Command::Activate(a) => activate(a),
        Command::Rollback(a) => rollback(a),
        Command::Status(a) => status(a),
        Command::Follow(a) => follow::follow(a),
        Command::Refit(a) => refit::refit(a),
    }
}

fn seconds(name: &str, v: Option<f64>) -> Result<Option<Duration>, CliError> {
    match v {
        None => Ok(None),
        Some(s) if s.is_finite() && s > 0.0 && s <= 31_536_000.0 => {
            Ok(Some(Duration::from_secs_f64(s)))
        }
        Some(_) => Err(CliError::refused(format!("{name}: give 0-31536000 s"))),
    }
}

fn ingest(a: IngestArgs) -> Result<(), CliError> {
    let config = truepos_fleet_store::ingest::Config {
        broker: BrokerUrl::parse(&a.mqtt).map_err(CliError::refused)?,
        db: a.db,
        client_id: a.client_id,
        idle_exit: seconds("--idle-exit-s", a.idle_exit_s)?,
        deadline: seconds("--duration-s", a.duration_s)?,
    };
    let s = truepos_fleet_store::ingest::run(&config);
    eprintln!(
        "ingest: {} messages; {} seconds, {} events and {} probe events written, {} already there; {} skipped{}; {} database failure(s), {} broker connection(s){}",
        s.messages,
        s.seconds,
        s.events,
        s.probes,
        s.duplicates,
        s.skipped,
        s.last_skip.as_deref().map(|w| format!(" (last: {w})")).unwrap_or_default(),
        s.db_failures,
        s.connects,
        s.last_error.as_deref().map(|w| format!("; last error: {w}")).unwrap_or_default(),
    );
    Ok(())
}

fn publish(a: PublishArgs) -> Result<(), CliError> {
    if !(a.timeout_s.is_finite() && a.timeout_s > 0.0 && a.timeout_s <= 86_400.0) {
        return Err(CliError::refused("--timeout-s: give 0-86400 s"));
    }
    if !(a.replay_per_s.is_finite() && a.replay_per_s >= 0.1) {
        return Err(CliError::refused("--replay-per-s: give at least 0.1"));
    }
    let broker = BrokerUrl::parse(&a.mqtt).map_err(CliError::refused)?;
    truepos_fleet::sparkplug::check_id("--mqtt-group", &a.mqtt_group).map_err(CliError::refused)?;
    if let Some(node) = &a.mqtt_node {
        truepos_fleet::sparkplug::check_id("--mqtt-node", node).map_err(CliError::refused)?;
    }
    let mut config = Config::new(broker, a.log);
    config.group = a.mqtt_group;
    config.replay_per_s = a.replay_per_s;
    config.node = a.mqtt_node;
    let p = Publisher::start(config).map_err(CliError::refused)?;
    let s = p.stop(Duration::from_secs_f64(a.timeout_s));
    eprintln!("{}", describe(&s));
    if s.caught_up {
        Ok(())
    } else {
        Err(CliError::refused(format!(
            "not everything was acknowledged within {} s",
            a.timeout_s
        )))
    }
}

/// Connects to the store and applies the migrations not applied yet.
fn connect(store: &Store) -> Result<Client, CliError> {
    let mut db = Client::connect(&store.db, NoTls)
        .map_err(|e| CliError::refused(format!("--db: PostgreSQL: {e}")))?;
    truepos_fleet_store::schema::migrate(&mut db)
        .map_err(|e| CliError::refused(format!("--db: PostgreSQL: migrations: {e}")))?;
    Ok(db)
}

fn store_error(e: ModelError) -> CliError {
    CliError::refused(e.to_string())
}

impl Why {
    /// Who and why, the reason defaulting to `command`'s name.
    fn words(&self, command: &str) -> (Option<String>, String) {
        let by = self
            .by
            .clone()
            .or_else(|| std::env::var("USER").ok().filter(|u| !u.is_empty()));
        let reason = self
            .reason
            .clone()
            .unwrap_or_else(|| format!("`truepos fleet {command}`"));
        (by, reason)
    }
}

/// The `provenance` and `validation` tables of a model file's text, as JSON (`{}` where it
/// has none): JSON for a `.json` file or text that opens with `{`, else TOML.
fn figures(path: &Path, text: &str) -> Result<(serde_json::Value, serde_json::Value), CliError> {
    let json = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"))
        || text.trim_start().starts_with('{');
    let doc: serde_json::Value = if json {
        serde_json::from_str(text)
            .map_err(|e| CliError::refused(format!("{}: {e}", path.display())))?
    } else {
        let table: toml::Table = toml::from_str(text)
            .map_err(|e| CliError::refused(format!("{}: {e}", path.display())))?;
        serde_json::to_value(table)?
    };
    let table = |key: &str| match doc.get(key) {
        Some(v @ serde_json::Value::Object(_)) => v.clone(),
        _ => serde_json::json!({}),
    };
    Ok((table("provenance"), table("validation")))
}

/// The model's text, read once: its signature verified, loaded for the machine and admitted
/// through the same door as `truepos run --trusted-keys` (`io::model_file`, runtime's
/// admission); returns the text and its signature line.
fn verified_and_admitted(a: &RegisterArgs) -> Result<(String, String), CliError> {
    if !(a.period_ms.is_finite() && (0.1..=10_000.0).contains(&a.period_ms)) {
        return Err(CliError::refused("--period-ms: give 0.1-10000"));
    }
    let machine = truepos_io::machine_file::load(&a.machine_file)?;
    let keys = TrustedKeys::load(&a.trusted_keys)?;
    signed_and_admitted(
        &a.model,
        &machine,
        &keys,
        a.period_ms,
        &a.machine,
        &a.machine_file,
    )
}

/// [`verified_and_admitted`] with the machine file and the trust list read: `fleet models
/// register` and `fleet refit` admit a model through this one door.
fn signed_and_admitted(
    model: &Path,
    machine: &truepos_runtime::MachineConfig,
    keys: &TrustedKeys,
    period_ms: f64,
    node_id: &str,
    machine_file: &Path,
) -> Result<(String, String), CliError> {
    let node = truepos_fleet::sparkplug::sanitize_id(&machine.machine.name);
    if node != node_id {
        // A machine type's name is allowed; a service of another machine than the file's
        // that fetched the model would refuse it (the loader binds a model to its machine).
        eprintln!(
            "note: --machine `{node_id}` is not the node id of {} (`{node}`): right for a \
             service started with --mqtt-node `{node_id}`",
            machine_file.display()
        );
    }
    let text = crate::write::read_text(model, truepos_files::MODEL)?;
    let entry = truepos_io::model_file::entry_of_text(model, &text, machine, Some(keys))?;
    truepos_runtime::admission::admit(&entry, machine, period_ms / 1000.0).map_err(|why| {
        CliError::refused(format!("{}: refused at admission: {why}", model.display()))
    })?;
    // The line read again is checked again against the very bytes verified and loaded.
    let sig_path = signature_path(model);
    let line = crate::write::read_text(&sig_path, truepos_files::CONFIG)?;
    verify_line(&line, text.as_bytes(), &keys.keys).map_err(|why| {
        CliError::refused(format!(
            "{}: refused: {}: {why}",
            model.display(),
            sig_path.display()
        ))
    })?;
    Ok((text, line.trim().to_string()))
}

fn register(a: RegisterArgs) -> Result<(), CliError> {
    let (text, line) = verified_and_admitted(&a)?;
    let (provenance, validation) = figures(&a.model, &text)?;
    let file_name = a
        .model
        .file_name()
        .and_then(|n| n.to_str())
        .ok_or_else(|| CliError::refused(format!("{}: not a file name", a.model.display())))?;
    let public_key = line.split_whitespace().nth(1).unwrap_or_default();
    let mut db = connect(&a.store)?;
    let m = register_candidate(
        &mut db,
        (&a.machine, file_name),
        (&text, &line, public_key),
        (provenance, validation),
        (&a.why, "models register"),
    )?;
    println!("{}: registered as {}", m.machine, as_candidate(&m));
    Ok(())
}

/// Registers a signed, admitted model's text as a candidate of the machine (`fleet models
/// register`, `fleet refit`): `signed` is the text, its signature line and the public key it
/// verifies with, `figures` its provenance and validation tables.
fn register_candidate(
    db: &mut Client,
    (machine, file_name): (&str, &str),
    (text, line, public_key): (&str, &str, &str),
    (provenance, validation): (serde_json::Value, serde_json::Value),
    (why, command): (&Why, &str),
) -> Result<Model, CliError> {
    let (by, reason) = why.words(command);
    models::register(
        db,
        &NewModel {
            machine,
            file_name,
            bytes: text.as_bytes(),
            signature: line,
            public_key,
            provenance,
            validation,
        },
        &Change {
            by: by.as_deref(),
            reason: &reason,
        },
    )
    .map_err(store_error)
}

/// "version 3 (candidate, parent 2), sha256 …": a registered model, as the register commands
/// print it.
fn as_candidate(m: &Model) -> String {
    format!(
        "version {} (candidate{}), sha256 {}",
        m.version,
        m.parent
            .map(|p| format!(", parent {p}"))
            .unwrap_or_default(),
        m.sha256
    )
}

fn model_row(m: &Model) -> String {
    format!(
        "{:<20} {:>7} {:>6} {:<9} {:<20} {:<12} {}",
        m.machine,
        m.version,
        m.parent
            .map(|p| p.to_string())
            .unwrap_or_else(|| "-".into()),
        m.state.as_str(),
        utc_text(m.state_changed_unix_s),
        &m.sha256[..12.min(m.sha256.len())],
        m.file_name
    )
}

fn list(a: ListArgs) -> Result<(), CliError> {
    let mut db = connect(&a.store)?;
    let all = models::list(&mut db, a.machine.as_deref()).map_err(store_error)?;
    if a.json {
        let v: Vec<serde_json::Value> = all.iter().map(Model::to_json).collect();
        println!("{}", serde_json::json!({ "models": v }));
        return Ok(());
    }
    println!(
        "{:<20} {:>7} {:>6} {:<9} {:<20} {:<12} file",
        "machine", "version", "parent", "state", "since", "sha256"
    );
    for m in &all {
        println!("{}", model_row(m));
    }
    Ok(())
}

fn get(a: GetArgs) -> Result<(), CliError> {
    let which = match a.version {
        Some(v) => Which::Version(v),
        None => Which::State(State::parse(&a.state).ok_or_else(|| {
            CliError::refused("--state: give candidate, shadow, active or retired")
        })?),
    };
    let keys = a
        .trusted_keys
        .as_deref()
        .map(TrustedKeys::load)
        .transpose()?;
    let mut db = connect(&a.store)?;
    let f = models::fetch(&mut db, &a.machine, which).map_err(store_error)?;
    if models::sha256_hex(&f.bytes) != f.sha256 {
        return Err(CliError::refused(format!(
            "{} version {}: the stored bytes do not match their sha256; nothing written",
            a.machine, f.version
        )));
    }
    if let Some(keys) = &keys {
        verify_line(&f.signature, &f.bytes, &keys.keys).map_err(|why| {
            CliError::refused(format!(
                "{} version {} in the store: refused: {why}; nothing written",
                a.machine, f.version
            ))
        })?;
    }
    std::fs::create_dir_all(&a.out).map_err(|e| CliError::File {
        path: a.out.clone(),
        doing: Some("cannot create"),
        source: Box::new(e),
    })?;
    let model = a.out.join(&f.file_name);
    // As `fleet follow` writes it: both synced, the signature renamed into place first.
    let sig = follow::write_signed_model(&model, &f.bytes, &f.signature)?;
    println!(
        "{}: version {} ({}) written, with {}",
        model.display(),
        f.version,
        f.state,
        sig.display()
    );
    Ok(())
}

fn history(a: HistoryArgs) -> Result<(), CliError> {
    let mut db = connect(&a.store)?;
    let all = models::history(&mut db, &a.machine).map_err(store_error)?;
    if a.json {
        let v: Vec<serde_json::Value> = all.iter().map(models::Changed::to_json).collect();
        println!("{}", serde_json::json!({ "changes": v }));
        return Ok(());
    }
    println!(
        "{:<21} {:>7} {:<9} {:<9} {:<12} reason",
        "when", "version", "from", "to", "by"
    );
    for c in &all {
        println!(
            "{:<21} {:>7} {:<9} {:<9} {:<12} {}",
            utc_text(c.unix_s),
            c.version,
            c.from.map_or("-", State::as_str),
            c.to.as_str(),
            c.by,
            c.reason
        );
    }
    Ok(())
}

fn shadow(a: ActivateArgs) -> Result<(), CliError> {
    let mut db = connect(&a.store)?;
    let (by, reason) = a.why.words("models shadow");
    let change = Change {
        by: by.as_deref(),
        reason: &reason,
    };
    models::shadow(&mut db, &a.machine, a.version, &change).map_err(store_error)?;
    println!("{}: version {} is shadow", a.machine, a.version);
    Ok(())
}

fn activate(a: ActivateArgs) -> Result<(), CliError> {
    let mut db = connect(&a.store)?;
    let (by, reason) = a.why.words("activate");
    let change = Change {
        by: by.as_deref(),
        reason: &reason,
    };
    let old = models::activate(&mut db, &a.machine, a.version, &change).map_err(store_error)?;
    println!(
        "{}: version {} is active{}",
        a.machine,
        a.version,
        old.map(|o| format!(", version {o} retired"))
            .unwrap_or_default()
    );
    Ok(())
}

fn rollback(a: RollbackArgs) -> Result<(), CliError> {
    let mut db = connect(&a.store)?;
    let (by, reason) = a.why.words("rollback");
    let change = Change {
        by: by.as_deref(),
        reason: &reason,
    };
    let (retired, now) = models::rollback(&mut db, &a.machine, &change).map_err(store_error)?;
    println!(
        "{}: version {retired} retired, version {now} is active again",
        a.machine
    );
    Ok(())
}

fn status_row(s: &MachineStatus) -> String {
    let online = match s.online {
        Some(true) => "online",
        Some(false) => "offline",
        None => "never",
    };
    let model = match s.active_model {
        Some(v) => format!("v{v} active"),
        None => "none active".into(),
    };
    let waiting: Vec<String> = s
        .waiting
        .iter()
        .map(|(v, st)| format!("v{v} {st}"))
        .collect();
    format!(
        "{:<20} {:<8} {:<21} {:<13} {:<12} {:>6}  {}",
        s.machine,
        online,
        s.last_message_unix_s
            .map(utc_text)
            .unwrap_or_else(|| "-".into()),
        model,
        s.compensating().as_str(),
        s.faults_last_hour,
        if waiting.is_empty() {
            "-".into()
        } else {
            waiting.join(", ")
        }
    )
}

fn status(a: StatusArgs) -> Result<(), CliError> {
    let http = truepos_live::host::HttpArgs::check(a.http.as_deref(), a.http_token_file.as_deref())
        .map_err(CliError::refused)?;
    let mut db = connect(&a.store)?;
    if let Some(http) = http {
        drop(db);
        let duration = seconds("--duration-s", a.duration_s)?;
        return view::serve(&a.store.db, http, duration);
    }
    let all = truepos_fleet_store::status::fleet(&mut db)
        .map_err(|e| CliError::refused(format!("--db: PostgreSQL: {e}")))?;
    if a.json {
        let v: Vec<serde_json::Value> = all.iter().map(MachineStatus::to_json).collect();
        println!("{}", serde_json::json!({ "machines": v }));
        return Ok(());
    }
    println!(
        "{:<20} {:<8} {:<21} {:<13} {:<12} {:>6}  waiting",
        "machine", "online", "last message", "model", "compensating", "faults"
    );
    for s in &all {
        println!("{}", status_row(s));
    }
    if all.is_empty() {
        println!("(no machine in the store yet)");
    }
    Ok(())
}
