//! Least squares by Householder QR, never by unguarded normal equations.
//!
//! Rows stream into an [`Accumulator`] that keeps only the triangular factor R of the augmented
//! matrix [A | B] (regressors and targets side by side): rows are gathered in blocks, and each
//! block is stacked under the current R and factored again (a tall-skinny QR, "TSQR"). Because
//! Q is orthogonal, R carries everything least squares needs: Rᵀ·R = [A|B]ᵀ·[A|B] without ever
//! forming that product (forming it squares the condition number). Row blocks factor in parallel
//! on every core ([`Accumulator::from_matrix`]) and their R factors merge by one more QR.
//!
//! [`Triangle::solve`] then scales the columns of A to unit norm (column norms of A are the column
//! norms of R) — or, for a [`SolveOptions::shared_scale`] group, by the group's RMS norm —,
//! optionally stacks √λ·I under it (ridge), and solves through the singular value decomposition
//! of the small n × n triangle: singular values below `rcond · s_max` are dropped, giving the
//! minimum-norm solution, and each dropped direction is reported with the columns that span it
//! (the culprits of the rank deficiency).
//!
//! Weights: a row with weight w enters as √w·[a | b], so the fit minimises Σ w·(a·x − b)².

#![allow(clippy::needless_range_loop)] // index loops mirror the matrix formulas

use std::fmt;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::qr::no_pivoting::factor::{
    qr_in_place, qr_in_place_scratch, recommended_block_size,
};
use faer::reborrow::{Reborrow, ReborrowMut};
use faer::{Mat, MatRef, Par};

/// Rows gathered before each block QR.
const BLOCK_ROWS: usize = 1024;

/// Bad data handed to the solver.
#[derive(Debug, Clone, PartialEq)]
pub enum SolveError {
    /// A row or weight holds NaN or ∞, or a weight is negative.
    NonFinite {
        /// Row index (counted from the first row pushed).
        row: usize,
    },
    /// A row does not have the declared number of regressors or targets.
    Shape {
        /// What was expected.
        expected: usize,
        /// What was given.
        got: usize,
    },
    /// There are no regressors or no rows.
    Empty,
    /// The SVD of the triangle did not converge (should not happen for finite data).
    NoConvergence,
}

impl fmt::Display for SolveError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NonFinite { row } => write!(
                f,
                "row {row}: a regressor, target or weight is NaN or infinite (or a weight is negative)"
            ),
            Self::Shape { expected, got } => write!(f, "expected {expected} values, got {got}"),
            Self::Empty => write!(f, "no rows or no regressors to fit"),
            Self::NoConvergence => write!(f, "the singular value decomposition did not converge"),
        }
    }
}

impl std::error::Error for SolveError {}

/// Streaming QR of [A | B]: push rows, keep only R.
#[derive(Debug, Clone)]
pub struct Accumulator {
    n: usize,
    k: usize,
    /// Rows 0..p hold R (upper triangle); rows p..p+filled the rows waiting for the next block QR.
    buf: Mat<f64>,
    filled: usize,
    rows: usize,
}

impl Accumulator {
    /// An empty accumulator for `regressors` columns of A and `targets` columns of B.
    pub fn new(regressors: usize, targets: usize) -> Self {
        let p = regressors + targets;
        Self {
            n: regressors,
            k: targets,
            buf: Mat::zeros(BLOCK_ROWS + p, p),
            filled: 0,
            rows: 0,
        }
    }

    fn p(&self) -> usize {
        self.n + self.k
    }

    /// Number of rows pushed so far.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Adds one row: regressors `a`, targets `b`, weight `w` (≥ 0).
    pub fn push_row(&mut self, a: &[f64], b: &[f64], w: f64) -> Result<(), SolveError> {
        if a.len() != self.n {
            return Err(SolveError::Shape {
                expected: self.n,
                got: a.len(),
            });
        }
        if b.len() != self.k {
            return Err(SolveError::Shape {
                expected: self.k,
                got: b.len(),
            });
        }
        let finite = a.iter().chain(b).all(|v| v.is_finite());
        if !(w.is_finite() && w >= 0.0 && finite) {
            return Err(SolveError::NonFinite { row: self.rows });
        }
        let s = w.sqrt();
        let i = self.p() + self.filled;
        for (j, v) in a.iter().chain(b).enumerate() {
            self.buf[(i, j)] = s * v;
        }
        self.filled += 1;
        self.rows += 1;
        if self.filled == BLOCK_ROWS {
            self.flush();
        }
        Ok(())
    }

