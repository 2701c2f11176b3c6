//! Structural parts as thermo-elastic beams (docs/glossary.md: bending radius).
//!
//! A part (bed, column, slide, spindle head) is a beam of length `L` along `e_len` with a
//! rectangular section: height `H` along `e_h` (top/bottom, or front/rear for an upright part)
//! and width `W` along `e_w`. It is cut into `segments` slices along its length, and each slice
//! into four corner nodes of the thermal network (`−h/+h` × `−w/+w`), which carries gradients
//! across both directions of the section.
//!
//! ## Deformation of one slice of length ℓ
//! - It grows along its length by `ℓ·α·(T̄ − T_ref)` (uniform heating, `ΔL = α·L·ΔT`) and
//!   across its section by `α·(T̄ − T_ref)` per mm (`ΔH = α·H·ΔT`).
//! - Its two faces have lengths `L_± = ℓ·(1 + α·(T_± − T_ref))`. The slice bends to the radius
//!   `R = H·L_long / (L_long − L_short)` (the longer, hotter face is outside; the glossary
//!   writes it for a hotter bottom: `R = H·L_bottom / (L_bottom − L_top)`), so its curvature is
//!   `1/R`, and the beam bends away from the hotter face: `w'' = −(L₊ − L₋)/(H·L_long)`.
//!
//! Curvatures are integrated slice by slice (exact for piecewise-constant curvature) into
//! slopes `θ` and deflections `w`, then referred to the part's supports: clamped at one station
//! (a column on the bed, a head held by its carriages) or resting on two stations (a bed on its
//! feet, a slide on its guide carriages). Along the length the part is held at its datum station
//! (the fixed end of its measuring system). Angles are small (radii are kilometres), so
//! deflections are those of the arc to better than 10⁻⁶ relative.

use crate::deviation::{add, cross, scale, Deviation, Vec3};
use crate::network::Network;

/// The material of a part.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Material {
    /// Linear expansion coefficient α in 1/K.
    pub alpha_per_k: f64,
    /// Density in kg/m³.
    pub density_kg_m3: f64,
    /// Specific heat in J/(kg·K).
    pub specific_heat_j_kg_k: f64,
    /// Thermal conductivity in W/(m·K).
    pub conductivity_w_m_k: f64,
}

impl Material {
    /// Grey cast iron (EN-GJL-250): α = 10.5e-6 /K, ρ = 7200 kg/m³, c = 460 J/(kg·K),
    /// k = 48 W/(m·K).
    pub const CAST_IRON: Material = Material {
        alpha_per_k: 10.5e-6,
        density_kg_m3: 7200.0,
        specific_heat_j_kg_k: 460.0,
        conductivity_w_m_k: 48.0,
    };
    /// Structural steel: α = 11.5e-6 /K, ρ = 7850 kg/m³, c = 470 J/(kg·K), k = 45 W/(m·K).
    pub const STEEL: Material = Material {
        alpha_per_k: 11.5e-6,
        density_kg_m3: 7850.0,
        specific_heat_j_kg_k: 470.0,
        conductivity_w_m_k: 45.0,
    };
}

/// How a part is held, which fixes its rigid-body motion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Support {
    /// Clamped at one station (mm from the part's start): no deflection, no slope there.
    Clamped {
        /// Station of the clamp in mm.
        at_mm: f64,
    },
    /// Resting on two stations (mm from the part's start): no deflection at either.
    TwoPoint {
        /// First support station in mm.
        a_mm: f64,
        /// Second support station in mm.
        b_mm: f64,
    },
}

