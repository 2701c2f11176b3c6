//! The lumped thermal network and its exponential integrator.
//!
//! Each node `i` has a heat capacity `C_i` (J/K); nodes exchange heat through conductances
//! `G_ij` (W/K) and lose it to the ambient air through `g_i` (W/K, convection and radiation
//! lumped). With node powers `P_i(t)` (W) and the ambient temperature `T_a(t)`:
//!
//! ```text
//! C dT/dt = −(K + diag g)·T + P(t) + g·T_a(t)        K: the conductance Laplacian
//!   dT/dt = A·T + C⁻¹·(P + g·T_a),   A = −C⁻¹·(K + diag g)
//! ```
//!
//! ## Integration method
//! The inputs are held constant over a step `h` (zero-order hold) and the linear system is then
//! integrated *exactly*:
//!
//! ```text
//! T_{k+1} = Φ·T_k + Γ·C⁻¹·(P_k + g·T_a,k),   Φ = e^{A·h},   Γ = ∫₀ʰ e^{A·τ} dτ
//! ```
//!
//! `Φ` and `Γ` are computed once per step size by scaling and squaring (`Φ(2h) = Φ(h)²`,
//! `Γ(2h) = (I + Φ(h))·Γ(h)`) from a Taylor series of degree 18 at a step scaled down until
//! `‖A·h‖₁ ≤ 1/2`. The scheme is unconditionally stable however stiff the network is (all
//! eigenvalues of `A` are real and ≤ 0, so `‖Φ‖` never grows), conserves energy exactly when
//! `g = 0` (`1ᵀ·C·Φ = 1ᵀ·C`, `1ᵀ·C·Γ·C⁻¹·P = h·ΣP`), and has no step limit from stability.
//! The only step limit is the zero-order hold: the inputs (spindle speed, axis speeds, ambient)
//! must be close to constant over one step — 1 s is far shorter than any change that matters
//! thermally. A step costs one dense `n × n` matrix–vector product plus one column per heated
//! node.

/// A dense square matrix stored column by column (`a[j * n + i]` is row `i`, column `j`), which
/// makes the matrix–vector product a sequence of vectorisable column updates.
#[derive(Debug, Clone, PartialEq)]
pub struct Matrix {
    n: usize,
    a: Vec<f64>,
}

impl Matrix {
    /// The `n × n` zero matrix.
    pub fn zeros(n: usize) -> Self {
        Self {
            n,
            a: vec![0.0; n * n],
        }
    }

    /// The `n × n` identity.
    pub fn identity(n: usize) -> Self {
        let mut m = Self::zeros(n);
        for i in 0..n {
            m.set(i, i, 1.0);
        }
        m
    }

    /// Dimension.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Entry at row `i`, column `j`.
    pub fn get(&self, i: usize, j: usize) -> f64 {
        self.a[j * self.n + i]
    }

    /// Sets the entry at row `i`, column `j`.
    pub fn set(&mut self, i: usize, j: usize, v: f64) {
        self.a[j * self.n + i] = v;
    }

    /// Column `j`.
    pub fn column(&self, j: usize) -> &[f64] {
        &self.a[j * self.n..(j + 1) * self.n]
    }

    /// The product `self · other`.
    pub fn mul(&self, other: &Matrix) -> Matrix {
        let n = self.n;
        let mut out = Matrix::zeros(n);
        for j in 0..n {
            let col = &mut out.a[j * n..(j + 1) * n];
            for k in 0..n {
                let b = other.a[j * n + k];
                if b != 0.0 {
                    axpy(col, b, &self.a[k * n..(k + 1) * n]);
                }
            }
        }
        out
    }

    /// `self + s · other`.
    pub fn add_scaled(&self, s: f64, other: &Matrix) -> Matrix {
        let mut out = self.clone();
        for (o, b) in out.a.iter_mut().zip(&other.a) {
            *o += s * b;
        }
        out
    }

