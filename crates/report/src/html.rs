//! The HTML page: headline figures, tables, and the figures embedded.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::correlation::correlation_figure;
use crate::histogram::histogram_figure;
use crate::metrics::channel_metrics;
use crate::time_series::{channel_figure, temperature_figure};
use crate::{ReportData, ReportError};

fn escape(s: &str) -> String {
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

/// Writes `report.html` (self-contained) and the figures as SVG files into `dir`; returns the
/// path of the HTML file.
pub fn write_report(dir: &Path, data: &ReportData) -> Result<PathBuf, ReportError> {
    let io = |p: &Path| {
        let p = p.to_path_buf();
        move |e: std::io::Error| ReportError(format!("{}: {e}", p.display()))
    };
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let mut figures: Vec<(String, String, String)> = Vec::new();
    for ch in &data.channels {
        figures.push((
            format!("{}_over_time.svg", file_stem(&ch.name)),
            format!("{}: measured, predicted, residual", ch.name),
            channel_figure(data, ch)?,
        ));
    }
    if !data.channels.is_empty() {
        figures.push((
            "residual_histogram.svg".into(),
            "Residual histogram".into(),
            histogram_figure(data)?,
        ));
    }
    if !data.temperatures.is_empty() {
        figures.push((
            "temperatures.svg".into(),
            "Temperatures".into(),
            temperature_figure(data)?,
        ));
        figures.push((
            "correlation.svg".into(),
            "Correlation heat map".into(),
            correlation_figure(data)?,
        ));
    }
    for (file, _, svg) in &figures {
        let p = dir.join(file);
        std::fs::write(&p, svg).map_err(io(&p))?;
    }

    let n = data.time_s.len();
    let test = data.test_from.unwrap_or(0).min(n)..n;
    let mut html = String::new();
    let _ = write!(
        html,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{t}</title>\
         <style>body{{font-family:sans-serif;max-width:980px;margin:2em auto;color:#222}}\
         table{{border-collapse:collapse;margin:1em 0}}td,th{{border:1px solid #ccc;padding:4px 8px;text-align:right}}\
         th{{background:#f3f3f3}}td.l,th.l{{text-align:left}}figure{{margin:1.5em 0}}</style></head><body>\
         <h1>{t}</h1>",
        t = escape(&data.title)
    );
    let which = if data.test_from.is_some() {
        "on the held-out part, which the fit never saw"
    } else {
        "over the whole run"
    };
    let _ = write!(
        html,
        "<h2>Figures of merit</h2><p>Residual = measured − predicted, {which} ({} samples).</p>\
         <table><tr><th class=\"l\">channel</th><th>RMSE</th><th>max |residual|</th><th>peak-to-peak</th>\
         <th>uncompensated RMS</th><th>reduction</th></tr>",
        test.len()
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
    for (_, caption, svg) in &figures {
        let _ = write!(
            html,
            "<figure>{svg}<figcaption>{}</figcaption></figure>",
            escape(caption)
        );
    }
    if !data.coefficients.is_empty() {
        html.push_str("<h2>Coefficients</h2><table><tr><th class=\"l\">channel</th><th class=\"l\">feature</th><th>value</th></tr>");
        for c in &data.coefficients {
            let _ = write!(
                html,
                "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{:.6}</td></tr>",
                escape(&c.channel),
                escape(&c.feature),
                c.value
            );
        }
        html.push_str("</table>");
    }
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
    html.push_str("</body></html>\n");
    let path = dir.join("report.html");
    std::fs::write(&path, html).map_err(io(&path))?;
    Ok(path)
}