/// A structural part modelled as a beam.
#[derive(Debug, Clone, PartialEq)]
pub struct Beam {
    /// Name (`column`), also the prefix of its node names.
    pub name: String,
    /// Direction of the length (unit vector, world axes).
    pub e_len: Vec3,
    /// Direction of the height: the `+h` face is the top (or front) face.
    pub e_h: Vec3,
    /// Direction of the width: the `+w` face.
    pub e_w: Vec3,
    /// Length in mm.
    pub length_mm: f64,
    /// Height (across `e_h`) in mm.
    pub height_mm: f64,
    /// Width (across `e_w`) in mm.
    pub width_mm: f64,
    /// Number of slices along the length (each has four nodes).
    pub segments: usize,
    /// Material.
    pub material: Material,
    /// Share of the bounding box that is metal (ribbed castings: 0.3–0.5): scales the heat
    /// capacity.
    pub fill: f64,
    /// Share of the section that carries heat across and along the part: heat flows through
    /// thin walls and ribs, so this is well below `fill` (0.08–0.2 for ribbed castings).
    pub web: f64,
    /// How the part is held.
    pub support: Support,
    /// Station (mm) that does not move along the length.
    pub datum_mm: f64,
    /// Where across the height the part is held, as an offset along `e_h` from the centreline
    /// (mm): −H/2 for a part resting on its bottom face (a bed on its feet, a slide on its
    /// carriages), 0 for a part held at its centreline. The section grows away from it.
    pub support_offset_mm: f64,
    /// Index of the first of its `4·segments` nodes in the network.
    pub first_node: usize,
}

/// Which corner of a slice: `h` = +h face (top/front), `w` = +w face.
pub fn corner(h: bool, w: bool) -> usize {
    2 * usize::from(h) + usize::from(w)
}

impl Beam {
    /// Node index of slice `seg`, corner (`h`, `w`).
    pub fn node(&self, seg: usize, h: bool, w: bool) -> usize {
        self.first_node + 4 * seg + corner(h, w)
    }

    /// Number of nodes (4 per slice).
    pub fn node_count(&self) -> usize {
        4 * self.segments
    }

    /// Slice length in mm.
    pub fn slice_mm(&self) -> f64 {
        self.length_mm / self.segments as f64
    }

    /// The slice containing station `s` (clamped to the part).
    pub fn slice_at(&self, s_mm: f64) -> usize {
        let i = (s_mm / self.slice_mm()).floor();
        (i.max(0.0) as usize).min(self.segments - 1)
    }

    /// Adds the part's nodes to the network: capacities, conduction inside the part, and
    /// convection `h_conv` (W/(m²·K)) from its faces, each face's exposed share given as
    /// `[−h, +h, −w, +w, ends]`. Sets `first_node`.
    pub fn add_to(&mut self, net: &mut Network, h_conv_w_m2k: f64, exposed: [f64; 5]) {
        self.first_node = net.len();
        let m = self.material;
        let (l, hh, ww) = (
            self.slice_mm() * 1e-3,
            self.height_mm * 1e-3 / 2.0,
            self.width_mm * 1e-3 / 2.0,
        );
        let cap = m.density_kg_m3 * m.specific_heat_j_kg_k * self.fill * l * hh * ww;
        for seg in 0..self.segments {
            for h in [false, true] {
                for w in [false, true] {
                    let mut area =
                        l * ww * exposed[usize::from(h)] + l * hh * exposed[2 + usize::from(w)];
                    if seg == 0 || seg + 1 == self.segments {
                        area += hh * ww * exposed[4];
                    }
                    let name = format!(
                        "{}.s{seg}.{}.{}",
                        self.name,
                        if h { "+h" } else { "-h" },
                        if w { "+w" } else { "-w" }
                    );
                    net.add_node(name, cap, h_conv_w_m2k * area);
                }
            }
        }
        let k = m.conductivity_w_m_k * self.web;
        let g_h = k * l * ww / hh; // across the height: area ℓ·W/2, distance H/2
        let g_w = k * l * hh / ww; // across the width
        let g_l = k * hh * ww / l; // along the length
        for seg in 0..self.segments {
            for w in [false, true] {
                net.link(self.node(seg, false, w), self.node(seg, true, w), g_h);
            }
            for h in [false, true] {
                net.link(self.node(seg, h, false), self.node(seg, h, true), g_w);
            }
            if seg + 1 < self.segments {
                for c in 0..4 {
                    net.link(
                        self.first_node + 4 * seg + c,
                        self.first_node + 4 * (seg + 1) + c,
                        g_l,
                    );
                }
            }
        }
    }

