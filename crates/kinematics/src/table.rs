//! Compensation tables: an error value as a function of one axis position, given at support
//! points and interpolated in between (`F_A_X(0)`, `F_A_X(10)` …
//! `F_A_X(350)`, "values between support points are interpolated").
//!
//! * Support points need not be equidistant; positions must be strictly increasing.
//! * [`Interpolation::Linear`] joins support points by straight lines;
//!   [`Interpolation::MonotoneCubic`] is a C¹ piecewise cubic Hermite curve whose slopes follow
//!   Fritsch & Butland (1984, "A method for constructing local monotone piecewise cubic
//!   interpolants", SIAM J. Sci. Stat. Comput. 5): between two support points it never leaves
//!   the range of their values, so it adds no overshoot.
//! * A table of a linear axis holds its end values outside the support range. A table of a
//!   rotary axis is periodic with 360°: the last support point joins the first one (shifted by
//!   360°) seamlessly, and a position is wrapped into the period before lookup.
//! * A directional table holds two value columns, one for travel in the positive (forward) and
//!   one for the negative (reverse) direction, for backlash-like errors (LinuxCNC's
//!   `forward`/`reverse` columns).
//!
//! Building a table allocates; [`CompTable::value`] does not allocate and never panics.

use alloc::vec::Vec;
use core::fmt;

/// Period of a rotary axis in degrees.
pub const ROTARY_PERIOD_DEG: f64 = 360.0;

/// How a table continues outside its support points.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wrap {
    /// Linear axis: hold the first / last value outside the range.
    Hold,
    /// Rotary axis: periodic with 360°; the last support point joins the first seamlessly.
    Rotary,
}

/// How values between support points are found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Interpolation {
    /// Straight lines between support points.
    Linear,
    /// C¹ piecewise cubic that stays monotone between support points (Fritsch–Butland slopes).
    MonotoneCubic,
}

/// Direction of travel of the axis that drives a table.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Direction {
    /// Travel towards larger positions (LinuxCNC "forward").
    #[default]
    Forward,
    /// Travel towards smaller positions (LinuxCNC "reverse").
    Reverse,
}

/// Why a table cannot be built. Indices are 0-based support-point indices.
#[derive(Debug, Clone, PartialEq)]
pub enum TableError {
    /// Fewer than two support points.
    TooFewPoints(usize),
    /// The value columns do not have one value per position.
    LengthMismatch {
        /// Number of positions.
        positions: usize,
        /// Number of values in the offending column.
        values: usize,
    },
    /// A position or value is NaN or infinite.
    NonFinite {
        /// Support point index.
        index: usize,
    },
    /// Position `index` is not larger than the one before.
    NotIncreasing {
        /// Support point index.
        index: usize,
    },
    /// A rotary table spans more than 360°.
    SpanTooLarge {
        /// last − first position in degrees.
        span_deg: f64,
    },
    /// A rotary table spans exactly 360° but its first and last values differ, so the joint
    /// would jump.
    JointMismatch {
        /// Value at the first support point.
        first: f64,
        /// Value at the last support point.
        last: f64,
    },
}

impl fmt::Display for TableError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::TooFewPoints(n) => {
                write!(f, "{n} support point(s); expected at least 2")
            }
            Self::LengthMismatch { positions, values } => write!(
                f,
                "{positions} positions but {values} values; expected one value per position"
            ),
            Self::NonFinite { index } => {
                write!(f, "support point #{index} is not a finite number")
            }
            Self::NotIncreasing { index } => write!(
                f,
                "support point #{index}: position is not larger than the one before; expected strictly increasing positions"
            ),
            Self::SpanTooLarge { span_deg } => write!(
                f,
                "rotary table spans {span_deg}°; expected at most {ROTARY_PERIOD_DEG}°"
            ),
            Self::JointMismatch { first, last } => write!(
                f,
                "rotary table spans 360° but its first value {first} differs from its last value {last}; the joint at 360° would jump"
            ),
        }
    }
}

impl core::error::Error for TableError {}