    /// `s · self`.
    pub fn scaled(&self, s: f64) -> Matrix {
        let mut out = self.clone();
        out.a.iter_mut().for_each(|v| *v *= s);
        out
    }

    /// Maximum absolute column sum (the induced 1-norm).
    pub fn norm1(&self) -> f64 {
        (0..self.n)
            .map(|j| self.column(j).iter().map(|v| v.abs()).sum::<f64>())
            .fold(0.0, f64::max)
    }

    /// `y = self · x` (overwrites `y`).
    pub fn mul_vec_into(&self, x: &[f64], y: &mut [f64]) {
        y.iter_mut().for_each(|v| *v = 0.0);
        self.add_columns(y, x.iter().copied().enumerate());
    }

    /// `y += Σ s_j · column(j)` over the given `(j, s_j)`, four columns per pass over `y` (a
    /// quarter of the loads and stores of one pass per column).
    pub fn add_columns(&self, y: &mut [f64], mut cols: impl Iterator<Item = (usize, f64)>) {
        loop {
            let mut block = [(0usize, 0.0f64); 4];
            let mut k = 0;
            while k < 4 {
                match cols.next() {
                    Some(c) => {
                        block[k] = c;
                        k += 1;
                    }
                    None => break,
                }
            }
            if k < 4 {
                for &(j, s) in &block[..k] {
                    axpy(y, s, self.column(j));
                }
                return;
            }
            let [(j0, s0), (j1, s1), (j2, s2), (j3, s3)] = block;
            let (c0, c1, c2, c3) = (
                self.column(j0),
                self.column(j1),
                self.column(j2),
                self.column(j3),
            );
            for (i, yi) in y.iter_mut().enumerate() {
                *yi += s0 * c0[i] + s1 * c1[i] + s2 * c2[i] + s3 * c3[i];
            }
        }
    }
}

/// `y += s · x`.
#[inline]
pub(crate) fn axpy(y: &mut [f64], s: f64, x: &[f64]) {
    for (yi, xi) in y.iter_mut().zip(x) {
        *yi += s * xi;
    }
}

/// The thermal network: capacities, conductances, convection to ambient.
#[derive(Debug, Clone, Default)]
pub struct Network {
    /// Heat capacity of each node in J/K.
    pub capacity_j_per_k: Vec<f64>,
    /// Name of each node (`column.s2.front.left`), for people and for sensor placement.
    pub names: Vec<String>,
    /// Conductances between nodes: `(i, j, G)` in W/K.
    pub links: Vec<(usize, usize, f64)>,
    /// Conductance of each node to the ambient air in W/K.
    pub ambient_w_per_k: Vec<f64>,
}

impl Network {
    /// Adds a node and returns its index.
    pub fn add_node(
        &mut self,
        name: impl Into<String>,
        capacity_j_per_k: f64,
        ambient_w_per_k: f64,
    ) -> usize {
        self.names.push(name.into());
        self.capacity_j_per_k.push(capacity_j_per_k);
        self.ambient_w_per_k.push(ambient_w_per_k);
        self.names.len() - 1
    }

    /// Connects two nodes with a conductance in W/K (added to any existing one).
    pub fn link(&mut self, i: usize, j: usize, g_w_per_k: f64) {
        if i != j && g_w_per_k > 0.0 {
            self.links.push((i, j, g_w_per_k));
        }
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.capacity_j_per_k.len()
    }

    /// Whether the network has no node.
    pub fn is_empty(&self) -> bool {
        self.capacity_j_per_k.is_empty()
    }

