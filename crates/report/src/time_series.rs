//! Series over time: measured, predicted and residual per channel; temperatures, as one figure
//! up to [`ONE_FIGURE_MAX`] channels and as small multiples beyond (16–24 overlaid curves in 8
//! colours cannot be told apart; one small panel per sensor with its own range can).

use plotters::coord::Shift;
use plotters::prelude::*;

use plotters::coord::types::RangedCoordf64;

use crate::clock;
use crate::metrics::{range_of, thin};
use crate::style::{plot_err, side_legend, Mark, LEGEND_W, PALETTE};
use crate::{Channel, ReportData, ReportError};

/// Most temperature channels drawn in one figure.
pub(crate) const ONE_FIGURE_MAX: usize = 6;
const WIDTH: u32 = 960;
const COLUMNS: usize = 4;
const PANEL_H: u32 = 150;

fn hours(data: &ReportData) -> Vec<f64> {
    data.time_s.iter().map(|t| t / 3600.0).collect()
}

/// A tick label of the time axis from the time in hours.
type TickLabel = Box<dyn Fn(&f64) -> String>;

/// How the time axis reads: hours since the start, or clock time when the run has a clock
/// (tick labels `HH:MM`, with the day in front when the data span more than a day).
fn time_axis(data: &ReportData, (t0, t1): (f64, f64)) -> (String, Option<TickLabel>) {
    match data.clock_start_s {
        Some(start) => {
            let several_days = t1 - t0 > 24.0;
            let first = data.time_s.first().copied().unwrap_or(0.0);
            (
                format!("clock time, UTC (from {})", clock::date_time(start + first)),
                Some(Box::new(move |h: &f64| {
                    clock::tick(start + 3600.0 * h, several_days)
                })),
            )
        }
        None => ("time / h".to_string(), None),
    }
}

/// The grid and axis labels of a figure over time; the time axis as [`time_axis`] says.
fn time_mesh<DB: DrawingBackend>(
    chart: &mut ChartContext<'_, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    data: &ReportData,
    span: (f64, f64),
    y_desc: &str,
) -> Result<(), ReportError> {
    let (x_desc, tick) = time_axis(data, span);
    let mut mesh = chart.configure_mesh();
    mesh.x_desc(x_desc).y_desc(y_desc);
    if let Some(tick) = &tick {
        // Fewer ticks: a clock label is wider than an hour count.
        mesh.x_labels(7).x_label_formatter(tick);
    }
    mesh.draw().map_err(plot_err)
}

/// The runs' start times in hours with their names, when the figure shows several runs.
fn run_marks(data: &ReportData, hours: &[f64]) -> Vec<(f64, String)> {
    if data.run_starts.len() < 2 {
        return Vec::new();
    }
    data.run_starts
        .iter()
        .filter_map(|(i, name)| Some((*hours.get(*i)?, short_run_name(name))))
        .collect()
}

/// The sample ranges of the runs laid end to end (the whole series when there is one run).
fn run_segments(data: &ReportData, n: usize) -> Vec<std::ops::Range<usize>> {
    let mut starts: Vec<usize> = data
        .run_starts
        .iter()
        .map(|(i, _)| *i)
        .filter(|&i| i > 0 && i < n)
        .collect();
    starts.sort_unstable();
    starts.dedup();
    let mut out = Vec::new();
    let mut from = 0;
    for s in starts.into_iter().chain(std::iter::once(n)) {
        if s > from {
            out.push(from..s);
        }
        from = s;
    }
    out
}

/// A run's name as a label: a file's name without its folders (`days/monday.csv` → `monday.csv`).
fn short_run_name(name: &str) -> String {
    match name.rfind('/') {
        Some(k) if k + 1 < name.len() => name[k + 1..].to_string(),
        _ => name.to_string(),
    }
}

