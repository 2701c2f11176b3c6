//! Data as users have it (issue 13, item 1): `truepos fit`, `eval` and `report` read runs
//! without a time column, ISO 8601 times, `;`-separated files with decimal commas, several runs
//! in one file, units in column names and sparse measurements — and each shape fits exactly
//! as the plain comma file with seconds, µm and °C does. Every bad input gets its located
//! message, checked word for word.

mod support;

use std::path::{Path, PathBuf};

use support::{repo, run, scratch};

/// Three runs, 24 samples a minute apart: temperature t1 (°C) and error dz (µm) = k·rise + an
/// offset (targets count from a run's first sample, so the offset vanishes).
fn runs() -> Vec<(&'static str, Vec<f64>, Vec<f64>)> {
    let make = |t0: f64, slope: f64, wobble: f64, k: f64, offset: f64| {
        let t: Vec<f64> = (0..24)
            .map(|i| t0 + slope * i as f64 + wobble * ((i % 5) as f64 - 2.0))
            .collect();
        let y = t.iter().map(|v| k * (v - t[0]) + offset).collect();
        (t, y)
    };
    let (ta, ya) = make(20.0, 0.25, 0.05, 2.0, 5.0);
    let (tb, yb) = make(22.0, 0.15, 0.1, 2.0, 0.0);
    let (tc, yc) = make(21.0, 0.2, -0.08, 1.5, 1.0);
    vec![("a", ta, ya), ("b", tb, yb), ("c", tc, yc)]
}

/// How one generated file writes a row: (header, row i of a run) given its temperature and
/// error.
type Writer = dyn Fn(usize, f64, f64) -> String;

/// Writes each run to `<dir>/<name>.csv` with `header` and `row`; returns the paths.
fn write_each(dir: &Path, header: &str, row: &Writer) -> Vec<PathBuf> {
    runs()
        .iter()
        .map(|(name, t, y)| {
            let mut text = format!("{header}\n");
            for i in 0..t.len() {
                text += &row(i, t[i], y[i]);
                text.push('\n');
            }
            let p = dir.join(format!("{name}.csv"));
            std::fs::write(&p, text).unwrap();
            p
        })
        .collect()
}

fn fit(paths: &[PathBuf], extra: &[&str]) -> (bool, String, String) {
    let mut args = vec!["fit"];
    for p in paths {
        args.extend(["--run", p.to_str().unwrap()]);
    }
    args.extend(["--family", "static", "--ridge", "0", "--split", "runs"]);
    args.extend(extra);
    run(&args)
}

/// The validation figures of a `--json` fit: per run (held out) and pooled, as numbers.
fn figures(json: &str) -> Vec<f64> {
    let v: serde_json::Value = serde_json::from_str(json).unwrap();
    let mut out = Vec::new();
    let keys = ["rmse_um", "max_abs_um", "uncompensated_rmse_um", "samples"];
    for m in v["validation"]["metrics"].as_array().unwrap() {
        out.extend(keys.iter().map(|k| m[k].as_f64().unwrap()));
    }
    for r in v["validation"]["per_run"].as_array().unwrap() {
        for m in r["targets"].as_array().unwrap() {
            out.extend(keys.iter().map(|k| m[k].as_f64().unwrap()));
        }
    }
    out
}

fn same(a: &[f64], b: &[f64], what: &str) {
    assert_eq!(a.len(), b.len(), "{what}");
    for (x, y) in a.iter().zip(b) {
        assert!(
            (x - y).abs() <= 1e-9 * x.abs().max(1.0),
            "{what}: {a:?} vs {b:?}"
        );
    }
}

/// The plain form: `,`, seconds, °C, µm, one run per file.
fn plain(dir: &Path) -> Vec<PathBuf> {
    write_each(dir, "time_s,t1_c,dz_um", &|i, t, y| {
        format!("{},{t},{y}", 60 * i)
    })
}

