//! `truepos export` writes what a control applies, and the control's compensation matches the
//! model within the projection error it states — checked against `truepos eval`, the model as
//! the control loop runs it, on rows at other positions and temperatures than the ones exported.

mod support;

use std::path::Path;

use support::{repo, run, scratch};
use truepos_controls::siemens::read_program;

const M: &str = "examples/vmc3/machine.toml";

/// The vmc3 example run's last row (the exported moment) repeated at `positions`.
fn rows_at(
    dir: &Path,
    positions: &[[f64; 3]],
    temps: Option<&dyn Fn(usize) -> f64>,
) -> std::path::PathBuf {
    let text = std::fs::read_to_string(repo("examples/vmc3/run.csv")).unwrap();
    let header = text.lines().next().unwrap();
    let last: Vec<String> = text
        .lines()
        .last()
        .unwrap()
        .split(',')
        .map(String::from)
        .collect();
    let mut out = format!("{header}\n");
    for (i, p) in positions.iter().enumerate() {
        let mut cells = last.clone();
        cells[0] = (i * 10).to_string();
        for k in 0..3 {
            cells[1 + k] = p[k].to_string();
        }
        if let Some(t) = temps {
            for c in cells.iter_mut().take(20).skip(4) {
                *c = format!("{}", c.parse::<f64>().unwrap() + t(i));
            }
        }
        out += &(cells.join(",") + "\n");
    }
    let path = dir.join(format!("rows{}.csv", positions.len()));
    std::fs::write(&path, out).unwrap();
    path
}