    /// The part's shape at the given node temperatures (°C) and zero-strain temperature `t_ref`.
    pub fn shape(&self, temps_c: &[f64], t_ref_c: f64) -> Shape {
        let a = self.material.alpha_per_k;
        let n = self.segments;
        let l = self.slice_mm();
        let mut strain = Vec::with_capacity(n);
        let mut kappa_h = Vec::with_capacity(n);
        let mut kappa_w = Vec::with_capacity(n);
        let t = |seg, h, w| temps_c[self.node(seg, h, w)] - t_ref_c;
        for seg in 0..n {
            let (pp, pm, mp, mm) = (
                t(seg, true, true),
                t(seg, true, false),
                t(seg, false, true),
                t(seg, false, false),
            );
            strain.push(a * (pp + pm + mp + mm) / 4.0);
            kappa_h.push(curvature(
                l,
                self.height_mm,
                a,
                (pp + pm) / 2.0,
                (mp + mm) / 2.0,
            ));
            kappa_w.push(curvature(
                l,
                self.width_mm,
                a,
                (pp + mp) / 2.0,
                (pm + mm) / 2.0,
            ));
        }
        Shape::new(self, strain, kappa_h, kappa_w)
    }
}

/// Curvature (1/mm) of a slice of length `l` and depth `d` whose `+` face is `dt_plus` and `−` face
/// `dt_minus` above the zero-strain temperature: `(L₊ − L₋)/(d·L_long)` = 1/R of the bending
/// radius, signed positive when the `+` face is longer.
pub fn curvature(l_mm: f64, depth_mm: f64, alpha: f64, dt_plus: f64, dt_minus: f64) -> f64 {
    let lp = l_mm * (1.0 + alpha * dt_plus);
    let lm = l_mm * (1.0 + alpha * dt_minus);
    (lp - lm) / (depth_mm * lp.max(lm))
}

/// The bending radius `R = H·L_bottom/(L_bottom − L_top)` (docs/glossary.md) of a part of length
/// `L` and height `H` heated by `dt_bottom` below and `dt_top` above (mm; infinite without
/// gradient).
pub fn bending_radius_mm(l_mm: f64, h_mm: f64, alpha: f64, dt_bottom: f64, dt_top: f64) -> f64 {
    let lb = l_mm + alpha * l_mm * dt_bottom;
    let lt = l_mm + alpha * l_mm * dt_top;
    h_mm * lb / (lb - lt)
}

/// The deformed shape of one part: per-slice strain and curvatures, integrated.
#[derive(Debug, Clone, PartialEq)]
pub struct Shape {
    l: f64,
    strain: Vec<f64>,
    kh: Vec<f64>,
    kw: Vec<f64>,
    // raw integrals from station 0 at slice boundaries: axial u, slope θ, deflection w
    u0: Vec<f64>,
    th: Vec<f64>,
    wh: Vec<f64>,
    tw: Vec<f64>,
    ww: Vec<f64>,
    // support corrections: w_true(s) = w_raw(s) − (c0 + c1·s), θ_true = θ_raw − c1; u − u_datum
    ch: (f64, f64),
    cw: (f64, f64),
    u_datum: f64,
    e_len: Vec3,
    e_h: Vec3,
    e_w: Vec3,
}

/// Local deformation of a part at one station.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Station {
    /// Displacement along the length (mm).
    pub u_mm: f64,
    /// Deflection along `e_h` (mm).
    pub w_h_mm: f64,
    /// Deflection along `e_w` (mm).
    pub w_w_mm: f64,
    /// Slope `dw_h/ds` (rad).
    pub slope_h: f64,
    /// Slope `dw_w/ds` (rad).
    pub slope_w: f64,
    /// Strain of the section (growth of its height and width per mm).
    pub strain: f64,
}

