//! The closed forms on the nominal chain and the error pre-correction: the three linear axes
//! of a 3-axis chain from its affine map, and for 3 linear + 2 rotary axes the two rotations
//! from the tool direction (Paden–Kahan subproblem 2; R. M. Murray, Z. Li, S. S. Sastry, "A
//! Mathematical Introduction to Robotic Manipulation", 1994, §3.3.2) with both branches, each
//! rotary angle at the turn nearest the previous set-point within travel, the pole (tool
//! direction along the outer axis) keeping the outer angle, then the linear axes from a 3×3
//! linear system.

#![allow(clippy::needless_range_loop)] // index-heavy small matrix maths reads clearer with indices

use truepos_model::{AxisKind, MAX_AXES};

use super::vec3::*;
use super::{directions_from, within_travel, TRAVEL_SLACK};
use crate::chain::{Chain, Directions, ErrRef, Geometry, Layout, Pose, Step};
use crate::description::KinAxis;
use crate::error::KinError;
use crate::forward::Tangents;
use crate::table::Location;
use crate::{sincos, DEG};

/// A 3-axis machine cannot turn the tool: a target direction further than this from the
/// nominal tool direction is refused (real tilts from angular errors are far smaller).
const THREE_AXIS_DIRECTION_SLACK: f64 = 1e-3;
/// Below this distance of the tool direction from a rotary axis (rad) the angle of that axis
/// is undetermined (the pole) and keeps its previous value.
const POLE: f64 = 1e-12;

/// The rotation angle about unit axis `u` that carries `from` onto `to` (both projected onto
/// the plane normal to `u`), or `None` if either projection is at the pole.
fn angle_about(u: &V3, from: &V3, to: &V3) -> Option<f64> {
    let f = sub(from, &scale(u, dot(u, from)));
    let t = sub(to, &scale(u, dot(u, to)));
    // Squared lengths against POLE²: the same test without two square roots.
    if dot(&f, &f) < POLE * POLE || dot(&t, &t) < POLE * POLE {
        return None;
    }
    Some(libm::atan2(dot(u, &cross(&f, &t)), dot(&f, &t)))
}

/// Structure of a 5-axis chain for the closed form.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct FiveAxis {
    pub(super) linear: [usize; 3],
    /// Rotary axes: [inner (nearer the tool), outer].
    pub(super) rotary: [usize; 2],
    pub(super) sign: [f64; 2],
    /// Tool direction in the frame just before the inner axis.
    pub(super) v: V3,
    /// Inner axis direction and tool direction, in the frame just before the outer axis.
    pub(super) u1: V3,
    /// Rotations between the inner and the outer axis.
    pub(super) g1: M3,
    /// Outer axis direction.
    pub(super) u2: V3,
    /// Rotations after the outer axis.
    pub(super) g2: M3,
    /// No table reads a linear axis and none has a reverse column: the real TCP is then
    /// affine in the linear axes at any rotary set-points, so the closed form can solve them
    /// on the real chain directly (see [`Chain::inverse`]).
    pub(super) real_linear: bool,
    /// Every linear axis row lies on the workpiece side of both rotary rows: the derivatives
    /// with respect to the rotary axes do not depend on the linear axes, so the derivatives
    /// found while solving the linear axes hold at the solution too.
    pub(super) linear_outside: bool,
    /// Every linear axis row lies on the tool side of every row that depends on a rotary axis
    /// (a trunnion table): moving the linear axes by a TCP displacement u changes the
    /// derivative with respect to rotary axis j by ω_j × u (ω_j: its angular velocity).
    pub(super) linear_inside: bool,
}

