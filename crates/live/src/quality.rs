//! The model's quality (`/api/quality`): the validation figures each model file carries (its
//! `[validation]` table, the figures `[provenance]` keeps — a fit's inner cross-validation error
//! per output — and a fitted dynamic model's `validation`), read from the file on the request's
//! thread, and the residuals of this run's last probe events from the log's `probes` table
//! (measured error − the error the model in effect predicted there).

use std::path::{Path, PathBuf};

use serde_json::{json, Map, Value};
use truepos_runtime::log;

/// Probe events answered, the newest.
pub const LAST_PROBES: usize = 20;
/// Figures answered per model file, at most (a fit's validation can list every run).
const MAX_FIGURES: usize = 60;
/// Keys of a validation that are lists of names or texts, not figures.
const NOT_FIGURES: [&str; 4] = ["choices", "sensors", "warnings", "protocol"];

/// A number for JSON: `null` when it is not finite.
fn num(v: f64) -> Value {
    if v.is_finite() {
        json!(v)
    } else {
        Value::Null
    }
}

/// The numbers under `v`, each named by its path (`metrics.Z.rmse_um`; a list's entries by their
/// `target`, `run` or `name` when they have one, else their index).
fn figures(v: &Value, prefix: &str, out: &mut Vec<(String, f64)>, depth: usize) {
    if out.len() >= MAX_FIGURES || depth > 4 {
        return;
    }
    let join = |k: &str| {
        if prefix.is_empty() {
            k.to_string()
        } else {
            format!("{prefix}.{k}")
        }
    };
    match v {
        Value::Number(n) => {
            if let Some(f) = n.as_f64() {
                out.push((prefix.to_string(), f));
            }
        }
        Value::Object(m) => {
            for (k, x) in m {
                if !NOT_FIGURES.iter().any(|n| k.starts_with(n)) {
                    figures(x, &join(k), out, depth + 1);
                }
            }
        }
        Value::Array(list) => {
            for (i, x) in list.iter().enumerate() {
                let label = ["target", "run", "name"]
                    .iter()
                    .find_map(|k| x.get(k).and_then(Value::as_str))
                    .map_or(i.to_string(), str::to_string);
                figures(x, &join(&label), out, depth + 1);
            }
        }
        _ => {}
    }
}

/// What a model file says of its validation: its figures, the protocol in words and the
/// warnings, or why it could not be read.
pub fn model_file_quality(path: &Path) -> Value {
    let text = match truepos_files::read::read_text(path, truepos_files::MODEL) {
        Ok(t) => t,
        Err(e) => return json!({"error": e.to_string()}),
    };
    let is_json = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    let doc: Result<Value, String> = if is_json {
        serde_json::from_str(&text).map_err(|e| e.to_string())
    } else {
        toml::from_str::<toml::Table>(&text)
            .map_err(|e| e.to_string())
            .and_then(|t| serde_json::to_value(t).map_err(|e| e.to_string()))
    };
    let doc = match doc {
        Ok(d) => d,
        Err(e) => return json!({"error": format!("{}: {e}", path.display())}),
    };
    let validation = doc.get("validation").cloned().unwrap_or(Value::Null);
    let provenance = doc.get("provenance").cloned().unwrap_or(Value::Null);
    let mut list = Vec::new();
    figures(&validation, "", &mut list, 0);
    // What the provenance keeps of a validation: errors named so (`Z_inner_cv_rmse_um`).
    if let Value::Object(p) = &provenance {
        for (k, v) in p {
            if k.contains("rmse") || k.contains("error") {
                if let Some(f) = v.as_f64() {
                    list.push((k.clone(), f));
                }
            }
        }
    }
    list.truncate(MAX_FIGURES);
    let protocol = validation
        .get("protocol_text")
        .or_else(|| provenance.get("validation"))
        .and_then(Value::as_str);
    let warnings: Vec<&str> = validation
        .get("warnings")
        .and_then(Value::as_array)
        .map(|w| w.iter().filter_map(Value::as_str).take(10).collect())
        .unwrap_or_default();
    let figures: Vec<Value> = list
        .into_iter()
        .map(|(k, v)| json!({"key": k, "value": num(v)}))
        .collect();
    json!({
        "figures": figures,
        "protocol": protocol,
        "warnings": warnings,
        "generation_in_file": provenance.get("generation"),
    })
}

