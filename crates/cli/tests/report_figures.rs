//! The reports show what users judge a model by, and a real browser renders them cleanly:
//! the error over the working volume before and after (demo) or as the model predicts it
//! (`truepos report` with a position-dependent model), a table per held-out run that marks a
//! run made worse (`truepos fit --report`), temperatures as small multiples beyond six
//! channels; then headless Chromium (installed by `scripts/install_chromium.sh`) lays every
//! report out with real fonts and `tests/browser/layout_check.js` checks that each figure has
//! a size and no two labels overlap or leave their figure.

mod support;

use std::path::{Path, PathBuf};
use std::process::Command;

use support::{repo, run, scratch};

/// The browser's verdict on one report: figures rendered, and the layout problems found.
fn browser_check(html: &Path) -> (u64, Vec<String>) {
    let chromium = Path::new("/usr/bin/chromium");
    assert!(
        chromium.exists(),
        "/usr/bin/chromium is missing: run `bash scripts/install_chromium.sh` (scripts/test.sh does)"
    );
    let page = html.with_file_name("layout-check.html");
    let script = std::fs::read_to_string(repo("tests/browser/layout_check.js")).unwrap();
    let text = std::fs::read_to_string(html).unwrap();
    std::fs::write(&page, format!("{text}<script>{script}</script>")).unwrap();
    let profile = html.with_file_name("chromium-profile");
    let out = Command::new(chromium)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            "--window-size=1100,900",
            "--virtual-time-budget=5000",
            "--dump-dom",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg(format!("file://{}", page.display()))
        .output()
        .unwrap();
    let dom = String::from_utf8_lossy(&out.stdout);
    let start = dom.find("<pre id=\"layout-verdict\">").unwrap_or_else(|| {
        panic!(
            "no verdict from chromium: {}",
            String::from_utf8_lossy(&out.stderr)
        )
    });
    let rest = &dom[start + "<pre id=\"layout-verdict\">".len()..];
    let json = rest[..rest.find("</pre>").unwrap()].replace("&quot;", "\"");
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let problems = v["problems"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p.as_str().unwrap().to_string())
        .collect();
    (v["figures"].as_u64().unwrap(), problems)
}

fn assert_clean_in_browser(html: &Path, min_figures: u64) {
    let (figures, problems) = browser_check(html);
    assert!(
        figures >= min_figures,
        "{}: {figures} figures rendered",
        html.display()
    );
    assert!(problems.is_empty(), "{}: {problems:#?}", html.display());
}

/// One run of a single sensor, `k` µm per kelvin of rise.
fn write_run(path: &Path, t0: f64, k: f64) {
    let mut text = String::from("time_s,t1_c,dz_um\n");
    for i in 0..30 {
        let t = t0 + 4.0 * (1.0 - (-(i as f64) / 8.0).exp());
        text += &format!(
            "{},{t},{}\n",
            60 * i,
            k * (t - t0) + 0.05 * ((i % 3) as f64 - 1.0)
        );
    }
    std::fs::write(path, text).unwrap();
}

/// Leave-one-run-out: two runs grow 2 µm/K and one shrinks 1 µm/K, so the model fitted
/// without the odd run makes it worse than no compensation — its table row says so.
#[test]
fn fit_report_has_a_row_per_held_out_run_and_marks_a_run_made_worse() {
    let dir = scratch("fit-report");
    let runs: Vec<PathBuf> = [("a", 20.0, 2.0), ("b", 21.0, 2.0), ("odd", 20.5, -1.0)]
        .iter()
        .map(|(name, t0, k)| {
            let p = dir.join(format!("{name}.csv"));
            write_run(&p, *t0, *k);
            p
        })
        .collect();
    let out = dir.join("report");
    let mut args = vec![
        "fit", "--inputs", "t1_c", "--split", "runs", "--family", "static", "--ridge", "0",
    ];
    for r in &runs {
        args.extend(["--run", r.to_str().unwrap()]);
    }
    args.extend(["--report", out.to_str().unwrap()]);
    let (ok, _, err) = run(&args);
    assert!(ok, "{err}");
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(html.contains("<h2>Per held-out run</h2>"));
    for r in &runs {
        assert!(html.contains(&r.display().to_string()), "{}", r.display());
    }
    assert!(html.contains("1 run/channel pair(s) made worse than uncompensated"));
    let worse_row = html.split("<tr class=\"worse\">").nth(1).unwrap();
    assert!(worse_row.split("</tr>").next().unwrap().contains("odd.csv"));
    assert!(html.contains("held-out runs made worse than uncompensated"));
    assert!(html.contains("out of fold only"));
    assert_clean_in_browser(&out.join("report.html"), 3);
    std::fs::remove_dir_all(&dir).ok();
}

/// Seed A's cross-slide example is position-dependent (the bed factor of Z): its report maps
/// the predicted error over the X–Z travel.
#[test]
fn report_of_a_position_dependent_model_maps_the_working_volume() {
    let dir = scratch("report-volume");
    let original = std::fs::read_to_string(repo("examples/cross-slide/run.csv")).unwrap();
    let mut text = String::new();
    for (i, line) in original.lines().enumerate() {
        text += &if i == 0 {
            format!("{line},x_um\n")
        } else {
            format!("{line},{i}\n")
        };
    }
    let csv = dir.join("run.csv");
    std::fs::write(&csv, text).unwrap();
    let out = dir.join("report");
    let (ok, _, err) = run(&[
        "report",
        "--machine",
        "examples/cross-slide/machine.toml",
        "--model",
        "examples/cross-slide/model.toml",
        "--measured",
        "X=x_um",
        "--run",
        csv.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(
        html.contains("<h2>Working volume</h2>"),
        "no volume section"
    );
    assert!(html.contains("9 × 9 × 1 grid over the travel"));
    let map = std::fs::read_to_string(out.join("volume_error_of_X.svg")).unwrap();
    assert!(map.contains("predicted error"));
    // One measured channel, not two (each --measured pair is one channel).
    assert_eq!(
        html.matches("measured, predicted, residual</figcaption>")
            .count(),
        1
    );
    assert_clean_in_browser(&out.join("report.html"), 4);
    std::fs::remove_dir_all(&dir).ok();
}

/// The demo's report: before/after maps per direction, 24 temperature channels as small
/// multiples, the headline figures.
#[test]
fn demo_report_shows_the_volume_before_and_after() {
    let dir = scratch("demo-report");
    let (ok, _, err) = run(&["demo", "--json", "--out", dir.to_str().unwrap()]);
    assert!(ok, "{err}");
    let html_path = dir.join("report/report.html");
    let html = std::fs::read_to_string(&html_path).unwrap();
    for d in ["dx__X_", "dy__Y_", "dz__Z_"] {
        let svg = std::fs::read_to_string(dir.join(format!("report/volume_{d}.svg"))).unwrap();
        assert_eq!(svg.matches("uncompensated, Z =").count(), 3, "{d}");
        assert_eq!(svg.matches("after compensation, Z =").count(), 3, "{d}");
    }
    assert!(html.contains("largest error over the volume, uncompensated"));
    let temps = std::fs::read_to_string(dir.join("report/temperatures.svg")).unwrap();
    assert!(temps.contains("one panel per sensor"));
    assert_clean_in_browser(&html_path, 9);
    std::fs::remove_dir_all(&dir).ok();
}