fn plain_figures(dir: &Path) -> Vec<f64> {
    let (ok, out, err) = fit(&plain(dir), &["--inputs", "t1_c", "--json"]);
    assert!(ok, "{err}");
    figures(&out)
}

#[test]
fn semicolons_and_decimal_commas_fit_like_commas() {
    let dir = scratch("shapes-semicolon");
    let want = plain_figures(&dir);
    let semi = dir.join("semi");
    std::fs::create_dir_all(&semi).unwrap();
    let paths = write_each(&semi, "time_s;t1_c;dz_um", &|i, t, y| {
        format!(
            "{};{};{}",
            60 * i,
            t.to_string().replace('.', ","),
            y.to_string().replace('.', ",")
        )
    });
    let (ok, out, err) = fit(&paths, &["--inputs", "t1_c", "--json"]);
    assert!(ok, "{err}");
    same(&figures(&out), &want, "`;` and decimal commas");
    // Given explicitly, the same; forced to `,`, the header is one column and the decimal
    // commas split the rows.
    let (ok, out, _) = fit(&paths, &["--inputs", "t1_c", "--json", "--delimiter", ";"]);
    assert!(ok);
    same(&figures(&out), &want, "--delimiter ;");
    let (ok, _, err) = fit(&paths, &["--inputs", "t1_c", "--delimiter", ","]);
    assert!(!ok);
    assert_eq!(
        err.trim(),
        format!(
            "error: {}:2:1: expected 1 fields as in the header, found 2",
            paths[0].display()
        )
    );
}

#[test]
fn iso_times_and_a_sample_period_fit_like_seconds() {
    let dir = scratch("shapes-time");
    let want = plain_figures(&dir);
    for (sub, header, row) in [
        (
            "iso",
            "time,t1_c,dz_um",
            Box::new(|i: usize, t: f64, y: f64| format!("2024-03-01T08:{:02}:00+01:00,{t},{y}", i))
                as Box<Writer>,
        ),
        (
            "space",
            "time,t1_c,dz_um",
            Box::new(|i: usize, t: f64, y: f64| {
                format!("2024-03-01 07:{:02}:00.000,{t},{y}", 30 + i)
            }),
        ),
        (
            "day-first",
            "time,t1_c,dz_um",
            Box::new(|i: usize, t: f64, y: f64| format!("01.03.2024 08:{i:02},{t},{y}")),
        ),
        (
            "us",
            "time,t1_c,dz_um",
            Box::new(|i: usize, t: f64, y: f64| format!("03/01/2024 08:{i:02} PM,{t},{y}")),
        ),
        (
            "none",
            "t1_c,dz_um",
            Box::new(|_: usize, t: f64, y: f64| format!("{t},{y}")),
        ),
    ] {
        let d = dir.join(sub);
        std::fs::create_dir_all(&d).unwrap();
        let paths = write_each(&d, header, &*row);
        let extra: &[&str] = match sub {
            "none" => &["--sample-period", "60"],
            "us" => &["--time", "time", "--time-format", "%m/%d/%Y %I:%M %p"],
            _ => &["--time", "time"],
        };
        let mut args = vec!["--inputs", "t1_c", "--json"];
        args.extend(extra);
        let pred = d.join("pred.csv");
        args.extend(["--predictions", pred.to_str().unwrap()]);
        let (ok, out, err) = fit(&paths, &args);
        assert!(ok, "{sub}: {err}");
        same(&figures(&out), &want, sub);
        // Times count from the run's first row in seconds.
        let text = std::fs::read_to_string(&pred).unwrap();
        let times: Vec<&str> = text
            .lines()
            .skip(1)
            .take(3)
            .map(|l| l.split(',').nth(1).unwrap())
            .collect();
        assert_eq!(times, ["0", "60", "120"], "{sub}");
    }
}