/// The residuals of this run's last probe events (rows after `after` of the log's `probes`
/// table), newest last, and per axis their RMS over the accepted ones listed.
pub fn probes_json(file: &Path, after: i64, axes: &[String]) -> Value {
    let table = match log::read_probes(file) {
        Ok(t) => t,
        Err(e) => return json!({"error": e.to_string()}),
    };
    let column = |name: &str| table.columns.iter().position(|c| c == name);
    let cols: Vec<(usize, Option<usize>, Option<usize>)> = axes
        .iter()
        .enumerate()
        .map(|(a, name)| {
            let [_, measured, predicted] = log::probe_axis_columns(name);
            (a, column(&measured), column(&predicted))
        })
        .collect();
    let rows: Vec<&log::ProbeRow> = table.rows.iter().filter(|r| r.row > after).collect();
    let count = rows.len();
    let mut sums = vec![(0.0, 0usize); axes.len()];
    let events: Vec<Value> = rows
        .iter()
        .skip(count.saturating_sub(LAST_PROBES))
        .map(|r| {
            let value = |c: Option<usize>| c.and_then(|c| r.values.get(c).copied().flatten());
            let measured: Vec<Value> = cols
                .iter()
                .filter_map(|&(a, m, p)| {
                    let m = value(m)?;
                    let p = value(p).unwrap_or(f64::NAN);
                    let residual = m - p;
                    if r.accepted && residual.is_finite() {
                        sums[a].0 += residual * residual;
                        sums[a].1 += 1;
                    }
                    Some(json!({"axis": axes[a], "measured_um": num(m), "predicted_um": num(p), "residual_um": num(residual)}))
                })
                .collect();
            json!({"row": r.row, "time_s": num(r.time_s), "accepted": r.accepted, "reason": r.reason, "axes": measured})
        })
        .collect();
    let rms: Map<String, Value> = axes
        .iter()
        .zip(&sums)
        .filter(|(_, (_, n))| *n > 0)
        .map(|(a, (s, n))| {
            (
                a.clone(),
                json!({"rms_um": num((s / *n as f64).sqrt()), "events": n}),
            )
        })
        .collect();
    json!({"events": events, "count": count, "residual_rms": rms})
}

/// `/api/quality`: per model of the set its name, generation, file and validation figures
/// (`figures`: as read when that generation was loaded, [`model_file_quality`]); the last probe
/// events with their residuals (`null` without a log).
pub fn quality_json(
    models: &[(String, Option<PathBuf>)],
    generations: &[u64],
    figures: &[Value],
    probes: Option<(&Path, i64)>,
    axes: &[String],
) -> Value {
    let models: Vec<Value> = models
        .iter()
        .enumerate()
        .map(|(i, (name, file))| {
            let mut v = figures.get(i).cloned().unwrap_or_else(|| json!({}));
            v["name"] = json!(name);
            v["generation"] = json!(generations.get(i));
            v["file"] = json!(file.as_ref().map(|f| f.display().to_string()));
            v
        })
        .collect();
    let probes = probes.map(|(f, after)| probes_json(f, after, axes));
    json!({"models": models, "probes": probes})
}

/// A model's figures from its file, or what stands in for them when it has none.
pub fn figures_of(file: Option<&Path>) -> Value {
    match file {
        Some(f) => model_file_quality(f),
        None => json!({"error": "no model file (a model built in)"}),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn figures_are_named_by_their_path_and_lists_by_their_target() {
        let v = json!({
            "protocol_text": "leave one run out",
            "metrics": [{"target": "Z", "rmse_um": 2.5, "samples": 10}],
            "held_out_rows_beyond_training": 3,
            "sensors": [["a", "b"]],
            "warnings": ["run 2 worse"]
        });
        let mut out = Vec::new();
        figures(&v, "", &mut out, 0);
        assert_eq!(
            out,
            vec![
                ("held_out_rows_beyond_training".to_string(), 3.0),
                ("metrics.Z.rmse_um".to_string(), 2.5),
                ("metrics.Z.samples".to_string(), 10.0),
            ]
        );
    }

    #[test]
    fn a_model_file_gives_its_validation_table_and_the_errors_its_provenance_keeps() {
        let dir = std::env::temp_dir().join(format!("truepos-live-quality-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("m.toml");
        std::fs::write(
            &f,
            "name = \"m\"\n[provenance]\ngeneration = 2\nZ_inner_cv_rmse_um = 1.5\nvalidation = \"5-fold\"\n\
             [validation]\nwindow_new_rmse_um = 1.25\nwindow_measurements = 30\n",
        )
        .unwrap();
        let q = model_file_quality(&f);
        let keys: Vec<&str> = q["figures"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x["key"].as_str().unwrap())
            .collect();
        assert_eq!(
            keys,
            [
                "window_measurements",
                "window_new_rmse_um",
                "Z_inner_cv_rmse_um"
            ],
            "{q}"
        );
        assert_eq!(q["protocol"], "5-fold");
        assert_eq!(q["generation_in_file"], 2);
        let missing = model_file_quality(&dir.join("none.toml"));
        assert!(missing["error"].is_string(), "{missing}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