/// A compensation table: values (in the unit of the file, e.g. µm or µrad) at support positions
/// (mm or degrees) of one axis.
#[derive(Debug, Clone, PartialEq)]
pub struct CompTable {
    positions: Vec<f64>,
    forward: Vec<f64>,
    reverse: Option<Vec<f64>>,
    wrap: Wrap,
    interpolation: Interpolation,
    // Per segment: its start and 1 / its width. Segments 0..n−1 join neighbouring support
    // points; segment n − 1 is the rotary joint or, for a linear axis, the held end value
    // (width 0, so its slope vanishes). Precomputed so a lookup does no division.
    segments: Vec<[f64; 2]>,
    // Per segment and column: the interpolant as a cubic in t ∈ [0, 1] (power basis, constant
    // term first), so a lookup is three multiply-adds whichever interpolation was chosen.
    coef_forward: Vec<[f64; 4]>,
    coef_reverse: Vec<[f64; 4]>,
    // 1 / step if the support points are equidistant (to 1e-12 of the span): the segment is
    // then found by one multiplication instead of a binary search.
    inverse_step: Option<f64>,
    // First and last support positions, kept beside the vector to spare a lookup two loads.
    first: f64,
    last: f64,
}

/// Where a position falls among a table's support points: found once by
/// [`CompTable::locate`] and shared by every table with the same support points
/// ([`CompTable::same_support`]), so several error tables of one axis cost one search.
/// Crate-private: a location is only meaningful in a table with the same support points,
/// which the kinematics chain checks once when it is built.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct Location {
    position: f64,
    segment: usize,
    // Position within the segment, 0 at its start and 1 at its end.
    t: f64,
    // dt / dposition (0 where a linear axis' table holds its end value).
    dt: f64,
}

impl Location {
    /// The segment the position falls in.
    #[inline(always)]
    pub(crate) fn segment(self) -> usize {
        self.segment
    }

    /// Value and (if `SLOPE`) slope per unit of position of the cubic `c` of this location's
    /// segment (power basis in t, constant term first): three multiply-adds.
    #[inline(always)]
    pub(crate) fn cubic<const SLOPE: bool>(self, c: &[f64; 4]) -> (f64, f64) {
        let &[c0, c1, c2, c3] = c;
        let t = self.t;
        let value = ((c3 * t + c2) * t + c1) * t + c0;
        let slope = if SLOPE {
            ((3.0 * c3 * t + 2.0 * c2) * t + c1) * self.dt
        } else {
            0.0
        };
        (value, slope)
    }

    /// [`Location::cubic`] for `N` cubics at once, coefficients by power (`c[i][s]`: the
    /// coefficient of tⁱ of cubic s), so the lanes vectorise; the same operations per cubic.
    #[inline(always)]
    pub(crate) fn cubics<const SLOPE: bool, const N: usize>(
        self,
        c: &[[f64; N]; 4],
    ) -> ([f64; N], [f64; N]) {
        let t = self.t;
        let mut value = [0.0; N];
        let mut slope = [0.0; N];
        for s in 0..N {
            value[s] = ((c[3][s] * t + c[2][s]) * t + c[1][s]) * t + c[0][s];
        }
        if SLOPE {
            for s in 0..N {
                slope[s] = ((3.0 * c[3][s] * t + 2.0 * c[2][s]) * t + c[1][s]) * self.dt;
            }
        }
        (value, slope)
    }

    /// At the start of `segment` with zero slope (a held end value).
    fn held(position: f64, segment: usize) -> Self {
        Self {
            position,
            segment,
            t: 0.0,
            dt: 0.0,
        }
    }
}

impl CompTable {
    /// A table with one value column (the same for both directions of travel).
    pub fn new(
        positions: Vec<f64>,
        values: Vec<f64>,
        wrap: Wrap,
        interpolation: Interpolation,
    ) -> Result<Self, TableError> {
        Self::build(positions, values, None, wrap, interpolation)
    }

