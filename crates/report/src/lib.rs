//! # truepos-report — the curves people look at before they trust a model
//!
//! [`write_report`] turns a [`ReportData`] (time, measured and predicted error per channel,
//! temperatures, coefficients, validation protocol) into one self-contained HTML file with the
//! figures embedded, and the same figures as SVG files beside it:
//!
//! - measured, predicted and residual error over time, one figure per channel, with the held-out
//!   part shaded;
//! - a histogram of the residuals of the held-out part;
//! - temperatures over time;
//! - a correlation heat map of temperatures and measured errors;
//! - the coefficients and the validation protocol as tables.
//!
//! ```
//! use truepos_report::*;
//! let time_s: Vec<f64> = (0..100).map(|i| 60.0 * i as f64).collect();
//! let temp: Vec<f64> = time_s.iter().map(|t| 20.0 + 5.0 * (1.0 - (-t / 1800.0).exp())).collect();
//! let measured: Vec<f64> = temp.iter().map(|t| 3.0 * (t - 20.0)).collect();
//! let predicted: Vec<f64> = temp.iter().map(|t| 2.9 * (t - 20.0)).collect();
//! let data = ReportData {
//!     title: "spindle growth".into(),
//!     time_s,
//!     test_from: Some(60),
//!     channels: vec![Channel { name: "Z".into(), unit: "µm".into(), measured, predicted }],
//!     temperatures: vec![("spindle".into(), temp)],
//!     coefficients: vec![Coefficient { channel: "Z".into(), feature: "spindle − ambient".into(), value: 2.9 }],
//!     protocol: vec![("split".into(), "chronological, first 60 % train".into())],
//! };
//! let dir = std::env::temp_dir().join("truepos-report-doc");
//! let html = write_report(&dir, &data).unwrap();
//! assert!(std::fs::read_to_string(html).unwrap().contains("<svg"));
//! let m = channel_metrics(&data.channels[0], 60..100);
//! assert!(m.rmse_um < m.uncompensated_rmse_um);
//! ```
#![forbid(unsafe_code)]
#![warn(missing_docs)]

use std::fmt::Write as _;
use std::ops::Range;
use std::path::{Path, PathBuf};

use plotters::prelude::*;

/// One error channel (a probe, an axis direction).
#[derive(Debug, Clone, PartialEq)]
pub struct Channel {
    /// Name (`ch1_um`, `Z`).
    pub name: String,
    /// Unit of the values (µm).
    pub unit: String,
    /// Measured error per sample.
    pub measured: Vec<f64>,
    /// The model's prediction per sample.
    pub predicted: Vec<f64>,
}

/// A coefficient of the model.
#[derive(Debug, Clone, PartialEq)]
pub struct Coefficient {
    /// The channel it predicts.
    pub channel: String,
    /// The feature it multiplies.
    pub feature: String,
    /// Its value.
    pub value: f64,
}

/// Everything a report shows.
#[derive(Debug, Clone, PartialEq)]
pub struct ReportData {
    /// Title.
    pub title: String,
    /// Time of each sample in s.
    pub time_s: Vec<f64>,
    /// Index of the first held-out sample (the model never saw it and later ones), if any.
    pub test_from: Option<usize>,
    /// Error channels.
    pub channels: Vec<Channel>,
    /// Temperatures by name, one value per sample.
    pub temperatures: Vec<(String, Vec<f64>)>,
    /// The model's coefficients.
    pub coefficients: Vec<Coefficient>,
    /// How the model was chosen and validated, as (item, description).
    pub protocol: Vec<(String, String)>,
}

/// Figures of merit of one channel over a range of samples.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Metrics {
    /// Root-mean-square residual.
    pub rmse_um: f64,
    /// Largest absolute residual.
    pub max_abs_um: f64,
    /// Peak-to-peak of the residual.
    pub peak_to_peak_um: f64,
    /// RMS of the uncompensated error: measured relative to the first sample of the run.
    pub uncompensated_rmse_um: f64,
    /// 1 − rmse / uncompensated rmse.
    pub reduction: f64,
}