    /// The system matrix `A = −C⁻¹·(K + diag g)`.
    pub fn system_matrix(&self) -> Matrix {
        let n = self.len();
        let mut a = Matrix::zeros(n);
        for &(i, j, g) in &self.links {
            a.set(i, j, a.get(i, j) + g);
            a.set(j, i, a.get(j, i) + g);
            a.set(i, i, a.get(i, i) - g);
            a.set(j, j, a.get(j, j) - g);
        }
        for i in 0..n {
            a.set(i, i, a.get(i, i) - self.ambient_w_per_k[i]);
        }
        for j in 0..n {
            for i in 0..n {
                a.set(i, j, a.get(i, j) / self.capacity_j_per_k[i]);
            }
        }
        a
    }

    /// Discretises the network for a step of `h_s` seconds.
    pub fn discretise(&self, h_s: f64) -> Stepper {
        let n = self.len();
        let a = self.system_matrix();
        let (phi, gamma) = exp_and_integral(&a, h_s);
        // Input matrix for powers: Γ·C⁻¹ (column j scaled by 1/C_j).
        let mut gp = gamma.clone();
        for j in 0..n {
            let c = self.capacity_j_per_k[j];
            for v in &mut gp.a[j * n..(j + 1) * n] {
                *v /= c;
            }
        }
        let mut ga = vec![0.0; n];
        gp.mul_vec_into(&self.ambient_w_per_k, &mut ga);
        Stepper {
            h_s,
            phi,
            power_input: gp,
            ambient_input: ga,
            scratch: vec![0.0; n],
            power: vec![0.0; n],
        }
    }
}

/// `(e^{A·h}, ∫₀ʰ e^{A·τ} dτ)` by Taylor series and scaling and squaring.
pub fn exp_and_integral(a: &Matrix, h: f64) -> (Matrix, Matrix) {
    let n = a.n();
    let norm = a.norm1() * h;
    let mut squarings = 0u32;
    let mut hs = h;
    if norm > 0.5 {
        squarings = (norm / 0.5).log2().ceil() as u32;
        hs = h / 2f64.powi(squarings as i32);
    }
    // Φ = Σ (A hs)^k / k!,  Γ = hs · Σ (A hs)^k / (k+1)!
    let ah = a.scaled(hs); // A·hs
    let mut term = Matrix::identity(n); // (A hs)^k / k!
    let mut phi = Matrix::identity(n);
    let mut gamma = Matrix::identity(n).scaled(hs); // hs·I
    for k in 1..=18u32 {
        term = ah.mul(&term);
        let inv_k = 1.0 / f64::from(k);
        term.a.iter_mut().for_each(|v| *v *= inv_k);
        phi = phi.add_scaled(1.0, &term);
        gamma = gamma.add_scaled(hs / f64::from(k + 1), &term);
    }
    for _ in 0..squarings {
        let g2 = gamma.add_scaled(1.0, &phi.mul(&gamma));
        phi = phi.mul(&phi);
        gamma = g2;
    }
    (phi, gamma)
}

/// One discretised step of the network: `T ← Φ·T + (Γ·C⁻¹)·P + (Γ·C⁻¹·g)·T_a`.
#[derive(Debug, Clone)]
pub struct Stepper {
    h_s: f64,
    phi: Matrix,
    power_input: Matrix,
    ambient_input: Vec<f64>,
    scratch: Vec<f64>,
    power: Vec<f64>,
}

impl Stepper {
    /// Step size in s.
    pub fn step_s(&self) -> f64 {
        self.h_s
    }

