//! The correction through the error tables, from the closed form's nominal solution (or the
//! previous set-point): chord iterations on one factorised Jacobian, then (rarely) Gauss–Newton
//! with Levenberg–Marquardt damping and the exact Jacobian of the erroneous chain.

#![allow(clippy::needless_range_loop)] // index-heavy small matrix maths reads clearer with indices

use truepos_model::MAX_AXES;

use super::closed_form::Affine;
use super::vec3::*;
use super::{DIRECTION_TOLERANCE_RAD, POSITION_TOLERANCE_MM};
use crate::chain::{Chain, Directions, Geometry, Pose};
use crate::error::KinError;
use crate::forward::Tangents;

/// Weight (mm) of a tool direction deviation against a TCP deviation in the least squares.
const DIRECTION_WEIGHT_MM: f64 = 100.0;
/// Newton steps of the fast path (away from the pole, from the nominal solution).
pub(super) const FAST_NEWTON_ITERATIONS: u32 = 6;

impl Chain {
    /// Newton then chord iterations of a 3-axis machine. The first transform, at the nominal
    /// solution, carries the exact TCP derivatives (through the tables' slopes and the error
    /// rotations): the tables change the real Jacobian by about their relative slopes (1e-4),
    /// so the nominal A⁻¹ would leave ~1e-4 of the residual (5 nm of 50 µm) and need a second
    /// step and a third transform, while the exact one leaves only second-order terms and
    /// one transform without derivatives confirms convergence. Later steps (rare) reuse that
    /// inverse (A⁻¹ if it is singular). The tool direction cannot be commanded and is only
    /// reported. Ends with [`KinError::NotConverged`] (`q` at the best point) if a step does
    /// not reduce the residual.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub(super) fn chord_affine(
        &self,
        af: &Affine,
        linear: &[usize; 3],
        target: &Pose,
        tool_mm: f64,
        dirs: Directions,
        q: &mut [f64; MAX_AXES],
    ) -> Result<(u32, f64, f64), KinError> {
        const CHORD_STEPS: u32 = 6;
        let n = self.axes.len();
        // The tool direction's residual (only reported: three linear axes cannot turn the
        // tool); the first transform leaves the direction out, so it is found on demand.
        let direction_residual = |q: &[f64; MAX_AXES], d: Option<V3>| -> f64 {
            let d = d.unwrap_or_else(|| {
                self.eval::<false>(&q[..n], tool_mm, dirs, Geometry::Actual, None)
                    .direction
            });
            norm(&sub(&d, &target.direction))
        };
        let mut best: ([f64; MAX_AXES], f64, Option<V3>) = (*q, f64::INFINITY, None);
        let mut inv = af.inv;
        for iterations in 0..=CHORD_STEPS {
            let first = if iterations == 0 {
                self.eval_position_jacobian3(&q[..n], tool_mm, dirs)
            } else {
                None
            };
            let (position, direction) = if let Some((position, dp)) = first {
                if let Some(i) = inverse3(&dp[linear[0]], &dp[linear[1]], &dp[linear[2]]) {
                    inv = i;
                }
                (position, None)
            } else {
                let pose = self.eval::<false>(&q[..n], tool_mm, dirs, Geometry::Actual, None);
                (pose.position, Some(pose.direction))
            };
            let rp = sub(&position, &target.position);
            let np = norm(&rp);
            if !np.is_finite() || direction.is_some_and(|d| !d.iter().all(|v| v.is_finite())) {
                return Err(KinError::NonFinite);
            }
            if np <= POSITION_TOLERANCE_MM {
                let nd = direction_residual(q, direction);
                if !nd.is_finite() {
                    return Err(KinError::NonFinite);
                }
                return Ok((iterations, np, nd));
            }
            if np >= best.1 {
                break;
            }
            best = (*q, np, direction);
            if iterations == CHORD_STEPS {
                break;
            }
            let step = mul_mv(&inv, &rp);
            for (c, &j) in linear.iter().enumerate() {
                q[j] -= step[c];
            }
        }
        *q = best.0;
        Err(KinError::NotConverged {
            position_mm: best.1,
            direction_rad: direction_residual(q, best.2),
        })
    }

    /// Chord iterations through the erroneous chain: the exact Jacobian at the start (the
    /// nominal solution), factorised once and reused. The errors are µm and µrad small, so
    /// the Jacobian barely changes over the correction: the first step is a full Newton step
    /// and each further one shrinks the residual by about the tables' relative slopes (1e-4),
    /// at the price of a forward transform without derivatives. `q` holds the last accepted
    /// set-points; a step that does not reduce the residual ends with
    /// [`KinError::NotConverged`] and the caller continues with [`Chain::newton`].
    ///
    /// `start`: the pose at `q` as predicted by the closed form, with the exact derivatives
    /// there, instead of a transform with derivatives here; a prediction that already meets
    /// the tolerances is confirmed by a transform before it counts.
    #[inline]
    pub(super) fn chord(
        &self,
        target: &Pose,
        tool_mm: f64,
        dirs: Directions,
        use_direction: bool,
        q: &mut [f64; MAX_AXES],
        start: Option<(&Pose, &Tangents)>,
    ) -> Result<(u32, f64, f64), KinError> {
        const CHORD_STEPS: u32 = 4;
        let n = self.axes.len();
        let w = if use_direction {
            DIRECTION_WEIGHT_MM
        } else {
            0.0
        };
        let residual = |pose: &Pose| -> ([f64; 6], f64, f64) {
            let rp = sub(&pose.position, &target.position);
            let rd = sub(&pose.direction, &target.direction);
            (
                [rp[0], rp[1], rp[2], w * rd[0], w * rd[1], w * rd[2]],
                norm(&rp),
                norm(&rd),
            )
        };
        let converged = |np: f64, nd: f64| {
            np <= POSITION_TOLERANCE_MM && (!use_direction || nd <= DIRECTION_TOLERANCE_RAD)
        };
        // Zeroed only when needed: a start brings its own derivatives.
        let mut own: Option<Tangents> = None;
        let (pose, t) = match start {
            Some((pose, t)) => (*pose, t),
            None => {
                let own = own.insert(Tangents::ZERO);
                let pose = self.eval::<true>(&q[..n], tool_mm, dirs, Geometry::Actual, Some(own));
                (pose, &*own)
            }
        };
        let (mut r, mut np, mut nd) = residual(&pose);
        if !(np.is_finite() && nd.is_finite()) {
            return Err(KinError::NonFinite);
        }
        if converged(np, nd) {
            if start.is_none() {
                return Ok((0, np, nd));
            }
            let measured = self.eval::<false>(&q[..n], tool_mm, dirs, Geometry::Actual, None);
            (r, np, nd) = residual(&measured);
            if converged(np, nd) {
                return Ok((0, np, nd));
            }
        }
        let mut jac = [[0.0; 6]; MAX_AXES];
        let mut colscale = [1.0; MAX_AXES];
        weighted_jacobian_into(t, n, w, &mut jac, &mut colscale);
        let not_converged = |np, nd| KinError::NotConverged {
            position_mm: np,
            direction_rad: nd,
        };
        let mut factor = Normal::EMPTY;
        if !factor.factor(&jac, &colscale, n, 1e-14) {
            return Err(not_converged(np, nd));
        }
        let cost = |r: &[f64; 6]| r.iter().map(|v| v * v).sum::<f64>();
        for iterations in 1..=CHORD_STEPS {
            let Some(step) = factor.solve(&jac, &r) else {
                break;
            };
            let mut trial = *q;
            for j in 0..n {
                trial[j] += step[j] * self.per_unit(j);
            }
            let p2 = self.eval::<false>(&trial[..n], tool_mm, dirs, Geometry::Actual, None);
            let (r2, np2, nd2) = residual(&p2);
            let (c2, c1) = (cost(&r2), cost(&r));
            if c2.is_nan() || c2 >= c1 {
                break;
            }
            *q = trial;
            (r, np, nd) = (r2, np2, nd2);
            if converged(np, nd) {
                return Ok((iterations, np, nd));
            }
        }
        Err(not_converged(np, nd))
    }

    /// Gauss–Newton with Levenberg–Marquardt damping through the chain (exact Jacobian).
    /// Returns (iterations, TCP residual mm, direction residual rad).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn newton(
        &self,
        target: &Pose,
        tool_mm: f64,
        dirs: Directions,
        geometry: Geometry,
        use_direction: bool,
        max_iter: u32,
        q: &mut [f64; MAX_AXES],
    ) -> Result<(u32, f64, f64), KinError> {
        let n = self.axes.len();
        let residual = |pose: &Pose| -> ([f64; 6], f64, f64) {
            let rp = sub(&pose.position, &target.position);
            let rd = sub(&pose.direction, &target.direction);
            let w = if use_direction {
                DIRECTION_WEIGHT_MM
            } else {
                0.0
            };
            (
                [rp[0], rp[1], rp[2], w * rd[0], w * rd[1], w * rd[2]],
                norm(&rp),
                norm(&rd),
            )
        };
        let cost = |r: &[f64; 6]| r.iter().map(|v| v * v).sum::<f64>();
        let mut t = Tangents::ZERO;
        let pose = self.eval::<true>(&q[..n], tool_mm, dirs, geometry, Some(&mut t));
        let (mut r, mut np, mut nd) = residual(&pose);
        let mut mu = 0.0_f64;
        let mut iterations = 0;
        loop {
            if !(np.is_finite() && nd.is_finite()) {
                return Err(KinError::NonFinite);
            }
            if np <= POSITION_TOLERANCE_MM && (!use_direction || nd <= DIRECTION_TOLERANCE_RAD) {
                return Ok((iterations, np, nd));
            }
            if iterations >= max_iter {
                return Err(KinError::NotConverged {
                    position_mm: np,
                    direction_rad: nd,
                });
            }
            iterations += 1;
            // Weighted Jacobian (6 × n); the least-squares step comes from a QR factorisation
            // of [J·S; √μ·I] with S scaling every column to unit length (normal equations
            // would square the condition number, which near the pole reaches 1e5 and more).
            let w = if use_direction {
                DIRECTION_WEIGHT_MM
            } else {
                0.0
            };
            let (jac, colscale) = weighted_jacobian(&t, n, w);
            let mut accepted = false;
            for _ in 0..12 {
                // Away from the pole the scaled normal equations (Cholesky) are accurate enough
                // and several times cheaper than QR.
                let step = if max_iter <= FAST_NEWTON_ITERATIONS {
                    normal_step(&jac, &colscale, &r, n, mu.max(1e-14))
                } else {
                    damped_step(&jac, &colscale, &r, n, mu.max(1e-20))
                };
                let Some(step) = step else {
                    mu = (mu * 10.0).max(1e-9);
                    continue;
                };
                let mut trial = *q;
                for j in 0..n {
                    trial[j] += step[j] * self.per_unit(j);
                }
                let mut t2 = Tangents::ZERO;
                let p2 = self.eval::<true>(&trial[..n], tool_mm, dirs, geometry, Some(&mut t2));
                let (r2, np2, nd2) = residual(&p2);
                if cost(&r2) < cost(&r) || cost(&r2) == 0.0 {
                    *q = trial;
                    t = t2;
                    (r, np, nd) = (r2, np2, nd2);
                    mu *= 0.1;
                    if mu < 1e-12 {
                        mu = 0.0;
                    }
                    accepted = true;
                    break;
                }
                mu = (mu * 10.0).max(1e-6);
            }
            if !accepted {
                return Err(KinError::NotConverged {
                    position_mm: np,
                    direction_rad: nd,
                });
            }
        }
    }
}

