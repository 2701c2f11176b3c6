//! `truepos fit` tells the truth about its validation: a figure per held-out run beside the
//! pooled one, the same on screen and in `--json`; predictions that come from a model that did
//! not see their row; a warning for a run the model makes worse; absurd targets refused at
//! their cell. The runs are made by hand so that every figure is computed here, independently:
//! one sensor, `--family static --ridge 0`, so each fold's model is the straight line
//! (ordinary least squares) through its training rows, relative target against rise.

mod support;

use std::path::{Path, PathBuf};

use support::{run, scratch};

/// One run: `n` samples a minute apart; the temperature `t0 + temp(i)`, the target
/// `k·rise + offset` (the offset vanishes: targets count from the run's first sample).
struct Hand {
    temp: Vec<f64>,
    k: f64,
}

impl Hand {
    fn new(t0: f64, temp: impl Fn(usize) -> f64, k: f64) -> Self {
        Self {
            temp: (0..20).map(|i| t0 + temp(i)).collect(),
            k,
        }
    }

    fn rise(&self) -> Vec<f64> {
        self.temp.iter().map(|t| t - self.temp[0]).collect()
    }

    fn target(&self) -> Vec<f64> {
        self.rise().iter().map(|r| self.k * r).collect()
    }

    fn write(&self, path: &Path, offset: f64) {
        let mut text = String::from("time_s,t1_c,dz_um\n");
        for (i, (t, y)) in self.temp.iter().zip(self.target()).enumerate() {
            text += &format!("{},{t},{}\n", 60 * i, y + offset);
        }
        std::fs::write(path, text).unwrap();
    }
}

/// Ordinary least squares y = b0 + k·x: (b0, k).
fn line(x: &[f64], y: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx).powi(2)).sum();
    let k = sxy / sxx;
    (my - k * mx, k)
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|e| e * e).sum::<f64>() / v.len() as f64).sqrt()
}

/// Runs a and b grow 2 µm/K, run c shrinks 1 µm/K.
fn three_runs(dir: &Path) -> (Vec<Hand>, Vec<PathBuf>) {
    let hands = vec![
        Hand::new(20.0, |i| 0.5 * i as f64, 2.0),
        Hand::new(22.0, |i| 0.3 * i as f64 + 0.2 * (i % 3) as f64, 2.0),
        Hand::new(21.0, |i| 0.4 * i as f64 - 0.1 * (i % 4) as f64, -1.0),
    ];
    let paths: Vec<PathBuf> = ["a.csv", "b.csv", "c.csv"]
        .iter()
        .map(|n| dir.join(n))
        .collect();
    for (h, (p, offset)) in hands.iter().zip(paths.iter().zip([5.0, 0.0, 1.0])) {
        h.write(p, offset);
    }
    (hands, paths)
}