/// A report that could not be written.
#[derive(Debug)]
pub struct ReportError(pub String);

impl std::fmt::Display for ReportError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for ReportError {}

/// Metrics of a channel over `range` (NaN samples skipped). The uncompensated error is taken
/// relative to the first sample of the run, as a machine is zeroed when it starts.
pub fn channel_metrics(ch: &Channel, range: Range<usize>) -> Metrics {
    // Relative to the first measurement: with sparse measurements the first rows may have none.
    let first = ch
        .measured
        .iter()
        .copied()
        .find(|m| m.is_finite())
        .unwrap_or(0.0);
    let (mut se, mut su, mut n) = (0.0, 0.0, 0usize);
    let (mut max_abs, mut lo, mut hi) = (0.0_f64, f64::INFINITY, f64::NEG_INFINITY);
    for i in range.clone() {
        let (Some(&m), Some(&p)) = (ch.measured.get(i), ch.predicted.get(i)) else {
            continue;
        };
        let r = m - p;
        if !r.is_finite() {
            continue;
        }
        se += r * r;
        su += (m - first) * (m - first);
        n += 1;
        max_abs = max_abs.max(r.abs());
        lo = lo.min(r);
        hi = hi.max(r);
    }
    let rmse = if n > 0 {
        (se / n as f64).sqrt()
    } else {
        f64::NAN
    };
    let unc = if n > 0 {
        (su / n as f64).sqrt()
    } else {
        f64::NAN
    };
    Metrics {
        rmse_um: rmse,
        max_abs_um: max_abs,
        peak_to_peak_um: if n > 0 { hi - lo } else { f64::NAN },
        uncompensated_rmse_um: unc,
        reduction: if unc > 0.0 {
            1.0 - rmse / unc
        } else {
            f64::NAN
        },
    }
}

/// Pearson correlation of two series (pairs with a NaN skipped); NaN if either is constant.
pub fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let pairs = || {
        a.iter()
            .zip(b)
            .filter(|(x, y)| x.is_finite() && y.is_finite())
    };
    let n = pairs().count() as f64;
    if n < 2.0 {
        return f64::NAN;
    }
    let ma = pairs().map(|p| p.0).sum::<f64>() / n;
    let mb = pairs().map(|p| p.1).sum::<f64>() / n;
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in pairs() {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    if saa == 0.0 || sbb == 0.0 {
        f64::NAN
    } else {
        sab / (saa * sbb).sqrt()
    }
}

/// At most `max` points of a series, keeping the minimum and maximum of each bucket so that
/// peaks survive the thinning.
fn thin(time: &[f64], v: &[f64], max: usize) -> Vec<(f64, f64)> {
    let pts: Vec<(f64, f64)> = time
        .iter()
        .zip(v)
        .filter(|(t, y)| t.is_finite() && y.is_finite())
        .map(|(t, y)| (*t, *y))
        .collect();
    if pts.len() <= max || max < 4 {
        return pts;
    }
    let bucket = pts.len().div_ceil(max / 2);
    let mut out = Vec::with_capacity(max + 2);
    for chunk in pts.chunks(bucket) {
        let lo = chunk
            .iter()
            .enumerate()
            .min_by(|a, b| a.1 .1.total_cmp(&b.1 .1))
            .map(|(i, _)| i);
        let hi = chunk
            .iter()
            .enumerate()
            .max_by(|a, b| a.1 .1.total_cmp(&b.1 .1))
            .map(|(i, _)| i);
        if let (Some(lo), Some(hi)) = (lo, hi) {
            let (a, b) = if lo <= hi { (lo, hi) } else { (hi, lo) };
            out.push(chunk[a]);
            if a != b {
                out.push(chunk[b]);
            }
        }
    }
    out
}

fn range_of<'a>(series: impl Iterator<Item = &'a [f64]>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for s in series {
        for &v in s.iter().filter(|v| v.is_finite()) {
            lo = lo.min(v);
            hi = hi.max(v);
        }
    }
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let pad = ((hi - lo) * 0.05).max(1e-6);
    (lo - pad, hi + pad)
}