/// Finds the layout of a chain (see [`Layout`]).
pub(crate) fn analyse(axes: &[KinAxis], steps: &[Step]) -> Layout {
    let mut linear = [0usize; 3];
    let mut nl = 0;
    let mut rotary = [0usize; 2];
    let mut sign = [0.0; 2];
    let mut k_rot = [0usize; 2];
    let mut nr = 0;
    let mut m = I3;
    let mut gs = [I3; 3];
    let (mut real_linear, mut last_rotary, mut first_linear) = (true, 0, usize::MAX);
    // Last linear axis row, first row that depends on a rotary axis.
    let (mut last_linear, mut first_rotary_dependent) = (0, usize::MAX);
    for (i, step) in steps.iter().enumerate() {
        match *step {
            Step::ErrTranslate { e, .. } | Step::ErrRotate { e, .. } => {
                let axis = &axes[usize::from(e.axis)];
                if axis.kind != AxisKind::Rotary || e.forward != e.reverse {
                    real_linear = false;
                }
            }
            _ => {}
        }
        match *step {
            Step::AxisTranslate { .. } => {
                first_linear = first_linear.min(i);
                last_linear = i;
            }
            Step::AxisRotate { .. } => {
                last_rotary = i;
                first_rotary_dependent = first_rotary_dependent.min(i);
            }
            Step::ErrTranslate { .. } | Step::ErrRotate { .. } => {
                // With `real_linear` every table reads a rotary axis.
                first_rotary_dependent = first_rotary_dependent.min(i);
            }
            _ => {}
        }
        match *step {
            Step::Rotate { k, c, s } => rotate_m(&mut m, k, c, s),
            Step::ConstErrRotate {
                k,
                nominal_c,
                nominal_s,
                ..
            } => rotate_m(&mut m, k, nominal_c, nominal_s),
            Step::ErrRotate { k, e } => {
                let (s, c) = sincos(e.offset);
                rotate_m(&mut m, k, c, s);
            }
            Step::AxisTranslate { axis, .. } => {
                if nl < 3 {
                    linear[nl] = axis;
                }
                nl += 1;
            }
            Step::AxisRotate { k, axis, sign: sg } => {
                if nr < 2 {
                    rotary[nr] = axis;
                    sign[nr] = sg;
                    k_rot[nr] = k;
                    gs[nr] = m;
                }
                nr += 1;
                m = I3;
            }
            _ => {}
        }
    }
    debug_assert_eq!(nl + nr, axes.len());
    match (nl, nr) {
        (3, 0) => Layout::ThreeAxis {
            linear,
            affine: None,
        },
        (3, 2) => {
            gs[2] = m;
            let v = mul_mv(&gs[0], &[0.0, 0.0, 1.0]);
            let u1 = mul_mv(&gs[1], &unit(k_rot[0]));
            let u2 = unit(k_rot[1]);
            if norm(&cross(&u1, &u2)) < 1e-9 {
                return Layout::General;
            }
            Layout::FiveAxis(FiveAxis {
                linear,
                rotary,
                sign,
                v,
                u1,
                g1: gs[1],
                u2,
                g2: gs[2],
                real_linear,
                linear_outside: first_linear > last_rotary,
                linear_inside: last_linear < first_rotary_dependent,
            })
        }
        _ => Layout::General,
    }
}

/// The nominal chain of a 3-axis machine: p = A·q + b₀ + L·b_L (its fixed rotations do not
/// depend on the axes), with A⁻¹ kept so the closed form is one matrix product.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Affine {
    pub(super) inv: M3,
    pub(super) b0: V3,
    pub(super) per_tool_mm: V3,
    pub(super) direction: V3,
}

/// The affine map of a 3-axis chain's nominal geometry, from its exact derivatives at q = 0;
/// `None` if A is singular (the inverse then reports [`KinError::Singular`]).
pub(crate) fn affine(chain: &Chain, linear: &[usize; 3]) -> Option<Affine> {
    let n = chain.axes.len();
    let zero = [0.0; MAX_AXES];
    let mut t = Tangents::ZERO;
    let p0 = chain.eval::<true>(
        &zero[..n],
        0.0,
        Directions(0),
        Geometry::Nominal,
        Some(&mut t),
    );
    let p1 = chain.eval::<false>(&zero[..n], 1.0, Directions(0), Geometry::Nominal, None);
    let (c0, c1, c2) = (t.dp[linear[0]], t.dp[linear[1]], t.dp[linear[2]]);
    let det = dot(&c0, &cross(&c1, &c2));
    let bound = 1e-12 * norm(&c0) * norm(&c1) * norm(&c2);
    if det.is_nan() || libm::fabs(det) <= bound {
        return None;
    }
    // Rows of A⁻¹ are the cross products of A's columns over its determinant.
    let inv = [
        scale(&cross(&c1, &c2), 1.0 / det),
        scale(&cross(&c2, &c0), 1.0 / det),
        scale(&cross(&c0, &c1), 1.0 / det),
    ];
    Some(Affine {
        inv,
        b0: p0.position,
        per_tool_mm: sub(&p1.position, &p0.position),
        direction: p0.direction,
    })
}

