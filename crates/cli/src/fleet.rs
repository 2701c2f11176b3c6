//! `truepos run --mqtt URL` (the publisher beside the service), `truepos fleet publish`
//! (forward a log that is already written, e.g. after the service was killed) and `truepos
//! fleet ingest` (the broker into PostgreSQL): options into `truepos_fleet`'s and
//! `truepos_fleet_store`'s values, the summary printed.

use std::path::{Path, PathBuf};
use std::time::Duration;

use truepos_fleet::{BrokerUrl, Config, Publisher, Summary};

use crate::error::CliError;

/// How long `truepos run` forwards what is left after the service stopped, at most; what is not
/// acknowledged by then stays in the log and goes with the next start.
const DRAIN_AT_STOP: Duration = Duration::from_secs(10);

/// `--mqtt` checked before anything starts: the broker's address, and the log's rows of the
/// runs before this one (not sent unless this broker's cursor already covers them).
pub struct MqttArgs {
    broker: BrokerUrl,
    group: String,
    log: PathBuf,
    before: truepos_fleet::Rows,
}

impl MqttArgs {
    /// `None` without `--mqtt`; refuses a bad URL or a run without a log.
    pub fn check(
        url: Option<&str>,
        group: &str,
        log: Option<&Path>,
    ) -> Result<Option<Self>, CliError> {
        let Some(url) = url else { return Ok(None) };
        let broker = BrokerUrl::parse(url).map_err(CliError::refused)?;
        let log = log.ok_or_else(|| {
            CliError::refused("--mqtt forwards the log: give --log FILE as well (docs/fleet.md)")
        })?;
        Ok(Some(MqttArgs {
            broker,
            group: group.to_string(),
            log: log.to_path_buf(),
            before: truepos_fleet::last_rows(log),
        }))
    }

    /// Starts the publisher (after the service, which creates the log).
    pub fn start(self) -> Result<Publisher, CliError> {
        let mut config = Config::new(self.broker, self.log);
        config.group = self.group;
        config.start_after = self.before;
        Publisher::start(config).map_err(|e| CliError::refused(format!("--mqtt: {e}")))
    }
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
        "ingest: {} messages; {} seconds and {} events written, {} already there; {} skipped{}; {} database failure(s), {} broker connection(s){}",
        s.messages,
        s.seconds,
        s.events,
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
    let mut config = Config::new(broker, a.log);
    config.group = a.mqtt_group;
    config.replay_per_s = a.replay_per_s;
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