fn plot_err<E: std::fmt::Debug>(e: E) -> ReportError {
    ReportError(format!("cannot draw a figure: {e:?}"))
}

const PALETTE: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
];

/// Measured, predicted and residual of one channel over time, in hours.
fn channel_figure(data: &ReportData, ch: &Channel) -> Result<String, ReportError> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (900, 420)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let hours: Vec<f64> = data.time_s.iter().map(|t| t / 3600.0).collect();
        let residual: Vec<f64> = ch
            .measured
            .iter()
            .zip(&ch.predicted)
            .map(|(m, p)| m - p)
            .collect();
        let (t0, t1) = range_of(std::iter::once(hours.as_slice()));
        let (y0, y1) = range_of(
            [
                ch.measured.as_slice(),
                ch.predicted.as_slice(),
                residual.as_slice(),
            ]
            .into_iter(),
        );
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!("{}: measured, predicted and residual", ch.name),
                ("sans-serif", 18),
            )
            .margin(10)
            .x_label_area_size(36)
            .y_label_area_size(56)
            .build_cartesian_2d(t0..t1, y0..y1)
            .map_err(plot_err)?;
        chart
            .configure_mesh()
            .x_desc("time / h")
            .y_desc(format!("error / {}", ch.unit))
            .draw()
            .map_err(plot_err)?;
        if let Some(i) = data.test_from.filter(|&i| i < hours.len()) {
            let from = hours[i];
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(from, y0), (t1, y1)],
                    RGBColor(240, 240, 240).filled(),
                )))
                .map_err(plot_err)?
                .label("held out (never seen by the fit)")
                .legend(|(x, y)| {
                    Rectangle::new(
                        [(x, y - 5), (x + 16, y + 5)],
                        RGBColor(220, 220, 220).filled(),
                    )
                });
        }
        for (name, v, color) in [
            ("measured", &ch.measured, PALETTE[0]),
            ("predicted", &ch.predicted, PALETTE[1]),
            ("residual", &residual, PALETTE[3]),
        ] {
            chart
                .draw_series(LineSeries::new(
                    thin(&hours, v, 2000),
                    color.stroke_width(1),
                ))
                .map_err(plot_err)?
                .label(name)
                .legend(legend_line(color));
        }
        draw_legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
        root.present().map_err(plot_err)?;
    }
    Ok(svg)
}

/// A series' mark in the legend: a short line in its colour.
fn legend_line(color: RGBColor) -> impl Fn((i32, i32)) -> PathElement<(i32, i32)> {
    move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], color)
}

/// The legend of every labelled series, boxed on a light background at `position`.
fn draw_legend<'a, DB: DrawingBackend + 'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
    position: SeriesLabelPosition,
) -> Result<(), ReportError> {
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(position)
        .draw()
        .map_err(plot_err)
}