    /// A directional table: `forward` applies while the axis travels towards larger positions,
    /// `reverse` while it travels towards smaller ones.
    pub fn directional(
        positions: Vec<f64>,
        forward: Vec<f64>,
        reverse: Vec<f64>,
        wrap: Wrap,
        interpolation: Interpolation,
    ) -> Result<Self, TableError> {
        Self::build(positions, forward, Some(reverse), wrap, interpolation)
    }

    fn build(
        positions: Vec<f64>,
        forward: Vec<f64>,
        reverse: Option<Vec<f64>>,
        wrap: Wrap,
        interpolation: Interpolation,
    ) -> Result<Self, TableError> {
        let n = positions.len();
        if n < 2 {
            return Err(TableError::TooFewPoints(n));
        }
        for col in core::iter::once(&forward).chain(reverse.as_ref()) {
            if col.len() != n {
                return Err(TableError::LengthMismatch {
                    positions: n,
                    values: col.len(),
                });
            }
        }
        for i in 0..n {
            let rev_ok = reverse.as_ref().is_none_or(|r| r[i].is_finite());
            if !(positions[i].is_finite() && forward[i].is_finite() && rev_ok) {
                return Err(TableError::NonFinite { index: i });
            }
            if i > 0 && positions[i] <= positions[i - 1] {
                return Err(TableError::NotIncreasing { index: i });
            }
        }
        if wrap == Wrap::Rotary {
            let span_deg = positions[n - 1] - positions[0];
            if span_deg > ROTARY_PERIOD_DEG {
                return Err(TableError::SpanTooLarge { span_deg });
            }
            if span_deg == ROTARY_PERIOD_DEG {
                for col in core::iter::once(&forward).chain(reverse.as_ref()) {
                    // The two ends are the same physical position: they must agree.
                    let (first, last) = (col[0], col[n - 1]);
                    if libm::fabs(first - last)
                        > 1e-9 * (1.0 + libm::fmax(libm::fabs(first), libm::fabs(last)))
                    {
                        return Err(TableError::JointMismatch { first, last });
                    }
                }
            }
        }
        let mut table = Self {
            positions,
            forward,
            reverse,
            wrap,
            interpolation,
            segments: Vec::new(),
            coef_forward: Vec::new(),
            coef_reverse: Vec::new(),
            inverse_step: None,
            first: 0.0,
            last: 0.0,
        };
        table.first = table.positions[0];
        table.last = table.positions[n - 1];
        let span = table.positions[n - 1] - table.positions[0];
        table.inverse_step = table.step(1e-12 * span).map(|h| 1.0 / h);
        table.segments = table.segment_bounds();
        table.coef_forward = table.coefficients(&table.forward);
        if let Some(r) = &table.reverse {
            table.coef_reverse = table.coefficients(r);
        }
        Ok(table)
    }

    /// Start and 1 / width of each of the n segments (see the `segments` field).
    fn segment_bounds(&self) -> Vec<[f64; 2]> {
        let p = &self.positions;
        let n = p.len();
        let mut out: Vec<[f64; 2]> = p.windows(2).map(|w| [w[0], 1.0 / (w[1] - w[0])]).collect();
        let joint = self.joint_width();
        let last_inv = if self.wrap == Wrap::Rotary && joint > 0.0 {
            1.0 / joint
        } else {
            0.0
        };
        out.push([p[n - 1], last_inv]);
        out
    }

