//! Figures of merit and the series helpers every figure uses.

use std::ops::Range;

use crate::{Channel, Metrics};

/// Metrics of a channel over `range` (NaN samples skipped). The uncompensated error is the
/// measured error as the channel holds it — the same reference point as the residual: the caller
/// takes the measured errors relative to the run's first sample, or as measured, once
/// (`truepos report` as the model was fitted, `fit --report` relative, the demo as measured), so
/// a headline and a table of one report never disagree.
pub fn channel_metrics(ch: &Channel, range: Range<usize>) -> Metrics {
    let (mut se, mut su, mut n) = (0.0, 0.0, 0usize);
    let (mut max_abs, mut lo, mut hi) = (0.0_f64, f64::INFINITY, f64::NEG_INFINITY);
    for i in range.clone() {
        let (Some(&m), Some(&p)) = (ch.measured.get(i), ch.predicted.get(i)) else {
            continue;
        };
        let r = m - p;
        if !r.is_finite() {
            continue;
        }
        se += r * r;
        su += m * m;
        n += 1;
        max_abs = max_abs.max(r.abs());
        lo = lo.min(r);
        hi = hi.max(r);
    }
    let rmse = if n > 0 {
        (se / n as f64).sqrt()
    } else {
        f64::NAN
    };
    let unc = if n > 0 {
        (su / n as f64).sqrt()
    } else {
        f64::NAN
    };
    Metrics {
        rmse_um: rmse,
        max_abs_um: max_abs,
        peak_to_peak_um: if n > 0 { hi - lo } else { f64::NAN },
        uncompensated_rmse_um: unc,
        reduction: if unc > 0.0 {
            1.0 - rmse / unc
        } else {
            f64::NAN
        },
    }
}

/// Pearson correlation of two series (pairs with a NaN skipped); NaN if either is constant.
pub fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let pairs = || {
        a.iter()
            .zip(b)
            .filter(|(x, y)| x.is_finite() && y.is_finite())
    };
    let n = pairs().count() as f64;
    if n < 2.0 {
        return f64::NAN;
    }
    let ma = pairs().map(|p| p.0).sum::<f64>() / n;
    let mb = pairs().map(|p| p.1).sum::<f64>() / n;
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in pairs() {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    if saa == 0.0 || sbb == 0.0 {
        f64::NAN
    } else {
        sab / (saa * sbb).sqrt()
    }
}

/// At most `max` points of a series, keeping the minimum and maximum of each bucket so that
/// peaks survive the thinning.
pub(crate) fn thin(time: &[f64], v: &[f64], max: usize) -> Vec<(f64, f64)> {
    let pts: Vec<(f64, f64)> = time
        .iter()
        .zip(v)
        .filter(|(t, y)| t.is_finite() && y.is_finite())
        .map(|(t, y)| (*t, *y))
        .collect();
    if pts.len() <= max || max < 4 {
        return pts;
    }
    let bucket = pts.len().div_ceil(max / 2);
    let mut out = Vec::with_capacity(max + 2);
    for chunk in pts.chunks(bucket) {
        let lo = chunk
            .iter()
            .enumerate()
            .min_by(|a, b| a.1 .1.total_cmp(&b.1 .1))
            .map(|(i, _)| i);
        let hi = chunk
            .iter()
            .enumerate()
            .max_by(|a, b| a.1 .1.total_cmp(&b.1 .1))
            .map(|(i, _)| i);
        if let (Some(lo), Some(hi)) = (lo, hi) {
            let (a, b) = if lo <= hi { (lo, hi) } else { (hi, lo) };
            out.push(chunk[a]);
            if a != b {
                out.push(chunk[b]);
            }
        }
    }
    out
}

pub(crate) fn range_of<'a>(series: impl Iterator<Item = &'a [f64]>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for s in series {
        for &v in s.iter().filter(|v| v.is_finite()) {
            lo = lo.min(v);
            hi = hi.max(v);
        }
    }
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let pad = ((hi - lo) * 0.05).max(1e-6);
    (lo - pad, hi + pad)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// RMSE of residuals (1, −1, 1, −1) = 1; max 1; peak-to-peak 2; measured as given (10, 12,
    /// 14, 16) → RMS √((100 + 144 + 196 + 256)/4) = √174; reduction 1 − 1/√174.
    #[test]
    fn metrics_by_hand() {
        let ch = Channel {
            name: "c".into(),
            unit: "µm".into(),
            measured: vec![10.0, 12.0, 14.0, 16.0],
            predicted: vec![9.0, 13.0, 13.0, 17.0],
        };
        let m = channel_metrics(&ch, 0..4);
        assert!((m.rmse_um - 1.0).abs() < 1e-12);
        assert_eq!(m.max_abs_um, 1.0);
        assert_eq!(m.peak_to_peak_um, 2.0);
        assert!((m.uncompensated_rmse_um - 174f64.sqrt()).abs() < 1e-12);
        assert!((m.reduction - (1.0 - 1.0 / 174f64.sqrt())).abs() < 1e-12);
        // Over the last two samples only: residuals 1, −1; measured 14, 16.
        let m = channel_metrics(&ch, 2..4);
        assert!((m.rmse_um - 1.0).abs() < 1e-12);
        assert!((m.uncompensated_rmse_um - 226f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn correlation_by_hand() {
        assert!((correlation(&[1.0, 2.0, 3.0], &[2.0, 4.0, 6.0]) - 1.0).abs() < 1e-12);
        assert!((correlation(&[1.0, 2.0, 3.0], &[3.0, 2.0, 1.0]) + 1.0).abs() < 1e-12);
        assert!(correlation(&[1.0, 1.0, 1.0], &[1.0, 2.0, 3.0]).is_nan());
    }

    #[test]
    fn thinning_keeps_the_peaks() {
        let t: Vec<f64> = (0..10_000).map(f64::from).collect();
        let mut v = vec![0.0; 10_000];
        v[4321] = 50.0;
        v[7000] = -20.0;
        let p = thin(&t, &v, 500);
        assert!(p.len() <= 502);
        assert!(p.contains(&(4321.0, 50.0)));
        assert!(p.contains(&(7000.0, -20.0)));
    }
}