/// The value of `q` + 360·m nearest `prev` inside travel, or `None`.
pub(super) fn nearest_turn(q: f64, prev: f64, axis: &KinAxis) -> Option<f64> {
    let m0 = libm::round((prev - q) / 360.0);
    let c0 = q + 360.0 * m0;
    // Less than half a turn away and within travel: every other turn is further (the common
    // case, decided without the search below).
    if libm::fabs(c0 - prev) < 180.0 && within_travel(axis, c0) {
        return Some(c0);
    }
    let mut best: Option<f64> = None;
    for dm in [-1.0, 0.0, 1.0, -2.0, 2.0] {
        let c = q + 360.0 * (m0 + dm);
        if c >= axis.travel_min - TRAVEL_SLACK && c <= axis.travel_max + TRAVEL_SLACK {
            let better = best.is_none_or(|b| libm::fabs(c - prev) < libm::fabs(b - prev));
            if better {
                best = Some(c);
            }
        }
    }
    best
}

impl Chain {
    /// Error pre-correction: solves the closed form again with every error rotation frozen at
    /// the current set-points (and the TCP on the erroneous chain).
    /// Near the pole the error tilts move the outer angle a lot and the plain
    /// iteration q ← F(q) converges slowly or swings around the solution. The
    /// steps s = F(q) − q are relaxed, q ← q + ω·s, with ω from the ratio t of
    /// successive steps (a secant estimate of the contraction ρ of F:
    /// ρ = 1 + (t − 1)/ω, and ω_next = 1/(1 − ρ) = ω/(1 − t)).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn refine_frozen(
        &self,
        fa: &FiveAxis,
        target: &Pose,
        tool_mm: f64,
        prev: &[f64; MAX_AXES],
        previous_dirs: Directions,
        fixed_dirs: Option<Directions>,
        q: &mut [f64; MAX_AXES],
    ) {
        let n = self.axes.len();
        let mut omega = 1.0_f64;
        let mut last = [0.0_f64; MAX_AXES];
        for round in 0..24 {
            let dirs = fixed_dirs.unwrap_or_else(|| directions_from(q, prev, previous_dirs, n));
            let frozen = self.frozen_rotations(fa, q, dirs);
            let mut q2 = *q;
            // The branch and turn nearest the current iterate, not the previous set-point: near
            // the pole both branches can be almost equally far from it, and switching between
            // them would stall the iteration.
            let current = *q;
            let mut scratch = Tangents::ZERO;
            if self
                .five_axis(
                    &frozen,
                    target,
                    tool_mm,
                    &current,
                    &mut q2,
                    Some(dirs),
                    &mut scratch,
                )
                .is_err()
            {
                break;
            }
            let mut step = [0.0_f64; MAX_AXES];
            let (mut cross_, mut last2, mut size) = (0.0, 0.0, 0.0_f64);
            for j in fa.rotary {
                step[j] = q2[j] - q[j];
                cross_ += step[j] * last[j];
                last2 += last[j] * last[j];
                size = size.max(libm::fabs(step[j]));
            }
            if round > 0 && last2 > 0.0 {
                let t = cross_ / last2;
                omega = (omega / (1.0 - t)).clamp(0.05, 10.0);
                if !omega.is_finite() {
                    omega = 1.0;
                }
            }
            for j in 0..n {
                q[j] += omega * (q2[j] - q[j]);
            }
            for j in 0..n {
                last[j] = omega * step[j];
            }
            if size < 1e-10 {
                break;
            }
        }
    }

    /// Closed form on the nominal chain, best branch into `q`.
    pub(super) fn closed_form(
        &self,
        layout: &Layout,
        target: &Pose,
        tool_mm: f64,
        prev: &[f64; MAX_AXES],
        q: &mut [f64; MAX_AXES],
    ) -> Result<(), KinError> {
        match layout {
            Layout::ThreeAxis {
                linear,
                affine: Some(af),
            } => {
                if norm(&sub(&af.direction, &target.direction)) > THREE_AXIS_DIRECTION_SLACK {
                    return Err(KinError::UnreachableDirection);
                }
                let rhs = sub(
                    &sub(&target.position, &af.b0),
                    &scale(&af.per_tool_mm, tool_mm),
                );
                let lin = mul_mv(&af.inv, &rhs);
                *q = *prev;
                for (c, &j) in linear.iter().enumerate() {
                    q[j] = lin[c];
                    if !within_travel(&self.axes[j], q[j]) {
                        return Err(KinError::OutsideTravel {
                            axis: j,
                            value: q[j],
                        });
                    }
                }
                Ok(())
            }
            Layout::ThreeAxis { linear, .. } => {
                let mut t = Tangents::ZERO;
                *q = *prev;
                let pose = self.eval::<true>(
                    &q[..self.axes.len()],
                    tool_mm,
                    Directions(0),
                    Geometry::Nominal,
                    Some(&mut t),
                );
                if norm(&sub(&pose.direction, &target.direction)) > THREE_AXIS_DIRECTION_SLACK {
                    return Err(KinError::UnreachableDirection);
                }
                self.solve_linear(linear, &pose, &t, target, q)
            }
            Layout::FiveAxis(fa) => {
                let mut t = Tangents::ZERO;
                self.five_axis(fa, target, tool_mm, prev, q, None, &mut t)
                    .map(|_| ())
            }
            Layout::General => Ok(()),
        }
    }

    /// Given the rotary set-points in `q`, moves the three linear axes so that the nominal TCP
    /// lands on the target: the TCP is affine in them, p = p(q) + J·Δ.
    fn solve_linear(
        &self,
        linear: &[usize; 3],
        pose: &Pose,
        t: &Tangents,
        target: &Pose,
        q: &mut [f64; MAX_AXES],
    ) -> Result<(), KinError> {
        // 3×3 system by Cramer's rule: columns are the TCP's derivatives along each axis.
        let col = |c: usize| -> V3 { t.dp[linear[c]] };
        let (c0, c1, c2) = (col(0), col(1), col(2));
        let rhs = sub(&target.position, &pose.position);
        let det = dot(&c0, &cross(&c1, &c2));
        let scale_ = norm(&c0) * norm(&c1) * norm(&c2);
        if libm::fabs(det) <= 1e-12 * scale_ || det.is_nan() {
            return Err(KinError::Singular);
        }
        let b = [
            dot(&rhs, &cross(&c1, &c2)) / det,
            dot(&c0, &cross(&rhs, &c2)) / det,
            dot(&c0, &cross(&c1, &rhs)) / det,
        ];
        for (c, &j) in linear.iter().enumerate() {
            q[j] += b[c];
        }
        for &j in linear {
            if !within_travel(&self.axes[j], q[j]) {
                return Err(KinError::OutsideTravel {
                    axis: j,
                    value: q[j],
                });
            }
        }
        Ok(())
    }

    /// The 5-axis closed form. With `actual` (travel directions), `fa` holds the rotations of
    /// the erroneous chain frozen at some set-points and the linear axes are solved on the
    /// erroneous chain (one Newton step; exact if the tables do not depend on them).
    ///
    /// Returns the pose at the solution as the (affine) linear axes predict it, with the
    /// derivatives found on the way in `t` (taken before the linear axes moved).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn five_axis(
        &self,
        fa: &FiveAxis,
        target: &Pose,
        tool_mm: f64,
        prev: &[f64; MAX_AXES],
        q: &mut [f64; MAX_AXES],
        actual: Option<Directions>,
        t: &mut Tangents,
    ) -> Result<Pose, KinError> {
        let n = self.axes.len();
        let (cands, mut failure) = self.rotary_branches(fa, target, prev)?;
        // The nearest branch whose linear axes stay within travel.
        let (geometry, dirs) = match actual {
            Some(d) => (Geometry::Actual, d),
            None => (Geometry::Nominal, Directions(0)),
        };
        // Derivatives valid at the solution for linear axes inside the rotary ones need the
        // angular velocities (see `FiveAxis::linear_inside`).
        let omega = actual.is_some() && fa.real_linear && fa.linear_inside;
        for &(cost, ref branch) in &cands {
            if !cost.is_finite() {
                continue;
            }
            let mut cand = *branch;
            let before = cand;
            let mut w = [[0.0; 3]; MAX_AXES];
            let mut pose = if omega {
                self.eval_with_angular_velocity(&cand[..n], tool_mm, dirs, t, &mut w)
            } else {
                self.eval::<true>(&cand[..n], tool_mm, dirs, geometry, Some(t))
            };
            match self.solve_linear(&fa.linear, &pose, t, target, &mut cand) {
                Ok(()) => {
                    moved_linear(fa, &before, &cand, &mut pose, t, omega.then_some(&w));
                    *q = cand;
                    return Ok(pose);
                }
                Err(e) => failure = e,
            }
        }
        Err(failure)
    }

    /// The rotary set-points of both branches of R(u2, φ2)·R(u1, φ1)·v' = w, each the nearest
    /// turn to `prev` within travel, with its distance from `prev` (infinite for a branch that
    /// failed), the nearest first; and the error of the last branch that failed. A direction
    /// neither branch reaches is an error.
    #[allow(clippy::type_complexity)]
    fn rotary_branches(
        &self,
        fa: &FiveAxis,
        target: &Pose,
        prev: &[f64; MAX_AXES],
    ) -> Result<([(f64, [f64; MAX_AXES]); 2], KinError), KinError> {
        // R(u2, φ2)·R(u1, φ1)·v' = w, with v' = G1·v and w = G2ᵀ·d.
        let vp = mul_mv(&fa.g1, &fa.v);
        let w = mul_tv(&fa.g2, &target.direction);
        let (u1, u2) = (&fa.u1, &fa.u2);
        // c = α·u1 + β·u2 + γ·(u1 × u2) with u1·c = u1·v', u2·c = u2·w, |c| = 1.
        let k = dot(u1, u2);
        let (a, b) = (dot(u1, &vp), dot(u2, &w));
        let den = 1.0 - k * k;
        let alpha = (a - k * b) / den;
        let beta = (b - k * a) / den;
        let g2 = (1.0 - alpha * alpha - beta * beta - 2.0 * alpha * beta * k) / den;
        if g2 < -1e-10 {
            return Err(KinError::UnreachableDirection);
        }
        let gamma = libm::sqrt(g2.max(0.0));
        let nrm = cross(u1, u2);
        let mut failure = KinError::UnreachableDirection;
        // The rotary set-points of both branches, with their distance from the previous ones.
        let mut cands: [(f64, [f64; MAX_AXES]); 2] = [(f64::INFINITY, *prev); 2];
        let branches: &[f64] = if gamma == 0.0 { &[1.0] } else { &[1.0, -1.0] };
        for (b, &sg) in branches.iter().enumerate() {
            let mut c = [0.0; 3];
            for i in 0..3 {
                c[i] = alpha * u1[i] + beta * u2[i] + sg * gamma * nrm[i];
            }
            let mut cand = *prev;
            let [r1, r2] = fa.rotary;
            // Angles in rad; the pole keeps the previous set-point.
            let phi1 = angle_about(u1, &vp, &c);
            let phi2 = angle_about(u2, &c, &w);
            let mut ok = true;
            let mut cost = 0.0;
            for (idx, (axis, phi)) in [(r1, phi1), (r2, phi2)].into_iter().enumerate() {
                let Some(phi) = phi else {
                    continue;
                };
                let raw = phi / DEG * fa.sign[idx];
                match nearest_turn(raw, prev[axis], &self.axes[axis]) {
                    Some(v) => {
                        cand[axis] = v;
                        cost += libm::fabs(v - prev[axis]);
                    }
                    None => {
                        failure = KinError::OutsideTravel { axis, value: raw };
                        ok = false;
                    }
                }
            }
            if ok {
                cands[b] = (cost, cand);
            }
        }
        if cands[1].0 < cands[0].0 {
            cands.swap(0, 1);
        }
        Ok((cands, failure))
    }

    /// The rotation structure of the erroneous chain with every error rotation read from its
    /// table at `q` (see [`FiveAxis`]).
    pub(super) fn frozen_rotations(
        &self,
        fa: &FiveAxis,
        q: &[f64; MAX_AXES],
        dirs: Directions,
    ) -> FiveAxis {
        let mut m = I3;
        let mut gs = [I3; 3];
        let mut k_rot = [0usize; 2];
        let mut nr = 0;
        let n = self.axes.len();
        let mut at = Location::default();
        for step in &self.steps {
            match *step {
                Step::Rotate { k, c, s } | Step::ConstErrRotate { k, c, s, .. } => {
                    rotate_m(&mut m, k, c, s)
                }
                Step::ErrRotate { k, e } => {
                    // Translation rows are skipped here, so every row locates its position.
                    let e = ErrRef {
                        relocate: true,
                        ..e
                    };
                    let (angle, _) = self.error_value::<false>(&e, &mut at, &q[..n], dirs);
                    let (s, c) = sincos(angle);
                    rotate_m(&mut m, k, c, s);
                }
                Step::AxisRotate { k, .. } => {
                    if nr < 2 {
                        k_rot[nr] = k;
                        gs[nr] = m;
                    }
                    nr += 1;
                    m = I3;
                }
                _ => {}
            }
        }
        gs[2] = m;
        FiveAxis {
            linear: fa.linear,
            rotary: fa.rotary,
            sign: fa.sign,
            v: mul_mv(&gs[0], &[0.0, 0.0, 1.0]),
            u1: mul_mv(&gs[1], &unit(k_rot[0])),
            g1: gs[1],
            u2: unit(k_rot[1]),
            g2: gs[2],
            real_linear: fa.real_linear,
            linear_outside: fa.linear_outside,
            linear_inside: fa.linear_inside,
        }
    }
}