    /// Factors the waiting rows into R.
    fn flush(&mut self) {
        if self.filled == 0 {
            return;
        }
        let p = self.p();
        let m = p + self.filled;
        let bs = recommended_block_size::<f64>(m, p);
        let mut q_coeff = Mat::<f64>::zeros(bs, p);
        let mut mem = MemBuffer::new(qr_in_place_scratch::<f64>(
            m,
            p,
            bs,
            Par::Seq,
            Default::default(),
        ));
        qr_in_place(
            self.buf.as_mut().get_mut(..m, ..),
            q_coeff.as_mut(),
            Par::Seq,
            MemStack::new(&mut mem),
            Default::default(),
        );
        for j in 0..p {
            for i in j + 1..p {
                self.buf[(i, j)] = 0.0;
            }
        }
        self.filled = 0;
    }

    /// Adds a whole block of rows at once (A and B with equal row counts, optional weights).
    pub fn push_block(
        &mut self,
        a: MatRef<'_, f64>,
        b: MatRef<'_, f64>,
        weights: Option<&[f64]>,
    ) -> Result<(), SolveError> {
        if a.ncols() != self.n || b.ncols() != self.k {
            return Err(SolveError::Shape {
                expected: self.p(),
                got: a.ncols() + b.ncols(),
            });
        }
        if b.nrows() != a.nrows() || weights.is_some_and(|w| w.len() != a.nrows()) {
            return Err(SolveError::Shape {
                expected: a.nrows(),
                got: b.nrows(),
            });
        }
        let p = self.p();
        let mut start = 0;
        while start < a.nrows() {
            let take = (BLOCK_ROWS - self.filled).min(a.nrows() - start);
            let top = p + self.filled;
            let mut dst = self.buf.as_mut().get_mut(top..top + take, ..);
            dst.rb_mut()
                .get_mut(.., ..self.n)
                .copy_from(a.get(start..start + take, ..));
            dst.rb_mut()
                .get_mut(.., self.n..)
                .copy_from(b.get(start..start + take, ..));
            for i in 0..take {
                let w = weights.map_or(1.0, |w| w[start + i]);
                let bad =
                    !(w.is_finite() && w >= 0.0) || (0..p).any(|j| !dst.rb().get(i, j).is_finite());
                if bad {
                    // Forget the rows of this block: the accumulator stays as before the call
                    // would have left it up to the bad row.
                    self.rows += i;
                    self.filled += i;
                    return Err(SolveError::NonFinite { row: self.rows });
                }
                if weights.is_some() {
                    let s = w.sqrt();
                    for j in 0..p {
                        *dst.rb_mut().get_mut(i, j) *= s;
                    }
                }
            }
            self.filled += take;
            self.rows += take;
            start += take;
            if self.filled == BLOCK_ROWS {
                self.flush();
            }
        }
        Ok(())
    }

    /// Adds the rows another accumulator has seen (merging two R factors is one more QR).
    pub fn merge(&mut self, mut other: Accumulator) -> Result<(), SolveError> {
        other.flush();
        if other.n != self.n || other.k != self.k {
            return Err(SolveError::Shape {
                expected: self.p(),
                got: other.p(),
            });
        }
        let p = self.p();
        let rows = self.rows + other.rows;
        let ones = vec![1.0; p];
        self.push_block(
            other.buf.as_ref().get(..p, ..self.n),
            other.buf.as_ref().get(..p, self.n..),
            Some(&ones),
        )?;
        self.rows = rows;
        Ok(())
    }

    /// Factors a whole matrix, splitting its rows over every available core.
    pub fn from_matrix(
        a: MatRef<'_, f64>,
        b: MatRef<'_, f64>,
        weights: Option<&[f64]>,
    ) -> Result<Self, SolveError> {
        let m = a.nrows();
        let threads = std::thread::available_parallelism()
            .map_or(1, |n| n.get())
            .min(m / (4 * BLOCK_ROWS))
            .max(1);
        let chunk = m.div_ceil(threads);
        let parts: Vec<Result<Accumulator, SolveError>> = std::thread::scope(|scope| {
            let handles: Vec<_> = (0..threads)
                .map(|t| {
                    let (r0, r1) = (t * chunk, ((t + 1) * chunk).min(m));
                    let (n, k) = (a.ncols(), b.ncols());
                    scope.spawn(move || {
                        let mut acc = Accumulator::new(n, k);
                        acc.push_block(
                            a.get(r0..r1, ..),
                            b.get(r0..r1, ..),
                            weights.map(|w| &w[r0..r1]),
                        )
                        .map_err(|e| match e {
                            SolveError::NonFinite { row } => {
                                SolveError::NonFinite { row: row + r0 }
                            }
                            e => e,
                        })?;
                        Ok(acc)
                    })
                })
                .collect();
            handles
                .into_iter()
                .map(|h| h.join().unwrap_or(Err(SolveError::NoConvergence)))
                .collect()
        });
        let mut parts = parts.into_iter();
        let mut acc = parts
            .next()
            .unwrap_or(Ok(Accumulator::new(a.ncols(), b.ncols())))?;
        for part in parts {
            acc.merge(part?)?;
        }
        Ok(acc)
    }