    /// The interpolant of one value column as a cubic in t per segment. Hermite form
    /// y0·h00 + m0·h10 + y1·h01 + m1·h11 (m = slope × width) expanded into powers of t:
    /// c0 = y0, c1 = m0, c2 = 3(y1 − y0) − 2m0 − m1, c3 = 2(y0 − y1) + m0 + m1.
    fn coefficients(&self, values: &[f64]) -> Vec<[f64; 4]> {
        let n = self.positions.len();
        let slopes = match self.interpolation {
            Interpolation::MonotoneCubic => self.slopes(values),
            Interpolation::Linear => Vec::new(),
        };
        let joint = self.wrap == Wrap::Rotary && self.joint_width() > 0.0;
        (0..n)
            .map(|i| {
                let (y0, y1, j, h) = if i + 1 < n {
                    (
                        values[i],
                        values[i + 1],
                        i + 1,
                        self.positions[i + 1] - self.positions[i],
                    )
                } else if joint {
                    (values[n - 1], values[0], 0, self.joint_width())
                } else {
                    // A held end value (or the empty joint of a full circle): constant.
                    return [values[n - 1], 0.0, 0.0, 0.0];
                };
                match self.interpolation {
                    Interpolation::Linear => [y0, y1 - y0, 0.0, 0.0],
                    Interpolation::MonotoneCubic => {
                        let (m0, m1) = (slopes[i] * h, slopes[j] * h);
                        [
                            y0,
                            m0,
                            3.0 * (y1 - y0) - 2.0 * m0 - m1,
                            2.0 * (y0 - y1) + m0 + m1,
                        ]
                    }
                }
            })
            .collect()
    }

    /// Fritsch–Butland slopes: zero where the secants change sign, otherwise a weighted harmonic
    /// mean of the neighbouring secants (which never exceeds three times the smaller one, the
    /// Fritsch–Carlson bound for monotonicity). Linear axes take the secant at the ends; rotary
    /// tables treat the joint segment like any other.
    fn slopes(&self, values: &[f64]) -> Vec<f64> {
        let n = self.positions.len();
        // Segments: i = 0..n-1 between points i and i+1, plus the joint segment for rotary.
        let segment = |i: usize| -> (f64, f64) {
            if i + 1 < n {
                let h = self.positions[i + 1] - self.positions[i];
                (h, (values[i + 1] - values[i]) / h)
            } else {
                let h = self.positions[0] + ROTARY_PERIOD_DEG - self.positions[n - 1];
                (h, (values[0] - values[n - 1]) / h)
            }
        };
        let closed = self.wrap == Wrap::Rotary && self.joint_width() > 0.0;
        let harmonic = |(h0, d0): (f64, f64), (h1, d1): (f64, f64)| -> f64 {
            if d0 * d1 <= 0.0 {
                0.0
            } else {
                let w1 = 2.0 * h1 + h0;
                let w2 = h1 + 2.0 * h0;
                (w1 + w2) / (w1 / d0 + w2 / d1)
            }
        };
        let full_circle = self.wrap == Wrap::Rotary && !closed;
        let mut out = Vec::with_capacity(n);
        for i in 0..n {
            let slope = if i == 0 {
                if closed {
                    harmonic(segment(n - 1), segment(0))
                } else if full_circle {
                    // First and last points are the same position: the segment before point 0
                    // is the last real segment.
                    harmonic(segment(n - 2), segment(0))
                } else {
                    segment(0).1
                }
            } else if i == n - 1 {
                if closed {
                    harmonic(segment(n - 2), segment(n - 1))
                } else if full_circle {
                    harmonic(segment(n - 2), segment(0))
                } else {
                    segment(n - 2).1
                }
            } else {
                harmonic(segment(i - 1), segment(i))
            };
            out.push(slope);
        }
        out
    }

    /// Width of the rotary joint segment from the last support point to the first + 360°.
    fn joint_width(&self) -> f64 {
        self.positions[0] + ROTARY_PERIOD_DEG - self.positions[self.positions.len() - 1]
    }

    /// Support positions (mm or degrees).
    pub fn positions(&self) -> &[f64] {
        &self.positions
    }

    /// Values for forward travel (the only column of a non-directional table).
    pub fn forward(&self) -> &[f64] {
        &self.forward
    }

    /// Values for reverse travel, if the table is directional.
    pub fn reverse(&self) -> Option<&[f64]> {
        self.reverse.as_deref()
    }

    /// How the table continues outside its support points.
    pub fn wrap(&self) -> Wrap {
        self.wrap
    }

    /// How values between support points are found.
    pub fn interpolation(&self) -> Interpolation {
        self.interpolation
    }

