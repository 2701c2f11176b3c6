//! The HTML page: headline figures, tables, and the figures embedded.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::coefficients::coefficient_tables;
use crate::correlation::correlation_figure;
use crate::histogram::histogram_figure;
use crate::metrics::channel_metrics;
use crate::time_series::{channel_figure, temperature_figure};
use crate::volume::{max_abs, volume_figure};
use crate::{ReportData, ReportError, RunRow, VolumeMap};

pub(crate) fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// A file name made of the safe characters of a channel name.
fn file_stem(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// A figure: its file name, caption and SVG.
struct Figure {
    file: String,
    caption: String,
    svg: String,
}

/// Every figure of the report, in the order they are shown: the working volume first (what a
/// position-dependent model is judged by), then the series over time.
fn figures(data: &ReportData) -> Result<Vec<Figure>, ReportError> {
    let mut out = Vec::new();
    if let Some(map) = &data.volume {
        map.check()?;
        for d in &map.directions {
            out.push(Figure {
                file: format!("volume_{}.svg", file_stem(&d.name)),
                caption: format!("{}: error over the working volume, {}", d.name, map.moment),
                svg: volume_figure(map, d)?,
            });
        }
    }
    for ch in &data.channels {
        out.push(Figure {
            file: format!("{}_over_time.svg", file_stem(&ch.name)),
            caption: format!(
                "{}: drift over {} — measured, predicted, residual",
                ch.name,
                if data.clock_start_s.is_some() {
                    "clock time"
                } else {
                    "time"
                }
            ),
            svg: channel_figure(data, ch)?,
        });
    }
    if !data.channels.is_empty() {
        out.push(Figure {
            file: "residual_histogram.svg".into(),
            caption: "Residual histogram".into(),
            svg: histogram_figure(data)?,
        });
    }
    if !data.temperatures.is_empty() {
        out.push(Figure {
            file: "temperatures.svg".into(),
            caption: "Temperatures".into(),
            svg: temperature_figure(data)?,
        });
        out.push(Figure {
            file: "correlation.svg".into(),
            caption: "Correlation heat map".into(),
            svg: correlation_figure(data)?,
        });
    }
    Ok(out)
}

/// Writes `report.html` (self-contained) and the figures as SVG files into `dir`; returns the
/// path of the HTML file. The files are written together: every output is checked and written
/// to a temporary name before the first is renamed, so a refused or failed report leaves
/// neither a half-written file nor a folder of figures without their page.
pub fn write_report(dir: &Path, data: &ReportData) -> Result<PathBuf, ReportError> {
    let figures = figures(data)?;
    // A link to a folder is a folder; a link to nothing, a file or a device is not.
    let exists = std::fs::symlink_metadata(dir).is_ok();
    if exists && !std::fs::metadata(dir).is_ok_and(|m| m.is_dir()) {
        return Err(ReportError(format!(
            "{}: is not a folder: a report is a folder of files (give a new name or a folder)",
            dir.display()
        )));
    }
    std::fs::create_dir_all(dir).map_err(io_error(dir))?;
    let mut html = String::new();
    let _ = write!(
        html,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{t}</title>\
         <style>{STYLE}</style></head><body><h1>{t}</h1>",
        t = escape(&data.title)
    );
    headline(&mut html, data);
    merit_table(&mut html, data);
    runs_table(&mut html, &data.runs);
    if let Some(map) = &data.volume {
        volume_table(&mut html, map);
    }
    for f in &figures {
        let _ = write!(
            html,
            "<figure>{}<figcaption>{}</figcaption></figure>",
            f.svg,
            escape(&f.caption)
        );
    }
    key_value_tables(&mut html, data);
    html.push_str("</body></html>\n");
    let path = dir.join("report.html");
    let paths: Vec<PathBuf> = figures.iter().map(|f| dir.join(&f.file)).collect();
    let mut files: Vec<(&Path, &[u8])> = paths
        .iter()
        .zip(&figures)
        .map(|(p, f)| (p.as_path(), f.svg.as_bytes()))
        .collect();
    files.push((&path, html.as_bytes()));
    truepos_files::write::write_all_whole(&files, &[]).map_err(|e| ReportError(e.to_string()))?;
    Ok(path)
}

/// The page's style: on screen a column of at most 1000 px; in print A4 with margins a
/// printer can reach, every figure scaled to the page width and kept whole on one page (a
/// figure is read as a whole: half a drift plot on each of two pages shows neither), headings
/// kept with what follows, no background a printer would waste ink on except the shading
/// that marks a run made worse.
const STYLE: &str = "body{font-family:sans-serif;max-width:1000px;margin:2em auto;color:#222}\
table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #ccc;padding:4px 8px;text-align:right}\
th{background:#f3f3f3}td.l,th.l{text-align:left}tr.worse td{background:#fde0dc}figure{margin:1.5em 0}\
figure svg{max-width:100%;height:auto}\
.cards{display:flex;flex-wrap:wrap;gap:12px}.card{border:1px solid #ccc;border-radius:6px;padding:8px 14px}\
.card b{display:block;font-size:1.5em}\
@media print{@page{size:A4;margin:15mm 12mm}\
body{max-width:none;margin:0;font-size:10pt;color:#000;background:#fff}\
figure{break-inside:avoid;page-break-inside:avoid;margin:0.8em 0}\
figure svg{width:100%;height:auto}\
h1,h2,h3{break-after:avoid;page-break-after:avoid}\
tr,.card{break-inside:avoid;page-break-inside:avoid}\
th{background:none}\
tr.worse td{-webkit-print-color-adjust:exact;print-color-adjust:exact}}";

fn io_error(p: &Path) -> impl Fn(std::io::Error) -> ReportError {
    let p = p.to_path_buf();
    move |e| ReportError(format!("{}: {e}", p.display()))
}

/// The headline figures as cards.
fn headline(html: &mut String, data: &ReportData) {
    if data.headline.is_empty() {
        return;
    }
    html.push_str("<div class=\"cards\">");
    for (what, value) in &data.headline {
        let _ = write!(
            html,
            "<div class=\"card\"><b>{}</b>{}</div>",
            escape(value),
            escape(what)
        );
    }
    html.push_str("</div>");
}

fn merit_table(html: &mut String, data: &ReportData) {
    if data.channels.is_empty() {
        return;
    }
    let n = data.time_s.len();
    let test = data.test_from.unwrap_or(0).min(n)..n;
    let which = if data.test_from.is_some() {
        "on the held-out part, which the fit never saw"
    } else {
        "over the whole run"
    };
    // The figures count the rows that carry a measurement (a probe every 5 minutes in a
    // 1 s log leaves most rows empty), not the rows of the run.
    let measured = test
        .clone()
        .filter(|&i| {
            data.channels
                .iter()
                .any(|c| c.measured.get(i).is_some_and(|v| v.is_finite()))
        })
        .count();
    let count = if measured == test.len() {
        format!("{measured} samples")
    } else {
        format!(
            "{measured} samples with a measurement, of {} rows",
            test.len()
        )
    };
    let _ = write!(
        html,
        "<h2>Figures of merit</h2><p>Residual = measured − predicted, {which} ({count}).</p>\
         <table><tr><th class=\"l\">channel</th><th>RMSE</th><th>max |residual|</th><th>peak-to-peak</th>\
         <th>uncompensated RMS</th><th>reduction</th></tr>"
    );
    for ch in &data.channels {
        let m = channel_metrics(ch, test.clone());
        let _ = write!(
            html,
            "<tr><td class=\"l\">{}</td><td>{:.2} {u}</td><td>{:.2} {u}</td><td>{:.2} {u}</td><td>{:.2} {u}</td><td>{:.0} %</td></tr>",
            escape(&ch.name),
            m.rmse_um,
            m.max_abs_um,
            m.peak_to_peak_um,
            m.uncompensated_rmse_um,
            100.0 * m.reduction,
            u = escape(&ch.unit),
        );
    }
    html.push_str("</table>");
}

/// Leave-one-run-out: one row per held-out run and channel; a run the model made worse than
/// no compensation is shaded and counted above the table.
fn runs_table(html: &mut String, runs: &[RunRow]) {
    if runs.is_empty() {
        return;
    }
    let worse: Vec<&RunRow> = runs.iter().filter(|r| r.metrics.reduction < 0.0).collect();
    let _ = write!(
        html,
        "<h2>Per held-out run</h2><p>Each run predicted by a model fitted without it. {}</p>\
         <table><tr><th class=\"l\">run</th><th class=\"l\">channel</th><th>samples</th><th>RMSE</th>\
         <th>max |residual|</th><th>uncompensated RMS</th><th>reduction</th><th class=\"l\">family</th></tr>",
        if worse.is_empty() {
            "No run is made worse than uncompensated.".to_string()
        } else {
            format!(
                "<strong>{} run/channel pair(s) made worse than uncompensated</strong> (shaded).",
                worse.len()
            )
        }
    );
    for r in runs {
        let m = &r.metrics;
        let _ = write!(
            html,
            "<tr{}><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{}</td><td>{:.2} µm</td><td>{:.2} µm</td>\
             <td>{:.2} µm</td><td>{:.0} %</td><td class=\"l\">{}</td></tr>",
            if m.reduction < 0.0 { " class=\"worse\"" } else { "" },
            escape(&r.run),
            escape(&r.channel),
            r.samples,
            m.rmse_um,
            m.max_abs_um,
            m.uncompensated_rmse_um,
            100.0 * m.reduction,
            escape(r.family.as_deref().unwrap_or("—")),
        );
    }
    html.push_str("</table>");
}

/// Largest error over the grid per direction, before and after.
fn volume_table(html: &mut String, map: &VolumeMap) {
    let after = map.labels.1.as_deref();
    let _ = write!(
        html,
        "<h2>Working volume</h2><p>{} grid over the travel, {}.</p><table><tr><th class=\"l\">direction</th><th>max |{}|</th>",
        map.coords.iter().map(|c| c.len().to_string()).collect::<Vec<_>>().join(" × "),
        escape(&map.moment),
        escape(&map.labels.0),
    );
    if let Some(a) = after {
        let _ = write!(html, "<th>max |{}|</th><th>reduction</th>", escape(a));
    }
    html.push_str("</tr>");
    for d in &map.directions {
        let b = max_abs(&d.before);
        let _ = write!(
            html,
            "<tr><td class=\"l\">{}</td><td>{b:.2} µm</td>",
            escape(&d.name)
        );
        if let Some(a) = &d.after {
            let a = max_abs(a);
            let _ = write!(
                html,
                "<td>{a:.2} µm</td><td>{:.0} %</td>",
                100.0 * (1.0 - a / b)
            );
        }
        html.push_str("</tr>");
    }
    html.push_str("</table>");
}

fn key_value_tables(html: &mut String, data: &ReportData) {
    coefficient_tables(html, &data.coefficients);
    if !data.protocol.is_empty() {
        html.push_str("<h2>Validation protocol</h2><table>");
        for (k, v) in &data.protocol {
            let _ = write!(
                html,
                "<tr><th class=\"l\">{}</th><td class=\"l\">{}</td></tr>",
                escape(k),
                escape(v)
            );
        }
        html.push_str("</table>");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A probe every fifth row: the figures say how many rows carry a measurement.
    #[test]
    fn the_sample_count_counts_measured_rows() {
        let n = 20;
        let measured: Vec<f64> = (0..n)
            .map(|i| if i % 5 == 0 { i as f64 } else { f64::NAN })
            .collect();
        let data = ReportData {
            time_s: (0..n).map(|i| i as f64).collect(),
            channels: vec![crate::Channel {
                name: "dz_um".into(),
                unit: "µm".into(),
                predicted: measured.clone(),
                measured,
            }],
            ..Default::default()
        };
        let mut html = String::new();
        merit_table(&mut html, &data);
        assert!(
            html.contains("(4 samples with a measurement, of 20 rows)"),
            "{html}"
        );
    }

    /// A report whose page is refused (a link planted in its place) writes no figure either:
    /// the folder holds the page with its figures or nothing of this report.
    #[test]
    fn a_refused_page_leaves_no_figure_behind() {
        let d = std::env::temp_dir().join(format!("truepos-report-write-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        let victim = d.join("victim.txt");
        std::fs::write(&victim, "precious").unwrap();
        std::os::unix::fs::symlink(&victim, d.join("report.html")).unwrap();
        let data = ReportData {
            time_s: (0..20).map(f64::from).collect(),
            temperatures: vec![("t1".into(), (0..20).map(f64::from).collect())],
            ..Default::default()
        };
        let e = write_report(&d, &data).unwrap_err();
        assert!(e.0.contains("report.html"), "{}", e.0);
        assert_eq!(std::fs::read_to_string(&victim).unwrap(), "precious");
        let left: Vec<String> = std::fs::read_dir(&d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        let mut left = left;
        left.sort();
        assert_eq!(left, ["report.html", "victim.txt"]);
        // A report folder that is a file, a device or a link to one is refused by name.
        let e = write_report(&victim, &data).unwrap_err();
        assert!(e.0.ends_with("victim.txt: is not a folder: a report is a folder of files (give a new name or a folder)"), "{}", e.0);
        let _ = std::fs::remove_dir_all(&d);
    }
}
