//! # truepos-report — the curves people look at before they trust a model
//!
//! [`write_report`] turns a [`ReportData`] (time, measured and predicted error per channel,
//! temperatures, coefficients, validation protocol) into one self-contained HTML file with the
//! figures embedded, and the same figures as SVG files beside it:
//!
//! - the headline figures of the run, then the figures of merit per channel and, for
//!   leave-one-run-out, per held-out run (runs made worse than uncompensated are marked);
//! - the error over the working volume before and after compensation ([`VolumeMap`]): slices
//!   of the 3-D grid as heat maps, one figure per error direction, one colour scale per direction;
//! - drift plots in the manner of ISO 230-3, one per error direction: measured, predicted and
//!   residual error over clock time (or hours when the run has no clock), the held-out part
//!   shaded, and where several runs are laid end to end a labelled line at each run's start;
//! - a histogram of the residuals of the held-out part;
//! - temperatures over time: one figure up to six channels, small multiples beyond, so 16–24
//!   channels stay readable;
//! - a correlation heat map of temperatures and measured errors;
//! - the coefficients with their units, one table per input they belong to, and the validation
//!   protocol.
//!
//! Legends sit beside the plot, never over the data. A print stylesheet lays the page out on A4
//! with no figure cut by a page break, so the report prints to PDF from the browser.
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
//!     coefficients: vec![Coefficient {
//!         channel: "Z".into(),
//!         input: "spindle".into(),
//!         feature: "rise since the start".into(),
//!         meaning: String::new(),
//!         value: 2.9,
//!         unit: "µm/K".into(),
//!         readable: None,
//!     }],
//!     protocol: vec![("split".into(), "chronological, first 60 % train".into())],
//!     ..Default::default()
//! };
//! let dir = std::env::temp_dir().join("truepos-report-doc");
//! let html = write_report(&dir, &data).unwrap();
//! assert!(std::fs::read_to_string(html).unwrap().contains("<svg"));
//! let m = channel_metrics(&data.channels[0], 60..100);
//! assert!(m.rmse_um < m.uncompensated_rmse_um);
//! ```
#![forbid(unsafe_code)]
#![warn(missing_docs)]

mod clock;
mod coefficients;
mod correlation;
mod histogram;
mod html;
mod metrics;
mod style;
mod time_series;
mod volume;

pub use html::write_report;
pub use metrics::{channel_metrics, correlation};

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
    /// The input it belongs to (a sensor, a temperature difference, the spindle speed; empty
    /// for a constant): the report shows one table per input.
    pub input: String,
    /// What it multiplies, in words ("rise, lagged τ = 1 h") or symbols ("dT_bed · ratio(X)").
    pub feature: String,
    /// What the symbols of `feature` stand for ("dT_bed = bed_top − bed_bottom"), shown once
    /// under the input's heading; empty when the words say it all.
    pub meaning: String,
    /// Its value as the model file stores it.
    pub value: f64,
    /// The unit of `value` (µm/K, µm/(K/s), µm per 1/min, µm).
    pub unit: String,
    /// The same value in a unit a person reads more easily, if that differs (µm/(K/h) for a
    /// rate the model keeps in K/s, µm per 1000 rpm for a speed it keeps in 1/min).
    pub readable: Option<(f64, String)>,
}

/// Everything a report shows.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ReportData {
    /// Title.
    pub title: String,
    /// Time of each sample in s.
    pub time_s: Vec<f64>,
    /// The clock time at `time_s = 0`, in s since 1970-01-01T00:00:00 UTC, when the run's time
    /// is a clock (date-times in its time column): the drift plots then read clock time.
    pub clock_start_s: Option<f64>,
    /// Where each run starts when several are shown end to end: the index of its first sample
    /// and its name. The drift plots mark each with a labelled vertical line.
    pub run_starts: Vec<(usize, String)>,
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
    /// The run's headline figures, as (what, value with unit), shown first.
    pub headline: Vec<(String, String)>,
    /// Figures of merit per held-out run (leave-one-run-out), one row per run and channel.
    pub runs: Vec<RunRow>,
    /// The error over the working volume, if the model depends on the axis positions.
    pub volume: Option<VolumeMap>,
}

/// One held-out run's figures for one channel.
#[derive(Debug, Clone, PartialEq)]
pub struct RunRow {
    /// The run's name (file, sheet or run-column value).
    pub run: String,
    /// The channel.
    pub channel: String,
    /// Samples with a measured value.
    pub samples: usize,
    /// The run's figures, from a model that never saw it.
    pub metrics: Metrics,
    /// The family the fit chose without this run, if known.
    pub family: Option<String>,
}

/// The error over the working volume at one moment: values on a grid spanned by three axes.
#[derive(Debug, Clone, PartialEq)]
pub struct VolumeMap {
    /// What the maps show and when ("test day at 3.4 h, the largest uncompensated error").
    pub moment: String,
    /// Names of the three axes spanning the grid (their positions in mm).
    pub axes: [String; 3],
    /// Grid positions along each axis, mm, ascending.
    pub coords: [Vec<f64>; 3],
    /// What `before` and `after` hold ("uncompensated", "after compensation").
    pub labels: (String, Option<String>),
    /// One entry per error direction.
    pub directions: Vec<VolumeDirection>,
}

/// One error direction over the grid of a [`VolumeMap`]. Values are µm, indexed
/// `(ix · ny + iy) · nz + iz`; NaN where the model gives nothing.
#[derive(Debug, Clone, PartialEq)]
pub struct VolumeDirection {
    /// Its name (`dx (X)`).
    pub name: String,
    /// The error before compensation (or the model's prediction, as `labels.0` says).
    pub before: Vec<f64>,
    /// The error after compensation, if known.
    pub after: Option<Vec<f64>>,
}

/// Figures of merit of one channel over a range of samples.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct Metrics {
    /// Root-mean-square residual.
    pub rmse_um: f64,
    /// Largest absolute residual.
    pub max_abs_um: f64,
    /// Peak-to-peak of the residual.
    pub peak_to_peak_um: f64,
    /// RMS of the uncompensated error: the measured error as the channel holds it (the same
    /// reference point as the residual).
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
