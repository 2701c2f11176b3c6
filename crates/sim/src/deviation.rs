//! Small-angle homogeneous transforms: how a frame of the machine deviates from its nominal
//! pose.
//!
//! A structural frame that has moved by a small translation `δ` (mm) and turned by a small
//! rotation vector `ε` (rad) has the homogeneous transform
//!
//! ```text
//!     ⎡ I + [ε]×   δ ⎤        [ε]× = ⎡  0  −εz   εy ⎤
//! H = ⎣    0       1 ⎦               ⎢  εz   0  −εx ⎥
//!                                    ⎣ −εy  εx    0 ⎦
//! ```
//!
//! about a nominal point `O`. A point nominally at `P` on that frame moves by
//! `δ + ε × (P − O)`. Chaining two such transforms and dropping second-order terms (products of
//! µm-sized deviations, ≈ 10⁻⁹ relative) adds the translations (the second carried along the
//! first's rotation) and the rotation vectors: [`Deviation::then`]. This is how a bent slide
//! tilts every axis resting on it (docs/glossary.md: tilt).

/// A 3-vector in world coordinates (x, y, z).
pub type Vec3 = [f64; 3];

/// `a × b`.
pub fn cross(a: Vec3, b: Vec3) -> Vec3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `a + b`.
pub fn add(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// `a − b`.
pub fn sub(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `s · a`.
pub fn scale(s: f64, a: Vec3) -> Vec3 {
    [s * a[0], s * a[1], s * a[2]]
}

/// The deviation of a frame from its nominal pose, referred to the nominal point `at_mm`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Deviation {
    /// Nominal world position of the frame's reference point (mm).
    pub at_mm: Vec3,
    /// Translation of the reference point (mm).
    pub translation_mm: Vec3,
    /// Small rotation vector (rad).
    pub rotation_rad: Vec3,
}

impl Deviation {
    /// No deviation at the given point (the machine base).
    pub fn none_at(at_mm: Vec3) -> Self {
        Self {
            at_mm,
            ..Self::default()
        }
    }

    /// Displacement (mm) of a point rigidly attached to this frame whose nominal position is `p`.
    pub fn displacement_of(&self, p_mm: Vec3) -> Vec3 {
        add(
            self.translation_mm,
            cross(self.rotation_rad, sub(p_mm, self.at_mm)),
        )
    }

    /// The same frame referred to another nominal point.
    pub fn moved_to(&self, p_mm: Vec3) -> Self {
        Self {
            at_mm: p_mm,
            translation_mm: self.displacement_of(p_mm),
            rotation_rad: self.rotation_rad,
        }
    }

    /// The product `H_self · H_local` to first order: `local` is a deviation of a child frame
    /// relative to this one (nominal point `local.at_mm`, components in world axes).
    pub fn then(&self, local: &Deviation) -> Self {
        Self {
            at_mm: local.at_mm,
            translation_mm: add(self.displacement_of(local.at_mm), local.translation_mm),
            rotation_rad: add(self.rotation_rad, local.rotation_rad),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A frame turned by 1e-4 rad about z moves a point 300 mm along x by 0.03 mm along y; a
    /// child turned by a further 2e-4 rad about z carries a point 100 mm further along x by
    /// (1e-4 + 2e-4)·100 = 0.03 mm more.
    #[test]
    fn chained_rotations_add_and_carry_lever_arms() {
        let base = Deviation {
            at_mm: [0.0; 3],
            translation_mm: [0.0, 0.0, 0.001],
            rotation_rad: [0.0, 0.0, 1e-4],
        };
        let d = base.displacement_of([300.0, 0.0, 0.0]);
        assert!((d[1] - 0.03).abs() < 1e-15 && (d[2] - 0.001).abs() < 1e-15);
        let child = Deviation {
            at_mm: [300.0, 0.0, 0.0],
            translation_mm: [0.0; 3],
            rotation_rad: [0.0, 0.0, 2e-4],
        };
        let chained = base.then(&child);
        let p = chained.displacement_of([400.0, 0.0, 0.0]);
        assert!((p[1] - 0.06).abs() < 1e-15);
        // Exact HTM product for comparison: the second-order term is ε1·ε2·100 ≈ 2e-6 µm.
        assert!((chained.rotation_rad[2] - 3e-4).abs() < 1e-18);
    }
}
