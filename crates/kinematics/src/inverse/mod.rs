//! Inverse transform: TCP and tool direction in workpiece coordinates → axis set-points.
//!
//! 1. **Closed form on the nominal chain** (3 linear + 2 rotary axes, any fixed rotations
//!    between them): the two rotations follow from the tool direction alone (Paden–Kahan
//!    subproblem 2: two successive rotations about non-parallel axes that carry one unit vector
//!    onto another; R. M. Murray, Z. Li, S. S. Sastry, "A Mathematical Introduction to Robotic
//!    Manipulation", 1994, §3.3.2). Both branches are formed, each rotary angle is taken at the
//!    multiple of 360° nearest the previous set-point within travel, the three linear axes
//!    follow from a 3×3 linear system, and the branch nearest the previous set-point wins. At
//!    the pole (tool direction along the outer rotary axis) the outer angle is undetermined
//!    and keeps its previous value: no jump, no NaN.
//! 2. **Error pre-correction**: the error the tables add at that solution is subtracted from
//!    the target and the closed form is solved again (removes the errors to first order; also
//!    handles poses near the pole where the errors move the outer angle a lot).
//! 3. **Newton** (Gauss–Newton with Levenberg–Marquardt damping) through the full erroneous
//!    chain with its exact Jacobian, until the real TCP is within [`POSITION_TOLERANCE_MM`] and
//!    the real tool direction within [`DIRECTION_TOLERANCE_RAD`] of the target.
//!
//! Chains of another shape start Newton (damped least squares) from the previous set-point.

#![allow(clippy::needless_range_loop)] // index-heavy small matrix maths reads clearer with indices

use truepos_model::{AxisKind, MAX_AXES};

use crate::chain::{Chain, Directions, ErrRef, Geometry, Layout, Pose, Step};
use crate::description::KinAxis;
use crate::error::KinError;
use crate::forward::Tangents;
use crate::{sincos, DEG};

/// The inverse transform stops when the TCP is this close to the target (0.5 nm, half the
/// 1 nm the issue asks for).
pub const POSITION_TOLERANCE_MM: f64 = 5e-7;
/// … and the tool direction this close (0.5 µrad, half of 1 µrad).
pub const DIRECTION_TOLERANCE_RAD: f64 = 5e-7;
/// A 3-axis machine cannot turn the tool: a target direction further than this from the
/// nominal tool direction is refused (real tilts from angular errors are far smaller).
const THREE_AXIS_DIRECTION_SLACK: f64 = 1e-3;
/// Weight (mm) of a tool direction deviation against a TCP deviation in the least squares.
const DIRECTION_WEIGHT_MM: f64 = 100.0;
/// Below this distance of the tool direction from a rotary axis (rad) the angle of that axis
/// is undetermined (the pole) and keeps its previous value.
const POLE: f64 = 1e-12;
/// Newton steps of the fast path (away from the pole, from the nominal solution).
const FAST_NEWTON_ITERATIONS: u32 = 6;
/// A set-point this far beyond the end of travel is still accepted (rounding).
const TRAVEL_SLACK: f64 = 1e-9;

type M3 = [[f64; 3]; 3];
type V3 = [f64; 3];

const I3: M3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

fn mul_mv(m: &M3, v: &V3) -> V3 {
    [
        m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
        m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
        m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2],
    ]
}

fn mul_tv(m: &M3, v: &V3) -> V3 {
    [
        m[0][0] * v[0] + m[1][0] * v[1] + m[2][0] * v[2],
        m[0][1] * v[0] + m[1][1] * v[1] + m[2][1] * v[2],
        m[0][2] * v[0] + m[1][2] * v[1] + m[2][2] * v[2],
    ]
}

