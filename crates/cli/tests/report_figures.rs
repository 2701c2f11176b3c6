//! The reports show what users judge a model by, and a real browser renders them cleanly:
//! the error over the working volume before and after (demo) or as the model predicts it
//! (`truepos report` with a position-dependent model), a table per held-out run that marks a
//! run made worse (`truepos fit --report`), temperatures as small multiples beyond six
//! channels; then headless Chromium (installed by `scripts/install_chromium.sh`) lays every
//! report out with real fonts and `tests/browser/layout_check.js` checks that each figure has
//! a size and no two labels overlap or leave their figure; and prints every report to PDF as
//! a user would from the browser, which must give A4 pages in the expected number with no
//! figure cut by a page break.

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

/// Marks the top and the bottom of every figure with a tiny link whose address names the
/// figure: Chromium keeps links in the PDF as link annotations of the page they are on, so a
/// figure cut by a page break has its two marks on different pages.
fn with_figure_marks(html: &str) -> (String, usize) {
    let mark = |k: usize, end: &str| {
        format!(
            "<a style=\"position:absolute;left:0;{end}:0;width:4px;height:4px;display:block\" \
             href=\"https://truepos.invalid/figure{k}/{end}\"></a>"
        )
    };
    let mut out = String::new();
    let mut rest = html;
    let mut k = 0;
    while let Some(at) = rest.find("<figure>") {
        let close = at
            + rest[at..]
                .find("</figure>")
                .expect("a figure without its end");
        out.push_str(&rest[..at]);
        out.push_str("<figure style=\"position:relative\">");
        out.push_str(&mark(k, "top"));
        out.push_str(&rest[at + "<figure>".len()..close]);
        out.push_str(&mark(k, "bottom"));
        out.push_str("</figure>");
        rest = &rest[close + "</figure>".len()..];
        k += 1;
    }
    out.push_str(rest);
    (out, k)
}

/// The pages of a PDF as Chromium writes it (no object streams): per page object, the
/// addresses of the links on it. Page objects are `/Type /Page` (not `/Pages`, the tree).
fn pdf_pages_and_links(pdf: &[u8]) -> Vec<Vec<String>> {
    let text = String::from_utf8_lossy(pdf);
    let objects: Vec<(&str, &str)> = text
        .split("endobj")
        .filter_map(|chunk| {
            let head = chunk.find(" 0 obj")?;
            let number = chunk[..head].rsplit(|c: char| !c.is_ascii_digit()).next()?;
            Some((number, &chunk[head..]))
        })
        .collect();
    let uri_of = |number: &str| -> Option<String> {
        let body = objects.iter().find(|(n, _)| *n == number)?.1;
        let at = body.find("/URI (")? + "/URI (".len();
        Some(body[at..at + body[at..].find(')')?].to_string())
    };
    objects
        .iter()
        .filter(|(_, body)| {
            body.match_indices("/Type /Page")
                .any(|(i, m)| !body[i + m.len()..].starts_with('s'))
        })
        .map(|(_, body)| {
            let Some(at) = body.find("/Annots [") else {
                return Vec::new();
            };
            let list = &body[at + "/Annots [".len()..];
            list[..list.find(']').unwrap()]
                .split(" 0 R")
                .filter_map(|r| uri_of(r.trim()))
                .collect()
        })
        .collect()
}

/// Prints a report to PDF with headless Chromium, as "Print → Save as PDF" does, and checks
/// the page count is within `pages` and that every figure lies whole on one page. The ranges
/// are the pages these reports printed to when the print stylesheet was written (3, 5 and 20
/// A4 pages), widened for fonts that differ between machines: a figure scaled to nothing or
/// spread over several pages falls outside.
fn assert_prints(html: &Path, pages: std::ops::RangeInclusive<usize>) {
    let (marked, figures) = with_figure_marks(&std::fs::read_to_string(html).unwrap());
    let page = html.with_file_name("print-check.html");
    std::fs::write(&page, marked).unwrap();
    let pdf = html.with_file_name("print-check.pdf");
    let out = Command::new("/usr/bin/chromium")
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            "--no-pdf-header-footer",
        ])
        .arg(format!(
            "--user-data-dir={}",
            html.with_file_name("chromium-print-profile").display()
        ))
        .arg(format!("--print-to-pdf={}", pdf.display()))
        .arg(format!("file://{}", page.display()))
        .output()
        .unwrap();
    let bytes = std::fs::read(&pdf).unwrap_or_else(|e| {
        panic!(
            "{}: no PDF ({e}): {}",
            pdf.display(),
            String::from_utf8_lossy(&out.stderr)
        )
    });
    // A4 portrait, 595 × 842 points, as the print stylesheet's `@page` asks (Chromium's own
    // default is US Letter, 612 × 792).
    let text = String::from_utf8_lossy(&bytes);
    let media = &text[text.find("/MediaBox [0 0 ").expect("no page size") + 15..];
    let size: Vec<f64> = media[..media.find(']').unwrap()]
        .split_whitespace()
        .map(|v| v.parse().unwrap())
        .collect();
    assert!(
        (size[0] - 595.3).abs() < 1.0 && (size[1] - 841.9).abs() < 1.0,
        "{}: pages of {size:?} points, not A4",
        html.display()
    );
    let on_pages = pdf_pages_and_links(&bytes);
    assert!(
        pages.contains(&on_pages.len()),
        "{}: {} pages, expected {pages:?}",
        html.display(),
        on_pages.len()
    );
    let page_of = |link: &str| on_pages.iter().position(|p| p.iter().any(|l| l == link));
    let mut cut = Vec::new();
    for k in 0..figures {
        let top = page_of(&format!("https://truepos.invalid/figure{k}/top"));
        let bottom = page_of(&format!("https://truepos.invalid/figure{k}/bottom"));
        assert!(
            top.is_some() && bottom.is_some(),
            "figure {k}: a mark is missing from the PDF"
        );
        if top != bottom {
            cut.push(format!(
                "figure {k}: starts on page {top:?}, ends on page {bottom:?}"
            ));
        }
    }
    assert!(
        cut.is_empty(),
        "{}: figures cut by a page break: {cut:#?}",
        html.display()
    );
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
    // The drift plot lays the runs end to end and marks where each starts, by name.
    let drift = std::fs::read_to_string(out.join("dz_um_over_time.svg")).unwrap();
    assert!(drift.contains("start of a run"));
    for name in ["a.csv", "b.csv", "odd.csv"] {
        assert!(drift.contains(&format!("\n{name}\n")), "{name} marked");
    }
    assert_clean_in_browser(&out.join("report.html"), 3);
    assert_prints(&out.join("report.html"), 2..=4);
    std::fs::remove_dir_all(&dir).ok();
}

/// Document A's cross-slide example is position-dependent (the bed factor of Z): its report maps
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
    assert_prints(&out.join("report.html"), 4..=6);
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
    assert_prints(&html_path, 17..=23);
    std::fs::remove_dir_all(&dir).ok();
}
