//! Forward transform: axis set-points (+ tool length) → TCP and tool direction in workpiece
//! coordinates, nominal or through the error tables, optionally with the exact Jacobian
//! (forward-mode differentiation through every row, including the slopes of the tables).

use truepos_model::{AxisKind, MAX_AXES};

use crate::chain::{Chain, Directions, ErrRef, Geometry, Pose, Slide, Step};
use crate::error::KinError;
use crate::table::Location;
use crate::{sincos, DEG};

/// Derivatives of the TCP (`dp`) and the tool direction (`dd`) with respect to each axis, per
/// mm for linear axes and per radian for rotary ones.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Tangents {
    pub dp: [[f64; 3]; MAX_AXES],
    pub dd: [[f64; 3]; MAX_AXES],
}

impl Tangents {
    pub const ZERO: Self = Self {
        dp: [[0.0; 3]; MAX_AXES],
        dd: [[0.0; 3]; MAX_AXES],
    };
}

/// The angular velocity ω of everything on the tool side with respect to each axis (rad per
/// internal unit): a vector v carried on that side changes by ω × v (the derivative of the
/// tool direction is ω × d). Apart from [`Tangents`] so the other walks do not carry it.
pub(crate) type AngularVelocity = [[f64; 3]; MAX_AXES];

/// Bit of axis j in the mask of [`turn`] once its rotational derivatives (the tool
/// direction's and the angular velocity) may be non-zero: a rotation about or by the axis.
const TURNS: u32 = 1 << 16;

/// The bits a rotation about or by an axis sets in the mask of [`turn`] (shifted by the
/// axis): with `OMEGA` both, else the TCP's bit alone (those walks turn both sets by it).
#[inline(always)]
const fn turns_bit<const OMEGA: bool>() -> u32 {
    if OMEGA {
        1 + TURNS
    } else {
        1
    }
}

/// Turns the derivatives of the axes in `active` by the rotation of a row: only those need
/// turning. Bit j: axis j's TCP derivative is no longer zero; bit 16 + j ([`TURNS`]): its
/// direction derivative and angular velocity neither. A linear axis moves the TCP only, so
/// until an error rotation reads a table of it those two stay zero and are not turned. Only
/// the walk with angular velocities (`OMEGA`, the trunnion's: its linear axes come first and
/// are turned by every rotation) separates them; it pays only there, since the heads' linear
/// axes come after their rotations, so the other walks set only bit j and turn the direction
/// derivative with the TCP's.
#[inline(always)]
fn turn<const DIR_JAC: bool, const OMEGA: bool>(
    t: &mut Tangents,
    mut w: Option<&mut AngularVelocity>,
    active: u32,
    k: usize,
    c: f64,
    s: f64,
) {
    if !OMEGA {
        // (Those walks never set the TURNS bits: see `turns_bit`.)
        let mut bits = active;
        while bits != 0 {
            let j = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            rotate(&mut t.dp[j], k, c, s);
            if DIR_JAC {
                rotate(&mut t.dd[j], k, c, s);
            }
        }
        return;
    }
    let mut bits = active & (TURNS - 1);
    while bits != 0 {
        let j = bits.trailing_zeros() as usize;
        bits &= bits - 1;
        rotate(&mut t.dp[j], k, c, s);
    }
    {
        let mut bits = active / TURNS;
        while bits != 0 {
            let j = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            if DIR_JAC {
                rotate(&mut t.dd[j], k, c, s);
            }
            if OMEGA {
                if let Some(w) = w.as_deref_mut() {
                    rotate(&mut w[j], k, c, s);
                }
            }
        }
    }
}

/// An error rotation (k, cos, sin) of the pose and the derivatives; `g`: the slope of its
/// angle per internal unit of `axis` (used with `ACTUAL` only). With `ACTUAL` it moves with
/// the axis as a rotary axis turning by `g` per unit does, else it is a fixed rotation.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn err_rotate<const JAC: bool, const ACTUAL: bool, const DIR_JAC: bool, const OMEGA: bool>(
    x: &mut Pd,
    tangents: Option<&mut Tangents>,
    omega: Option<&mut AngularVelocity>,
    active: &mut u32,
    rotation: (usize, f64, f64),
    axis: usize,
    g: f64,
) {
    if ACTUAL {
        axis_rotate::<JAC, DIR_JAC, OMEGA>(x, tangents, omega, active, rotation, axis, g);
    } else {
        fixed_rotate::<JAC, DIR_JAC, OMEGA>(x, tangents, omega, *active, rotation);
    }
}

