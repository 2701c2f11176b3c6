//! The residuals of the held-out part as a histogram per channel.

use plotters::prelude::*;

use crate::metrics::range_of;
use crate::style::{plot_err, side_legend, Mark, LEGEND_W, PALETTE};
use crate::{ReportData, ReportError};

/// Histogram of the held-out residuals of every channel.
pub(crate) fn histogram_figure(data: &ReportData) -> Result<String, ReportError> {
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
        let root = SVGBackend::with_string(&mut svg, (960, 380)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let (plot, side) = root.split_horizontally(960 - LEGEND_W);
        let mut legend = Vec::new();
        let what = if data.test_from.is_some() {
            "held-out part"
        } else {
            "whole run"
        };
        let mut chart = ChartBuilder::on(&plot)
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
                .map_err(plot_err)?;
            legend.push((name.clone(), color, Mark::Line));
        }
        side_legend(&side, &legend)?;
        root.present().map_err(plot_err)?;
    }
    Ok(svg)
}