/// Measured, predicted and residual of one channel over time — the drift plot of one
/// direction in the manner of ISO 230-3 — with the held-out part shaded and, when several runs
/// are laid end to end, a labelled line where each run starts.
pub(crate) fn channel_figure(data: &ReportData, ch: &Channel) -> Result<String, ReportError> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (WIDTH, 420)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let (plot, side) = root.split_horizontally(WIDTH - LEGEND_W);
        let hours = hours(data);
        let residual: Vec<f64> = ch
            .measured
            .iter()
            .zip(&ch.predicted)
            .map(|(m, p)| m - p)
            .collect();
        let (t0, t1) = range_of(std::iter::once(hours.as_slice()));
        let series = [
            ("measured", &ch.measured, PALETTE[0]),
            ("predicted", &ch.predicted, PALETTE[1]),
            ("residual", &residual, PALETTE[3]),
        ];
        let (y0, mut y1) = range_of(series.iter().map(|s| s.1.as_slice()));
        let runs = run_marks(data, &hours);
        if !runs.is_empty() {
            // Headroom for the runs' names, so they sit above the curves, not on them.
            y1 += 0.12 * (y1 - y0);
        }
        let mut chart = ChartBuilder::on(&plot)
            .caption(
                format!("{}: drift — measured, predicted and residual", ch.name),
                ("sans-serif", 18),
            )
            .margin(10)
            .x_label_area_size(36)
            .y_label_area_size(56)
            .build_cartesian_2d(t0..t1, y0..y1)
            .map_err(plot_err)?;
        time_mesh(&mut chart, data, (t0, t1), &format!("error / {}", ch.unit))?;
        let mut legend = Vec::new();
        if let Some(i) = data.test_from.filter(|&i| i < hours.len()) {
            let shade = RGBColor(235, 235, 235);
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(hours[i], y0), (t1, y1)],
                    shade.filled(),
                )))
                .map_err(plot_err)?;
            legend.push(("held out (never seen by the fit)".into(), shade, Mark::Area));
        }
        if !runs.is_empty() {
            draw_run_marks(&mut chart, &runs, (t1, y0, y1))?;
            legend.push(("start of a run".into(), RUN_MARK, Mark::Line));
        }
        let segments = run_segments(data, hours.len());
        for (name, v, color) in series {
            // One line per run: a run's end is not joined to the next run's start.
            for r in &segments {
                let budget = (2000 * r.len()).div_ceil(hours.len().max(1)).max(2);
                chart
                    .draw_series(LineSeries::new(
                        thin(&hours[r.clone()], &v[r.clone()], budget),
                        color.stroke_width(1),
                    ))
                    .map_err(plot_err)?;
            }
            legend.push((name.to_string(), color, Mark::Line));
        }
        side_legend(&side, &legend)?;
        root.present().map_err(plot_err)?;
    }
    Ok(svg)
}

/// Colour of the lines that mark where a run starts.
const RUN_MARK: RGBColor = RGBColor(90, 90, 90);
/// Width of a character of a run's label, generously, in px (13 px sans-serif).
const LABEL_CHAR_PX: f64 = 8.0;

/// A vertical line at each run's start (not the first: the axis begins there) and the run's
/// name beside it at the top, cut short with `…` to the room before the next run so that no
/// two names overlap; a run too short for three characters keeps its line only.
fn draw_run_marks<DB: DrawingBackend>(
    chart: &mut ChartContext<'_, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    runs: &[(f64, String)],
    (t1, y0, y1): (f64, f64, f64),
) -> Result<(), ReportError> {
    let style = ("sans-serif", 13).into_font().color(&RUN_MARK);
    for (k, (x, name)) in runs.iter().enumerate() {
        if k > 0 {
            chart
                .draw_series(std::iter::once(PathElement::new(
                    vec![(*x, y0), (*x, y1)],
                    RUN_MARK.stroke_width(1),
                )))
                .map_err(plot_err)?;
        }
        let next = runs.get(k + 1).map_or(t1, |r| r.0);
        let room_px =
            f64::from(chart.backend_coord(&(next, y1)).0 - chart.backend_coord(&(*x, y1)).0) - 10.0;
        let fits = (room_px / LABEL_CHAR_PX).floor().max(0.0) as usize;
        let chars = name.chars().count();
        let label = if chars <= fits {
            name.clone()
        } else if fits >= 3 {
            name.chars().take(fits - 1).collect::<String>() + "…"
        } else {
            continue;
        };
        chart
            .draw_series(std::iter::once(
                EmptyElement::at((*x, y1)) + Text::new(label, (4, 4), style.clone()),
            ))
            .map_err(plot_err)?;
    }
    Ok(())
}