/// A fixed rotation (k, cos, sin) of the pose, turning the derivatives found so far; no axis
/// moves it, so it adds no derivative of its own.
#[inline(always)]
fn fixed_rotate<const JAC: bool, const DIR_JAC: bool, const OMEGA: bool>(
    x: &mut Pd,
    tangents: Option<&mut Tangents>,
    omega: Option<&mut AngularVelocity>,
    active: u32,
    (k, c, s): (usize, f64, f64),
) {
    x.rotate(k, c, s);
    if JAC {
        if let Some(t) = tangents {
            turn::<DIR_JAC, OMEGA>(t, omega, active, k, c, s);
        }
    }
}

/// The rotation (k, cos, sin) of a rotary axis turning by `sign` · its set-point: it turns the
/// derivatives found so far, then adds its own, e_k × the TCP (and × the tool direction with
/// `DIR_JAC`) and, with `OMEGA`, its angular velocity about e_k.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn axis_rotate<const JAC: bool, const DIR_JAC: bool, const OMEGA: bool>(
    x: &mut Pd,
    tangents: Option<&mut Tangents>,
    mut omega: Option<&mut AngularVelocity>,
    active: &mut u32,
    (k, c, s): (usize, f64, f64),
    axis: usize,
    sign: f64,
) {
    x.rotate(k, c, s);
    if JAC {
        if let Some(t) = tangents {
            turn::<DIR_JAC, OMEGA>(t, omega.as_deref_mut(), *active, k, c, s);
            add_cross(&mut t.dp[axis], k, &x.p(), sign);
            if DIR_JAC {
                add_cross(&mut t.dd[axis], k, &x.d(), sign);
            }
            if OMEGA {
                if let Some(w) = omega {
                    w[axis][k] += sign;
                }
            }
            *active |= turns_bit::<OMEGA>() << axis;
        }
    }
}

/// Zeroes the derivatives (with `JAC`) and the angular velocities (with `OMEGA`) of the first
/// `n` axes, the ones a walk adds to.
#[inline(always)]
fn clear<const JAC: bool, const OMEGA: bool>(
    n: usize,
    tangents: Option<&mut Tangents>,
    omega: Option<&mut AngularVelocity>,
) {
    if OMEGA {
        if let Some(w) = omega {
            for wj in w.iter_mut().take(n) {
                *wj = [0.0; 3];
            }
        }
    }
    if JAC {
        if let Some(t) = tangents {
            for j in 0..n {
                t.dp[j] = [0.0; 3];
                t.dd[j] = [0.0; 3];
            }
        }
    }
}

/// x ← R_k(θ)·x with c = cos θ, s = sin θ (active rotation about coordinate axis k).
///
/// The rotation plane comes from a select on k (no remainders), which is cheaper than one arm
/// per axis that builds the whole vector anew.
#[inline(always)]
fn rotate(x: &mut [f64; 3], k: usize, c: f64, s: f64) {
    let (i, j) = match k {
        0 => (1, 2),
        1 => (2, 0),
        _ => (0, 1),
    };
    let (a, b) = (x[i], x[j]);
    x[i] = c * a - s * b;
    x[j] = s * a + c * b;
}

/// The TCP p and the tool direction d of a walk.
#[derive(Clone, Copy)]
struct Pd {
    p: [f64; 3],
    d: [f64; 3],
}

impl Pd {
    const START: Self = Self {
        p: [0.0; 3],
        d: [0.0, 0.0, 1.0],
    };

    /// R_k(θ)·p and R_k(θ)·d.
    #[inline(always)]
    fn rotate(&mut self, k: usize, c: f64, s: f64) {
        rotate(&mut self.p, k, c, s);
        rotate(&mut self.d, k, c, s);
    }

    /// p ← p + v·e_k, one arm per axis with a constant index: `p[k] += v` with a computed index
    /// would keep the pose in memory instead of registers.
    #[inline(always)]
    fn translate(&mut self, k: usize, v: f64) {
        match k {
            0 => self.p[0] += v,
            1 => self.p[1] += v,
            _ => self.p[2] += v,
        }
    }