    /// True if every value of every column is zero.
    pub fn is_zero(&self) -> bool {
        self.forward
            .iter()
            .chain(self.reverse.iter().flatten())
            .all(|v| *v == 0.0)
    }

    /// The interpolated value at `position` for travel in `direction`. A non-finite position
    /// gives the first value (callers check positions; this never returns NaN from finite
    /// support values).
    #[inline]
    pub fn value(&self, position: f64, direction: Direction) -> f64 {
        self.lookup::<false>(position, direction).0
    }

    /// The interpolated value and its derivative with respect to position (value unit per mm or
    /// per degree) at `position`. Where a linear axis' table holds its end value the slope is 0.
    #[inline]
    pub fn value_and_slope(&self, position: f64, direction: Direction) -> (f64, f64) {
        self.lookup::<true>(position, direction)
    }

    /// Where `position` falls among the support points (after wrapping a rotary table into its
    /// period or holding a linear one at its ends). A non-finite position reads the first value.
    #[inline(always)]
    pub(crate) fn locate(&self, position: f64) -> Location {
        let (first, last) = (self.first, self.last);
        let x = match self.wrap {
            Wrap::Hold => {
                // NaN reads the first value too.
                if position <= first || position.is_nan() {
                    return Location::held(position, 0);
                }
                if position >= last {
                    return Location::held(position, self.segments.len() - 1);
                }
                position
            }
            Wrap::Rotary => {
                let top = first + ROTARY_PERIOD_DEG;
                if position >= first && position < top {
                    position
                } else if position < first && position >= first - ROTARY_PERIOD_DEG {
                    // One turn below (axes within ±360° are the common case): an addition is
                    // far cheaper than fmod. Rounding may land on the period's end, which is
                    // its start.
                    let x = position + ROTARY_PERIOD_DEG;
                    if x >= top {
                        first
                    } else {
                        x
                    }
                } else {
                    return self.locate_far(position);
                }
            }
        };
        self.locate_within(x, position)
    }

    /// [`CompTable::locate`] for a rotary position more than one turn below or at least one
    /// turn above the table, or not finite (first value).
    #[inline(never)]
    fn locate_far(&self, position: f64) -> Location {
        if !position.is_finite() {
            return Location::held(position, 0);
        }
        let first = self.first;
        let mut r = libm::fmod(position - first, ROTARY_PERIOD_DEG);
        if r < 0.0 {
            r += ROTARY_PERIOD_DEG;
        }
        let x = first + r;
        // Rounding may put x on the period's end: that is its start.
        let x = if x >= first + ROTARY_PERIOD_DEG || x < first {
            first
        } else {
            x
        };
        self.locate_within(x, position)
    }

    /// The segment of x ∈ [first, first + period) (rotary) or (first, last) (linear).
    #[inline(always)]
    fn locate_within(&self, x: f64, position: f64) -> Location {
        let n = self.segments.len();
        // Segment i covers [p[i], p[i + 1]); x ≥ p[n − 1] is the rotary joint (segment n − 1).
        let segment = if x >= self.last {
            n - 1
        } else {
            match self.inverse_step {
                // x ≥ first here, so the cast is of a non-negative number; rounding may put x
                // one segment off, which only evaluates the neighbouring cubic a hair outside
                // [0, 1], where it joins this one continuously. Through i64: the signed
                // conversion is one instruction, the unsigned one a branchy sequence.
                Some(inv) => (((x - self.first) * inv) as i64 as usize).min(n - 2),
                None => self.positions.partition_point(|&q| q <= x).clamp(1, n - 1) - 1,
            }
        };
        let [x0, inv_h] = self.segments.get(segment).copied().unwrap_or([x, 0.0]);
        Location {
            position,
            segment,
            t: (x - x0) * inv_h,
            dt: inv_h,
        }
    }

    /// True if `other` has the same support points and wrapping, so a position located in one
    /// table (the crate's `Location`) is valid in the other.
    pub fn same_support(&self, other: &CompTable) -> bool {
        self.wrap == other.wrap && self.positions == other.positions
    }