fn dot(a: &V3, b: &V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: &V3, b: &V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn norm(a: &V3) -> f64 {
    libm::sqrt(dot(a, a))
}

fn unit(k: usize) -> V3 {
    let mut e = [0.0; 3];
    e[k] = 1.0;
    e
}

/// R_k(c, s)·M.
fn rotate_m(m: &mut M3, k: usize, c: f64, s: f64) {
    let (i, j) = ((k + 1) % 3, (k + 2) % 3);
    for col in 0..3 {
        let (a, b) = (m[i][col], m[j][col]);
        m[i][col] = c * a - s * b;
        m[j][col] = s * a + c * b;
    }
}

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

fn sub(a: &V3, b: &V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn scale(a: &V3, s: f64) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}

/// Structure of a 5-axis chain for the closed form.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct FiveAxis {
    linear: [usize; 3],
    /// Rotary axes: [inner (nearer the tool), outer].
    rotary: [usize; 2],
    sign: [f64; 2],
    /// Tool direction in the frame just before the inner axis.
    v: V3,
    /// Inner axis direction and tool direction, in the frame just before the outer axis.
    u1: V3,
    /// Rotations between the inner and the outer axis.
    g1: M3,
    /// Outer axis direction.
    u2: V3,
    /// Rotations after the outer axis.
    g2: M3,
    /// No table reads a linear axis and none has a reverse column: the real TCP is then
    /// affine in the linear axes at any rotary set-points, so the closed form can solve them
    /// on the real chain directly (see [`Chain::inverse`]).
    real_linear: bool,
    /// Every linear axis row lies on the workpiece side of both rotary rows: the derivatives
    /// with respect to the rotary axes do not depend on the linear axes, so the derivatives
    /// found while solving the linear axes hold at the solution too.
    linear_outside: bool,
    /// Every linear axis row lies on the tool side of every row that depends on a rotary axis
    /// (a trunnion table): moving the linear axes by a TCP displacement u changes the
    /// derivative with respect to rotary axis j by ω_j × u (ω_j: its angular velocity).
    linear_inside: bool,
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
    inv: M3,
    b0: V3,
    per_tool_mm: V3,
    direction: V3,
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

/// The inverse of the 3×3 matrix with columns c0, c1, c2 (rows: cross products of the
/// columns over the determinant), or `None` if it is singular.
fn inverse3(c0: &V3, c1: &V3, c2: &V3) -> Option<M3> {
    let det = dot(c0, &cross(c1, c2));
    let bound = 1e-12 * norm(c0) * norm(c1) * norm(c2);
    if det.is_nan() || libm::fabs(det) <= bound {
        return None;
    }
    Some([
        scale(&cross(c1, c2), 1.0 / det),
        scale(&cross(c2, c0), 1.0 / det),
        scale(&cross(c0, c1), 1.0 / det),
    ])
}

/// What one inverse transform did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InverseReport {
    /// Newton iterations after the closed form (0: the closed form was exact).
    pub iterations: u32,
    /// Remaining TCP deviation in mm.
    pub position_residual_mm: f64,
    /// Remaining tool direction deviation in rad (not controlled on machines with fewer than
    /// two rotary axes).
    pub direction_residual_rad: f64,
    /// Travel directions of the axes at the new set-points (for directional tables).
    pub directions: Directions,
}