    #[inline(always)]
    fn p(&self) -> [f64; 3] {
        self.p
    }

    #[inline(always)]
    fn d(&self) -> [f64; 3] {
        self.d
    }
}

/// See [`Chain::eval_position_jacobian3`]: lane 0 the TCP, lanes 1–3 its derivatives with
/// respect to the three axes.
#[derive(Clone, Copy)]
struct Lanes([[f64; 4]; 3]);

impl Lanes {
    /// Every lane turned by R_k(θ), with the operations of [`rotate`]. Every index is a
    /// constant (one arm per axis), so the lanes can stay in registers.
    #[inline(always)]
    fn rotate(&mut self, k: usize, c: f64, s: f64) {
        match k {
            0 => self.rotate_rows::<1, 2>(c, s),
            1 => self.rotate_rows::<2, 0>(c, s),
            _ => self.rotate_rows::<0, 1>(c, s),
        }
    }

    #[inline(always)]
    fn rotate_rows<const I: usize, const J: usize>(&mut self, c: f64, s: f64) {
        let (a, b) = (self.0[I], self.0[J]);
        for l in 0..4 {
            self.0[I][l] = c * a[l] - s * b[l];
            self.0[J][l] = s * a[l] + c * b[l];
        }
    }

    /// p ← p + v·e_k.
    #[inline(always)]
    fn translate(&mut self, k: usize, v: f64) {
        self.add(k, 0, v);
    }

    /// Lane `lane` (0 to 3) of coordinate k += v, with constant indices.
    #[inline(always)]
    fn add(&mut self, k: usize, lane: usize, v: f64) {
        match k {
            0 => self.add_row::<0>(lane, v),
            1 => self.add_row::<1>(lane, v),
            _ => self.add_row::<2>(lane, v),
        }
    }

    #[inline(always)]
    fn add_row<const K: usize>(&mut self, lane: usize, v: f64) {
        match lane {
            0 => self.0[K][0] += v,
            1 => self.0[K][1] += v,
            2 => self.0[K][2] += v,
            _ => self.0[K][3] += v,
        }
    }

    /// Lane `lane` += g · (e_k × p), as [`add_cross`].
    #[inline(always)]
    fn add_cross(&mut self, k: usize, lane: usize, g: f64) {
        let p = [self.0[0][0], self.0[1][0], self.0[2][0]];
        match k {
            0 => {
                self.add(1, lane, -(g * p[2]));
                self.add(2, lane, g * p[1]);
            }
            1 => {
                self.add(2, lane, -(g * p[0]));
                self.add(0, lane, g * p[2]);
            }
            _ => {
                self.add(0, lane, -(g * p[1]));
                self.add(1, lane, g * p[0]);
            }
        }
    }
}

/// t += g · (e_k × x).
#[inline(always)]
fn add_cross(t: &mut [f64; 3], k: usize, x: &[f64; 3], g: f64) {
    match k {
        0 => {
            t[1] -= g * x[2];
            t[2] += g * x[1];
        }
        1 => {
            t[2] -= g * x[0];
            t[0] += g * x[2];
        }
        _ => {
            t[0] -= g * x[1];
            t[1] += g * x[0];
        }
    }
}

impl Chain {
    /// Checks that `q` has one finite value per axis.
    pub(crate) fn check_positions(&self, q: &[f64]) -> Result<(), KinError> {
        if q.len() != self.axes.len() {
            return Err(KinError::AxisCount {
                expected: self.axes.len(),
                got: q.len(),
            });
        }
        if q.iter().any(|v| !v.is_finite()) {
            return Err(KinError::NonFinite);
        }
        Ok(())
    }

    /// The tool pose in workpiece coordinates for axis set-points `q` (mm, degrees, in
    /// [`Chain::axes`] order), tool length `tool_mm`, travel directions `dirs` (for directional
    /// tables) and `geometry`. Allocates nothing; a NaN/∞ input gives [`KinError::NonFinite`].
    pub fn forward(
        &self,
        q: &[f64],
        tool_mm: f64,
        dirs: Directions,
        geometry: Geometry,
    ) -> Result<Pose, KinError> {
        self.check_positions(q)?;
        if !tool_mm.is_finite() {
            return Err(KinError::NonFinite);
        }
        let pose = self.eval::<false>(q, tool_mm, dirs, geometry, None);
        if pose
            .position
            .iter()
            .chain(&pose.direction)
            .all(|v| v.is_finite())
        {
            Ok(pose)
        } else {
            Err(KinError::NonFinite)
        }
    }

