//! Series over time: measured, predicted and residual per channel; temperatures, as one figure
//! up to [`ONE_FIGURE_MAX`] channels and as small multiples beyond (16–24 overlaid curves in 8
//! colours cannot be told apart; one small panel per sensor with its own range can).

use plotters::coord::Shift;
use plotters::prelude::*;

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

/// Measured, predicted and residual of one channel over time, in hours.
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
        let (y0, y1) = range_of(series.iter().map(|s| s.1.as_slice()));
        let mut chart = ChartBuilder::on(&plot)
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
        for (name, v, color) in series {
            chart
                .draw_series(LineSeries::new(
                    thin(&hours, v, 2000),
                    color.stroke_width(1),
                ))
                .map_err(plot_err)?;
            legend.push((name.to_string(), color, Mark::Line));
        }
        side_legend(&side, &legend)?;
        root.present().map_err(plot_err)?;
    }
    Ok(svg)
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
        chart
            .configure_mesh()
            .x_desc("time / h")
            .y_desc("temperature / °C")
            .draw()
            .map_err(plot_err)?;
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
        head.draw(&Text::new(
            format!("Temperatures / °C over time / h, one panel per sensor ({n}), each on its own scale"),
            (10, 10),
            ("sans-serif", 18),
        ))
        .map_err(plot_err)?;
        let hours = hours(data);
        let (t0, t1) = range_of(std::iter::once(hours.as_slice()));
        let panels = body.split_evenly((rows, COLUMNS));
        for (k, (name, v)) in data.temperatures.iter().enumerate() {
            let last_row = k / COLUMNS == rows - 1 || k + COLUMNS >= n;
            small_panel(&panels[k], name, &hours, v, (t0, t1), last_row)?;
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
    time_labels: bool,
) -> Result<(), ReportError> {
    let (y0, y1) = range_of(std::iter::once(v));
    let mut chart = ChartBuilder::on(area)
        .caption(name, ("sans-serif", 13))
        .margin(4)
        .x_label_area_size(if time_labels { 22 } else { 4 })
        .y_label_area_size(40)
        .build_cartesian_2d(t0..t1, y0..y1)
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_labels(if time_labels { 4 } else { 0 })
        .y_labels(3)
        .label_style(("sans-serif", 10))
        .light_line_style(WHITE)
        .draw()
        .map_err(plot_err)?;
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
}
