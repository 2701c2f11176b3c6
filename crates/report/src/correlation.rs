//! The correlation heat map of temperatures and measured errors.

use plotters::prelude::*;

use crate::metrics::correlation;
use crate::style::{diverging, plot_err};
use crate::{ReportData, ReportError};

/// Correlation heat map of every temperature and every measured error channel.
pub(crate) fn correlation_figure(data: &ReportData) -> Result<String, ReportError> {
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