    /// The pose and, if `JAC`, its exact derivatives. Inputs must be checked by the caller.
    #[inline]
    pub(crate) fn eval<const JAC: bool>(
        &self,
        q: &[f64],
        tool_mm: f64,
        dirs: Directions,
        geometry: Geometry,
        tangents: Option<&mut Tangents>,
    ) -> Pose {
        // One copy of the walk per geometry: the nominal one then carries no table code.
        match (geometry, self.slides.is_empty()) {
            (Geometry::Nominal, true) => {
                self.walk::<JAC, false, true, false, false>(q, tool_mm, dirs, tangents, None)
            }
            (Geometry::Nominal, false) => {
                self.walk::<JAC, false, true, false, true>(q, tool_mm, dirs, tangents, None)
            }
            (Geometry::Actual, true) => {
                self.walk::<JAC, true, true, false, false>(q, tool_mm, dirs, tangents, None)
            }
            (Geometry::Actual, false) => {
                self.walk::<JAC, true, true, false, true>(q, tool_mm, dirs, tangents, None)
            }
        }
    }

    /// The TCP through the error tables and its derivatives with respect to the three axes
    /// of a chain of three linear axes (what the 3-axis inverse needs: it cannot turn the
    /// tool, so the tool direction is left out), `dp[j]` for axis j; `None` for another chain.
    ///
    /// The walk keeps everything one rotation turns as lanes of the coordinate it changes,
    /// `[p, ∂p/∂q₀, ∂p/∂q₁, ∂p/∂q₂]`, so a rotation turns the TCP and the three derivatives
    /// with the same two two-lane operations per coordinate instead of a loop over the
    /// derivatives, with constant indices so the lanes stay in registers. The TCP lane takes
    /// exactly the operations of [`Chain::eval`].
    pub(crate) fn eval_position_jacobian3(
        &self,
        q: &[f64],
        tool_mm: f64,
        dirs: Directions,
    ) -> Option<([f64; 3], [[f64; 3]; 3])> {
        if q.len() != 3 || self.axes.len() != 3 {
            return None;
        }
        // Lane of the derivative with respect to axis j: 1 + j (j < 3 here).
        let mut x = Lanes([[0.0; 4]; 3]);
        let mut at = Location::default();
        for step in &self.steps {
            match *step {
                Step::Translate { k, v } => x.translate(k, v),
                Step::Tool { k, sign, offset } => x.translate(k, sign * tool_mm + offset),
                Step::AxisTranslate { k, axis, sign } => {
                    x.translate(k, sign * q[axis]);
                    x.add(k, 1 + axis, sign);
                }
                Step::ErrTranslate { k, e } => {
                    let (v, slope) = self.error_value::<true>(&e, &mut at, q, dirs);
                    x.translate(k, v);
                    x.add(k, 1 + usize::from(e.axis), slope * e.per_unit);
                }
                Step::ConstErrTranslate { k, v, .. } => x.translate(k, v),
                Step::ConstErrRotate { k, c, s, .. } | Step::Rotate { k, c, s } => {
                    x.rotate(k, c, s)
                }
                Step::AxisRotate { .. } => return None,
                Step::ErrRotate { k, e } => {
                    let (angle, slope) = self.error_value::<true>(&e, &mut at, q, dirs);
                    let (s, c) = sincos(angle);
                    x.rotate(k, c, s);
                    x.add_cross(k, 1 + usize::from(e.axis), slope * e.per_unit);
                }
                Step::Slide { index } => {
                    let sl = self.slides.get(index)?;
                    let axis = usize::from(sl.axis);
                    at = self.tables[usize::from(sl.table)].table.locate(q[axis]);
                    let base = if dirs.0 >> axis & 1 == 1 {
                        sl.reverse
                    } else {
                        sl.forward
                    };
                    let block = self.slide_cubics.get(base as usize + at.segment())?;
                    let (v, slope) = at.cubics::<true, 6>(block);
                    let lane = 1 + axis;
                    for k in 0..3 {
                        if sl.present >> k & 1 == 1 {
                            x.translate(k, v[k]);
                            x.add(k, lane, slope[k] * sl.per_unit);
                        }
                    }
                    for k in 0..3 {
                        if sl.present >> (3 + k) & 1 == 1 {
                            let (s, c) = sincos(v[3 + k]);
                            x.rotate(k, c, s);
                            x.add_cross(k, lane, slope[3 + k] * sl.per_unit);
                        }
                    }
                }
            }
        }
        let lane = |l: usize| [x.0[0][l], x.0[1][l], x.0[2][l]];
        Some((lane(0), [lane(1), lane(2), lane(3)]))
    }

