//! `truepos fleet refit`: a machine's model fitted again from what the fleet store holds of it —
//! its seconds (`fleet_seconds`) and its accepted probe events (`fleet_probes`) — by the very
//! code `truepos fit --machine` runs, with its defaults; refused where `fit` or `fleet models
//! register` would refuse, or where the model is worse than no compensation out of fold;
//! otherwise signed with the given key and registered as the machine's candidate (parent: its
//! active model), which `truepos fleet follow` then shadows like any other.
//!
//! The run it fits (docs/fleet.md, "Refit from the store"): one row per stored second, its
//! inputs the second's means; at a probe event's second the row is the probe's own cycle (its
//! temperatures and operating state as logged with the probe, its positions the probed ones)
//! with the measured errors `probe_d<axis>_um`, empty on every other row — the sparse form
//! `truepos fit` takes for probes (an empty target cell steps the filters, neither trains nor
//! scores), so every second drives the lags and only the probes train.

use std::collections::BTreeMap;
use std::path::PathBuf;

use clap::Parser;
use truepos_io::model_file::signature::{
    public_hex, signature_line, signature_path, SecretKey, TrustedKeys,
};

use super::{connect, figures, Store, Why};
use crate::error::CliError;

/// Arguments of `truepos fleet refit`.
#[derive(clap::Args)]
pub struct RefitArgs {
    #[command(flatten)]
    store: Store,
    /// The machine: its Sparkplug node id in the store (the machine file's name with `/`, `+`,
    /// `#` as `_`).
    #[arg(long)]
    machine: String,
    /// The machine description the model is fitted for (as `truepos fit --machine`).
    #[arg(long, value_name = "FILE")]
    machine_file: PathBuf,
    /// The secret key the model is signed with (`truepos sign --new-key`).
    #[arg(long, value_name = "FILE")]
    key: PathBuf,
    /// Only data from this time on (a PostgreSQL timestamp, e.g. `2026-11-29 08:00Z`).
    #[arg(long, value_name = "TIME")]
    since: Option<String>,
    /// Only data before this time.
    #[arg(long, value_name = "TIME")]
    until: Option<String>,
    /// Where the run (`run.csv`), the model (`model.toml` when the machine's active model is
    /// TOML, else `model.json`) and its signature are written.
    #[arg(long, value_name = "DIR", default_value = "refit")]
    out: PathBuf,
    /// Refuse with fewer accepted probe events than this in the range (1–1000000).
    #[arg(long, default_value_t = 20)]
    min_probes: usize,
    /// The cycle period the model must fit, ms (as `truepos run --period-ms`).
    #[arg(long, default_value_t = 1.0)]
    period_ms: f64,
    #[command(flatten)]
    why: Why,
}

/// `truepos fit`'s options, parsed as the command line parses them: the fit gets exactly the
/// defaults a person typing `truepos fit` gets.
#[derive(Parser)]
struct FitCommand {
    #[command(flatten)]
    fit: crate::fit::Args,
}

/// One row of the run: service time and its values by column.
type RunRow = BTreeMap<String, f64>;

/// The run built from the store.
struct StoreRun {
    /// Column names: `time_s`, the inputs, then the measured errors.
    columns: Vec<String>,
    /// Rows by whole second since the epoch.
    rows: BTreeMap<i64, RunRow>,
    /// Probe events used, and those dropped (a second that had one already).
    probes: usize,
    dropped: usize,
    /// The measured-error columns (targets) with the axis each measures.
    targets: Vec<(String, String)>,
    /// Stored seconds read.
    seconds: usize,
}

fn number(v: &serde_json::Value) -> Option<f64> {
    v.as_f64().filter(|x| x.is_finite())
}