impl Shape {
    fn new(beam: &Beam, strain: Vec<f64>, kh: Vec<f64>, kw: Vec<f64>) -> Self {
        let n = strain.len();
        let l = beam.slice_mm();
        let mut s = Self {
            l,
            u0: vec![0.0; n + 1],
            th: vec![0.0; n + 1],
            wh: vec![0.0; n + 1],
            tw: vec![0.0; n + 1],
            ww: vec![0.0; n + 1],
            strain,
            kh,
            kw,
            ch: (0.0, 0.0),
            cw: (0.0, 0.0),
            u_datum: 0.0,
            e_len: beam.e_len,
            e_h: beam.e_h,
            e_w: beam.e_w,
        };
        for i in 0..n {
            s.u0[i + 1] = s.u0[i] + s.strain[i] * l;
            s.th[i + 1] = s.th[i] - s.kh[i] * l;
            s.wh[i + 1] = s.wh[i] + s.th[i] * l - s.kh[i] * l * l / 2.0;
            s.tw[i + 1] = s.tw[i] - s.kw[i] * l;
            s.ww[i + 1] = s.ww[i] + s.tw[i] * l - s.kw[i] * l * l / 2.0;
        }
        // The support stations hold the face at `support_offset_mm`: there the centreline sits
        // `−strain·offset` away from the support (the section grows from the supported face).
        let line = |w: &dyn Fn(f64) -> (f64, f64), off: f64| match beam.support {
            Support::Clamped { at_mm } => {
                let (w0, t0) = w(at_mm);
                let w0 = w0 + s.strain_at(at_mm) * off;
                (w0 - t0 * at_mm, t0)
            }
            Support::TwoPoint { a_mm, b_mm } => {
                let wa = w(a_mm).0 + s.strain_at(a_mm) * off;
                let wb = w(b_mm).0 + s.strain_at(b_mm) * off;
                let c1 = (wb - wa) / (b_mm - a_mm);
                (wa - c1 * a_mm, c1)
            }
        };
        let ch = line(&|x| s.raw(x, true), beam.support_offset_mm);
        let cw = line(&|x| s.raw(x, false), 0.0);
        s.ch = ch;
        s.cw = cw;
        s.u_datum = s.raw_u(beam.datum_mm);
        s
    }

    /// Slice index and offset into it; stations beyond the ends continue the end slice's
    /// tangent (no curvature outside the part).
    fn locate(&self, s: f64) -> (usize, f64, bool) {
        let n = self.strain.len();
        if s <= 0.0 {
            (0, s, true)
        } else if s >= self.l * n as f64 {
            (n, s - self.l * n as f64, true)
        } else {
            let i = ((s / self.l) as usize).min(n - 1);
            (i, s - self.l * i as f64, false)
        }
    }

    fn raw(&self, s: f64, h: bool) -> (f64, f64) {
        let (theta, w, k) = if h {
            (&self.th, &self.wh, &self.kh)
        } else {
            (&self.tw, &self.ww, &self.kw)
        };
        let (i, t, outside) = self.locate(s);
        if outside {
            (w[i] + theta[i] * t, theta[i])
        } else {
            (
                w[i] + theta[i] * t - k[i] * t * t / 2.0,
                theta[i] - k[i] * t,
            )
        }
    }

    fn raw_u(&self, s: f64) -> f64 {
        let (i, t, outside) = self.locate(s);
        if outside {
            let e = self.strain[i.min(self.strain.len() - 1)];
            self.u0[i] + e * t
        } else {
            self.u0[i] + self.strain[i] * t
        }
    }

    fn strain_at(&self, s: f64) -> f64 {
        let (i, _, _) = self.locate(s);
        self.strain[i.min(self.strain.len() - 1)]
    }

    /// The deformation at station `s` (mm from the part's start).
    pub fn station(&self, s: f64) -> Station {
        let (wh, th) = self.raw(s, true);
        let (ww, tw) = self.raw(s, false);
        let (i, _, _) = self.locate(s);
        Station {
            u_mm: self.raw_u(s) - self.u_datum,
            w_h_mm: wh - (self.ch.0 + self.ch.1 * s),
            w_w_mm: ww - (self.cw.0 + self.cw.1 * s),
            slope_h: th - self.ch.1,
            slope_w: tw - self.cw.1,
            strain: self.strain[i.min(self.strain.len() - 1)],
        }
    }

