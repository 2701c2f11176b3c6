//! The 3-vector and 3×3-matrix maths of the closed forms, on fixed-size arrays (no allocation,
//! no dependency).

pub(super) type M3 = [[f64; 3]; 3];
pub(super) type V3 = [f64; 3];

pub(super) const I3: M3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

pub(super) fn mul_mv(m: &M3, v: &V3) -> V3 {
    [
        m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
        m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
        m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2],
    ]
}

pub(super) fn mul_tv(m: &M3, v: &V3) -> V3 {
    [
        m[0][0] * v[0] + m[1][0] * v[1] + m[2][0] * v[2],
        m[0][1] * v[0] + m[1][1] * v[1] + m[2][1] * v[2],
        m[0][2] * v[0] + m[1][2] * v[1] + m[2][2] * v[2],
    ]
}

pub(super) fn dot(a: &V3, b: &V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(super) fn cross(a: &V3, b: &V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

pub(super) fn norm(a: &V3) -> f64 {
    libm::sqrt(dot(a, a))
}

pub(super) fn unit(k: usize) -> V3 {
    let mut e = [0.0; 3];
    e[k] = 1.0;
    e
}

/// R_k(c, s)·M.
pub(super) fn rotate_m(m: &mut M3, k: usize, c: f64, s: f64) {
    let (i, j) = ((k + 1) % 3, (k + 2) % 3);
    for col in 0..3 {
        let (a, b) = (m[i][col], m[j][col]);
        m[i][col] = c * a - s * b;
        m[j][col] = s * a + c * b;
    }
}

pub(super) fn sub(a: &V3, b: &V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(super) fn scale(a: &V3, s: f64) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}

/// The inverse of the 3×3 matrix with columns c0, c1, c2 (rows: cross products of the
/// columns over the determinant), or `None` if it is singular.
pub(super) fn inverse3(c0: &V3, c1: &V3, c2: &V3) -> Option<M3> {
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