/// Histogram of the held-out residuals of every channel.
fn histogram_figure(data: &ReportData) -> Result<String, ReportError> {
    let from = data.test_from.unwrap_or(0);
    let residuals: Vec<(String, Vec<f64>)> = data
        .channels
        .iter()
        .map(|c| {
            let r = c
                .measured
                .iter()
                .zip(&c.predicted)
                .skip(from)
                .map(|(m, p)| m - p)
                .filter(|r| r.is_finite())
                .collect();
            (c.name.clone(), r)
        })
        .collect();
    let (lo, hi) = range_of(residuals.iter().map(|(_, r)| r.as_slice()));
    let bins = 40usize;
    let width = (hi - lo) / bins as f64;
    let counts: Vec<Vec<u32>> = residuals
        .iter()
        .map(|(_, r)| {
            let mut c = vec![0u32; bins];
            for &v in r {
                let b = (((v - lo) / width) as usize).min(bins - 1);
                c[b] += 1;
            }
            c
        })
        .collect();
    let top = counts.iter().flatten().copied().max().unwrap_or(1).max(1);
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (900, 380)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let what = if data.test_from.is_some() {
            "held-out part"
        } else {
            "whole run"
        };
        let mut chart = ChartBuilder::on(&root)
            .caption(format!("Residuals, {what}"), ("sans-serif", 18))
            .margin(10)
            .x_label_area_size(36)
            .y_label_area_size(56)
            .build_cartesian_2d(lo..hi, 0u32..(top + top / 10 + 1))
            .map_err(plot_err)?;
        let unit = data.channels.first().map_or("µm", |c| c.unit.as_str());
        chart
            .configure_mesh()
            .x_desc(format!("residual / {unit}"))
            .y_desc("samples")
            .draw()
            .map_err(plot_err)?;
        for (k, ((name, _), c)) in residuals.iter().zip(&counts).enumerate() {
            let color = PALETTE[k % PALETTE.len()];
            let steps: Vec<(f64, u32)> = c
                .iter()
                .enumerate()
                .flat_map(|(b, &n)| {
                    let x0 = lo + b as f64 * width;
                    [(x0, n), (x0 + width, n)]
                })
                .collect();
            chart
                .draw_series(LineSeries::new(steps, color.stroke_width(2)))
                .map_err(plot_err)?
                .label(name.clone())
                .legend(legend_line(color));
        }
        draw_legend(&mut chart, SeriesLabelPosition::MiddleRight)?;
        root.present().map_err(plot_err)?;
    }
    Ok(svg)
}

/// Temperatures over time.
fn temperature_figure(data: &ReportData) -> Result<String, ReportError> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (900, 420)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let hours: Vec<f64> = data.time_s.iter().map(|t| t / 3600.0).collect();
        let (t0, t1) = range_of(std::iter::once(hours.as_slice()));
        let (y0, y1) = range_of(data.temperatures.iter().map(|(_, v)| v.as_slice()));
        let mut chart = ChartBuilder::on(&root)
            .caption("Temperatures", ("sans-serif", 18))
            .margin(10)
            .x_label_area_size(36)
            .y_label_area_size(56)
            .right_y_label_area_size(10)
            .build_cartesian_2d(t0..t1, y0..y1)
            .map_err(plot_err)?;
        chart
            .configure_mesh()
            .x_desc("time / h")
            .y_desc("temperature / °C")
            .draw()
            .map_err(plot_err)?;
        for (k, (name, v)) in data.temperatures.iter().enumerate() {
            let color = PALETTE[k % PALETTE.len()];
            chart
                .draw_series(LineSeries::new(
                    thin(&hours, v, 1500),
                    color.stroke_width(1),
                ))
                .map_err(plot_err)?
                .label(name.clone())
                .legend(legend_line(color));
        }
        draw_legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
        root.present().map_err(plot_err)?;
    }
    Ok(svg)
}

/// Blue (−1) … white (0) … red (+1).
fn diverging(r: f64) -> RGBColor {
    if !r.is_finite() {
        return RGBColor(200, 200, 200);
    }
    let r = r.clamp(-1.0, 1.0);
    let fade = |full: u8, t: f64| (255.0 + (f64::from(full) - 255.0) * t) as u8;
    if r >= 0.0 {
        RGBColor(fade(178, r), fade(24, r), fade(43, r))
    } else {
        RGBColor(fade(33, -r), fade(102, -r), fade(172, -r))
    }
}