    /// [`Chain::eval`] with derivatives through the error tables, and the angular velocity of
    /// the tool side with respect to each axis in `omega`.
    pub(crate) fn eval_with_angular_velocity(
        &self,
        q: &[f64],
        tool_mm: f64,
        dirs: Directions,
        tangents: &mut Tangents,
        omega: &mut AngularVelocity,
    ) -> Pose {
        if self.slides.is_empty() {
            self.walk::<true, true, true, true, false>(
                q,
                tool_mm,
                dirs,
                Some(tangents),
                Some(omega),
            )
        } else {
            self.walk::<true, true, true, true, true>(q, tool_mm, dirs, Some(tangents), Some(omega))
        }
    }

    /// [`Chain::eval`] for one geometry (`ACTUAL`: through the error tables); `DIR_JAC`: the
    /// derivatives of the tool direction too; `SLIDES`: the chain has slide steps (the other
    /// chains get a copy without their code, which would otherwise slow the 5-axis walks).
    #[inline(always)]
    fn walk<
        const JAC: bool,
        const ACTUAL: bool,
        const DIR_JAC: bool,
        const OMEGA: bool,
        const SLIDES: bool,
    >(
        &self,
        q: &[f64],
        tool_mm: f64,
        dirs: Directions,
        mut tangents: Option<&mut Tangents>,
        mut omega: Option<&mut AngularVelocity>,
    ) -> Pose {
        clear::<JAC, OMEGA>(
            self.axes.len(),
            tangents.as_deref_mut(),
            omega.as_deref_mut(),
        );
        let mut x = Pd::START;
        // Bit j set: the tangents of axis j are no longer zero (the layout of [`turn`]).
        let mut active: u32 = 0;
        // Where the axis position of the last error row fell in its table: rows reading tables
        // with the same support points of the same axis follow each other (the 6 errors of a
        // slide), so one search serves them all. Every first row of a group relocates.
        let mut at = Location::default();
        for step in &self.steps {
            match *step {
                Step::Translate { k, v } => x.translate(k, v),
                Step::Tool { k, sign, offset } => x.translate(k, sign * tool_mm + offset),
                Step::AxisTranslate { k, axis, sign } => {
                    x.translate(k, sign * q[axis]);
                    if JAC {
                        if let Some(t) = tangents.as_deref_mut() {
                            t.dp[axis][k] += sign;
                            active |= 1 << axis;
                        }
                    }
                }
                Step::ErrTranslate { k, e } => {
                    let state = (&mut x, &mut active, &mut at);
                    let t = tangents.as_deref_mut();
                    self.err_translate::<JAC, ACTUAL>(k, &e, q, dirs, state, t);
                }
                Step::ConstErrTranslate { k, v, nominal } => {
                    x.translate(k, if ACTUAL { v } else { nominal });
                }
                Step::ConstErrRotate {
                    k,
                    c,
                    s,
                    nominal_c,
                    nominal_s,
                } => {
                    let (c, s) = if ACTUAL {
                        (c, s)
                    } else {
                        (nominal_c, nominal_s)
                    };
                    // A constant table has no slope: only turn the tangents.
                    let (t, w) = (tangents.as_deref_mut(), omega.as_deref_mut());
                    fixed_rotate::<JAC, DIR_JAC, OMEGA>(&mut x, t, w, active, (k, c, s));
                }
                Step::Rotate { k, c, s } => {
                    let (t, w) = (tangents.as_deref_mut(), omega.as_deref_mut());
                    fixed_rotate::<JAC, DIR_JAC, OMEGA>(&mut x, t, w, active, (k, c, s));
                }
                Step::AxisRotate { k, axis, sign } => {
                    let (s, c) = sincos(sign * q[axis] * DEG);
                    let (t, w) = (tangents.as_deref_mut(), omega.as_deref_mut());
                    let turn = (k, c, s);
                    axis_rotate::<JAC, DIR_JAC, OMEGA>(&mut x, t, w, &mut active, turn, axis, sign);
                }
                Step::ErrRotate { k, e } => {
                    let (angle, slope) = if ACTUAL {
                        self.error_value::<JAC>(&e, &mut at, q, dirs)
                    } else {
                        (e.offset, 0.0)
                    };
                    let (s, c) = sincos(angle);
                    let axis = usize::from(e.axis);
                    err_rotate::<JAC, ACTUAL, DIR_JAC, OMEGA>(
                        &mut x,
                        tangents.as_deref_mut(),
                        omega.as_deref_mut(),
                        &mut active,
                        (k, c, s),
                        axis,
                        slope * e.per_unit,
                    );
                }
                Step::Slide { .. } if !SLIDES => {}
                Step::Slide { index } => {
                    let state = (&mut x, &mut active, &mut at);
                    let (t, w) = (tangents.as_deref_mut(), omega.as_deref_mut());
                    self.slide_step::<JAC, ACTUAL, DIR_JAC, OMEGA>(index, q, dirs, state, t, w);
                }
            }
        }
        Pose {
            position: x.p(),
            direction: x.d(),
        }
    }

