//! The timing argument: how wrong a position-dependent term is when it is updated every T ms
//! instead of every control cycle.
//!
//! Between two updates an axis at feed v travels Δs = v·T, so the ratio r = position / length is
//! stale by at most Δr = v·T / L. The worst-case error of a term, relative to the term's full
//! span over the travel, is then
//!
//! - ratio r (span 1): Δr;
//! - ratio squared r² (span 1, steepest at r = 1): 1 − (1 − Δr)² = 2Δr − Δr²;
//! - bed factor KFA = 2r − 1 (span 2, slope 2): 2Δr / 2 = Δr.
//!
//! The glossary's case: 100 m/min, 4 ms, 500 mm → Δs = 6.67 mm, Δr = 1.3 %.

use crate::model::PositionFactor;

/// Distance in mm an axis travels at `feed_mm_per_min` during `period_ms`.
pub fn travel_per_update_mm(feed_mm_per_min: f64, period_ms: f64) -> f64 {
    feed_mm_per_min / 60_000.0 * period_ms
}

/// Worst-case error of a position-dependent term updated every `period_ms`, as a fraction of
/// the term's full span over the travel (0.013 = 1.3 %). Inputs must be positive; the result is
/// capped at 1 (an update slower than a full traverse is no better than none).
pub fn update_error_fraction(
    feed_mm_per_min: f64,
    period_ms: f64,
    axis_length_mm: f64,
    factor: PositionFactor,
) -> f64 {
    let dr = (travel_per_update_mm(feed_mm_per_min, period_ms) / axis_length_mm).clamp(0.0, 1.0);
    match factor {
        PositionFactor::Ratio | PositionFactor::BedFactor => dr,
        PositionFactor::RatioSquared => 2.0 * dr - dr * dr,
    }
}