/// The Jacobian with the direction rows weighted by `w` (6 × n, one array per axis) and the
/// factors that scale each column to unit length (`n` a constant for common counts, as in
/// [`Normal::factor`]).
fn weighted_jacobian(t: &Tangents, n: usize, w: f64) -> ([[f64; 6]; MAX_AXES], [f64; MAX_AXES]) {
    let mut jac = [[0.0; 6]; MAX_AXES];
    let mut colscale = [1.0; MAX_AXES];
    weighted_jacobian_into(t, n, w, &mut jac, &mut colscale);
    (jac, colscale)
}

/// [`weighted_jacobian`] written into the caller's arrays (columns from `n` on untouched), so
/// the chord loop does not copy them per iteration.
fn weighted_jacobian_into(
    t: &Tangents,
    n: usize,
    w: f64,
    jac: &mut [[f64; 6]; MAX_AXES],
    colscale: &mut [f64; MAX_AXES],
) {
    match n {
        5 => weighted_jacobian_n(t, 5, w, jac, colscale),
        3 => weighted_jacobian_n(t, 3, w, jac, colscale),
        _ => weighted_jacobian_n(t, n, w, jac, colscale),
    }
}

#[inline(always)]
fn weighted_jacobian_n(
    t: &Tangents,
    n: usize,
    w: f64,
    jac: &mut [[f64; 6]; MAX_AXES],
    colscale: &mut [f64; MAX_AXES],
) {
    for j in 0..n {
        for i in 0..3 {
            jac[j][i] = t.dp[j][i];
            jac[j][i + 3] = w * t.dd[j][i];
        }
        let l = libm::sqrt(jac[j].iter().map(|v| v * v).sum::<f64>());
        colscale[j] = if l > 0.0 { 1.0 / l } else { 1.0 };
    }
}