    /// An error translation along k: the error row's value (`ACTUAL`) or its nominal offset,
    /// and with `JAC` its slope as the derivative of the TCP by the row's axis.
    #[inline(always)]
    fn err_translate<const JAC: bool, const ACTUAL: bool>(
        &self,
        k: usize,
        e: &ErrRef,
        q: &[f64],
        dirs: Directions,
        (x, active, at): (&mut Pd, &mut u32, &mut Location),
        tangents: Option<&mut Tangents>,
    ) {
        if ACTUAL {
            let (v, slope) = self.error_value::<JAC>(e, at, q, dirs);
            x.translate(k, v);
            if JAC {
                if let Some(t) = tangents {
                    let axis = usize::from(e.axis);
                    t.dp[axis][k] += slope * e.per_unit;
                    *active |= 1 << axis;
                }
            }
        } else {
            x.translate(k, e.offset);
        }
    }

    /// Slide `index` applied to the pose and the derivatives; full slides (the six errors of
    /// ISO 230-1) take a copy of `slide` without a test per slot.
    #[allow(clippy::type_complexity)]
    #[inline(always)]
    fn slide_step<const JAC: bool, const ACTUAL: bool, const DIR_JAC: bool, const OMEGA: bool>(
        &self,
        index: usize,
        q: &[f64],
        dirs: Directions,
        state: (&mut Pd, &mut u32, &mut Location),
        t: Option<&mut Tangents>,
        w: Option<&mut AngularVelocity>,
    ) {
        let Some(sl) = self.slides.get(index) else {
            return;
        };
        if sl.present == 0x3f {
            self.slide::<JAC, ACTUAL, DIR_JAC, OMEGA, true>(sl, q, dirs, state, t, w);
        } else {
            self.slide::<JAC, ACTUAL, DIR_JAC, OMEGA, false>(sl, q, dirs, state, t, w);
        }
    }