    /// The deviation, relative to the part's supports, of the section at station `s`, referred
    /// to the point offset by `a` along `e_h` and `b` along `e_w` from the centreline, whose
    /// nominal world position is `at_mm`. The section turns with the slopes and grows with the
    /// slice's strain.
    pub fn deviation(&self, s: f64, a_mm: f64, b_mm: f64, at_mm: Vec3) -> Deviation {
        let st = self.station(s);
        let rot = add(
            scale(st.slope_h, cross(self.e_len, self.e_h)),
            scale(st.slope_w, cross(self.e_len, self.e_w)),
        );
        let centre = add(
            scale(st.u_mm, self.e_len),
            add(scale(st.w_h_mm, self.e_h), scale(st.w_w_mm, self.e_w)),
        );
        let offset = add(scale(a_mm, self.e_h), scale(b_mm, self.e_w));
        Deviation {
            at_mm,
            translation_mm: add(centre, add(cross(rot, offset), scale(st.strain, offset))),
            rotation_rad: rot,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn slide(support: Support) -> Beam {
        Beam {
            name: "slide".into(),
            e_len: [1.0, 0.0, 0.0],
            e_h: [0.0, 0.0, 1.0],
            e_w: [0.0, 1.0, 0.0],
            length_mm: 500.0,
            height_mm: 100.0,
            width_mm: 200.0,
            segments: 5,
            material: Material::STEEL,
            fill: 1.0,
            web: 1.0,
            support,
            datum_mm: 0.0,
            support_offset_mm: 0.0,
            first_node: 0,
        }
    }

    fn temps(beam: &Beam, top: f64, bottom: f64) -> Vec<f64> {
        let mut t = vec![0.0; beam.node_count()];
        for seg in 0..beam.segments {
            for w in [false, true] {
                t[beam.node(seg, true, w)] = top;
                t[beam.node(seg, false, w)] = bottom;
            }
        }
        t
    }

    /// Uniform heating by 8 K of a 500 mm steel slide (α = 11.5e-6): ΔL = α·L·ΔT
    /// = 11.5e-6·500·8 = 0.046 mm at the free end, exactly; the 100 mm height grows by
    /// 11.5e-6·100·8 = 0.0092 mm (top face 0.0046 mm above the centreline's growth); no bending.
    #[test]
    fn uniform_heating_gives_alpha_l_delta_t() {
        let b = slide(Support::Clamped { at_mm: 0.0 });
        let shape = b.shape(&temps(&b, 28.0, 28.0), 20.0);
        let end = shape.station(500.0);
        assert!((end.u_mm - 0.046).abs() < 1e-15);
        assert!(end.w_h_mm.abs() < 1e-18 && end.slope_h.abs() < 1e-18);
        let top = shape.deviation(500.0, 50.0, 0.0, [500.0, 0.0, 50.0]);
        assert!((top.translation_mm[0] - 0.046).abs() < 1e-15);
        assert!((top.translation_mm[2] - 0.0046).abs() < 1e-15);
    }

    /// The bending radius for a 500 mm steel slide, H = 100 mm, bottom 3 K and top 1 K above the
    /// reference: L_bottom = 500·(1 + 3α) = 500.01725 mm, L_top = 500.00575 mm,
    /// R = 100·500.01725/0.0115 = 4 347 976.09 mm. The slide clamped at one end lies on the arc
    /// of that radius: its sag at s is R − √(R² − s²) = 28.7490 µm at s = 500 mm and 7.1873 µm at
    /// 250 mm, and it bends away from the hotter bottom (upwards, the ends rise).
    #[test]
    fn a_gradient_gives_the_bending_radius_and_the_arc_sag() {
        let alpha = Material::STEEL.alpha_per_k;
        let r = bending_radius_mm(500.0, 100.0, alpha, 3.0, 1.0);
        assert!((r - 4_347_976.086_973).abs() < 1e-3, "R = {r}");
        // Per slice the same radius: curvature = 1/R.
        let k = curvature(100.0, 100.0, alpha, 1.0, 3.0);
        assert!((k * r + 1.0).abs() < 1e-9, "{}", k * r);
        let b = slide(Support::Clamped { at_mm: 0.0 });
        let shape = b.shape(&temps(&b, 21.0, 23.0), 20.0);
        for (s, expect_um) in [(500.0, 28.7490), (250.0, 7.1873)] {
            let arc = r - (r * r - s * s).sqrt();
            assert!((arc * 1e3 - expect_um).abs() < 1e-4);
            let w = shape.station(s).w_h_mm;
            assert!(w > 0.0, "a hotter bottom bends the slide up");
            assert!((w - arc).abs() < 1e-6 * arc, "s {s}: {w} vs {arc}");
        }
        // Resting on both ends instead, the middle sinks by R − √(R² − 250²) = 7.1873 µm.
        let b2 = slide(Support::TwoPoint {
            a_mm: 0.0,
            b_mm: 500.0,
        });
        let mid = b2.shape(&temps(&b2, 21.0, 23.0), 20.0).station(250.0);
        assert!((mid.w_h_mm * 1e3 + 7.1873).abs() < 1e-4);
        assert!(mid.slope_h.abs() < 1e-15);
    }
}