/// The Cholesky factor of the scaled normal equations SᵀJᵀJS + μI = L·Lᵀ, kept to solve for
/// several right-hand sides with one Jacobian (chord iterations).
struct Normal {
    l: [[f64; MAX_AXES]; MAX_AXES],
    colscale: [f64; MAX_AXES],
    n: usize,
}

impl Normal {
    /// Room for a factor (see [`Normal::factor`]); all zeros, so it is set by a `memset`
    /// rather than copied from a constant.
    const EMPTY: Self = Self {
        l: [[0.0; MAX_AXES]; MAX_AXES],
        colscale: [0.0; MAX_AXES],
        n: 0,
    };

    /// Factorises into `self` (in place, so the factor is not copied on return); `false` if
    /// the matrix is not positive definite. The
    /// common axis counts get their own copy with `n` a constant, so the small loops unroll
    /// and lose their bounds checks (this runs once per inverse transform).
    fn factor(
        &mut self,
        jac: &[[f64; 6]; MAX_AXES],
        colscale: &[f64; MAX_AXES],
        n: usize,
        mu: f64,
    ) -> bool {
        match n {
            5 => self.factor_n(jac, colscale, 5, mu),
            3 => self.factor_n(jac, colscale, 3, mu),
            _ => self.factor_n(jac, colscale, n, mu),
        }
    }