/// The value of `q` + 360·m nearest `prev` inside travel, or `None`.
fn nearest_turn(q: f64, prev: f64, axis: &KinAxis) -> Option<f64> {
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

fn within_travel(axis: &KinAxis, v: f64) -> bool {
    v >= axis.travel_min - TRAVEL_SLACK && v <= axis.travel_max + TRAVEL_SLACK
}

impl Chain {
    /// Axis set-points that put the tool at `target` (TCP in mm, direction normalised here) in
    /// workpiece coordinates, written to `out` (one value per axis).
    ///
    /// `previous` are the last set-points (the branch and the turn of each rotary axis nearest
    /// to them are chosen; at the pole the outer rotary axis keeps its value) and
    /// `previous_dirs` the last travel directions. With [`Geometry::Actual`] the set-points
    /// make the **real** tool, through every error table, land on the target. Allocates
    /// nothing; failures (unreachable, outside travel, no convergence) are values.
    ///
    /// On [`KinError::NotConverged`] `out` holds the best set-points found (if within travel).
    pub fn inverse(
        &self,
        target: &Pose,
        tool_mm: f64,
        previous: &[f64],
        previous_dirs: Directions,
        geometry: Geometry,
        out: &mut [f64],
    ) -> Result<InverseReport, KinError> {
        self.inverse_impl(
            target,
            tool_mm,
            previous,
            previous_dirs,
            false,
            geometry,
            out,
        )
    }

    /// Like [`Chain::inverse`], but `reference` only chooses the branch and the turn of each
    /// rotary axis, and the travel directions for directional tables are `directions` as given
    /// (for rewriting programs, where the reference is the programmed nominal position).
    pub fn inverse_near(
        &self,
        target: &Pose,
        tool_mm: f64,
        reference: &[f64],
        directions: Directions,
        geometry: Geometry,
        out: &mut [f64],
    ) -> Result<InverseReport, KinError> {
        self.inverse_impl(target, tool_mm, reference, directions, true, geometry, out)
    }

    #[allow(clippy::too_many_arguments)]
    fn inverse_impl(
        &self,
        target: &Pose,
        tool_mm: f64,
        previous: &[f64],
        previous_dirs: Directions,
        fixed_dirs: bool,
        geometry: Geometry,
        out: &mut [f64],
    ) -> Result<InverseReport, KinError> {
        let directions_from =
            |q: &[f64; MAX_AXES], prev: &[f64; MAX_AXES], before: Directions, n: usize| {
                if fixed_dirs {
                    before
                } else {
                    directions_from(q, prev, before, n)
                }
            };
        self.check_positions(previous)?;
        let n = self.axes.len();
        if out.len() != n {
            return Err(KinError::AxisCount {
                expected: n,
                got: out.len(),
            });
        }
        if !(tool_mm.is_finite()
            && target
                .position
                .iter()
                .chain(&target.direction)
                .all(|v| v.is_finite()))
        {
            return Err(KinError::NonFinite);
        }
        let len = norm(&target.direction);
        if len <= 1e-12 {
            return Err(KinError::ZeroDirection);
        }
        let target = Pose {
            position: target.position,
            direction: scale(&target.direction, 1.0 / len),
        };
        let mut q = [0.0_f64; MAX_AXES];
        let mut prev = [0.0_f64; MAX_AXES];
        prev[..n].copy_from_slice(previous);
        let with_errors = geometry == Geometry::Actual;
        let use_direction = self.rotary_count() >= 2;
        // Away from the pole Newton converges from the nominal solution in two or three steps;
        // near it (or if Newton fails) the error pre-correction comes first.
        let near_pole = match &self.layout {
            Layout::FiveAxis(fa) => {
                let outer = mul_mv(&fa.g2, &fa.u2);
                norm(&cross(&outer, &target.direction)) < 1e-2
            }
            _ => false,
        };
        // The start of the chord iterations when the closed form already knows the real pose
        // and its derivatives there (see below).
        // (The derivatives are written where they stay, in `start_t`, rather than moved into
        // the option. Zeroed only on that path.)
        let mut start: Option<Pose> = None;
        let mut start_t: Option<Tangents> = None;
        let closed = match &self.layout {
            Layout::General => {
                // Damped least squares from the previous set-point.
                for j in 0..n {
                    let a = &self.axes[j];
                    q[j] = prev[j].clamp(a.travel_min, a.travel_max);
                }
                false
            }
            Layout::FiveAxis(fa)
                if with_errors
                    && !near_pole
                    && fa.real_linear
                    && (fa.linear_outside || fa.linear_inside) =>
            {
                // The real TCP is affine in the linear axes: solve them on the real chain
                // (the rotary axes from the nominal closed form). The transform with
                // derivatives this takes also starts the chord iterations: one such
                // transform per target instead of two (nominal, then real). With the linear
                // axes outside the rotary ones the derivatives do not depend on them; inside
                // (a trunnion table) the rotary ones are moved to the solution through the
                // angular velocities. Other arrangements take the nominal closed form.
                let pose = self.five_axis(
                    fa,
                    &target,
                    tool_mm,
                    &prev,
                    &mut q,
                    Some(previous_dirs),
                    start_t.insert(Tangents::ZERO),
                )?;
                start = Some(pose);
                true
            }
            layout => {
                self.closed_form(layout, &target, tool_mm, &prev, &mut q)?;
                true
            }
        };
        let refine = |q: &mut [f64; MAX_AXES]| {
            if let (Layout::FiveAxis(fa), true) = (&self.layout, with_errors) {
                let fixed = fixed_dirs.then_some(previous_dirs);
                self.refine_frozen(fa, &target, tool_mm, &prev, previous_dirs, fixed, q);
            }
        };
        let nominal_start = q;
        if near_pole {
            refine(&mut q);
        }
        let dirs = directions_from(&q, &prev, previous_dirs, n);
        let mut report = InverseReport {
            iterations: 0,
            position_residual_mm: 0.0,
            direction_residual_rad: 0.0,
            directions: dirs,
        };
        if with_errors || !closed {
            let max_iter = if closed { 100 } else { 200 };
            let mut result = if closed && with_errors && !near_pole {
                // Fast path: chord steps from the nominal solution, then (rarely) full Newton.
                let chord = match &self.layout {
                    Layout::ThreeAxis {
                        linear,
                        affine: Some(af),
                    } => self.chord_affine(af, linear, &target, tool_mm, dirs, &mut q),
                    _ => self.chord(
                        &target,
                        tool_mm,
                        dirs,
                        use_direction,
                        &mut q,
                        start.as_ref().zip(start_t.as_ref()),
                    ),
                };
                match chord {
                    Ok(r) => Ok(r),
                    Err(KinError::NotConverged { .. }) => self.newton(
                        &target,
                        tool_mm,
                        dirs,
                        geometry,
                        use_direction,
                        FAST_NEWTON_ITERATIONS,
                        &mut q,
                    ),
                    Err(e) => Err(e),
                }
            } else {
                self.newton(
                    &target,
                    tool_mm,
                    dirs,
                    geometry,
                    use_direction,
                    max_iter,
                    &mut q,
                )
            };
            if result.is_err() && closed && with_errors && !near_pole {
                q = nominal_start;
                refine(&mut q);
                result = self.newton(
                    &target,
                    tool_mm,
                    dirs,
                    geometry,
                    use_direction,
                    max_iter,
                    &mut q,
                );
            }
            if let (Err(KinError::NotConverged { .. }), Layout::FiveAxis(fa), true) =
                (&result, &self.layout, with_errors)
            {
                // Within a few µrad of the real pole the outer angle is barely determined and
                // Newton may creep: start again with the outer axis turned by 45°, 90°, …
                let outer = fa.rotary[1];
                let start = nominal_start;
                for k in 1..8 {
                    let mut q2 = start;
                    q2[outer] += 45.0 * k as f64;
                    if !within_travel(&self.axes[outer], q2[outer]) {
                        q2[outer] -= 360.0;
                    }
                    refine(&mut q2);
                    let r2 = self.newton(
                        &target,
                        tool_mm,
                        dirs,
                        geometry,
                        use_direction,
                        max_iter,
                        &mut q2,
                    );
                    if r2.is_ok() {
                        q = q2;
                        result = r2;
                        break;
                    }
                }
            }
            if let Err(KinError::NotConverged { .. }) = result {
                // The best set-points found, for callers that accept a residual (a tool
                // direction the real machine cannot reach exactly, e.g. at the pole).
                if (0..n).all(|j| within_travel(&self.axes[j], q[j])) {
                    out.copy_from_slice(&q[..n]);
                }
            }
            let (it, rp, rd) = result?;
            report.iterations = it;
            report.position_residual_mm = rp;
            report.direction_residual_rad = rd;
        } else {
            let pose = self.eval::<false>(&q[..n], tool_mm, dirs, geometry, None);
            report.position_residual_mm = norm(&sub(&pose.position, &target.position));
            report.direction_residual_rad = norm(&sub(&pose.direction, &target.direction));
        }
        // A rotary axis may have wandered by whole turns during the iterations (rotary tables
        // repeat every 360°): take the turn nearest the previous set-point within travel.
        for j in 0..n {
            if self.periodic >> j & 1 == 1 {
                if let Some(v) = nearest_turn(q[j], prev[j], &self.axes[j]) {
                    q[j] = v;
                }
            }
            if !within_travel(&self.axes[j], q[j]) {
                return Err(KinError::OutsideTravel {
                    axis: j,
                    value: q[j],
                });
            }
        }
        out.copy_from_slice(&q[..n]);
        Ok(report)
    }

    /// Error pre-correction: solves the closed form again with every error rotation frozen at
    /// the current set-points (and the TCP on the erroneous chain).
    /// Near the pole the error tilts move the outer angle a lot and the plain
    /// iteration q ← F(q) converges slowly or swings around the solution. The
    /// steps s = F(q) − q are relaxed, q ← q + ω·s, with ω from the ratio t of
    /// successive steps (a secant estimate of the contraction ρ of F:
    /// ρ = 1 + (t − 1)/ω, and ω_next = 1/(1 − ρ) = ω/(1 − t)).
    #[allow(clippy::too_many_arguments)]
    fn refine_frozen(
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
    fn closed_form(
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
    fn five_axis(
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
                    // The TCP is affine in the linear axes: it moved by u = Σ ∂p/∂q_j · Δq_j.
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
                    if omega {
                        for j in fa.rotary {
                            let turn = cross(&w[j], &u);
                            for i in 0..3 {
                                t.dp[j][i] += turn[i];
                            }
                        }
                    }
                    *q = cand;
                    return Ok(pose);
                }
                Err(e) => failure = e,
            }
        }
        Err(failure)
    }

    /// The rotation structure of the erroneous chain with every error rotation read from its
    /// table at `q` (see [`FiveAxis`]).
    fn frozen_rotations(&self, fa: &FiveAxis, q: &[f64; MAX_AXES], dirs: Directions) -> FiveAxis {
        let mut m = I3;
        let mut gs = [I3; 3];
        let mut k_rot = [0usize; 2];
        let mut nr = 0;
        let n = self.axes.len();
        let mut at = crate::table::Location::default();
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
    fn chord_affine(
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
    fn chord(
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
    fn newton(
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
/// factors that scale each column to unit length.
/// The Jacobian with the direction rows weighted by `w`, and the scale of each column to unit
/// length (`n` a constant for common counts, as in [`Normal::factor`]).
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

    /// The step Δ = −S·(L·Lᵀ)⁻¹·SᵀJᵀr; `None` if not finite.
    /// The least-squares step from the factor (`n` a constant for common counts, as in
    /// [`Normal::factor`]).
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

/// Travel directions at new set-points `q`: towards larger positions is forward; an axis that
/// does not move keeps its previous direction.
fn directions_from(
    q: &[f64; MAX_AXES],
    prev: &[f64; MAX_AXES],
    before: Directions,
    n: usize,
) -> Directions {
    let mut bits = before.0;
    for j in 0..n {
        if q[j] > prev[j] {
            bits &= !(1 << j);
        } else if q[j] < prev[j] {
            bits |= 1 << j;
        }
    }
    Directions(bits)
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
