//! A newcomer's route from a shop's own files to a model: three days of a machining centre as a
//! workbook with a sheet per day and real date-time cells, and the same days as `;`-separated
//! Windows-1252 CSV files with decimal commas and day-first dates; German headers with units in
//! brackets, a spindle speed in `[1/min]`, a drift probed every other row. `truepos fit` takes
//! both without `--time` or `--target`, finds the spindle speed as operating state by its unit,
//! and gives the same figures from both routes.

mod support;

use std::path::Path;

use rust_xlsxwriter::{ExcelDateTime, Format, Workbook};
use support::{run, scratch};

const HEADER: [&str; 5] = [
    "Datum/Uhrzeit",
    "Spindel vorne [°C]",
    "Bett [°C]",
    "S [1/min]",
    "Z-Drift [µm]",
];

/// One day (`d` = 0, 1, 2) at a five-minute period over eight hours: (hour, minute), the
/// spindle and bed temperatures, the spindle speed, and the drift on every other row.
fn day(d: usize) -> Vec<(u16, u8, [f64; 3], Option<f64>)> {
    let speed = [6000.0, 3000.0, 8000.0][d];
    let (mut spindle, mut bed) = (20.0 + 0.5 * d as f64, 20.0 + 0.3 * d as f64);
    let (t0, b0) = (spindle, bed);
    (0..96)
        .map(|i| {
            let on = (i / 24) % 2 == 0;
            let target = if on { 20.0 + speed / 400.0 } else { 20.5 };
            spindle += (target - spindle) * 0.08;
            bed += (spindle - bed) * 0.01;
            let drift = (i % 2 == 0).then(|| {
                let z = 2.1 * (spindle - t0) + 1.4 * (bed - b0);
                (z * 1000.0).round() / 1000.0
            });
            let s = (spindle * 100.0).round() / 100.0;
            let b = (bed * 100.0).round() / 100.0;
            let minutes = 5 * i;
            let rpm = if on { speed } else { 0.0 };
            (
                6 + (minutes / 60) as u16,
                (minutes % 60) as u8,
                [s, b, rpm],
                drift,
            )
        })
        .collect()
}

fn write_workbook(path: &Path) {
    let mut book = Workbook::new();
    let when = Format::new().set_num_format("dd.mm.yyyy hh:mm");
    for d in 0..3 {
        let sheet = book.add_worksheet();
        sheet
            .set_name(["Montag", "Dienstag", "Mittwoch"][d])
            .unwrap();
        for (c, name) in HEADER.iter().enumerate() {
            sheet.write_string(0, c as u16, *name).unwrap();
        }
        for (i, (h, m, values, drift)) in day(d).into_iter().enumerate() {
            let row = i as u32 + 1;
            let at = ExcelDateTime::from_ymd(2024, 3, 4 + d as u8)
                .unwrap()
                .and_hms(h, m, 0)
                .unwrap();
            sheet
                .write_datetime_with_format(row, 0, &at, &when)
                .unwrap();
            for (c, v) in values.iter().enumerate() {
                sheet.write_number(row, c as u16 + 1, *v).unwrap();
            }
            if let Some(z) = drift {
                sheet.write_number(row, 4, z).unwrap();
            }
        }
    }
    book.save(path).unwrap();
}

fn write_csv(path: &Path, d: usize) {
    let comma = |v: f64| format!("{v}").replace('.', ",");
    let mut text = HEADER.join(";") + "\r\n";
    for (h, m, values, drift) in day(d) {
        let cells: Vec<String> = values.iter().map(|v| comma(*v)).collect();
        text += &format!(
            "{:02}.03.2024 {h:02}:{m:02};{};{}\r\n",
            4 + d,
            cells.join(";"),
            drift.map_or(String::new(), comma)
        );
    }
    let (bytes, _, unmappable) = encoding_rs::WINDOWS_1252.encode(&text);
    assert!(!unmappable);
    std::fs::write(path, bytes).unwrap();
}

/// `truepos fit … --json` on `runs`: the pooled held-out RMSE and each run's.
fn fit(runs: &[&Path], model: &Path) -> (f64, Vec<f64>, serde_json::Value) {
    let mut args = vec!["fit"];
    for r in runs {
        args.extend(["--run", r.to_str().unwrap()]);
    }
    args.extend(["--inputs", "Spindel*,Bett*,S *", "--split", "runs"]);
    args.extend(["--axis", "Z-Drift [µm]=Z", "--json", "--model"]);
    args.push(model.to_str().unwrap());
    let (ok, out, err) = run(&args);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    let pooled = v["validation"]["metrics"][0]["rmse_um"].as_f64().unwrap();
    let per_run = v["validation"]["per_run"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["targets"][0]["rmse_um"].as_f64().unwrap())
        .collect();
    (pooled, per_run, v)
}

#[test]
fn the_shops_workbook_and_its_csv_fit_the_same_model() {
    let dir = scratch("shop-journey");
    let book = dir.join("Messung.xlsx");
    write_workbook(&book);
    let csvs: Vec<_> = (0..3)
        .map(|d| dir.join(format!("Tag{}.csv", d + 1)))
        .collect();
    for (d, p) in csvs.iter().enumerate() {
        write_csv(p, d);
    }
    let (book_rmse, book_runs, v) = fit(&[&book], &dir.join("book.json"));
    let csv_paths: Vec<&Path> = csvs.iter().map(|p| p.as_path()).collect();
    let (csv_rmse, csv_runs, _) = fit(&csv_paths, &dir.join("csv.json"));
    assert_eq!(v["targets"][0], "Z-Drift [µm]", "{v}");
    assert_eq!(v["inputs"][2], "S [1/min]", "{v}");
    assert!(
        (book_rmse - csv_rmse).abs() < 0.05,
        "{book_rmse} {csv_rmse}"
    );
    assert_eq!(book_runs.len(), 3);
    for (a, b) in book_runs.iter().zip(&csv_runs) {
        assert!((a - b).abs() < 0.05, "{book_runs:?} {csv_runs:?}");
    }
    // The day-long drift is learned: far below what was left uncompensated.
    let unc = v["validation"]["metrics"][0]["uncompensated_rmse_um"]
        .as_f64()
        .unwrap();
    assert!(book_rmse < 0.5 * unc, "{book_rmse} of {unc}");
    // `S [1/min]` is operating state by its unit: read as a temperature it would have been
    // refused (a speed does not fit a temperature).
    assert!(v["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .all(|w| !w.as_str().unwrap().contains("1/min")));
    std::fs::remove_dir_all(&dir).ok();
}