    /// Reads and writes only the lower triangle of the first `n` rows and columns.
    #[inline(always)]
    fn factor_n(
        &mut self,
        jac: &[[f64; 6]; MAX_AXES],
        colscale: &[f64; MAX_AXES],
        n: usize,
        mu: f64,
    ) -> bool {
        self.colscale = *colscale;
        self.n = n;
        let a = &mut self.l;
        for i in 0..n {
            for j in 0..=i {
                let mut s = 0.0;
                for k in 0..6 {
                    s += jac[i][k] * jac[j][k];
                }
                a[i][j] = s * colscale[i] * colscale[j];
            }
            a[i][i] += mu;
        }
        for j in 0..n {
            let mut d = a[j][j];
            for k in 0..j {
                d -= a[j][k] * a[j][k];
            }
            if d <= 0.0 || d.is_nan() {
                return false;
            }
            let d = libm::sqrt(d);
            a[j][j] = d;
            for i in j + 1..n {
                let mut s = a[i][j];
                for k in 0..j {
                    s -= a[i][k] * a[j][k];
                }
                a[i][j] = s / d;
            }
        }
        true
    }

    /// The least-squares step Δ = −S·(L·Lᵀ)⁻¹·SᵀJᵀr from the factor; `None` if not finite
    /// (`n` a constant for common counts, as in [`Normal::factor`]).
    fn solve(&self, jac: &[[f64; 6]; MAX_AXES], r: &[f64; 6]) -> Option<[f64; MAX_AXES]> {
        match self.n {
            5 => self.solve_n(jac, r, 5),
            3 => self.solve_n(jac, r, 3),
            n => self.solve_n(jac, r, n),
        }
    }

