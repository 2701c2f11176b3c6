//! # truepos-fit — learning compensation models from measured runs
//!
//! From recorded runs (time, temperatures, operating state, measured errors) to a model the
//! control can run, validated honestly:
//!
//! - [`dataset`]: runs in memory, built from run tables and column globs
//!   ([`dataset::Dataset::from_tables`]); targets are taken relative to each run's first sample.
//! - [`family`]: the one list of families a person chooses from, of both forms (filtered and
//!   position), by name.
//! - [`settings`]: what the selection may choose from and how — family, ridge, inner CV, rule,
//!   sensors, reference sensor — as typed values whose `FromStr` says what it expects.
//! - [`features`]: candidate regressors — temperature rises, their first-order low-pass filters
//!   and filtered rates of change, filtered spindle speed and its square — computed by the
//!   real-time crate's own [`truepos_model::FeatureBank`], so offline and online features agree.
//! - [`least_squares`]: Householder QR of row blocks (TSQR, parallel), column scaling, weights,
//!   ridge, SVD-based rank decisions that name the culprit columns. Never the normal equations.
//! - [`train`]: family, sensors and ridge chosen by blocked time-series cross-validation inside
//!   the training rows only, each held-out block separated from its training rows by a gap
//!   ([`inner_cv`]); the families blended by their out-of-fold predictions ([`stacking`]) or,
//!   with the paired selection, the best one kept only where it beats the simple baseline fold
//!   by fold; no compensation where nothing clearly beats none ([`selection`]); the baseline
//!   always fitted and reported beside the choice; export to a
//!   [`truepos_model::DynamicModel`].
//! - [`validate`]: chronological split, leave one run out, blocked k-fold; RMSE, max |e|,
//!   peak-to-peak and reduction versus uncompensated, per target channel; [`validate::fit`]
//!   runs features and validation in one call.
//! - [`export`]: the fit as a model file of the filtered form (`form = "filtered"`, JSON),
//!   whose reading and writing live in `truepos_io::model_file::filtered`, so that the runtime
//!   reads it without the solvers.
//! - [`position_model`]: the position-dependent thermal model's families (down to the prior art,
//!   and the reference-sensor regression) fitted from observations, the ridge chosen by blocked or
//!   rolling cross-validation; [`machine_fit`]: every family of a machine — dynamic and
//!   position-dependent — chosen by the same inner CV and validated by the same outer protocol
//!   (what `truepos fit --machine` and `truepos demo` run); [`reidentify`]: a model's parameters
//!   re-estimated on line from probe measurements.
//!
//! ## Example
//! A structure whose growth lags the spindle speed by a first-order lag of 1800 s: the
//! automatic selection finds a dynamic family and the validation on the last 40 % is tight.
//!
//! ```
//! use truepos_fit::dataset::{Dataset, InputKind, Run};
//! use truepos_fit::features::candidates;
//! use truepos_fit::settings::Settings;
//! use truepos_fit::validate::{validate, Split};
//!
//! let (mut t, mut rpm, mut temp, mut growth) = (vec![], vec![], vec![], vec![]);
//! let (mut lag, mut warm) = (0.0, 20.0);
//! for i in 0..2000 {
//!     let s = if (i / 300) % 2 == 1 { 3000.0 + 200.0 * (i / 600) as f64 } else { 0.0 };
//!     lag += (1.0 - (-30.0f64 / 1800.0).exp()) * (s - lag);
//!     warm += (1.0 - (-30.0f64 / 600.0).exp()) * (20.0 + s / 500.0 - warm);
//!     t.push(30.0 * i as f64); rpm.push(s); temp.push(warm); growth.push(0.004 * lag);
//! }
//! let ds = Dataset {
//!     input_names: vec!["t1_c".into(), "spindle_rpm".into()],
//!     input_kinds: vec![InputKind::Temperature, InputKind::Operating],
//!     target_names: vec!["dz_um".into()],
//!     runs: vec![Run { name: "run".into(), time_s: t, inputs: vec![temp, rpm], targets: vec![growth] }],
//! };
//! ds.check().unwrap();
//! let settings = Settings::default();
//! let cand = candidates(&ds, &settings.taus).unwrap();
//! let split: Split = "chrono:0.6".parse().unwrap();
//! let (v, _model, _pred) = validate(&ds, &cand, split, &settings, &mut |_, _| {}).unwrap();
//! assert!(v.metrics[0].rmse_um < 0.05 * v.metrics[0].uncompensated_rmse_um);
//! ```
#![forbid(unsafe_code)]
#![warn(missing_docs)]

mod blend;
pub mod dataset;
pub mod export;
pub mod family;
pub mod features;
mod forward;
pub mod inner_cv;
pub mod least_squares;
pub mod machine_fit;
mod out_of_fold;
pub mod position_model;
mod problem;
pub mod reidentify;
pub mod selection;
pub mod settings;
pub mod stacking;
pub mod train;
pub mod transfer;
pub mod validate;