    #[inline]
    fn lookup<const SLOPE: bool>(&self, position: f64, direction: Direction) -> (f64, f64) {
        // `locate` returns a segment below n and every column has n coefficient rows.
        self.polynomial::<SLOPE>(self.locate(position), direction)
            .unwrap_or((0.0, 0.0))
    }

    /// Horner evaluation of the segment's cubic; `None` if the segment does not exist here.
    #[inline(always)]
    fn polynomial<const SLOPE: bool>(
        &self,
        at: Location,
        direction: Direction,
    ) -> Option<(f64, f64)> {
        // Most tables have one column: test that before the direction.
        let coef = if !self.coef_reverse.is_empty() && direction == Direction::Reverse {
            &self.coef_reverse
        } else {
            &self.coef_forward
        };
        Some(at.cubic::<SLOPE>(coef.get(at.segment)?))
    }

    /// The cubic of every segment of one value column (the forward one for a table without a
    /// reverse column), indexed by [`Location::segment`]: the kinematics chain copies them,
    /// scaled to its units, into one flat array so a row's lookup needs no indirection.
    pub(crate) fn cubics(&self, direction: Direction) -> &[[f64; 4]] {
        if direction == Direction::Reverse && !self.coef_reverse.is_empty() {
            &self.coef_reverse
        } else {
            &self.coef_forward
        }
    }