    /// Advances the temperatures by one step. `powers` lists `(node, W)` pairs (repeats add up).
    pub fn step(&mut self, temps: &mut [f64], powers: &[(usize, f64)], ambient_c: f64) {
        self.phi.mul_vec_into(temps, &mut self.scratch);
        axpy(&mut self.scratch, ambient_c, &self.ambient_input);
        // Sum the powers per node first, then add one column per heated node.
        for &(node, p) in powers {
            self.power[node] += p;
        }
        let power = &mut self.power;
        self.power_input.add_columns(
            &mut self.scratch,
            powers.iter().filter_map(|&(node, _)| {
                let p = std::mem::take(&mut power[node]);
                (p != 0.0).then_some((node, p))
            }),
        );
        temps.copy_from_slice(&self.scratch);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One node, C = 50 kJ/K, g = 10 W/K, P = 100 W, ambient 20 °C: steady state
    /// T∞ = 20 + 100/10 = 30 °C, time constant τ = C/g = 5000 s. After τ the rise is
    /// 10·(1 − e⁻¹) = 6.3212 K; after 5τ, 10·(1 − e⁻⁵) = 9.9326 K.
    #[test]
    fn single_node_steady_state_and_time_constant() {
        let mut net = Network::default();
        net.add_node("n", 50_000.0, 10.0);
        for h in [1.0, 7.0, 250.0] {
            let mut st = net.discretise(h);
            let mut t = [20.0];
            let steps = (5000.0 / h) as usize;
            let mut elapsed = 0.0;
            for _ in 0..steps {
                st.step(&mut t, &[(0, 100.0)], 20.0);
                elapsed += h;
            }
            let exact = 20.0 + 10.0 * (1.0 - (-elapsed / 5000.0f64).exp());
            assert!((t[0] - exact).abs() < 1e-9, "h {h}: {} vs {exact}", t[0]);
            for _ in 0..(20_000.0 / h) as usize {
                st.step(&mut t, &[(0, 100.0)], 20.0);
            }
            assert!((t[0] - 30.0).abs() < 0.07, "h {h}: {}", t[0]);
        }
        let mut st = net.discretise(5000.0);
        let mut t = [20.0];
        st.step(&mut t, &[(0, 100.0)], 20.0);
        assert!((t[0] - 26.321_205_588).abs() < 1e-8);
    }

    /// Without convection the total heat Σ C_i·T_i grows by exactly ∫P dt, however stiff the
    /// network and however long the step.
    #[test]
    fn energy_is_conserved_without_convection() {
        let mut net = Network::default();
        let caps = [1_000.0, 200_000.0, 5.0, 40_000.0];
        for (i, c) in caps.iter().enumerate() {
            net.add_node(format!("n{i}"), *c, 0.0);
        }
        net.link(0, 1, 3.0);
        net.link(1, 2, 500.0);
        net.link(2, 3, 0.2);
        net.link(0, 3, 40.0);
        for h in [1.0, 60.0] {
            let mut st = net.discretise(h);
            let mut t = [20.0, 21.0, 19.0, 25.0];
            let e0: f64 = t.iter().zip(&caps).map(|(t, c)| t * c).sum();
            for _ in 0..1000 {
                st.step(&mut t, &[(0, 150.0), (2, 30.0)], 35.0);
            }
            let e1: f64 = t.iter().zip(&caps).map(|(t, c)| t * c).sum();
            let added = 180.0 * 1000.0 * h;
            assert!(
                ((e1 - e0) - added).abs() < 1e-9 * added,
                "h {h}: {} vs {added}",
                e1 - e0
            );
        }
    }

    /// Two nodes coupled by G relax to their mean with rate G·(1/C1 + 1/C2).
    #[test]
    fn two_nodes_relax_with_the_analytic_rate() {
        let mut net = Network::default();
        net.add_node("a", 100.0, 0.0);
        net.add_node("b", 300.0, 0.0);
        net.link(0, 1, 2.0);
        let mut st = net.discretise(10.0);
        let mut t = [30.0, 10.0];
        st.step(&mut t, &[], 0.0);
        // mean (weighted) = (100·30 + 300·10)/400 = 15; difference 20·e^{−2·(1/100+1/300)·10}
        let diff = 20.0 * (-2.0 * (1.0 / 100.0 + 1.0 / 300.0) * 10.0f64).exp();
        assert!(((t[0] - t[1]) - diff).abs() < 1e-12);
        assert!(((100.0 * t[0] + 300.0 * t[1]) / 400.0 - 15.0).abs() < 1e-12);
    }
}