/// Correlation heat map of every temperature and every measured error channel.
fn correlation_figure(data: &ReportData) -> Result<String, ReportError> {
    let mut names: Vec<&str> = data.temperatures.iter().map(|(n, _)| n.as_str()).collect();
    let mut series: Vec<&[f64]> = data
        .temperatures
        .iter()
        .map(|(_, v)| v.as_slice())
        .collect();
    for c in &data.channels {
        names.push(&c.name);
        series.push(&c.measured);
    }
    let n = names.len();
    let cell = (520 / n.max(1)).clamp(8, 40) as i32;
    let left = 150;
    let top = 40;
    let size = (
        (left + cell * n as i32 + 160) as u32,
        (top + cell * n as i32 + 150) as u32,
    );
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        root.draw(&Text::new(
            "Correlation of temperatures and measured errors",
            (10, 10),
            ("sans-serif", 18),
        ))
        .map_err(plot_err)?;
        for i in 0..n {
            for j in 0..n {
                let r = correlation(series[i], series[j]);
                let (x, y) = (left + cell * j as i32, top + cell * i as i32);
                root.draw(&Rectangle::new(
                    [(x, y), (x + cell, y + cell)],
                    diverging(r).filled(),
                ))
                .map_err(plot_err)?;
            }
            let font = ("sans-serif", (cell - 2).clamp(8, 13));
            root.draw(&Text::new(
                names[i].to_string(),
                (4, top + cell * i as i32 + cell / 4),
                font,
            ))
            .map_err(plot_err)?;
            let style = TextStyle::from(font).transform(FontTransform::Rotate90);
            root.draw(&Text::new(
                names[i].to_string(),
                (
                    left + cell * i as i32 + cell * 3 / 4,
                    top + cell * n as i32 + 4,
                ),
                style,
            ))
            .map_err(plot_err)?;
        }
        // Colour key.
        let kx = left + cell * n as i32 + 30;
        for k in 0..=20 {
            let r = 1.0 - k as f64 / 10.0;
            let y = top + k * 10;
            root.draw(&Rectangle::new(
                [(kx, y), (kx + 20, y + 10)],
                diverging(r).filled(),
            ))
            .map_err(plot_err)?;
        }
        for (label, y) in [("+1", top), ("0", top + 100), ("−1", top + 200)] {
            root.draw(&Text::new(label, (kx + 26, y), ("sans-serif", 12)))
                .map_err(plot_err)?;
        }
        root.present().map_err(plot_err)?;
    }
    Ok(svg)
}

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

#[cfg(test)]
mod tests {
    use super::*;

    /// RMSE of residuals (1, −1, 1, −1) = 1; max 1; peak-to-peak 2; measured relative to the
    /// first sample (0, 2, 4, 6) → RMS √((0 + 4 + 16 + 36)/4) = √14 = 3.742; reduction 1 − 1/√14.
    #[test]
    fn metrics_by_hand() {
        let ch = Channel {
            name: "c".into(),
            unit: "µm".into(),
            measured: vec![10.0, 12.0, 14.0, 16.0],
            predicted: vec![9.0, 13.0, 13.0, 17.0],
        };
        let m = channel_metrics(&ch, 0..4);
        assert!((m.rmse_um - 1.0).abs() < 1e-12);
        assert_eq!(m.max_abs_um, 1.0);
        assert_eq!(m.peak_to_peak_um, 2.0);
        assert!((m.uncompensated_rmse_um - 14f64.sqrt()).abs() < 1e-12);
        assert!((m.reduction - (1.0 - 1.0 / 14f64.sqrt())).abs() < 1e-12);
        // Over the last two samples only: residuals 1, −1; measured − first = 4, 6.
        let m = channel_metrics(&ch, 2..4);
        assert!((m.rmse_um - 1.0).abs() < 1e-12);
        assert!((m.uncompensated_rmse_um - 26f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn correlation_by_hand() {
        assert!((correlation(&[1.0, 2.0, 3.0], &[2.0, 4.0, 6.0]) - 1.0).abs() < 1e-12);
        assert!((correlation(&[1.0, 2.0, 3.0], &[3.0, 2.0, 1.0]) + 1.0).abs() < 1e-12);
        assert!(correlation(&[1.0, 1.0, 1.0], &[1.0, 2.0, 3.0]).is_nan());
    }

    #[test]
    fn thinning_keeps_the_peaks() {
        let t: Vec<f64> = (0..10_000).map(f64::from).collect();
        let mut v = vec![0.0; 10_000];
        v[4321] = 50.0;
        v[7000] = -20.0;
        let p = thin(&t, &v, 500);
        assert!(p.len() <= 502);
        assert!(p.contains(&(4321.0, 50.0)));
        assert!(p.contains(&(7000.0, -20.0)));
    }
}