/// The store's seconds and probe events of the machine in the range, as one run.
fn build(
    db: &mut truepos_fleet_store::postgres::Client,
    a: &RefitArgs,
    machine: &truepos_model::Machine,
) -> Result<StoreRun, CliError> {
    let since = a.since.clone().unwrap_or_else(|| "-infinity".into());
    let until = a.until.clone().unwrap_or_else(|| "infinity".into());
    let q = |sql: &str| {
        format!(
            "SELECT extract(epoch FROM t)::float8, {sql}::text FROM {} WHERE node_id = $1 \
             AND t >= $2::text::timestamptz AND t < $3::text::timestamptz ORDER BY t",
            if sql == "stats" {
                "fleet_seconds"
            } else {
                "fleet_probes"
            }
        )
    };
    let refuse = |e: truepos_fleet_store::postgres::Error| {
        CliError::refused(format!("--db: PostgreSQL: {e}"))
    };
    let seconds = db
        .query(&q("stats"), &[&a.machine, &since, &until])
        .map_err(refuse)?;
    let probes = db
        .query(&q("\"values\""), &[&a.machine, &since, &until])
        .map_err(refuse)?;
    // The inputs as the log names them: positions, the measured temperatures (a lagged channel
    // is computed by the fit from its sensor, as by the control), operating state.
    let mut inputs: Vec<String> = machine.axes.iter().map(|x| x.position_column()).collect();
    inputs.extend(
        machine
            .temperatures
            .iter()
            .filter(|t| t.lag.is_none())
            .map(|t| t.id.clone()),
    );
    inputs.extend(machine.operating.iter().map(|o| o.id.clone()));
    let mut rows: BTreeMap<i64, RunRow> = BTreeMap::new();
    for r in &seconds {
        let t: f64 = r.get(0);
        let stats: String = r.get(1);
        let stats: serde_json::Value = serde_json::from_str(&stats)?;
        let mut row = RunRow::new();
        for c in &inputs {
            if let Some(mean) = stats.get(format!("Inputs/{c}")).and_then(|s| number(&s[1])) {
                row.insert(c.clone(), mean);
            }
        }
        rows.insert(t.floor() as i64, row);
    }
    let mut targets: Vec<(String, String)> = Vec::new();
    let (mut used, mut dropped) = (0, 0);
    for r in &probes {
        let t: f64 = r.get(0);
        let values: String = r.get(1);
        let values: serde_json::Value = serde_json::from_str(&values)?;
        let second = t.floor() as i64;
        let row = rows.entry(second).or_default();
        if row.keys().any(|k| k.starts_with("probe_d")) {
            dropped += 1;
            continue;
        }
        let mut measured = false;
        for axis in &machine.axes {
            let column = format!("probe_d{}_um", axis.name.to_lowercase());
            if let Some(e) = values.get(&column).and_then(number) {
                row.insert(column.clone(), e);
                measured = true;
                if !targets.iter().any(|(c, _)| *c == column) {
                    targets.push((column, axis.name.clone()));
                }
            }
        }
        if !measured {
            continue;
        }
        used += 1;
        // The probe's own cycle: its inputs as logged with it, its position the probed one.
        for c in &inputs {
            if let Some(v) = values.get(c).and_then(number) {
                row.insert(c.clone(), v);
            }
        }
        for axis in &machine.axes {
            let probed = format!("probe_{}_mm", axis.name.to_lowercase());
            if let Some(v) = values.get(&probed).and_then(number) {
                row.insert(axis.position_column(), v);
            }
        }
    }
    // The axes' order, not the order the probes met them.
    targets.sort_by_key(|(_, axis)| machine.axes.iter().position(|x| &x.name == axis));
    let mut columns = vec!["time_s".to_string()];
    columns.extend(
        inputs
            .into_iter()
            .filter(|c| rows.values().any(|r| r.contains_key(c))),
    );
    columns.extend(targets.iter().map(|(c, _)| c.clone()));
    Ok(StoreRun {
        columns,
        rows,
        probes: used,
        dropped,
        targets,
        seconds: seconds.len(),
    })
}

impl StoreRun {
    /// The run as CSV: `time_s` from the first row, empty cells where a column has no value.
    fn csv(&self) -> String {
        let t0 = self.rows.keys().next().copied().unwrap_or(0);
        let mut out = self.columns.join(",") + "\n";
        for (t, row) in &self.rows {
            let mut cells = vec![(t - t0).to_string()];
            for c in &self.columns[1..] {
                cells.push(row.get(c).map_or(String::new(), |v| format!("{v}")));
            }
            out += &cells.join(",");
            out.push('\n');
        }
        out
    }
}