    /// The rows of a slide (see [`Slide`]) applied to the pose and the derivatives, in
    /// the order and with the operations of the separate rows. `FULL`: every slot is present.
    #[allow(clippy::type_complexity)]
    #[inline(always)]
    fn slide<
        const JAC: bool,
        const ACTUAL: bool,
        const DIR_JAC: bool,
        const OMEGA: bool,
        const FULL: bool,
    >(
        &self,
        sl: &Slide,
        q: &[f64],
        dirs: Directions,
        (x, active, at): (&mut Pd, &mut u32, &mut Location),
        mut tangents: Option<&mut Tangents>,
        mut omega: Option<&mut AngularVelocity>,
    ) {
        let present = |s: usize| FULL || sl.present >> s & 1 == 1;
        let axis = usize::from(sl.axis);
        // Values (mm, rad) and slopes per internal unit of the six slots.
        let mut g = [0.0; 6];
        let v = if !ACTUAL {
            sl.nominal
        } else {
            *at = self.tables[usize::from(sl.table)].table.locate(q[axis]);
            let base = if dirs.0 >> axis & 1 == 1 {
                sl.reverse
            } else {
                sl.forward
            };
            // `locate` returns a segment below the table's segment count, the number of
            // blocks of the slide: the fallback (nominal) is never taken.
            match self.slide_cubics.get(base as usize + at.segment()) {
                Some(block) => {
                    // Empty slots have zero cubics: evaluating them costs less than a test.
                    let (v, slope) = at.cubics::<JAC, 6>(block);
                    if JAC {
                        for s in 0..6 {
                            g[s] = slope[s] * sl.per_unit;
                        }
                    }
                    v
                }
                None => sl.nominal,
            }
        };
        for k in 0..3 {
            if present(k) {
                x.translate(k, v[k]);
                if JAC && ACTUAL {
                    if let Some(t) = tangents.as_deref_mut() {
                        t.dp[axis][k] += g[k];
                        *active |= 1 << axis;
                    }
                }
            }
        }
        for k in 0..3 {
            if present(3 + k) {
                let (s, c) = sincos(v[3 + k]);
                err_rotate::<JAC, ACTUAL, DIR_JAC, OMEGA>(
                    x,
                    tangents.as_deref_mut(),
                    omega.as_deref_mut(),
                    active,
                    (k, c, s),
                    axis,
                    g[3 + k],
                );
            }
        }
    }

    /// The value of error row `e` (mm or rad, nominal part included) and, if `SLOPE`, its
    /// slope per mm or degree of its axis, located afresh if `e.relocate`, else at `at` (found
    /// by the previous error row on the same support points).
    #[inline(always)]
    pub(crate) fn error_value<const SLOPE: bool>(
        &self,
        e: &ErrRef,
        at: &mut Location,
        q: &[f64],
        dirs: Directions,
    ) -> (f64, f64) {
        let axis = usize::from(e.axis);
        if e.relocate {
            *at = self.tables[usize::from(e.table)].table.locate(q[axis]);
        }
        let base = if dirs.0 >> axis & 1 == 1 {
            e.reverse
        } else {
            e.forward
        };
        // `locate` returns a segment below the table's segment count, the length of the row's
        // block: the fallback (the nominal part) is never taken.
        match self.cubics.get(base as usize + at.segment()) {
            Some(c) => at.cubic::<SLOPE>(c),
            None => (e.offset, 0.0),
        }
    }