    #[inline(always)]
    fn solve_n(
        &self,
        jac: &[[f64; 6]; MAX_AXES],
        r: &[f64; 6],
        n: usize,
    ) -> Option<[f64; MAX_AXES]> {
        let a = &self.l;
        let mut b = [0.0; MAX_AXES];
        for i in 0..n {
            let mut s = 0.0;
            for k in 0..6 {
                s += jac[i][k] * r[k];
            }
            b[i] = -s * self.colscale[i];
        }
        for i in 0..n {
            let mut s = b[i];
            for k in 0..i {
                s -= a[i][k] * b[k];
            }
            b[i] = s / a[i][i];
        }
        for i in (0..n).rev() {
            let mut s = b[i];
            for k in i + 1..n {
                s -= a[k][i] * b[k];
            }
            b[i] = s / a[i][i];
        }
        for j in 0..n {
            b[j] *= self.colscale[j];
        }
        b[..n].iter().all(|v| v.is_finite()).then_some(b)
    }
}

/// The same step as [`damped_step`] from the normal equations (SᵀJᵀJS + μI)·y = −SᵀJᵀr, Δ = S·y,
/// by Cholesky factorisation; `None` if the matrix is not positive definite.
fn normal_step(
    jac: &[[f64; 6]; MAX_AXES],
    colscale: &[f64; MAX_AXES],
    r: &[f64; 6],
    n: usize,
    mu: f64,
) -> Option<[f64; MAX_AXES]> {
    let mut factor = Normal::EMPTY;
    if !factor.factor(jac, colscale, n, mu) {
        return None;
    }
    factor.solve(jac, r)
}

/// The step Δ minimising |J·Δ + r|² + μ·|S⁻¹Δ|² (S: column scaling), by Householder QR of the
/// (6 + n) × n matrix [J·S; √μ·I].
fn damped_step(
    jac: &[[f64; 6]; MAX_AXES],
    colscale: &[f64; MAX_AXES],
    r: &[f64; 6],
    n: usize,
    mu: f64,
) -> Option<[f64; MAX_AXES]> {
    const M: usize = 6 + MAX_AXES;
    let m = 6 + n;
    let mut a = [[0.0; MAX_AXES]; M];
    let mut b = [0.0; M];
    let sq = libm::sqrt(mu);
    for j in 0..n {
        for i in 0..6 {
            a[i][j] = jac[j][i] * colscale[j];
        }
        a[6 + j][j] = sq;
    }
    for i in 0..6 {
        b[i] = -r[i];
    }
    for k in 0..n {
        let mut norm2 = 0.0;
        for row in a.iter().take(m).skip(k) {
            norm2 += row[k] * row[k];
        }
        let norm = libm::sqrt(norm2);
        if norm == 0.0 {
            continue;
        }
        let alpha = if a[k][k] > 0.0 { -norm } else { norm };
        // v = x − α·e_1, stored in place; vᵀv = 2·(norm² − α·x_0).
        let vtv = 2.0 * (norm2 - alpha * a[k][k]);
        a[k][k] -= alpha;
        if vtv > 0.0 {
            for c in k + 1..n {
                let mut d = 0.0;
                for row in a.iter().take(m).skip(k) {
                    d += row[k] * row[c];
                }
                let f = 2.0 * d / vtv;
                for row in a.iter_mut().take(m).skip(k) {
                    row[c] -= f * row[k];
                }
            }
            let mut d = 0.0;
            for i in k..m {
                d += a[i][k] * b[i];
            }
            let f = 2.0 * d / vtv;
            for i in k..m {
                b[i] -= f * a[i][k];
            }
        }
        a[k][k] = alpha;
    }
    let mut x = [0.0; MAX_AXES];
    for k in (0..n).rev() {
        let mut s = b[k];
        for c in k + 1..n {
            s -= a[k][c] * x[c];
        }
        if a[k][k] == 0.0 {
            return None;
        }
        x[k] = s / a[k][k];
    }
    for j in 0..n {
        x[j] *= colscale[j];
    }
    x[..n].iter().all(|v| v.is_finite()).then_some(x)
}
