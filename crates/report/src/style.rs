//! What every figure shares: colours, the legend beside the plot, the error of a drawing.

use plotters::prelude::*;

use crate::ReportError;

pub(crate) fn plot_err<E: std::fmt::Debug>(e: E) -> ReportError {
    ReportError(format!("cannot draw a figure: {e:?}"))
}

pub(crate) const PALETTE: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
];

/// How a legend entry is marked: a line (a series) or a filled box (an area).
#[derive(Debug, Clone, Copy)]
pub(crate) enum Mark {
    Line,
    Area,
}

/// Width of the column beside a plot that holds its legend.
pub(crate) const LEGEND_W: u32 = 190;

/// The legend in its own column beside the plot (`area`, the right part of the figure), so it
/// never hides data: one entry per line, its mark then its name.
pub(crate) fn side_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    entries: &[(String, RGBColor, Mark)],
) -> Result<(), ReportError> {
    for (k, (name, color, mark)) in entries.iter().enumerate() {
        let y = 48 + 20 * k as i32;
        match mark {
            Mark::Line => area.draw(&PathElement::new(
                vec![(8, y), (28, y)],
                color.stroke_width(2),
            )),
            Mark::Area => area.draw(&Rectangle::new([(8, y - 5), (28, y + 5)], color.filled())),
        }
        .map_err(plot_err)?;
        area.draw(&Text::new(name.clone(), (34, y - 7), ("sans-serif", 13)))
            .map_err(plot_err)?;
    }
    Ok(())
}

/// Blue (−1) … white (0) … red (+1).
pub(crate) fn diverging(r: f64) -> RGBColor {
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