    /// True if the support points are equidistant within `tolerance` (Siemens tables need it).
    pub fn step(&self, tolerance: f64) -> Option<f64> {
        let p = &self.positions;
        let step = (p[p.len() - 1] - p[0]) / (p.len() - 1) as f64;
        p.windows(2)
            .all(|w| libm::fabs((w[1] - w[0]) - step) <= tolerance)
            .then_some(step)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use alloc::vec;

    fn lin(p: Vec<f64>, v: Vec<f64>, wrap: Wrap) -> CompTable {
        CompTable::new(p, v, wrap, Interpolation::Linear).unwrap()
    }

    #[test]
    fn linear_interpolation_between_unequal_support_points() {
        // Points (0, 0), (10, 5), (40, -1). At 4: 0 + 4/10·5 = 2. At 25: 5 + 15/30·(−6) = 2.
        let t = lin(vec![0.0, 10.0, 40.0], vec![0.0, 5.0, -1.0], Wrap::Hold);
        assert!((t.value(4.0, Direction::Forward) - 2.0).abs() < 1e-12);
        assert!((t.value(25.0, Direction::Forward) - 2.0).abs() < 1e-12);
        // Slope on the second segment: −6/30 = −0.2.
        assert!((t.value_and_slope(25.0, Direction::Forward).1 + 0.2).abs() < 1e-12);
        // Exactly at support points.
        assert_eq!(t.value(10.0, Direction::Forward), 5.0);
        assert_eq!(t.value(40.0, Direction::Forward), -1.0);
    }

    #[test]
    fn linear_axis_holds_end_values() {
        let t = lin(vec![0.0, 10.0], vec![3.0, 7.0], Wrap::Hold);
        assert_eq!(t.value(-100.0, Direction::Forward), 3.0);
        assert_eq!(t.value(1e9, Direction::Forward), 7.0);
        assert_eq!(t.value_and_slope(11.0, Direction::Forward).1, 0.0);
        assert_eq!(t.value(f64::NAN, Direction::Forward), 3.0);
    }

    #[test]
    fn rotary_joint_is_seamless() {
        // Support points every 10° from 0 to 350; the joint 350 → 360 joins
        // F(350) = 2 to F(0) = 0: at 355° the value is 1, and 355° ≡ −5°.
        let p: Vec<f64> = (0..36).map(|i| 10.0 * i as f64).collect();
        let mut v = vec![0.0; 36];
        v[35] = 2.0;
        let t = lin(p, v, Wrap::Rotary);
        assert!((t.value(355.0, Direction::Forward) - 1.0).abs() < 1e-12);
        assert!((t.value(-5.0, Direction::Forward) - 1.0).abs() < 1e-12);
        assert!((t.value(715.0, Direction::Forward) - 1.0).abs() < 1e-12);
        // Continuity at 360°.
        let below = t.value(360.0 - 1e-9, Direction::Forward);
        let above = t.value(360.0 + 1e-9, Direction::Forward);
        assert!((below - above).abs() < 1e-6);
        assert!(above.abs() < 1e-6);
    }

    #[test]
    fn rotary_full_circle_must_close() {
        let err = CompTable::new(
            vec![0.0, 180.0, 360.0],
            vec![0.0, 1.0, 0.5],
            Wrap::Rotary,
            Interpolation::Linear,
        )
        .unwrap_err();
        assert!(matches!(err, TableError::JointMismatch { .. }));
        let t = CompTable::new(
            vec![0.0, 180.0, 360.0],
            vec![0.0, 1.0, 0.0],
            Wrap::Rotary,
            Interpolation::MonotoneCubic,
        )
        .unwrap();
        assert!(t.value(359.999_999, Direction::Forward).abs() < 1e-5);
        assert!(t.value(0.000_001, Direction::Forward).abs() < 1e-5);
        assert!(matches!(
            CompTable::new(
                vec![0.0, 361.0],
                vec![0.0, 0.0],
                Wrap::Rotary,
                Interpolation::Linear
            ),
            Err(TableError::SpanTooLarge { .. })
        ));
    }

    #[test]
    fn bad_tables_are_refused() {
        assert_eq!(
            CompTable::new(vec![0.0], vec![0.0], Wrap::Hold, Interpolation::Linear),
            Err(TableError::TooFewPoints(1))
        );
        assert_eq!(
            CompTable::new(
                vec![0.0, 1.0, 1.0],
                vec![0.0; 3],
                Wrap::Hold,
                Interpolation::Linear
            ),
            Err(TableError::NotIncreasing { index: 2 })
        );
        assert_eq!(
            CompTable::new(
                vec![0.0, 1.0],
                vec![0.0, f64::NAN],
                Wrap::Hold,
                Interpolation::Linear
            ),
            Err(TableError::NonFinite { index: 1 })
        );
        assert!(matches!(
            CompTable::directional(
                vec![0.0, 1.0],
                vec![0.0; 2],
                vec![0.0; 3],
                Wrap::Hold,
                Interpolation::Linear
            ),
            Err(TableError::LengthMismatch { .. })
        ));
    }

    #[test]
    fn directional_table_picks_its_column() {
        // Backlash of 4 µm: forward reads +2, reverse −2.
        let t = CompTable::directional(
            vec![0.0, 100.0],
            vec![2.0, 2.0],
            vec![-2.0, -2.0],
            Wrap::Hold,
            Interpolation::Linear,
        )
        .unwrap();
        assert_eq!(t.value(50.0, Direction::Forward), 2.0);
        assert_eq!(t.value(50.0, Direction::Reverse), -2.0);
    }

    #[test]
    fn monotone_cubic_stays_within_neighbours_and_hits_support_points() {
        // A step-like table: linear-free cubics would overshoot beyond 1 near x = 2.
        let p = vec![0.0, 1.0, 2.0, 3.0, 10.0];
        let v = vec![0.0, 0.0, 1.0, 1.0, 1.5];
        let t = CompTable::new(
            p.clone(),
            v.clone(),
            Wrap::Hold,
            Interpolation::MonotoneCubic,
        )
        .unwrap();
        for (x, y) in p.iter().zip(&v) {
            assert!((t.value(*x, Direction::Forward) - y).abs() < 1e-12);
        }
        for k in 0..=1000 {
            let x = 10.0 * k as f64 / 1000.0;
            let i = p.partition_point(|&q| q <= x).clamp(1, p.len() - 1);
            let (lo, hi) = (v[i - 1].min(v[i]), v[i - 1].max(v[i]));
            let y = t.value(x, Direction::Forward);
            assert!(y >= lo - 1e-12 && y <= hi + 1e-12, "x={x} y={y}");
        }
        // On the flat segment [0, 1] the slopes at both ends are 0: the value stays 0.
        assert_eq!(t.value(0.5, Direction::Forward), 0.0);
        // Derivative check by central difference at 2.5.
        let (_, s) = t.value_and_slope(2.5, Direction::Forward);
        let fd = (t.value(2.5 + 1e-6, Direction::Forward)
            - t.value(2.5 - 1e-6, Direction::Forward))
            / 2e-6;
        assert!((s - fd).abs() < 1e-6);
    }

    #[test]
    fn equidistant_lookup_agrees_with_binary_search() {
        // The same support points, once exactly equidistant (direct index) and once with the
        // last point nudged (binary search): values agree everywhere but the last segment.
        let p: Vec<f64> = (0..37).map(|i| 10.0 * i as f64 - 180.0).collect();
        let v: Vec<f64> = p.iter().map(|x| libm::sin(x * 0.05) * 3.0).collect();
        let a = CompTable::new(
            p.clone(),
            v.clone(),
            Wrap::Hold,
            Interpolation::MonotoneCubic,
        )
        .unwrap();
        assert!(a.inverse_step.is_some());
        let mut q = p.clone();
        q[36] += 1e-3;
        let b = CompTable::new(q, v, Wrap::Hold, Interpolation::MonotoneCubic).unwrap();
        assert!(b.inverse_step.is_none());
        for k in 0..=3400 {
            let x = -180.0 + 0.1 * k as f64;
            let (ya, yb) = (
                a.value(x, Direction::Forward),
                b.value(x, Direction::Forward),
            );
            assert!((ya - yb).abs() < 1e-9, "x={x} {ya} {yb}");
        }
        // Support points themselves, where rounding of (x − p0)/h matters.
        for (x, y) in p.iter().zip(a.forward()) {
            assert!((a.value(*x, Direction::Forward) - y).abs() < 1e-12);
        }
    }

    #[test]
    fn shared_location_and_far_turns_agree_with_direct_lookup() {
        // Two tables on the same support points share one location. Rotary positions several turns
        // away (the fmod path) and one turn away (the addition path) wrap alike.
        let p: Vec<f64> = (0..36).map(|i| 10.0 * i as f64).collect();
        let sine = |a: f64| {
            p.iter()
                .map(|x| a * libm::sin(x * 0.03))
                .collect::<Vec<_>>()
        };
        let mk = |pos: Vec<f64>, v| {
            CompTable::new(pos, v, Wrap::Rotary, Interpolation::MonotoneCubic).unwrap()
        };
        let a = mk(p.clone(), sine(2.0));
        let b = mk(p.clone(), sine(-5.0));
        let c = mk(p[..20].to_vec(), sine(1.0)[..20].to_vec());
        assert!(a.same_support(&b) && !a.same_support(&c));
        for k in 0..2000 {
            let x = -1500.0 + 1.5 * k as f64;
            let at = a.locate(x);
            for t in [&a, &b, &c] {
                let at = if t.same_support(&a) { at } else { t.locate(x) };
                let (v, s) = at.cubic::<true>(&t.cubics(Direction::Forward)[at.segment()]);
                let (v2, s2) = t.value_and_slope(x, Direction::Forward);
                assert_eq!((v, s), (v2, s2), "x={x}");
                let y = t.value(x - 360.0 * libm::round(x / 360.0), Direction::Forward);
                assert!((v - y).abs() < 1e-9, "x={x} {v} {y}");
            }
        }
    }

    #[test]
    fn step_detects_equidistant_tables() {
        let t = lin(vec![0.0, 10.0, 20.0], vec![0.0; 3], Wrap::Hold);
        assert_eq!(t.step(1e-9), Some(10.0));
        let t = lin(vec![0.0, 10.0, 25.0], vec![0.0; 3], Wrap::Hold);
        assert_eq!(t.step(1e-9), None);
    }
}