/// Temperatures over time: one figure with a legend beside it, or small multiples.
pub(crate) fn temperature_figure(data: &ReportData) -> Result<String, ReportError> {
    if data.temperatures.len() > ONE_FIGURE_MAX {
        return temperature_multiples(data);
    }
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (WIDTH, 420)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let (plot, side) = root.split_horizontally(WIDTH - LEGEND_W);
        let hours = hours(data);
        let (t0, t1) = range_of(std::iter::once(hours.as_slice()));
        let (y0, y1) = range_of(data.temperatures.iter().map(|(_, v)| v.as_slice()));
        let mut chart = ChartBuilder::on(&plot)
            .caption("Temperatures", ("sans-serif", 18))
            .margin(10)
            .x_label_area_size(36)
            .y_label_area_size(56)
            .build_cartesian_2d(t0..t1, y0..y1)
            .map_err(plot_err)?;
        time_mesh(&mut chart, data, (t0, t1), "temperature / °C")?;
        let mut legend = Vec::new();
        for (k, (name, v)) in data.temperatures.iter().enumerate() {
            let color = PALETTE[k % PALETTE.len()];
            chart
                .draw_series(LineSeries::new(
                    thin(&hours, v, 1500),
                    color.stroke_width(1),
                ))
                .map_err(plot_err)?;
            legend.push((name.clone(), color, Mark::Line));
        }
        side_legend(&side, &legend)?;
        root.present().map_err(plot_err)?;
    }
    Ok(svg)
}

/// One small panel per temperature channel, [`COLUMNS`] to a row, each with its own range
/// (the shape of each curve matters more than a shared scale that flattens the quiet ones);
/// the time axis is shared.
fn temperature_multiples(data: &ReportData) -> Result<String, ReportError> {
    let n = data.temperatures.len();
    let rows = n.div_ceil(COLUMNS);
    let height = 40 + rows as u32 * PANEL_H;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (WIDTH, height)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let (head, body) = root.split_vertically(40);
        let hours = hours(data);
        let (t0, t1) = range_of(std::iter::once(hours.as_slice()));
        let (x_desc, tick) = time_axis(data, (t0, t1));
        head.draw(&Text::new(
            format!("Temperatures / °C over {x_desc}, one panel per sensor ({n}), each on its own scale"),
            (10, 10),
            ("sans-serif", 18),
        ))
        .map_err(plot_err)?;
        let panels = body.split_evenly((rows, COLUMNS));
        for (k, (name, v)) in data.temperatures.iter().enumerate() {
            let last_row = k / COLUMNS == rows - 1 || k + COLUMNS >= n;
            let time_labels = last_row.then_some(tick.as_ref());
            small_panel(&panels[k], name, &hours, v, (t0, t1), time_labels)?;
        }
        root.present().map_err(plot_err)?;
    }
    Ok(svg)
}