/// The pose and the derivatives after the linear axes moved from `before` to `cand`: the TCP
/// is affine in the linear axes, so it moved by u = Σ ∂p/∂q_j · Δq_j; with the angular
/// velocities `w` (linear axes inside the rotary ones) the rotary axes' derivatives turn that
/// displacement too.
fn moved_linear(
    fa: &FiveAxis,
    before: &[f64; MAX_AXES],
    cand: &[f64; MAX_AXES],
    pose: &mut Pose,
    t: &mut Tangents,
    w: Option<&[[f64; 3]; MAX_AXES]>,
) {
    let mut u = [0.0; 3];
    for &j in &fa.linear {
        let dq = cand[j] - before[j];
        for i in 0..3 {
            u[i] += t.dp[j][i] * dq;
        }
    }
    for i in 0..3 {
        pose.position[i] += u[i];
    }
    if let Some(w) = w {
        for j in fa.rotary {
            let turn = cross(&w[j], &u);
            for i in 0..3 {
                t.dp[j][i] += turn[i];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn subproblem_two_recovers_known_angles() {
        // Tool along Z, inner axis A (X), outer C (Z). A = 30°, C = 45° give
        // d = R_z(45°)·R_x(30°)·e_z = R_z(45°)·(0, −sin30, cos30) = (sin45·sin30, −cos45·sin30, cos30)
        //   = (0.353553, −0.353553, 0.866025).
        let v = [0.0, 0.0, 1.0];
        let u1 = unit(0);
        let u2 = unit(2);
        let d = [
            0.353_553_390_593_273_8,
            -0.353_553_390_593_273_8,
            0.866_025_403_784_438_6,
        ];
        let k = dot(&u1, &u2);
        let (a, b) = (dot(&u1, &v), dot(&u2, &d));
        let alpha = (a - k * b) / (1.0 - k * k);
        let beta = (b - k * a) / (1.0 - k * k);
        let g = libm::sqrt(1.0 - alpha * alpha - beta * beta);
        let n = cross(&u1, &u2);
        let mut found = false;
        for sg in [1.0, -1.0] {
            let c: V3 = core::array::from_fn(|i| alpha * u1[i] + beta * u2[i] + sg * g * n[i]);
            let p1 = angle_about(&u1, &v, &c).unwrap() / DEG;
            let p2 = angle_about(&u2, &c, &d).unwrap() / DEG;
            if (p1 - 30.0).abs() < 1e-9 && (p2 - 45.0).abs() < 1e-9 {
                found = true;
            }
            // The other branch: A = −30°, C = 45° + 180° = −135°.
            if (p1 + 30.0).abs() < 1e-9 && (p2 + 135.0).abs() < 1e-9 {
                found = true;
            }
        }
        assert!(found);
    }

    #[test]
    fn nearest_turn_respects_travel() {
        let c = KinAxis {
            name: "C".into(),
            kind: AxisKind::Rotary,
            travel_min: -720.0,
            travel_max: 720.0,
        };
        assert_eq!(nearest_turn(10.0, 365.0, &c), Some(370.0));
        assert_eq!(nearest_turn(-170.0, 170.0, &c), Some(190.0));
        let a = KinAxis {
            travel_min: -100.0,
            travel_max: 100.0,
            ..c
        };
        assert_eq!(nearest_turn(150.0, 0.0, &a), None);
        assert_eq!(nearest_turn(-170.0, 90.0, &a), None);
    }
}