/// Per row, the compensation of each axis `truepos eval` gives (µm).
fn eval_comp(model: &str, csv: &Path, out: &Path) -> Vec<[f64; 3]> {
    let (ok, _, err) = run(&[
        "eval",
        "--machine",
        M,
        "--model",
        model,
        "--run",
        csv.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let text = std::fs::read_to_string(out).unwrap();
    text.lines()
        .skip(1)
        .map(|l| {
            let c: Vec<f64> = l.split(',').take(7).map(|x| x.parse().unwrap()).collect();
            [c[2], c[4], c[6]]
        })
        .collect()
}

#[test]
fn the_siemens_program_applies_the_model_within_the_stated_error() {
    let dir = scratch("export-siemens");
    let out = dir.join("temp_comp.mpf");
    let (ok, stdout, err) = run(&[
        "export",
        "--to",
        "siemens",
        "--machine",
        M,
        "--model",
        "examples/vmc3/model.toml",
        "--run",
        "examples/vmc3/run.csv",
        "--p0",
        "X=400",
        "--max-error-um",
        "5",
        "--json",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let program = read_program("temp_comp.mpf", &std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(
        program.iter().map(|s| s.axis.as_str()).collect::<Vec<_>>(),
        ["X", "Y", "Z"]
    );
    assert_eq!(program[0].form.p0_mm, 400.0);
    // Every axis along its travel, the others where the run's last row left them, and then the
    // corners of the volume.
    let text = std::fs::read_to_string(repo("examples/vmc3/run.csv")).unwrap();
    let last: Vec<f64> = text
        .lines()
        .last()
        .unwrap()
        .split(',')
        .skip(1)
        .take(3)
        .map(|x| x.parse().unwrap())
        .collect();
    let (x, y, z) = (last[0], last[1], last[2]);
    let mut grid = Vec::new();
    for k in 0..=10 {
        let f = f64::from(k) / 10.0;
        grid.push([800.0 * f, y, z]);
        grid.push([x, 500.0 * f, z]);
        grid.push([x, y, 500.0 * f]);
    }
    for c in 0..8 {
        grid.push([
            800.0 * f64::from(c & 1),
            500.0 * f64::from(c >> 1 & 1),
            500.0 * f64::from(c >> 2 & 1),
        ]);
    }
    let comp = eval_comp(
        "examples/vmc3/model.toml",
        &rows_at(&dir, &grid, None),
        &dir.join("eval.csv"),
    );
    for (p, c) in grid.iter().zip(&comp) {
        for a in 0..3 {
            let control_um = 1000.0 * program[a].form.at(p[a]);
            let stated = v["axes"][a]["worst_um"].as_f64().unwrap();
            assert!(
                (control_um - c[a]).abs() <= stated + 1e-3,
                "axis {a} at {p:?}: control {control_um} µm, model {} µm, stated {stated}",
                c[a]
            );
        }
    }
    // On the travel of the axis itself, others where they are, the error is the smaller
    // along-the-travel figure.
    for (i, (p, c)) in grid.iter().zip(&comp).take(33).enumerate() {
        let a = i % 3;
        let along = v["axes"][a]["along_error_um"].as_f64().unwrap();
        let control_um = 1000.0 * program[a].form.at(p[a]);
        assert!(
            (control_um - c[a]).abs() <= along + 1e-3,
            "axis {a} at {p:?}: control {control_um} µm, model {} µm, along {along}",
            c[a]
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_form_that_misses_the_model_is_refused_and_nothing_is_written() {
    let dir = scratch("export-refused");
    let out = dir.join("offsets.csv");
    let (ok, _, err) = run(&[
        "export",
        "--to",
        "heidenhain9231",
        "--machine",
        M,
        "--model",
        "examples/vmc3/model.toml",
        "--run",
        "examples/vmc3/run.csv",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!ok);
    assert!(err.contains("axis X: the control's form misses the model by up to 3.887 µm (2.566 along its travel, 1.320 when Y travels, 0.000 when Z travels), more than --max-error-um 2; --force to write it anyway"), "{err}");
    assert!(!out.exists() && !dir.join("offsets.csv.partial").exists());
    let (ok, screen, err) = run(&[
        "export",
        "--to",
        "heidenhain9231",
        "--machine",
        M,
        "--model",
        "examples/vmc3/model.toml",
        "--run",
        "examples/vmc3/run.csv",
        "--out",
        out.to_str().unwrap(),
        "--force",
    ]);
    assert!(ok, "{err}");
    assert!(err.contains("warning: --force: axis X"));
    // The module's own words, not SINUMERIK's.
    assert!(
        screen.contains("X: module 9231 offset -31 × 0.1 µm") && !screen.contains("tanβ"),
        "{screen}"
    );
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(
        text.starts_with("axis,offset_0_1um,projection_error_um\nX,-31,3.887\n"),
        "{text}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// Evaluates a TEMPCOMP formula as the control would, with the PLC words holding the sensors
/// in tenths of a degree.
fn tempcomp_value(formula: &str, word: &dyn Fn(&str) -> f64) -> f64 {
    formula
        .split(" + ")
        .map(|term| match term.split_once(" * (") {
            None => term.parse::<f64>().unwrap(),
            Some((c, rest)) => {
                let (w, _) = rest.split_once(" * ").unwrap();
                c.parse::<f64>().unwrap() * (word(w) * 0.1 - 20.0)
            }
        })
        .sum()
}

#[test]
fn tempcomp_is_the_position_independent_model_at_any_temperature() {
    let dir = scratch("export-tempcomp");
    let text = std::fs::read_to_string(repo("examples/vmc3/model.toml")).unwrap();
    let (head, rest) = text.split_once("# Structure:").unwrap();
    let spindle = &rest[rest.find("# Spindle growth").unwrap()..];
    let model = dir.join("spindle.model.toml");
    std::fs::write(&model, format!("{head}{spindle}")).unwrap();
    let out = dir.join("tempcomp.txt");
    let args = |words: &[&'static str]| {
        let mut a = vec![
            "export",
            "--to",
            "heidenhain-tempcomp",
            "--machine",
            M,
            "--model",
            model.to_str().unwrap(),
            "--run",
            "examples/vmc3/run.csv",
            "--nominal",
            "Z=300",
            "--json",
            "--out",
            out.to_str().unwrap(),
        ];
        for w in words {
            a.extend(["--plc-word", w]);
        }
        a
    };
    let (ok, _, err) = run(&args(&["spindle_front_bearing=W486"]));
    assert!(!ok);
    // Every missing word in one message (a shop found 16 by 16 reruns).
    assert!(err.contains("2 sensor(s) without a PLC word: spindle_rear_bearing, ambient (give --plc-word spindle_rear_bearing=W…,ambient=W…)"), "{err}");
    let (ok, stdout, err) = run(&args(&[
        "spindle_front_bearing=W486",
        "spindle_rear_bearing=W488*0.1",
        "ambient=W490",
    ]));
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(v["axes"].as_array().unwrap().len(), 1, "{v}");
    let formula = v["axes"][0]["formula"].as_str().unwrap().to_string();
    assert!(std::fs::read_to_string(&out)
        .unwrap()
        .contains(&format!("Z = {formula}")));
    assert!(v["axes"][0]["position_error_um"].as_f64().unwrap() < 1e-9);
    // Rows 2 K, 4 K, … warmer than the exported one on every sensor: the formula with the
    // PLC's words equals the model's compensation (columns 14 front, 15 rear, 19 ambient).
    let shift = |i: usize| 2.0 * i as f64 - 5.0;
    let csv = rows_at(
        &dir,
        &[
            [100.0, 50.0, 20.0],
            [700.0, 400.0, 480.0],
            [400.0, 250.0, 250.0],
        ],
        Some(&shift),
    );
    let comp = eval_comp(model.to_str().unwrap(), &csv, &dir.join("eval.csv"));
    let rows: Vec<Vec<f64>> = std::fs::read_to_string(&csv)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    for (r, c) in rows.iter().zip(&comp) {
        let word = |w: &str| match w {
            "W486" => r[14] * 10.0,
            "W488" => r[15] * 10.0,
            "W490" => r[19] * 10.0,
            _ => panic!("{w}"),
        };
        let got_um = 1000.0 * (tempcomp_value(&formula, &word) - 300.0);
        assert!(
            (got_um - c[2]).abs() < 1e-3,
            "TEMPCOMP {got_um} µm, model {} µm",
            c[2]
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// The grid of `the_isg_…` and `the_fanuc_…`: every axis along its travel (the others at
/// mid-travel) and the 8 corners; per point, `control(axis, position)` must match `truepos
/// eval`'s compensation within the axis' stated `worst_um`.
fn within_stated(dir: &Path, v: &serde_json::Value, control: &dyn Fn(usize, f64) -> f64) {
    let mut grid = Vec::new();
    for k in 0..=10 {
        let f = f64::from(k) / 10.0;
        grid.push([800.0 * f, 250.0, 250.0]);
        grid.push([400.0, 500.0 * f, 250.0]);
        grid.push([400.0, 250.0, 500.0 * f]);
    }
    for c in 0..8 {
        grid.push([
            800.0 * f64::from(c & 1),
            500.0 * f64::from(c >> 1 & 1),
            500.0 * f64::from(c >> 2 & 1),
        ]);
    }
    let comp = eval_comp(
        "examples/vmc3/model.toml",
        &rows_at(dir, &grid, None),
        &dir.join("eval.csv"),
    );
    for (p, c) in grid.iter().zip(&comp) {
        for a in 0..3 {
            let control_um = control(a, p[a]);
            let stated = v["axes"][a]["worst_um"].as_f64().unwrap();
            assert!(
                (control_um - c[a]).abs() <= stated + 1e-3,
                "axis {a} at {p:?}: control {control_um} µm, model {} µm, stated {stated}",
                c[a]
            );
        }
    }
}

fn export_json(to: &str, out: &Path, extra: &[&str]) -> serde_json::Value {
    let mut args = vec![
        "export",
        "--to",
        to,
        "--machine",
        M,
        "--model",
        "examples/vmc3/model.toml",
        "--run",
        "examples/vmc3/run.csv",
        "--p0",
        "X=400",
        "--max-error-um",
        "5",
        "--json",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let (ok, stdout, err) = run(&args);
    assert!(ok, "{err}");
    serde_json::from_str(&stdout).unwrap()
}

/// The ISG parameter blocks, read back, give a compensation that matches `truepos eval` of the
/// model within the stated error (projection plus the parameters' whole units) along every
/// axis' travel and at the corners.
#[test]
fn the_isg_parameters_apply_the_model_within_the_stated_error() {
    use truepos_controls::isg::read_parameters;
    let dir = scratch("export-isg");
    let out = dir.join("temp_comp.lis");
    let v = export_json("isg", &out, &["--isg-axis", "Z=7"]);
    let text = std::fs::read_to_string(&out).unwrap();
    let params = read_parameters("temp_comp.lis", &text).unwrap();
    assert_eq!(
        params.iter().map(|p| p.axis_nr).collect::<Vec<_>>(),
        [1, 2, 7]
    );
    assert_eq!(params[0].position_0, 4_000_000, "P0 400 mm in 0.1 µm");
    within_stated(&dir, &v, &|a, p| 1000.0 * params[a].compensation_mm(p));
    // Malformed blocks are located.
    let e = read_parameters(
        "t.lis",
        &text.replace("coefficient       ", "coefficient       x"),
    )
    .unwrap_err();
    assert!(e.to_string().starts_with("t.lis:9:38:"), "{e}");
    let e = read_parameters(
        "t.lis",
        &text.replace(
            "lr_param.temp_comp_offset_0 ",
            "lr_param.temp_comp_ofset_0  ",
        ),
    )
    .unwrap_err();
    assert!(e.to_string().contains("unknown name"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The FANUC macro program, read back and applied as its comment says (ΔK = K0 + slope ·
/// (P − P0) / 1000 from three variables per axis), matches `truepos eval` within the stated
/// error; the `cnc_wrmacro` arguments in `--json` are the same numbers.
#[test]
fn the_fanuc_macro_variables_apply_the_model_within_the_stated_error() {
    use truepos_controls::fanuc::read_macro_program;
    let dir = scratch("export-fanuc");
    let out = dir.join("O9123.nc");
    let v = export_json(
        "fanuc",
        &out,
        &["--fanuc-macro-base", "510", "--fanuc-program", "9123"],
    );
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(
        text.starts_with("%\nO9123 (TRUEPOS THERMAL COMPENSATION)\n"),
        "{text}"
    );
    let vars = read_macro_program("O9123.nc", &text).unwrap();
    assert_eq!(vars.len(), 9);
    let var = |n: u32| vars.iter().find(|(k, _)| *k == n).unwrap().1;
    within_stated(&dir, &v, &|a, p| {
        let b = 510 + 3 * a as u32;
        var(b) + var(b + 1) * (p - var(b + 2)) / 1000.0
    });
    for a in 0..3 {
        for (i, call) in v["axes"][a]["fanuc"]["cnc_wrmacro"]
            .as_array()
            .unwrap()
            .iter()
            .enumerate()
        {
            let n = call["number"].as_u64().unwrap() as u32;
            assert_eq!(n, 510 + 3 * a as u32 + i as u32);
            let value = call["mcr_val"].as_i64().unwrap() as f64
                / 10f64.powi(call["dec_val"].as_i64().unwrap() as i32);
            assert!((value - var(n)).abs() < 1e-9, "#{n}: {value} vs {}", var(n));
        }
    }
    // Malformed programs are located; a base beyond the common variables is refused.
    let e = read_macro_program("p.nc", &text.replace("#511=", "#511=x")).unwrap_err();
    assert!(e.to_string().starts_with("p.nc:7:6:"), "{e}");
    let e = read_macro_program("p.nc", &text.replace("M99\n%\n", "M99\n")).unwrap_err();
    assert!(e.to_string().contains("cut short"), "{e}");
    let (ok, _, err) = run(&[
        "export",
        "--to",
        "fanuc",
        "--machine",
        M,
        "--model",
        "examples/vmc3/model.toml",
        "--run",
        "examples/vmc3/run.csv",
        "--fanuc-macro-base",
        "998",
        "--out",
        dir.join("bad.nc").to_str().unwrap(),
    ]);
    assert!(!ok && err.contains("#998 to #1006"), "{err}");
    assert!(!dir.join("bad.nc").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

/// The SINUMERIK program names an axis as the control knows it (`--siemens-axis`, as `kin
/// table` names it), with the same values as under the machine file's name; a name the control
/// could not take is refused.
#[test]
fn the_siemens_program_names_the_axes_as_the_control_knows_them() {
    let dir = scratch("export-siemens-names");
    let (plain, named) = (dir.join("plain.mpf"), dir.join("named.mpf"));
    export_json("siemens", &plain, &[]);
    export_json("siemens", &named, &["--siemens-axis", "X=X1,Z=AX3"]);
    let read = |p: &Path| read_program("p.mpf", &std::fs::read_to_string(p).unwrap()).unwrap();
    let (plain, named) = (read(&plain), read(&named));
    let names: Vec<&str> = named.iter().map(|a| a.axis.as_str()).collect();
    assert_eq!(names, ["X1", "Y", "AX3"]);
    for (p, n) in plain.iter().zip(&named) {
        assert_eq!(p.form, n.form);
    }
    let (ok, _, err) = run(&[
        "export",
        "--to",
        "siemens",
        "--machine",
        M,
        "--model",
        "examples/vmc3/model.toml",
        "--run",
        "examples/vmc3/run.csv",
        "--out",
        dir.join("bad.mpf").to_str().unwrap(),
        "--siemens-axis",
        "X=1X",
    ]);
    assert!(
        !ok && err.contains("`1X` is no SINUMERIK axis name"),
        "{err}"
    );
    assert!(!dir.join("bad.mpf").exists());
}