    /// The final triangle.
    pub fn finish(mut self) -> Triangle {
        self.flush();
        let p = self.p();
        Triangle {
            n: self.n,
            k: self.k,
            rows: self.rows,
            r: self.buf.as_ref().get(..p, ..).to_owned(),
        }
    }
}

/// The R factor of [A | B]: everything needed to solve for any ridge parameter.
#[derive(Debug, Clone)]
pub struct Triangle {
    n: usize,
    k: usize,
    rows: usize,
    r: Mat<f64>,
}

/// Each column's norm in the triangle and the factor that scales it for the ridge: 1/norm, or
/// for a column of a `shared_scale` group 1/(the group's root mean square norm).
fn column_scales(r: MatRef<'_, f64>, n: usize, groups: &[Vec<usize>]) -> (Vec<f64>, Vec<f64>) {
    let norms: Vec<f64> = (0..n).map(|j| r.get(..j + 1, j).norm_l2()).collect();
    let mut scale: Vec<f64> = norms
        .iter()
        .map(|&v| if v > 0.0 { 1.0 / v } else { 1.0 })
        .collect();
    for group in groups {
        let cols: Vec<usize> = group.iter().copied().filter(|&j| j < n).collect();
        let ms = cols.iter().map(|&j| norms[j] * norms[j]).sum::<f64>() / cols.len().max(1) as f64;
        if ms > 0.0 {
            for j in cols {
                scale[j] = 1.0 / ms.sqrt();
            }
        }
    }
    (norms, scale)
}

/// How to solve.
#[derive(Debug, Clone, Default)]
pub struct SolveOptions {
    /// Ridge parameter λ ≥ 0 on scaled columns: minimises ‖A·x − b‖² + λ·Σ_j (s_j·x_j)², s_j
    /// the norm ‖A_j‖ or, in a `shared_scale` group, the group's RMS norm, so λ is relative to
    /// the data's own sum of squares and independent of units.
    pub ridge: f64,
    /// Columns exempt from the ridge penalty (the intercept).
    pub unpenalized: Vec<usize>,
    /// Groups of columns in one physical unit that share one scale, the root mean square of
    /// their norms, instead of each its own: the penalty is then on the coefficients in that
    /// unit alike (µm/K for every temperature), so a column that barely varied in the data
    /// cannot earn a large coefficient from a small share of the variance. Columns in no group
    /// keep their own norm.
    pub shared_scale: Vec<Vec<usize>>,
    /// Singular values below `rcond · s_max` count as zero; `None` = ε·max(rows, columns), the
    /// default of LAPACK's `gelsd` as numpy uses it.
    pub rcond: Option<f64>,
}

/// A direction in which the columns are (nearly) linearly dependent.
#[derive(Debug, Clone, PartialEq)]
pub struct RankDeficiency {
    /// s / s_max of the dropped singular value (0 for an all-zero column).
    pub singular_value_ratio: f64,
    /// The columns spanning it, with their weight in the null direction, largest first.
    pub columns: Vec<(usize, f64)>,
}

impl RankDeficiency {
    /// A warning naming the culprit columns.
    pub fn describe(&self, names: &[String]) -> String {
        let name = |j: usize| names.get(j).cloned().unwrap_or_else(|| format!("#{j}"));
        let cols: Vec<String> = self.columns.iter().map(|&(j, _)| name(j)).collect();
        if self.singular_value_ratio == 0.0 && cols.len() == 1 {
            format!("column {} is all zero: it carries no information", cols[0])
        } else {
            format!(
                "columns {} are (nearly) linearly dependent (singular value ratio {:.1e}); their coefficients are not identifiable and were solved for the minimum norm",
                cols.join(", "),
                self.singular_value_ratio
            )
        }
    }
}

/// Coefficients and diagnostics.
#[derive(Debug, Clone)]
pub struct Solution {
    /// Coefficients, one vector of n per target.
    pub coefficients: Vec<Vec<f64>>,
    /// Numerical rank of the (scaled, possibly ridge-stacked) regressor matrix.
    pub rank: usize,
    /// s_max / s_min of the column-scaled matrix (∞ when rank deficient).
    pub condition: f64,
    /// Weighted residual sum of squares per target (data term only).
    pub rss: Vec<f64>,
    /// Dropped directions with their culprit columns; empty when of full rank.
    pub rank_deficiencies: Vec<RankDeficiency>,
}