fn fit_args<'a>(paths: &'a [PathBuf], extra: &[&'a str]) -> Vec<&'a str> {
    let mut args = vec!["fit"];
    for p in paths {
        args.extend(["--run", p.to_str().unwrap()]);
    }
    args.extend([
        "--inputs", "t1_c", "--target", "dz_um", "--family", "static", "--ridge", "0",
    ]);
    args.extend(extra);
    args
}

/// Figures of one held-out run, by hand: (uncompensated RMSE, RMSE, max |e|, reduction %),
/// and the predictions of the model fitted on the other runs.
fn held_out(hands: &[Hand], h: usize) -> ([f64; 4], Vec<f64>) {
    let (mut x, mut y) = (Vec::new(), Vec::new());
    for (_, hand) in hands.iter().enumerate().filter(|&(r, _)| r != h) {
        x.extend(hand.rise());
        y.extend(hand.target());
    }
    let (b0, k) = line(&x, &y);
    let pred: Vec<f64> = hands[h].rise().iter().map(|r| b0 + k * r).collect();
    let measured = hands[h].target();
    let res: Vec<f64> = measured.iter().zip(&pred).map(|(m, p)| m - p).collect();
    let (unc, rmse) = (rms(&measured), rms(&res));
    let max = res.iter().fold(0.0_f64, |a, e| a.max(e.abs()));
    ([unc, rmse, max, 100.0 * (1.0 - rmse / unc)], pred)
}

#[test]
fn leave_one_run_out_shows_every_run_the_same_on_screen_and_in_json() {
    let dir = scratch("fit-truth-runs");
    let (hands, paths) = three_runs(&dir);
    let pred_csv = dir.join("pred.csv");
    let (ok, json, json_err) = run(&fit_args(
        &paths,
        &[
            "--split",
            "runs",
            "--json",
            "--predictions",
            pred_csv.to_str().unwrap(),
        ],
    ));
    assert!(ok, "{json_err}");
    let (ok, screen, screen_err) = run(&fit_args(&paths, &["--split", "runs"]));
    assert!(ok, "{screen_err}");
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let per_run = v["validation"]["per_run"].as_array().unwrap();
    assert_eq!(per_run.len(), 3);
    let table: Vec<&str> = screen
        .lines()
        .skip_while(|l| *l != "per held-out run:")
        .skip(2)
        .collect();
    assert_eq!(table.len(), 3, "{screen}");
    for (h, (entry, line)) in per_run.iter().zip(&table).enumerate() {
        let name = paths[h].display().to_string();
        assert_eq!(entry["run"], name.as_str());
        let t = &entry["targets"][0];
        assert_eq!(t["target"], "dz_um");
        assert_eq!(t["family"], "static");
        let ([unc, rmse, max, reduction], _) = held_out(&hands, h);
        let got = |key: &str| t[key].as_f64().unwrap();
        for (key, want) in [
            ("uncompensated_rmse_um", unc),
            ("rmse_um", rmse),
            ("max_abs_um", max),
            ("rmse_reduction_percent", reduction),
        ] {
            assert!(
                (got(key) - want).abs() < 1e-6,
                "run {h} {key}: {} vs {want}",
                got(key)
            );
        }
        // The screen shows the JSON's numbers, rounded, and the run's measured rows.
        assert_eq!(t["samples"], 20);
        // The baseline, fitted on the same training rows beside the family named, has its
        // column: one sensor's rise at a whisper of ridge, so the same figure as static's.
        let want = format!(
            "{name} dz_um 20 {:.2} {:.2} {:.2} {:.1}% {:.2} static",
            got("uncompensated_rmse_um"),
            got("rmse_um"),
            got("max_abs_um"),
            got("rmse_reduction_percent"),
            got("baseline_rmse_um")
        );
        assert_eq!(line.split_whitespace().collect::<Vec<_>>().join(" "), want);
    }

    // Run c, held out, is predicted +2 µm/K where it moves −1 µm/K: worse than uncompensated,
    // and both outputs say so with the same words.
    let ([unc, rmse, ..], _) = held_out(&hands, 2);
    assert!(rmse > unc);
    let warning = format!(
        "run {}, dz_um held out: the model makes it worse: RMSE {rmse:.2} µm compensated, {unc:.2} µm uncompensated",
        paths[2].display()
    );
    assert!(
        v["warnings"]
            .as_array()
            .unwrap()
            .contains(&warning.as_str().into()),
        "{v}"
    );
    for err in [&json_err, &screen_err] {
        assert!(err.contains(&format!("warning: {warning}")), "{err}");
    }
    // Runs a and b, held out, are predicted better than uncompensated: no warning names them.
    for path in &paths[..2] {
        let name = format!("run {},", path.display());
        assert!(!screen_err.contains(&name), "{screen_err}");
    }

    // Every row of every run predicted by the model fitted on the other runs.
    let text = std::fs::read_to_string(&pred_csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some("run,time_s,held_out,dz_um,dz_um_predicted")
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 60);
    for (h, path) in paths.iter().enumerate() {
        let (_, pred) = held_out(&hands, h);
        let mine: Vec<&Vec<&str>> = rows
            .iter()
            .filter(|r| r[0] == path.display().to_string())
            .collect();
        assert_eq!(mine.len(), 20);
        for (i, r) in mine.iter().enumerate() {
            assert_eq!(r[2], "true");
            let got: f64 = r[4].parse().unwrap();
            assert!(
                (got - pred[i]).abs() < 1e-6,
                "run {h} row {i}: {got} vs {}",
                pred[i]
            );
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// A chronological split predicts the training part in sample: the file says which rows those
/// are (the first 60 % of each run, 12 of 20).
#[test]
fn a_chronological_split_marks_the_rows_it_trained_on() {
    let dir = scratch("fit-truth-chrono");
    let (_, paths) = three_runs(&dir);
    let pred_csv = dir.join("pred.csv");
    let (ok, _, err) = run(&fit_args(
        &paths,
        &[
            "--split",
            "chrono:0.6",
            "--predictions",
            pred_csv.to_str().unwrap(),
        ],
    ));
    assert!(ok, "{err}");
    let text = std::fs::read_to_string(&pred_csv).unwrap();
    let held: Vec<&str> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(2).unwrap())
        .collect();
    assert_eq!(held.len(), 60);
    for run in held.chunks(20) {
        assert!(run[..12].iter().all(|h| *h == "false"), "{run:?}");
        assert!(run[12..].iter().all(|h| *h == "true"), "{run:?}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// One 1e300 target would make a model with an intercept of 2.35e296 µm that `eval` calls ok:
/// it is refused at its cell, and nothing is written.
#[test]
fn an_absurd_target_is_refused_at_its_cell() {
    let dir = scratch("fit-truth-absurd");
    let (_, paths) = three_runs(&dir);
    let text = std::fs::read_to_string(&paths[1]).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let cells: Vec<&str> = lines[8].split(',').collect();
    lines[8] = format!("{},{},1e300", cells[0], cells[1]);
    std::fs::write(&paths[1], lines.join("\n") + "\n").unwrap();
    let model = dir.join("model.json");
    let (ok, _, err) = run(&fit_args(
        &paths,
        &["--split", "runs", "--model", model.to_str().unwrap()],
    ));
    assert!(!ok);
    assert_eq!(
        err.trim(),
        format!(
            "error: {}:9:3: `dz_um`: 1e300 µm is not a measured error: more than 1e6 µm (1 m) away (a unit or a corrupt cell?)",
            paths[1].display()
        )
    );
    assert!(!model.exists());
    std::fs::remove_dir_all(&dir).ok();
}

/// The model written after a chronological split is fitted on every row, not on the training
/// part the figures came from: the rows no fold held out are predicted in sample by it, so they
/// lie on the straight line through all 60 rows, not through the first 12 of each run.
#[test]
fn the_model_written_after_a_chronological_split_saw_every_row() {
    let dir = scratch("fit-truth-written");
    let (hands, paths) = three_runs(&dir);
    let pred_csv = dir.join("pred.csv");
    let model = dir.join("m.json");
    let (ok, _, err) = run(&fit_args(
        &paths,
        &[
            "--split",
            "chrono:0.6",
            "--predictions",
            pred_csv.to_str().unwrap(),
            "--model",
            model.to_str().unwrap(),
        ],
    ));
    assert!(ok, "{err}");
    let (x, y): (Vec<f64>, Vec<f64>) = hands
        .iter()
        .flat_map(|h| h.rise().into_iter().zip(h.target()))
        .unzip();
    let (b0, k) = line(&x, &y);
    let text = std::fs::read_to_string(&pred_csv).unwrap();
    let rows: Vec<Vec<&str>> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    for (r, hand) in hands.iter().enumerate() {
        for (i, rise) in hand.rise().iter().enumerate().take(12) {
            let row = &rows[20 * r + i];
            assert_eq!(row[2], "false");
            let predicted: f64 = row[4].parse().unwrap();
            assert!((predicted - (b0 + k * rise)).abs() < 1e-6, "{row:?}");
        }
    }
    let file = std::fs::read_to_string(&model).unwrap();
    assert!(file.contains("every row of every run"), "{file}");
    std::fs::remove_dir_all(&dir).ok();
}

/// A model for a target that names no axis would compensate nothing: refused before the fit
/// with the exact option, written with it or with --allow-unmapped; a dynamic model is JSON and
/// a name that says otherwise is refused before anything is fitted.
#[test]
fn a_model_for_no_axis_or_under_the_wrong_name_is_refused() {
    let dir = scratch("fit-truth-unmapped");
    let (_, paths) = three_runs(&dir);
    for p in &paths {
        let text = std::fs::read_to_string(p).unwrap();
        std::fs::write(p, text.replacen("dz_um", "Z-Drift [µm]", 1)).unwrap();
    }
    let args = |model: &Path, extra: &[&str]| -> (bool, String, String) {
        let mut a: Vec<&str> = vec!["fit"];
        for p in &paths {
            a.extend(["--run", p.to_str().unwrap()]);
        }
        a.extend([
            "--inputs", "t1_c", "--target", "Z-Drift*", "--family", "static",
        ]);
        a.extend(["--split", "runs", "--model", model.to_str().unwrap()]);
        a.extend(extra);
        run(&a)
    };
    let model = dir.join("m.json");
    let (ok, _, err) = args(&model, &[]);
    assert!(!ok);
    assert!(
        err.contains("target `Z-Drift [µm]`") && err.contains("--axis 'Z-Drift [µm]=Z'"),
        "{err}"
    );
    assert!(!model.exists());
    for extra in [&["--axis", "Z-Drift [µm]=Z"][..], &["--allow-unmapped"][..]] {
        let (ok, _, err) = args(&model, extra);
        assert!(ok, "{extra:?}: {err}");
        assert!(model.exists());
        std::fs::remove_file(&model).unwrap();
    }
    let toml = dir.join("pd.toml");
    let (ok, _, err) = args(&toml, &["--axis", "Z-Drift [µm]=Z"]);
    assert!(!ok);
    assert!(
        err.contains("written as JSON: name it") && err.contains("pd.json"),
        "{err}"
    );
    assert!(!toml.exists());
    std::fs::remove_dir_all(&dir).ok();
}
