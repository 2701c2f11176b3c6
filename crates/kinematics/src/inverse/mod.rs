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
//!
//! Here: the order of these steps, the travel directions and the turn of each rotary axis
//! (`Chain::inverse`); steps 1 and 2 in `closed_form`, step 3 in `newton`, their 3-vector maths
//! in `vec3`.

#![allow(clippy::needless_range_loop)] // index-heavy small matrix maths reads clearer with indices

mod closed_form;
mod newton;
mod vec3;

use truepos_model::MAX_AXES;

use closed_form::nearest_turn;
pub(crate) use closed_form::{affine, analyse, Affine, FiveAxis};
use newton::FAST_NEWTON_ITERATIONS;
use vec3::*;

use crate::chain::{Chain, Directions, Geometry, Layout, Pose};
use crate::description::KinAxis;
use crate::error::KinError;
use crate::forward::Tangents;

/// The inverse transform stops when the TCP is this close to the target (0.5 nm, half the
/// 1 nm bar of the kinematics table's accuracy, docs/kinematics.md).
pub const POSITION_TOLERANCE_MM: f64 = 5e-7;
/// … and the tool direction this close (0.5 µrad, half of 1 µrad).
pub const DIRECTION_TOLERANCE_RAD: f64 = 5e-7;
/// A set-point this far beyond the end of travel is still accepted (rounding).
const TRAVEL_SLACK: f64 = 1e-9;

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
        self.check_positions(previous)?;
        let n = self.axes.len();
        if out.len() != n {
            return Err(KinError::AxisCount {
                expected: n,
                got: out.len(),
            });
        }
        let target = checked_target(target, tool_mm)?;
        let mut prev = [0.0_f64; MAX_AXES];
        prev[..n].copy_from_slice(previous);
        let p = Problem {
            target,
            tool_mm,
            prev,
            previous_dirs,
            fixed_dirs,
            geometry,
            with_errors: geometry == Geometry::Actual,
            use_direction: self.rotary_count() >= 2,
            near_pole: self.near_pole(&target),
        };
        let mut q = [0.0_f64; MAX_AXES];
        // The start of the chord iterations when the closed form already knows the real pose
        // and its derivatives there (see `Chain::start`). The derivatives are written where
        // they stay, in `start_t`, rather than moved into the option, and zeroed only on the
        // path that uses them: they are the largest local of a transform.
        let mut start: Option<Pose> = None;
        let mut start_t: Option<Tangents> = None;
        let closed = self.start(&p, &mut q, &mut start, &mut start_t)?;
        let nominal_start = q;
        if p.near_pole {
            self.refine(&p, &mut q);
        }
        let dirs = p.directions(&q, n);
        let mut report = InverseReport {
            iterations: 0,
            position_residual_mm: 0.0,
            direction_residual_rad: 0.0,
            directions: dirs,
        };
        if p.with_errors || !closed {
            let start = start.as_ref().zip(start_t.as_ref());
            let (it, rp, rd) =
                self.correct(&p, closed, dirs, &nominal_start, start, &mut q, out)?;
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

    /// Whether the target's tool direction lies near the outer rotary axis of a 5-axis chain.
    /// Away from the pole Newton converges from the nominal solution in two or three steps;
    /// near it (or if Newton fails) the error pre-correction comes first.
    // The steps below run once per transform and are marked `#[inline]` so that they, and
    // the chord iterations they call in `newton`, compile into one function with
    // `inverse_impl` whichever codegen unit they land in: as calls they cost the 3-axis
    // inverse (~300 ns per target) about 6 %.
    #[inline]
    fn near_pole(&self, target: &Pose) -> bool {
        match &self.layout {
            Layout::FiveAxis(fa) => {
                let outer = mul_mv(&fa.g2, &fa.u2);
                norm(&cross(&outer, &target.direction)) < 1e-2
            }
            _ => false,
        }
    }

    /// The set-points the correction starts from, in `q`: the closed form's (true) or, for a
    /// chain without one, the previous set-points within travel (false, damped least squares
    /// follows).
    ///
    /// A 5-axis chain whose real TCP is affine in the linear axes has them solved on the real
    /// chain (the rotary axes from the nominal closed form); the transform with derivatives
    /// this takes also starts the chord iterations (`start`, `start_t`): one such transform
    /// per target instead of two (nominal, then real). With the linear axes outside the
    /// rotary ones the derivatives do not depend on them; inside (a trunnion table) the rotary
    /// ones are moved to the solution through the angular velocities. Other arrangements take
    /// the nominal closed form.
    #[inline]
    fn start(
        &self,
        p: &Problem,
        q: &mut [f64; MAX_AXES],
        start: &mut Option<Pose>,
        start_t: &mut Option<Tangents>,
    ) -> Result<bool, KinError> {
        Ok(match &self.layout {
            Layout::General => {
                for j in 0..self.axes.len() {
                    let a = &self.axes[j];
                    q[j] = p.prev[j].clamp(a.travel_min, a.travel_max);
                }
                false
            }
            Layout::FiveAxis(fa)
                if p.with_errors
                    && !p.near_pole
                    && fa.real_linear
                    && (fa.linear_outside || fa.linear_inside) =>
            {
                let pose = self.five_axis(
                    fa,
                    &p.target,
                    p.tool_mm,
                    &p.prev,
                    q,
                    Some(p.previous_dirs),
                    start_t.insert(Tangents::ZERO),
                )?;
                *start = Some(pose);
                true
            }
            layout => {
                self.closed_form(layout, &p.target, p.tool_mm, &p.prev, q)?;
                true
            }
        })
    }

    /// The error pre-correction of a 5-axis chain through the error tables (see
    /// [`Chain::refine_frozen`]); other chains and the nominal geometry leave `q` alone.
    #[inline]
    fn refine(&self, p: &Problem, q: &mut [f64; MAX_AXES]) {
        if let (Layout::FiveAxis(fa), true) = (&self.layout, p.with_errors) {
            let fixed = p.fixed_dirs.then_some(p.previous_dirs);
            self.refine_frozen(fa, &p.target, p.tool_mm, &p.prev, p.previous_dirs, fixed, q);
        }
    }

    /// From the start in `q` to set-points within the tolerances: away from the pole chord
    /// steps from the nominal solution, then (rarely) full Newton; if that fails, or near the
    /// pole, Newton after the error pre-correction; near the real pole, restarts with the
    /// outer axis turned. On [`KinError::NotConverged`] `out` gets the best set-points found
    /// if they are within travel. Returns (iterations, TCP residual mm, direction residual rad).
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn correct(
        &self,
        p: &Problem,
        closed: bool,
        dirs: Directions,
        nominal_start: &[f64; MAX_AXES],
        start: Option<(&Pose, &Tangents)>,
        q: &mut [f64; MAX_AXES],
        out: &mut [f64],
    ) -> Result<(u32, f64, f64), KinError> {
        let n = self.axes.len();
        let max_iter = if closed { 100 } else { 200 };
        let (target, tool_mm, geometry, use_direction) =
            (&p.target, p.tool_mm, p.geometry, p.use_direction);
        let fast = closed && p.with_errors && !p.near_pole;
        let mut result = if fast {
            let chord = match &self.layout {
                Layout::ThreeAxis {
                    linear,
                    affine: Some(af),
                } => self.chord_affine(af, linear, target, tool_mm, dirs, q),
                _ => self.chord(target, tool_mm, dirs, use_direction, q, start),
            };
            match chord {
                Ok(r) => Ok(r),
                Err(KinError::NotConverged { .. }) => self.newton(
                    target,
                    tool_mm,
                    dirs,
                    geometry,
                    use_direction,
                    FAST_NEWTON_ITERATIONS,
                    q,
                ),
                Err(e) => Err(e),
            }
        } else {
            self.newton(target, tool_mm, dirs, geometry, use_direction, max_iter, q)
        };
        if result.is_err() && fast {
            *q = *nominal_start;
            self.refine(p, q);
            result = self.newton(target, tool_mm, dirs, geometry, use_direction, max_iter, q);
        }
        if let (Err(KinError::NotConverged { .. }), Layout::FiveAxis(fa), true) =
            (&result, &self.layout, p.with_errors)
        {
            // Within a few µrad of the real pole the outer angle is barely determined and
            // Newton may creep: start again with the outer axis turned by 45°, 90°, …
            let outer = fa.rotary[1];
            for k in 1..8 {
                let mut q2 = *nominal_start;
                q2[outer] += 45.0 * k as f64;
                if !within_travel(&self.axes[outer], q2[outer]) {
                    q2[outer] -= 360.0;
                }
                self.refine(p, &mut q2);
                let r2 = self.newton(
                    target,
                    tool_mm,
                    dirs,
                    geometry,
                    use_direction,
                    max_iter,
                    &mut q2,
                );
                if r2.is_ok() {
                    *q = q2;
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
        result
    }
}

/// What one inverse transform works towards, fixed for the call.
struct Problem {
    /// The target with a unit tool direction.
    target: Pose,
    tool_mm: f64,
    /// The previous set-points (or the reference of [`Chain::inverse_near`]).
    prev: [f64; MAX_AXES],
    previous_dirs: Directions,
    /// The travel directions are `previous_dirs` as given, not found from the motion.
    fixed_dirs: bool,
    geometry: Geometry,
    with_errors: bool,
    /// Two rotary axes: the tool direction is controlled, not only reported.
    use_direction: bool,
    near_pole: bool,
}

impl Problem {
    /// The travel directions at set-points `q`.
    fn directions(&self, q: &[f64; MAX_AXES], n: usize) -> Directions {
        if self.fixed_dirs {
            self.previous_dirs
        } else {
            directions_from(q, &self.prev, self.previous_dirs, n)
        }
    }
}

/// The target with its tool direction normalised, or why it has none.
#[inline]
fn checked_target(target: &Pose, tool_mm: f64) -> Result<Pose, KinError> {
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
    Ok(Pose {
        position: target.position,
        direction: scale(&target.direction, 1.0 / len),
    })
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
