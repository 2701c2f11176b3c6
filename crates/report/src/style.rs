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

/// A series' mark in the legend: a short line in its colour.
pub(crate) fn legend_line(color: RGBColor) -> impl Fn((i32, i32)) -> PathElement<(i32, i32)> {
    move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], color)
}

/// The legend of every labelled series, boxed on a light background at `position`.
pub(crate) fn draw_legend<'a, DB: DrawingBackend + 'a, CT: CoordTranslate>(
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