/// The database URL without its password, for the provenance.
fn without_password(url: &str) -> String {
    if let Some((scheme, rest)) = url.split_once("://") {
        if let Some((user, host)) = rest.rsplit_once('@') {
            let user = user.split(':').next().unwrap_or_default();
            return format!("{scheme}://{user}@{host}");
        }
    }
    url.split_whitespace()
        .filter(|w| !w.starts_with("password="))
        .collect::<Vec<_>>()
        .join(" ")
}

fn utc(unix_s: i64) -> String {
    truepos_fleet_store::status::utc_text(unix_s as f64)
}

/// Runs `truepos fleet refit`.
pub fn refit(a: RefitArgs) -> Result<(), CliError> {
    if !(1..=1_000_000).contains(&a.min_probes) {
        return Err(CliError::refused("--min-probes: give 1 to 1000000"));
    }
    if !(a.period_ms.is_finite() && (0.1..=10_000.0).contains(&a.period_ms)) {
        return Err(CliError::refused("--period-ms: give 0.1-10000"));
    }
    let config = truepos_io::machine_file::load(&a.machine_file)?;
    let key = SecretKey::load(&a.key)?;
    let mut db = connect(&a.store)?;
    let run = stored_run(&mut db, &a, &config.machine)?;
    std::fs::create_dir_all(&a.out)
        .map_err(|e| CliError::refused(format!("--out {}: {e}", a.out.display())))?;
    let csv_path = a.out.join("run.csv");
    let file_name = candidate_name(&mut db, &a.machine)?;
    let model_path = a.out.join(file_name);
    crate::write::write_whole(&csv_path, run.csv(), &[])?;
    let first = *run.rows.keys().next().expect("seconds exist");
    let last = *run.rows.keys().last().expect("seconds exist");
    eprintln!(
        "refit: {} from {} to {}: {} rows ({} stored seconds), {} probe events{}; run {}",
        a.machine,
        utc(first),
        utc(last),
        run.rows.len(),
        run.seconds,
        run.probes,
        if run.dropped > 0 {
            format!(
                " ({} more dropped: a second with a probe already)",
                run.dropped
            )
        } else {
            String::new()
        },
        csv_path.display()
    );
    let fitted = fit_run(&a, &run, &csv_path, &model_path)?;
    let text = fitted
        .text
        .ok_or_else(|| CliError::refused("the fit wrote no model"))?;
    // Signed as `truepos sign` signs, then through the door `fleet models register` has: the
    // signature verified over the bytes read back, the model loaded and admitted.
    let line = signature_line(&key, text.as_bytes());
    crate::write::write_whole(
        &signature_path(&model_path),
        &line,
        &[("--key", a.key.as_path())],
    )?;
    let keys = TrustedKeys {
        file: a.key.clone(),
        keys: vec![key.public()],
    };
    let (text, line) = super::signed_and_admitted(
        &model_path,
        &config,
        &keys,
        a.period_ms,
        &a.machine,
        &a.machine_file,
    )?;
    let (mut provenance, validation) = figures(&model_path, &text)?;
    let validation = match validation {
        serde_json::Value::Object(m) if !m.is_empty() => serde_json::Value::Object(m),
        _ => serde_json::to_value(&fitted.outcome.validation)?,
    };
    provenance["refit"] = serde_json::json!({
        "tool": format!("truepos fleet refit {}", env!("CARGO_PKG_VERSION")),
        "store": without_password(&a.store.db),
        "machine": a.machine,
        "from": utc(first),
        "to": utc(last),
        "since": a.since,
        "until": a.until,
        "rows": run.rows.len(),
        "seconds": run.seconds,
        "probes": run.probes,
        "targets": run.targets.iter().map(|(c, _)| c.clone()).collect::<Vec<_>>(),
    });
    let public_key = public_hex(&key.public());
    let m = super::register_candidate(
        &mut db,
        (&a.machine, file_name),
        (&text, &line, &public_key),
        (provenance, validation),
        (&a.why, "refit"),
    )?;
    println!(
        "{}: refitted on {} probe events and registered as {}",
        m.machine,
        run.probes,
        super::as_candidate(&m)
    );
    Ok(())
}