fn small_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    name: &str,
    hours: &[f64],
    v: &[f64],
    (t0, t1): (f64, f64),
    // On the bottom row only: `Some`, with the clock's tick labels if the run has a clock.
    time_labels: Option<Option<&TickLabel>>,
) -> Result<(), ReportError> {
    let (y0, y1) = range_of(std::iter::once(v));
    let mut chart = ChartBuilder::on(area)
        .caption(name, ("sans-serif", 13))
        .margin(4)
        .x_label_area_size(if time_labels.is_some() { 22 } else { 4 })
        .y_label_area_size(40)
        .build_cartesian_2d(t0..t1, y0..y1)
        .map_err(plot_err)?;
    let mut mesh = chart.configure_mesh();
    mesh.x_labels(if time_labels.is_some() { 4 } else { 0 })
        .y_labels(3)
        .label_style(("sans-serif", 10))
        .light_line_style(WHITE);
    if let Some(Some(tick)) = time_labels {
        mesh.x_label_formatter(tick);
    }
    mesh.draw().map_err(plot_err)?;
    chart
        .draw_series(LineSeries::new(
            thin(hours, v, 400),
            PALETTE[0].stroke_width(1),
        ))
        .map_err(plot_err)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data(sensors: usize) -> ReportData {
        let time_s: Vec<f64> = (0..200).map(|i| 60.0 * f64::from(i)).collect();
        let temperatures = (0..sensors)
            .map(|k| {
                let v = time_s
                    .iter()
                    .map(|t| 20.0 + (k as f64) * 0.1 * t / 3600.0)
                    .collect();
                (format!("t{}_c", k + 1), v)
            })
            .collect();
        ReportData {
            time_s,
            temperatures,
            ..Default::default()
        }
    }

    /// Every text of an SVG with its x position.
    fn texts(svg: &str) -> Vec<(f64, String)> {
        svg.split("<text")
            .skip(1)
            .map(|t| {
                let x = t
                    .split("x=\"")
                    .nth(1)
                    .unwrap()
                    .split('"')
                    .next()
                    .unwrap()
                    .parse()
                    .unwrap();
                let body = t[t.find('>').unwrap() + 1..t.find("</text>").unwrap()].trim();
                (x, body.to_string())
            })
            .collect()
    }

    #[test]
    fn many_sensors_become_small_multiples() {
        let t = texts(&temperature_figure(&data(24)).unwrap());
        assert!(t
            .iter()
            .any(|(_, s)| s.contains("one panel per sensor (24)")));
        for k in 1..=24 {
            assert!(
                t.iter().any(|(_, s)| *s == format!("t{k}_c")),
                "panel t{k}_c"
            );
        }
        let few = texts(&temperature_figure(&data(4)).unwrap());
        assert!(!few.iter().any(|(_, s)| s.contains("one panel per sensor")));
        assert!(few.iter().any(|(_, s)| s == "t4_c"));
    }

    /// The legend is drawn right of the plotting area: every legend text starts beyond it.
    #[test]
    fn legends_sit_beside_the_data() {
        let mut d = data(3);
        d.channels.push(Channel {
            name: "dz".into(),
            unit: "µm".into(),
            measured: vec![1.0; 200],
            predicted: vec![0.9; 200],
        });
        d.test_from = Some(100);
        let t = texts(&channel_figure(&d, &d.channels[0]).unwrap());
        let limit = f64::from(WIDTH - LEGEND_W);
        for label in ["measured", "predicted", "residual", "held out"] {
            let (x, _) = t.iter().find(|(_, s)| s.starts_with(label)).expect(label);
            assert!(
                *x > limit,
                "{label} at x = {x}, inside the plot (< {limit})"
            );
        }
    }

    /// Three runs end to end: a labelled line at each later run's start, names shortened to
    /// their file name, and each curve drawn per run (a run's end not joined to the next start).
    #[test]
    fn runs_laid_end_to_end_are_marked_and_not_joined() {
        let mut d = data(1);
        d.channels.push(Channel {
            name: "dz".into(),
            unit: "µm".into(),
            measured: vec![1.0; 200],
            predicted: vec![0.9; 200],
        });
        d.run_starts = vec![
            (0, "days/monday.csv".into()),
            (80, "days/tuesday.csv".into()),
            (150, "days/wednesday.csv".into()),
        ];
        let svg = channel_figure(&d, &d.channels[0]).unwrap();
        let t = texts(&svg);
        for name in [
            "monday.csv",
            "tuesday.csv",
            "wednesday.csv",
            "start of a run",
        ] {
            assert!(t.iter().any(|(_, s)| s == name), "{name}");
        }
        // Per colour, one line per run plus the legend's mark: 3 + 1 measured (blue); the
        // boundaries, 2 + 1.
        let lines = |colour: &str| svg.matches(&format!("stroke=\"{colour}\"")).count();
        assert_eq!(lines("#1F77B4"), 4);
        assert_eq!(lines("#5A5A5A"), 3);
        assert_eq!(run_segments(&d, 200), [0..80, 80..150, 150..200]);
        d.run_starts.clear();
        assert_eq!(run_segments(&d, 200), vec![0..200usize]);
    }
}
