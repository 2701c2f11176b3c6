//! Series over time: measured, predicted and residual per channel; temperatures.

use plotters::prelude::*;

use crate::metrics::{range_of, thin};
use crate::style::{draw_legend, legend_line, plot_err, PALETTE};
use crate::{Channel, ReportData, ReportError};

/// Measured, predicted and residual of one channel over time, in hours.
pub(crate) fn channel_figure(data: &ReportData, ch: &Channel) -> Result<String, ReportError> {
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

/// Temperatures over time.
pub(crate) fn temperature_figure(data: &ReportData) -> Result<String, ReportError> {
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