/// The machine's run from the store, refused when it has no second or too few probe events.
fn stored_run(
    db: &mut truepos_fleet_store::postgres::Client,
    a: &RefitArgs,
    machine: &truepos_model::Machine,
) -> Result<StoreRun, CliError> {
    let run = build(db, a, machine)?;
    let range = format!(
        "{} to {}",
        a.since.as_deref().unwrap_or("the first"),
        a.until.as_deref().unwrap_or("the last")
    );
    if run.seconds == 0 {
        return Err(CliError::refused(format!(
            "{}: the store holds no second of this machine from {range}; nothing registered",
            a.machine
        )));
    }
    if run.probes < a.min_probes {
        return Err(CliError::refused(format!(
            "{}: {} accepted probe event(s) with a measured error in the store from {range}, \
             fewer than --min-probes {}: too few to fit and validate a model; nothing registered",
            a.machine, run.probes, a.min_probes
        )));
    }
    Ok(run)
}

/// The candidate's file name: its kind follows the active model's.
fn candidate_name(
    db: &mut truepos_fleet_store::postgres::Client,
    machine: &str,
) -> Result<&'static str, CliError> {
    // The model file's kind follows the active model's, so that the `fleet follow` that runs
    // it (whose --model has that extension) takes the candidate: `model.toml` beside a TOML
    // model (a fit that chooses the dynamic form, JSON only, is then refused naming why),
    // else `model.json`, which holds either form.
    let active_name: Option<String> = db
        .query_opt(
            "SELECT file_name FROM fleet_models WHERE machine = $1 AND state = 'active'",
            &[&machine],
        )
        .map_err(|e| CliError::refused(format!("--db: PostgreSQL: {e}")))?
        .map(|r| r.get(0));
    let file_name = match active_name.as_deref().map(|n| n.to_ascii_lowercase()) {
        Some(n) if n.ends_with(".toml") => "model.toml",
        _ => "model.json",
    };
    Ok(file_name)
}

/// The fit of the stored run with `truepos fit`'s defaults, refused when any target is no
/// better than no compensation out of fold.
fn fit_run(
    a: &RefitArgs,
    run: &StoreRun,
    csv_path: &std::path::Path,
    model_path: &std::path::Path,
) -> Result<crate::fit::machine::MachineFit, CliError> {
    // The fit as `truepos fit --run RUN --machine FILE --model OUT --axis T=A` runs it: every
    // other setting its default.
    let mut words: Vec<std::ffi::OsString> = vec![
        "fit".into(),
        "--run".into(),
        csv_path.to_path_buf().into(),
        "--machine".into(),
        a.machine_file.clone().into(),
        "--model".into(),
        model_path.to_path_buf().into(),
    ];
    for (column, axis) in &run.targets {
        words.push("--axis".into());
        words.push(format!("{column}={axis}").into());
    }
    let args = FitCommand::try_parse_from(&words)
        .map_err(|e| CliError::refused(format!("the fit's options: {e}")))?
        .fit;
    let fitted = crate::fit::machine::fit_and_write(args, &a.machine_file)
        .map_err(|e| CliError::refused(format!("refused by the fit: {e}; nothing registered")))?;
    crate::fit::machine::print_screen(&fitted.ds, &fitted.outcome);
    // Worse than no compensation on the rows it never saw: not a candidate.
    let worse: Vec<String> = fitted
        .outcome
        .validation
        .metrics
        .iter()
        .filter(|m| {
            // NaN counts as worse.
            m.rmse_um.partial_cmp(&m.uncompensated_rmse_um) != Some(std::cmp::Ordering::Less)
        })
        .map(|m| {
            format!(
                "{}: {:.2} µm out of fold against {:.2} µm uncompensated",
                m.target, m.rmse_um, m.uncompensated_rmse_um
            )
        })
        .collect();
    if !worse.is_empty() {
        return Err(CliError::refused(format!(
            "{}: the refitted model is no better than no compensation out of fold ({}); \
             nothing registered",
            a.machine,
            worse.join("; ")
        )));
    }
    Ok(fitted)
}

#[cfg(test)]
mod tests {
    use super::without_password;

    #[test]
    fn the_provenance_keeps_no_password() {
        assert_eq!(
            without_password("postgres://fleet:secret@db:5432/fleet"),
            "postgres://fleet@db:5432/fleet"
        );
        assert_eq!(
            without_password("postgres://fleet@db/fleet"),
            "postgres://fleet@db/fleet"
        );
        assert_eq!(
            without_password("host=db user=fleet password=secret"),
            "host=db user=fleet"
        );
    }
}