impl Triangle {
    /// Rows that went in.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// The rows of several triangles together (one QR of the stacked factors); `None` for an
    /// empty list or triangles of different shapes.
    pub fn stack<'t>(parts: impl IntoIterator<Item = &'t Triangle>) -> Option<Triangle> {
        let mut parts = parts.into_iter().peekable();
        let first = parts.peek()?;
        let (n, k) = (first.n, first.k);
        let mut acc = Accumulator::new(n, k);
        let mut rows = 0;
        for t in parts {
            if (t.n, t.k) != (n, k) {
                return None;
            }
            acc.push_block(t.r.as_ref().get(.., ..n), t.r.as_ref().get(.., n..), None)
                .ok()?;
            rows += t.rows;
        }
        acc.rows = rows;
        Some(acc.finish())
    }

    /// The triangle of [A | B]·M: the same rows with new columns, each a combination of the old
    /// ones (`regressors` then `targets` of them), since (Q·R)·M = Q·(R·M). A selection of
    /// columns, a difference of two, a shift by a multiple of another: no pass over the rows.
    pub fn transformed(&self, m: MatRef<'_, f64>, regressors: usize, targets: usize) -> Triangle {
        let rm = self.r.as_ref() * m;
        let mut acc = Accumulator::new(regressors, targets);
        if acc
            .push_block(
                rm.as_ref().get(.., ..regressors),
                rm.as_ref().get(.., regressors..),
                None,
            )
            .is_err()
        {
            // Non-finite M: a triangle that solves to an error rather than to garbage.
            return Triangle {
                n: regressors,
                k: targets,
                rows: 0,
                r: Mat::zeros(regressors + targets, regressors + targets),
            };
        }
        acc.rows = self.rows;
        acc.finish()
    }

    /// Column `j` minus `c` times column 0, in place: R·T changes only R's first row, because
    /// R's first column is zero below its first entry.
    pub fn subtract_first_column(&mut self, j: usize, c: f64) {
        let r00 = self.r[(0, 0)];
        self.r[(0, j)] -= c * r00;
    }

    /// Entry (i, j) of [A | B]ᵀ·[A | B], the sum over the rows of column i times column j.
    pub fn gram(&self, i: usize, j: usize) -> f64 {
        let r = self.r.as_ref();
        (0..=i.min(j)).map(|l| r[(l, i)] * r[(l, j)]).sum()
    }

    /// R·u: a combination u of the columns, in the triangle's coordinates. Two such vectors
    /// have the dot product of the combinations themselves over the rows (Q is orthonormal),
    /// so sums of squares and cross products of predictions need no pass over the rows.
    pub fn apply(&self, u: &[f64]) -> Vec<f64> {
        let r = self.r.as_ref();
        (0..r.nrows())
            .map(|i| (i..r.ncols()).map(|j| r[(i, j)] * u[j]).sum())
            .collect()
    }

    /// The coefficients of the first target for every ridge parameter of `ridges` (no column
    /// exempt from the penalty), from one SVD of the column-scaled triangle T = U·S·Vᵀ:
    /// x(λ) = D·V·diag(s/(s² + λ))·Uᵀ·c, which minimises ‖T·γ − c‖² + λ‖γ‖² exactly as
    /// [`solve`](Self::solve) does by stacking √λ·I under T; at λ = 0 the singular values below
    /// its rank threshold are dropped as there. For scoring ridge candidates, where one SVD
    /// instead of one per candidate is most of the time; the fit itself uses `solve`.
    pub fn ridge_path(
        &self,
        ridges: &[f64],
        shared_scale: &[Vec<usize>],
    ) -> Result<Vec<Vec<f64>>, SolveError> {
        let n = self.n;
        if n == 0 || self.rows == 0 || self.k == 0 {
            return Err(SolveError::Empty);
        }
        let r = self.r.as_ref();
        let (_, scale) = column_scales(r, n, shared_scale);
        let mut t = Mat::<f64>::zeros(n, n);
        for j in 0..n {
            for i in 0..=j {
                t[(i, j)] = r[(i, j)] * scale[j];
            }
        }
        let svd = t.thin_svd().map_err(|_| SolveError::NoConvergence)?;
        let s = svd.S().column_vector();
        let (u, v) = (svd.U(), svd.V());
        let s_max = (0..n).map(|i| s[i]).fold(0.0_f64, f64::max);
        let threshold = f64::EPSILON * self.rows.max(n) as f64 * s_max;
        // Uᵀ·c once; each ridge only reweights it.
        let proj: Vec<f64> = (0..n)
            .map(|i| (0..n).map(|row| u[(row, i)] * r[(row, n)]).sum())
            .collect();
        Ok(ridges
            .iter()
            .map(|&lambda| {
                let mut gamma = vec![0.0; n];
                for i in 0..n {
                    let f = if lambda > 0.0 {
                        s[i] / (s[i] * s[i] + lambda)
                    } else if s[i] > threshold {
                        1.0 / s[i]
                    } else {
                        0.0
                    };
                    if f != 0.0 {
                        for (j, g) in gamma.iter_mut().enumerate() {
                            *g += v[(j, i)] * f * proj[i];
                        }
                    }
                }
                gamma.iter().zip(&scale).map(|(g, d)| g * d).collect()
            })
            .collect())
    }

    /// Solves for the coefficients.
    pub fn solve(&self, options: &SolveOptions) -> Result<Solution, SolveError> {
        let (n, k) = (self.n, self.k);
        if n == 0 || self.rows == 0 {
            return Err(SolveError::Empty);
        }
        let r = self.r.as_ref();
        let (norms, scale) = column_scales(r, n, &options.shared_scale);
        // T = R·D (upper triangle), C = Qᵀ·B (top n rows).
        let mut t = Mat::<f64>::zeros(n, n);
        for j in 0..n {
            for i in 0..=j {
                t[(i, j)] = r[(i, j)] * scale[j];
            }
        }
        let mut c = r.get(..n, n..).to_owned();
        if options.ridge > 0.0 {
            let root = options.ridge.sqrt();
            let mut m = Mat::<f64>::zeros(2 * n, n + k);
            m.as_mut().get_mut(..n, ..n).copy_from(t.as_ref());
            m.as_mut().get_mut(..n, n..).copy_from(c.as_ref());
            for j in 0..n {
                if !options.unpenalized.contains(&j) {
                    m[(n + j, j)] = root;
                }
            }
            let qr = m.qr();
            let rr = qr.thin_R();
            t = Mat::zeros(n, n);
            for j in 0..n {
                for i in 0..=j {
                    t[(i, j)] = rr[(i, j)];
                }
            }
            c = rr.get(..n, n..).to_owned();
        }
        let svd = t.thin_svd().map_err(|_| SolveError::NoConvergence)?;
        let s = svd.S().column_vector();
        let (u, v) = (svd.U(), svd.V());
        let s_max = (0..n).map(|i| s[i]).fold(0.0_f64, f64::max);
        let rcond = options
            .rcond
            .unwrap_or(f64::EPSILON * self.rows.max(n) as f64);
        let threshold = rcond * s_max;
        let kept: Vec<usize> = (0..n).filter(|&i| s[i] > threshold).collect();
        let mut deficiencies = Vec::new();
        for j in 0..n {
            if norms[j] == 0.0 {
                deficiencies.push(RankDeficiency {
                    singular_value_ratio: 0.0,
                    columns: vec![(j, 1.0)],
                });
            }
        }
        for i in (0..n).filter(|&i| s[i] <= threshold) {
            let mut cols: Vec<(usize, f64)> = (0..n)
                .map(|j| (j, v[(j, i)]))
                .filter(|&(j, w)| w.abs() >= 0.1 && norms[j] > 0.0)
                .collect();
            if cols.is_empty() {
                continue;
            }
            cols.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
            cols.truncate(8);
            deficiencies.push(RankDeficiency {
                singular_value_ratio: if s_max > 0.0 { s[i] / s_max } else { 0.0 },
                columns: cols,
            });
        }
        let mut coefficients = Vec::with_capacity(k);
        let mut rss = Vec::with_capacity(k);
        for target in 0..k {
            // γ = V_r · S_r⁻¹ · U_rᵀ · c, x = D·γ.
            let mut gamma = vec![0.0; n];
            for &i in &kept {
                let mut proj = 0.0;
                for row in 0..n {
                    proj += u[(row, i)] * c[(row, target)];
                }
                let f = proj / s[i];
                for (j, g) in gamma.iter_mut().enumerate() {
                    *g += v[(j, i)] * f;
                }
            }
            let x: Vec<f64> = gamma.iter().zip(&scale).map(|(g, d)| g * d).collect();
            // ‖A·x − b‖² = ‖R·[x; −e_target]‖² since Q is orthogonal.
            let mut sum = 0.0;
            for row in 0..n + k {
                let mut e = -r[(row, n + target)];
                for (j, xj) in x.iter().enumerate().skip(row.min(n)) {
                    e += r[(row, j)] * xj;
                }
                sum += e * e;
            }
            rss.push(sum);
            coefficients.push(x);
        }
        let s_min = kept.iter().map(|&i| s[i]).fold(f64::INFINITY, f64::min);
        Ok(Solution {
            coefficients,
            rank: kept.len(),
            condition: if kept.len() == n && s_min > 0.0 {
                s_max / s_min
            } else {
                f64::INFINITY
            },
            rss,
            rank_deficiencies: deficiencies,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fit(rows: &[(Vec<f64>, f64)], opts: &SolveOptions) -> Solution {
        let n = rows[0].0.len();
        let mut acc = Accumulator::new(n, 1);
        for (a, b) in rows {
            acc.push_row(a, &[*b], 1.0).unwrap();
        }
        acc.finish().solve(opts).unwrap()
    }

    /// One SVD for every ridge gives what one solve per ridge gives, at λ = 0 too (a column
    /// scaled 1e3 apart from the others and a nearly dependent pair included).
    /// Stacking, transforming and applying a triangle give what a pass over the rows gives.
    #[test]
    fn triangles_stand_for_their_rows() {
        let rows: Vec<[f64; 4]> = (0..300)
            .map(|i| {
                let t = i as f64;
                [
                    1.0,
                    (t / 7.0).sin() * 3.0 + 40.0,
                    (t / 13.0).cos(),
                    0.2 * t - 1.0,
                ]
            })
            .collect();
        let tri = |range: std::ops::Range<usize>| {
            let mut acc = Accumulator::new(3, 1);
            for r in &rows[range] {
                acc.push_row(&r[..3], &r[3..], 1.0).unwrap();
            }
            acc.finish()
        };
        let all = Triangle::stack([&tri(0..100), &tri(100..300)]).unwrap();
        assert_eq!(all.rows(), 300);
        // New columns [1 | x2 − x1 | y].
        let mut m = Mat::<f64>::zeros(4, 3);
        m[(0, 0)] = 1.0;
        m[(2, 1)] = 1.0;
        m[(1, 1)] = -1.0;
        m[(3, 2)] = 1.0;
        let mut t = all.transformed(m.as_ref(), 2, 1);
        t.subtract_first_column(1, 0.5);
        let col = |r: &[f64; 4]| [1.0, r[2] - r[1] - 0.5, r[3]];
        for i in 0..3 {
            for j in 0..3 {
                let direct: f64 = rows.iter().map(|r| col(r)[i] * col(r)[j]).sum();
                assert!((t.gram(i, j) - direct).abs() < 1e-9 * direct.abs().max(1.0));
            }
        }
        // R·u and R·v have the dot product of the combinations u, v over the rows.
        let (u, v) = ([0.3, -1.0, 2.0, 0.0], [0.0, 0.5, 0.0, 1.0]);
        let dot: f64 = all
            .apply(&u)
            .iter()
            .zip(all.apply(&v))
            .map(|(a, b)| a * b)
            .sum();
        let direct: f64 = rows
            .iter()
            .map(|r| {
                let c = |w: &[f64; 4]| (0..4).map(|j| w[j] * r[j]).sum::<f64>();
                c(&u) * c(&v)
            })
            .sum();
        assert!((dot - direct).abs() < 1e-9 * direct.abs().max(1.0));
    }

    #[test]
    fn the_ridge_path_equals_one_solve_per_ridge() {
        let rows: Vec<(Vec<f64>, f64)> = (0..200)
            .map(|i| {
                let x = i as f64 / 50.0;
                let a = vec![1.0, x, 1e3 * x.sin(), x * x, x * x + 1e-9 * (i % 7) as f64];
                let y = 2.0 + 0.5 * x - 3e-3 * a[2] + 0.1 * (i % 5) as f64;
                (a, y)
            })
            .collect();
        let mut acc = Accumulator::new(5, 1);
        for (a, b) in &rows {
            acc.push_row(a, &[*b], 1.0).unwrap();
        }
        let tri = acc.finish();
        let ridges = [0.0, 1e-8, 1e-4, 1e-2, 1.0];
        let path = tri.ridge_path(&ridges, &[]).unwrap();
        for (r, &ridge) in ridges.iter().enumerate() {
            let one = &tri
                .solve(&SolveOptions {
                    ridge,
                    ..SolveOptions::default()
                })
                .unwrap()
                .coefficients[0];
            // Compared as predictions: a dropped direction may share its weight differently.
            for (a, _) in &rows {
                let p = |x: &[f64]| a.iter().zip(x).map(|(a, x)| a * x).sum::<f64>();
                assert!((p(&path[r]) - p(one)).abs() < 1e-6, "λ = {ridge}");
            }
        }
    }

    /// Two regressors in one unit, one varying ten times less than the other, y = x1 + x2:
    /// with each column's own scale the ridge shrinks both coefficients alike; with a shared
    /// scale (one penalty per unit of coefficient) the quiet column's coefficient is shrunk far
    /// more, as its share of the variance is small. The ridge path agrees with the solve under
    /// the shared scale too.
    #[test]
    fn a_shared_scale_shrinks_a_quiet_column_more() {
        let rows: Vec<(Vec<f64>, f64)> = (0..40)
            .map(|i| {
                let t = i as f64;
                let x1 = (t * 0.37).sin() * 10.0;
                let x2 = (t * 0.91).cos();
                (vec![1.0, x1, x2], x1 + x2)
            })
            .collect();
        let options = |shared_scale: Vec<Vec<usize>>| SolveOptions {
            ridge: 0.3,
            unpenalized: vec![0],
            rcond: None,
            shared_scale,
        };
        let own = fit(&rows, &options(Vec::new())).coefficients[0].clone();
        let shared = fit(&rows, &options(vec![vec![1, 2]])).coefficients[0].clone();
        assert!(shared[2] < 0.5 * own[2], "{shared:?} against {own:?}");
        assert!(shared[1] > own[1], "{shared:?} against {own:?}");
        let mut acc = Accumulator::new(3, 1);
        for (a, b) in &rows {
            acc.push_row(a, &[*b], 1.0).unwrap();
        }
        // The path penalises every column, the intercept too.
        let path = acc.finish().ridge_path(&[0.3], &[vec![1, 2]]).unwrap();
        let every = SolveOptions {
            unpenalized: Vec::new(),
            ..options(vec![vec![1, 2]])
        };
        let one = fit(&rows, &every).coefficients[0].clone();
        for (p, s) in path[0].iter().zip(&one) {
            assert!((p - s).abs() < 1e-9, "{:?} against {one:?}", path[0]);
        }
    }

    #[test]
    fn line_through_points_by_hand() {
        // y = 1 + 2x sampled at x = 0, 1, 2, 3 with residuals +0.1, −0.1, −0.1, +0.1:
        // the residual pattern is orthogonal to [1, x]·… only for the intercept, so by hand:
        // Σx = 6, Σx² = 14, Σy = 16, Σxy = 27.9+… — solved: slope 2, intercept 1 (the pattern
        // +,−,−,+ has Σe = 0 and Σx·e = 0 − 0.1 − 0.2 + 0.3 = 0).
        let ys = [1.1, 2.9, 4.9, 7.1];
        let rows: Vec<_> = ys
            .iter()
            .enumerate()
            .map(|(i, &y)| (vec![1.0, i as f64], y))
            .collect();
        let s = fit(&rows, &SolveOptions::default());
        assert!((s.coefficients[0][0] - 1.0).abs() < 1e-12);
        assert!((s.coefficients[0][1] - 2.0).abs() < 1e-12);
        // RSS = 4 · 0.01 = 0.04.
        assert!((s.rss[0] - 0.04).abs() < 1e-12);
        assert_eq!(s.rank, 2);
        assert!(s.rank_deficiencies.is_empty());
    }

    #[test]
    fn many_blocks_weights_and_merge_agree_with_direct() {
        // 5000 rows (several blocks): y = 3 − 0.5·x1 + 1e4·x2 exactly, x2 tiny (badly scaled).
        let mut acc1 = Accumulator::new(3, 1);
        let mut acc2 = Accumulator::new(3, 1);
        let mut acc3 = Accumulator::new(3, 1);
        for i in 0..5000 {
            let x1 = (i as f64 * 0.37).sin() * 100.0;
            let x2 = (i as f64 * 0.11).cos() * 1e-4;
            let y = 3.0 - 0.5 * x1 + 1e4 * x2;
            acc1.push_row(&[1.0, x1, x2], &[y], 1.0).unwrap();
            let half = if i < 2500 { &mut acc2 } else { &mut acc3 };
            half.push_row(&[1.0, x1, x2], &[y], 2.0).unwrap();
        }
        acc2.merge(acc3).unwrap();
        for acc in [acc1, acc2] {
            assert_eq!(acc.rows(), 5000);
            let s = acc.finish().solve(&SolveOptions::default()).unwrap();
            let x = &s.coefficients[0];
            assert!((x[0] - 3.0).abs() < 1e-10, "{x:?}");
            assert!((x[1] + 0.5).abs() < 1e-12, "{x:?}");
            assert!((x[2] - 1e4).abs() < 1e-6, "{x:?}");
            assert!(s.rss[0] < 1e-18);
        }
    }

    #[test]
    fn weights_weigh() {
        // Two rows for a constant: y = 0 (w = 1) and y = 3 (w = 2): weighted mean 2.
        let mut acc = Accumulator::new(1, 1);
        acc.push_row(&[1.0], &[0.0], 1.0).unwrap();
        acc.push_row(&[1.0], &[3.0], 2.0).unwrap();
        let s = acc.finish().solve(&SolveOptions::default()).unwrap();
        assert!((s.coefficients[0][0] - 2.0).abs() < 1e-14);
        // RSS = 1·(0−2)² + 2·(3−2)² = 6.
        assert!((s.rss[0] - 6.0).abs() < 1e-12);
    }

    #[test]
    fn ridge_by_hand() {
        // One unit-norm column a = [1, 0]… scaled: a = [3, 4] (norm 5), b = [3, 4]: the OLS
        // x = 1. With λ on the unit-norm column γ = x·5: min (γ − 5)² + λγ² ⇒ γ = 5/(1 + λ);
        // λ = 1 ⇒ γ = 2.5, x = 0.5.
        let rows = vec![(vec![3.0], 3.0), (vec![4.0], 4.0)];
        let s = fit(
            &rows,
            &SolveOptions {
                ridge: 1.0,
                ..Default::default()
            },
        );
        assert!((s.coefficients[0][0] - 0.5).abs() < 1e-14);
        // Unpenalised: plain OLS.
        let s = fit(
            &rows,
            &SolveOptions {
                ridge: 1.0,
                unpenalized: vec![0],
                ..Default::default()
            },
        );
        assert!((s.coefficients[0][0] - 1.0).abs() < 1e-14);
    }

    #[test]
    fn rank_deficiency_names_the_culprits() {
        // x3 = x1 + x2 exactly; column 4 is all zero.
        let rows: Vec<_> = (0..50)
            .map(|i| {
                let x1 = (i as f64).sin();
                let x2 = (i as f64 * 0.7).cos();
                (vec![1.0, x1, x2, x1 + x2, 0.0], 2.0 * x1 + 1.0)
            })
            .collect();
        let s = fit(&rows, &SolveOptions::default());
        assert_eq!(s.rank, 3);
        let names: Vec<String> = ["c", "x1", "x2", "x3", "z"].map(String::from).into();
        let msgs: Vec<String> = s
            .rank_deficiencies
            .iter()
            .map(|d| d.describe(&names))
            .collect();
        assert!(
            msgs.iter().any(|m| m.contains("column z is all zero")),
            "{msgs:?}"
        );
        let dep = msgs
            .iter()
            .find(|m| m.contains("linearly dependent"))
            .unwrap();
        assert!(
            dep.contains("x1") && dep.contains("x2") && dep.contains("x3") && !dep.contains(" c,")
        );
        // Minimum-norm solution still predicts exactly: x1 + x2 + x3 combination gives 2·x1.
        assert!(s.rss[0] < 1e-20, "{}", s.rss[0]);
        assert!(s.condition.is_infinite());
    }

    #[test]
    fn bad_rows_are_errors() {
        let mut acc = Accumulator::new(2, 1);
        assert_eq!(
            acc.push_row(&[1.0, f64::NAN], &[0.0], 1.0),
            Err(SolveError::NonFinite { row: 0 })
        );
        assert!(acc.push_row(&[1.0], &[0.0], 1.0).is_err());
        assert!(acc.push_row(&[1.0, 0.0], &[0.0], -1.0).is_err());
        assert_eq!(
            acc.finish().solve(&SolveOptions::default()).unwrap_err(),
            SolveError::Empty
        );
    }

    #[test]
    fn from_matrix_matches_streaming() {
        let m = 20_000;
        let a = Mat::<f64>::from_fn(m, 4, |i, j| ((i * (j + 3)) as f64 * 0.001).sin() + j as f64);
        let b = Mat::<f64>::from_fn(m, 2, |i, j| (i as f64 * 0.01).cos() * (j + 1) as f64);
        let whole = Accumulator::from_matrix(a.as_ref(), b.as_ref(), None)
            .unwrap()
            .finish()
            .solve(&SolveOptions::default())
            .unwrap();
        let mut acc = Accumulator::new(4, 2);
        for i in 0..m {
            let row: Vec<f64> = (0..4).map(|j| a[(i, j)]).collect();
            acc.push_row(&row, &[b[(i, 0)], b[(i, 1)]], 1.0).unwrap();
        }
        let streamed = acc.finish().solve(&SolveOptions::default()).unwrap();
        for t in 0..2 {
            for j in 0..4 {
                let (x, y) = (whole.coefficients[t][j], streamed.coefficients[t][j]);
                assert!((x - y).abs() <= 1e-10 * x.abs().max(1.0), "{x} {y}");
            }
        }
    }
}