#[test]
fn several_runs_in_one_file_are_named_by_their_column() {
    let dir = scratch("shapes-runcol");
    let want = plain_figures(&dir);
    let mut text = String::from("time_s,run,t1_c,dz_um\n");
    for (name, t, y) in runs() {
        for i in 0..t.len() {
            text += &format!("{},{name},{},{}\n", 60 * i, t[i], y[i]);
        }
    }
    let all = dir.join("all.csv");
    std::fs::write(&all, &text).unwrap();
    let pred = dir.join("pred.csv");
    let (ok, out, err) = fit(
        std::slice::from_ref(&all),
        &[
            "--inputs",
            "t1_c",
            "--run-column",
            "run",
            "--json",
            "--predictions",
            pred.to_str().unwrap(),
        ],
    );
    assert!(ok, "{err}");
    same(&figures(&out), &want, "--run-column");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    let names: Vec<&str> = v["validation"]["per_run"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["run"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["a", "b", "c"]);
    let runs_json: Vec<&str> = v["runs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["name"].as_str().unwrap())
        .collect();
    assert_eq!(runs_json, ["a", "b", "c"]);
    let text = std::fs::read_to_string(&pred).unwrap();
    assert!(
        text.lines().nth(1).unwrap().starts_with("a,0,true,"),
        "{text}"
    );
    assert!(
        text.lines().last().unwrap().starts_with("c,1380,true,"),
        "{text}"
    );
    // On screen, the per-run table names the runs by their value.
    let (ok, screen, _) = fit(
        std::slice::from_ref(&all),
        &["--inputs", "t1_c", "--run-column", "run"],
    );
    assert!(ok);
    let table: Vec<&str> = screen
        .lines()
        .skip_while(|l| *l != "per held-out run:")
        .skip(2)
        .collect();
    let first: Vec<&str> = table
        .iter()
        .map(|l| l.split_whitespace().next().unwrap())
        .collect();
    assert_eq!(first, ["a", "b", "c"], "{screen}");

    // A run that comes back after another is refused at the row where it does.
    let bad = dir.join("bad.csv");
    std::fs::write(
        &bad,
        "time_s,run,t1_c,dz_um\n0,a,20,0\n60,a,21,1\n0,b,20,0\n120,a,22,2\n",
    )
    .unwrap();
    let (ok, _, err) = fit(
        std::slice::from_ref(&bad),
        &["--inputs", "t1_c", "--run-column", "run"],
    );
    assert!(!ok);
    assert_eq!(
        err.trim(),
        format!(
            "error: {}:5:2: `run`: run `a` (from line 2) appears again after run `b`: the rows of one run must be together",
            bad.display()
        )
    );
    std::fs::write(&bad, "time_s,run,t1_c,dz_um\n0,a,20,0\n60,,21,1\n").unwrap();
    let (ok, _, err) = fit(
        std::slice::from_ref(&bad),
        &["--inputs", "t1_c", "--run-column", "run"],
    );
    assert!(!ok);
    assert_eq!(
        err.trim(),
        format!(
            "error: {}:3:2: `run`: expected the name of the row's run, the cell is empty",
            bad.display()
        )
    );
}

#[test]
fn units_in_column_names_are_converted() {
    let dir = scratch("shapes-units");
    let want = plain_figures(&dir);
    let (ok, plain_screen, _) = fit(&plain(&dir), &["--inputs", "t1_c"]);
    assert!(ok);
    let d = dir.join("units");
    std::fs::create_dir_all(&d).unwrap();
    // °F and mm: 1 K = 1.8 °F, 1 µm = 0.001 mm.
    let paths = write_each(&d, "time_s,t1 (°F),dz_mm", &|i, t, y| {
        format!("{},{},{}", 60 * i, t * 1.8 + 32.0, y / 1000.0)
    });
    let (ok, out, err) = fit(
        &paths,
        &["--inputs", "t1 (°F)", "--target", "dz_mm", "--json"],
    );
    assert!(ok, "{err}");
    same(&figures(&out), &want, "°F and mm");
    // The screen shows µm: the same figures as the µm file, not a thousandth of them.
    let (ok, screen, _) = fit(&paths, &["--inputs", "t1 (°F)", "--target", "dz_mm"]);
    assert!(ok);
    let figures_of = |s: &str| -> Vec<String> {
        s.lines()
            .skip_while(|l| *l != "per held-out run:")
            .skip(2)
            .map(|l| l.split_whitespace().skip(2).collect::<Vec<_>>().join(" "))
            .collect()
    };
    assert_eq!(figures_of(&screen), figures_of(&plain_screen), "{screen}");
    let k = d.join("k");
    std::fs::create_dir_all(&k).unwrap();
    let paths = write_each(&k, "time_s,t1_k,dz (in)", &|i, t, y| {
        format!("{},{},{}", 60 * i, t + 273.15, y / 25_400.0)
    });
    let (ok, out, err) = fit(
        &paths,
        &["--inputs", "t1_k", "--target", "dz (in)", "--json"],
    );
    assert!(ok, "{err}");
    same(&figures(&out), &want, "K and in");

    // A unit that does not fit the role the flag gives, or no unit at all, is named at the header.
    let bad = d.join("bad.csv");
    std::fs::write(
        &bad,
        "time_s,t1_mm,dz_c,dz (furlong)\n0,20,1,1\n60,21,2,2\n",
    )
    .unwrap();
    let one = std::slice::from_ref(&bad);
    for (inputs, target, message) in [
        ("t1_mm", "dz (furlong)", "1:2: `t1_mm`: the unit mm does not fit a temperature, expected °C, °F or K"),
        ("time_s", "dz_c", "1:3: `dz_c`: the unit °C does not fit a measured error (a length), expected nm, µm, mm, m or in"),
    ] {
        let (ok, _, err) = fit(one, &["--inputs", inputs, "--target", target]);
        assert!(!ok);
        assert_eq!(err.trim(), format!("error: {}:{message}", bad.display()));
    }
    std::fs::write(&bad, "time_s,t1_c,dz (furlong)\n0,20,1\n60,21,2\n").unwrap();
    let (ok, _, err) = fit(one, &["--inputs", "t1_c", "--target", "dz (furlong)"]);
    assert!(!ok);
    assert!(
        err.starts_with(&format!(
            "error: {}:1:3: `dz (furlong)`: unknown unit `furlong`; known: nm, µm",
            bad.display()
        )),
        "{err}"
    );
}

#[test]
fn sparse_measurements_train_on_measured_rows_only() {
    let dir = scratch("shapes-sparse");
    // The same runs measured every fourth row only (a probe every 4 minutes), and the same
    // runs with only those rows: a static fit (rises, no filter) must be the same on both.
    let sparse = dir.join("sparse");
    let thin = dir.join("thin");
    std::fs::create_dir_all(&sparse).unwrap();
    std::fs::create_dir_all(&thin).unwrap();
    let s = write_each(&sparse, "time_s,t1_c,probe_dz_um", &|i, t, y| {
        if i % 4 == 0 {
            format!("{},{t},{y}", 60 * i)
        } else {
            format!("{},{t},", 60 * i)
        }
    });
    let t = write_each(&thin, "time_s,t1_c,probe_dz_um", &|i, t, y| {
        if i % 4 == 0 {
            format!("{},{t},{y}", 60 * i)
        } else {
            String::new()
        }
    });
    let args = [
        "--inputs",
        "t1_c",
        "--target",
        "probe_dz_um",
        "--json",
        "--folds",
        "2",
    ];
    let (ok, out, err) = fit(&s, &args);
    assert!(ok, "{err}");
    let (ok, thin_out, err) = fit(&t, &args);
    assert!(ok, "{err}");
    same(&figures(&out), &figures(&thin_out), "sparse vs thinned");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    for r in v["runs"].as_array().unwrap() {
        assert_eq!(
            (r["samples"].as_u64(), r["measured"].as_u64()),
            (Some(24), Some(6))
        );
    }
    assert_eq!(v["validation"]["per_run"][0]["targets"][0]["samples"], 6);
    // Every row is predicted; the unmeasured ones have an empty measured cell.
    let pred = dir.join("pred.csv");
    let (ok, screen, err) = fit(
        &s,
        &[
            "--inputs",
            "t1_c",
            "--target",
            "probe_dz_um",
            "--folds",
            "2",
            "--predictions",
            pred.to_str().unwrap(),
        ],
    );
    assert!(ok, "{err}");
    assert!(
        screen.contains(&format!(
            "rows with a measurement (the others only step the filters): {} 6 of 24",
            s[0].display()
        )),
        "{screen}"
    );
    let text = std::fs::read_to_string(&pred).unwrap();
    let row: Vec<&str> = text.lines().nth(2).unwrap().split(',').collect();
    assert_eq!((row[1], row[2], row[3]), ("60", "true", ""), "{text}");
    assert!(row[4].parse::<f64>().unwrap().is_finite());
    // A dynamic family steps its filters through every row: it fits too.
    let mut args = vec!["fit"];
    for p in &s {
        args.extend(["--run", p.to_str().unwrap()]);
    }
    args.extend([
        "--inputs",
        "t1_c",
        "--target",
        "probe_dz_um",
        "--family",
        "dynamic",
        "--folds",
        "2",
        "--split",
        "runs",
    ]);
    let (ok, _, err) = run(&args);
    assert!(ok, "{err}");

    // A run without a single measurement is refused, naming run and column.
    let all = dir.join("all.csv");
    std::fs::write(
        &all,
        "time_s,run,t1_c,dz_um\n0,a,20,0\n60,a,21,1\n0,b,20,\n60,b,22,\n",
    )
    .unwrap();
    let (ok, _, err) = fit(
        std::slice::from_ref(&all),
        &["--inputs", "t1_c", "--run-column", "run"],
    );
    assert!(!ok);
    assert_eq!(
        err.trim(),
        format!(
            "error: {}:1:4: `dz_um`: run `b` has no measured value in this column (every cell is empty)",
            all.display()
        )
    );
}

#[test]
fn a_time_that_is_neither_seconds_nor_iso_is_located() {
    let dir = scratch("shapes-badtime");
    let bad = dir.join("bad.csv");
    std::fs::write(&bad, "time_s,t1_c,dz_um\n0,20,0\nnoon,21,1\n").unwrap();
    let (ok, _, err) = fit(std::slice::from_ref(&bad), &["--inputs", "t1_c"]);
    assert!(!ok);
    assert_eq!(
        err.trim(),
        format!(
            "error: {}:3:1: `time_s`: expected seconds (a number), an ISO 8601 date-time like 2024-03-01T08:00:00 or a day-first one like 01.03.2024 08:00:00, got `noon`",
            bad.display()
        )
    );
    std::fs::write(
        &bad,
        "time_s,t1_c,dz_um\n2024-03-01T08:00:00,20,0\n2024-03-01T08:01:00,21,1\n60,22,2\n",
    )
    .unwrap();
    let (ok, _, err) = fit(std::slice::from_ref(&bad), &["--inputs", "t1_c"]);
    assert!(!ok);
    assert_eq!(
        err.trim(),
        format!(
            "error: {}:4:1: `time_s`: expected an ISO 8601 date-time as in the first row, got a number or an empty cell",
            bad.display()
        )
    );
}

/// The vmc3 example run as one file of two runs with a run column, `;` and decimal commas, ISO
/// times and X in inches: `eval` gives each run what evaluating it alone gives.
#[test]
fn eval_and_report_read_the_same_shapes() {
    let dir = scratch("shapes-eval");
    let text = std::fs::read_to_string(repo("examples/vmc3/run.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    let half = rows.len() / 2;
    let x = header.iter().position(|h| *h == "X_mm").unwrap();
    let mut shaped = String::from("time;part;");
    shaped += &header[1..]
        .iter()
        .map(|h| {
            if *h == "X_mm" {
                "X [in]".to_string()
            } else {
                h.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join(";");
    shaped.push('\n');
    let mut first = header.join(",");
    first.push('\n');
    let mut second = first.clone();
    for (r, row) in rows.iter().enumerate() {
        let part = if r < half { "morning" } else { "afternoon" };
        let t0: f64 = rows[if r < half { 0 } else { half }][0].parse().unwrap();
        let secs: f64 = row[0].parse::<f64>().unwrap() - t0;
        let cells: Vec<String> = row[1..]
            .iter()
            .enumerate()
            .map(|(c, v)| {
                if c + 1 == x {
                    (v.parse::<f64>().unwrap() / 25.4)
                        .to_string()
                        .replace('.', ",")
                } else {
                    v.replace('.', ",")
                }
            })
            .collect();
        let h = (secs / 3600.0).floor();
        let m = ((secs - h * 3600.0) / 60.0).floor();
        let s = secs - h * 3600.0 - m * 60.0;
        shaped += &format!(
            "2024-03-01 {:02}:{:02}:{:02};{part};{}\n",
            8 + h as u32,
            m as u32,
            s as u32,
            cells.join(";")
        );
        let plain = if r < half { &mut first } else { &mut second };
        let mut row = row.clone();
        let t = format!("{secs}");
        row[0] = &t;
        *plain += &row.join(",");
        plain.push('\n');
    }
    let (f_all, f_a, f_b) = (dir.join("all.csv"), dir.join("a.csv"), dir.join("b.csv"));
    std::fs::write(&f_all, shaped).unwrap();
    std::fs::write(&f_a, first).unwrap();
    std::fs::write(&f_b, second).unwrap();
    let eval = |path: &Path, extra: &[&str]| {
        let mut args = vec![
            "eval",
            "--machine",
            "examples/vmc3/machine.toml",
            "--model",
            "examples/vmc3/model.toml",
            "--run",
            path.to_str().unwrap(),
        ];
        args.extend(extra);
        let (ok, out, err) = run(&args);
        assert!(ok, "{err}");
        out
    };
    let all = eval(&f_all, &["--run-column", "part", "--time", "time"]);
    let (a, b) = (eval(&f_a, &[]), eval(&f_b, &[]));
    let mut lines = all.lines();
    assert!(lines.next().unwrap().starts_with("run,time_s,X_error_um,"));
    let got: Vec<String> = lines.map(String::from).collect();
    let want: Vec<String> = a
        .lines()
        .skip(1)
        .map(|l| format!("morning,{l}"))
        .chain(b.lines().skip(1).map(|l| format!("afternoon,{l}")))
        .collect();
    assert_eq!(got.len(), want.len());
    for (g, w) in got.iter().zip(&want) {
        // X converted from inches may differ in the last digits of a micrometre.
        let (g, w): (Vec<&str>, Vec<&str>) = (g.split(',').collect(), w.split(',').collect());
        assert_eq!((g[0], g[1], g.last()), (w[0], w[1], w.last()));
        for (x, y) in g[2..g.len() - 1].iter().zip(&w[2..w.len() - 1]) {
            let (x, y): (f64, f64) = (x.parse().unwrap(), y.parse().unwrap());
            assert!((x - y).abs() < 1e-5, "{g:?} {w:?}");
        }
    }
    // report: one of the runs, chosen by name; several without a choice are refused.
    let out = dir.join("report");
    let report = |extra: &[&str]| {
        let mut args = vec![
            "report",
            "--machine",
            "examples/vmc3/machine.toml",
            "--model",
            "examples/vmc3/model.toml",
            "--run",
            f_all.to_str().unwrap(),
            "--run-column",
            "part",
            "--time",
            "time",
            "--measured",
            "Z=Z_mm",
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend(extra);
        run(&args)
    };
    let (ok, _, err) = report(&[]);
    assert!(!ok);
    assert_eq!(
        err.trim(),
        format!(
            "error: {} holds 2 runs; choose one with --select-run: morning, afternoon",
            f_all.display()
        )
    );
    let (ok, _, err) = report(&["--select-run", "afternoon", "--json"]);
    assert!(ok, "{err}");
}