    /// d(axis position in mm or degrees) / d(internal unknown in mm or radians).
    #[inline]
    pub(crate) fn per_unit(&self, axis: usize) -> f64 {
        match self.axes[axis].kind {
            AxisKind::Linear => 1.0,
            AxisKind::Rotary => 1.0 / DEG,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::table::{CompTable, Interpolation, Wrap};
    use crate::{Dof, ErrorTable, ErrorUnit, KinAxis, Row};
    use alloc::vec;
    use alloc::vec::Vec;

    fn chain() -> Chain {
        let rot_table = |name: &str, axis: usize, unit: ErrorUnit, amp: f64| {
            let pos: Vec<f64> = (0..36).map(|i| 10.0 * i as f64).collect();
            let val = pos
                .iter()
                .map(|p| amp * libm::sin(p * DEG * 2.0 + 0.3))
                .collect();
            ErrorTable {
                name: name.into(),
                axis,
                unit,
                table: CompTable::new(pos, val, Wrap::Rotary, Interpolation::MonotoneCubic)
                    .unwrap(),
            }
        };
        let lin_table = |name: &str, axis: usize, unit: ErrorUnit, amp: f64| {
            let pos: Vec<f64> = (0..11).map(|i| -500.0 + 100.0 * i as f64).collect();
            let val = pos.iter().map(|p| amp * libm::sin(p / 150.0)).collect();
            ErrorTable {
                name: name.into(),
                axis,
                unit,
                table: CompTable::new(pos, val, Wrap::Hold, Interpolation::MonotoneCubic).unwrap(),
            }
        };
        let ax = |name: &str, kind| KinAxis {
            name: name.into(),
            kind,
            travel_min: -500.0,
            travel_max: 500.0,
        };
        let axes = vec![
            ax("X", AxisKind::Linear),
            ax("A", AxisKind::Rotary),
            ax("C", AxisKind::Rotary),
        ];
        // Large errors so that the table terms dominate the finite-difference check.
        let tables = vec![
            rot_table("FAX", 1, ErrorUnit::Millimetre, 0.5),
            rot_table("FAB", 1, ErrorUnit::Degree, 2.0),
            rot_table("FCA", 2, ErrorUnit::Degree, 3.0),
            lin_table("FXC", 0, ErrorUnit::Degree, 1.0),
        ];
        let rows = vec![
            Row::Tool {
                dof: Dof::Z,
                sign: -1.0,
                offset: -100.0,
            },
            Row::Error {
                dof: Dof::X,
                offset: 0.0,
                table: 0,
            },
            Row::Error {
                dof: Dof::B,
                offset: 1.0,
                table: 1,
            },
            Row::Axis {
                dof: Dof::A,
                axis: 1,
                sign: 1.0,
            },
            Row::Fixed {
                dof: Dof::Y,
                value: 30.0,
            },
            Row::Error {
                dof: Dof::A,
                offset: 0.0,
                table: 2,
            },
            Row::Axis {
                dof: Dof::C,
                axis: 2,
                sign: -1.0,
            },
            Row::Error {
                dof: Dof::C,
                offset: 0.0,
                table: 3,
            },
            Row::Axis {
                dof: Dof::X,
                axis: 0,
                sign: 1.0,
            },
        ];
        Chain::new(axes, tables, rows).unwrap()
    }

    /// ω_j × d is the derivative of the tool direction, for every axis, and the derivatives
    /// of the other walks are the same.
    #[test]
    fn angular_velocity_turns_the_tool_direction() {
        let c = chain();
        let q = [123.0, 37.0, -71.0];
        let mut t = Tangents::ZERO;
        let mut omega = [[0.0; 3]; MAX_AXES];
        let pose = c.eval_with_angular_velocity(&q, 50.0, Directions(0), &mut t, &mut omega);
        let mut t2 = Tangents::ZERO;
        c.eval::<true>(&q, 50.0, Directions(0), Geometry::Actual, Some(&mut t2));
        let d = pose.direction;
        for (j, w) in omega.iter().enumerate().take(3) {
            let cross = [
                w[1] * d[2] - w[2] * d[1],
                w[2] * d[0] - w[0] * d[2],
                w[0] * d[1] - w[1] * d[0],
            ];
            for (x, y) in cross.iter().zip(&t.dd[j]) {
                assert!((x - y).abs() < 1e-12, "axis {j}");
            }
            assert_eq!((t.dp[j], t.dd[j]), (t2.dp[j], t2.dd[j]));
        }
        // X turns the tool side only through its rotation error table (FXC about Z).
        assert_eq!((omega[0][0], omega[0][1]), (0.0, 0.0));
        assert!(omega[0][2] != 0.0);
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let c = chain();
        let q = [123.0, 37.0, -71.0];
        let mut t = Tangents::ZERO;
        c.eval::<true>(&q, 50.0, Directions(0), Geometry::Actual, Some(&mut t));
        for j in 0..3 {
            // Step in the internal unit (mm or rad) converted to mm or degrees.
            let h = 1e-6;
            let hq = h * c.per_unit(j);
            let mut qp = q;
            let mut qm = q;
            qp[j] += hq;
            qm[j] -= hq;
            let a = c.eval::<false>(&qp, 50.0, Directions(0), Geometry::Actual, None);
            let b = c.eval::<false>(&qm, 50.0, Directions(0), Geometry::Actual, None);
            for i in 0..3 {
                let fd_p = (a.position[i] - b.position[i]) / (2.0 * h);
                let fd_d = (a.direction[i] - b.direction[i]) / (2.0 * h);
                assert!(
                    (fd_p - t.dp[j][i]).abs() < 1e-5 * (1.0 + fd_p.abs()),
                    "dp[{j}][{i}] {fd_p} vs {}",
                    t.dp[j][i]
                );
                assert!(
                    (fd_d - t.dd[j][i]).abs() < 1e-6,
                    "dd[{j}][{i}] {fd_d} vs {}",
                    t.dd[j][i]
                );
            }
        }
    }
}
