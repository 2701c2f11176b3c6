//! A model's coefficients as one parameter vector θ, and the regressors φ with
//! error_n = Σ_p θ_p · φ_p(n, cycle): the link between a model's structure and least squares.
//!
//! Fitting a structure (which summands, which position terms) to measured errors, and
//! re-estimating the parameters of an existing model on line (probing re-identification: "only
//! its parameters are re-estimated"), both work on these regressors.
//!
//! Parameter order: part by part; within a part, summand by summand (K_nm0, then each K_nmj in
//! order), then the part's constants. Disabled parts count too: their parameters exist.

use alloc::vec::Vec;

use crate::evaluate::{CycleInput, EvalError};
use crate::machine::{Machine, Reference};
use crate::model::{Model, ModelError, Part, PositionFactor};

impl Model {
    /// Number of parameters (coefficients and constants).
    pub fn parameter_count(&self) -> usize {
        self.parts()
            .iter()
            .map(|p| {
                p.summands
                    .iter()
                    .map(|s| 1 + s.position_terms.len())
                    .sum::<usize>()
                    + p.constants_um.len()
            })
            .sum()
    }

    /// The parameters θ in order.
    pub fn parameters(&self) -> Vec<f64> {
        let mut theta = Vec::with_capacity(self.parameter_count());
        for p in self.parts() {
            for s in &p.summands {
                theta.push(s.k0_um_per_k);
                theta.extend(s.position_terms.iter().map(|t| t.k_um_per_k));
            }
            theta.extend(p.constants_um.iter().map(|c| c.1));
        }
        theta
    }

    /// The same structure with new parameters θ (in [`parameters`](Self::parameters) order).
    pub fn with_parameters(&self, machine: &Machine, theta: &[f64]) -> Result<Model, ModelError> {
        let mut it = theta.iter().copied();
        let mut next = || it.next().unwrap_or(f64::NAN);
        let parts: Vec<Part> = self
            .parts()
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let mut q = p.clone();
                q.enabled = self.part_enabled(i);
                for s in &mut q.summands {
                    s.k0_um_per_k = next();
                    for t in &mut s.position_terms {
                        t.k_um_per_k = next();
                    }
                }
                for c in &mut q.constants_um {
                    c.1 = next();
                }
                q
            })
            .collect();
        // A θ too short leaves NaN, which Model::new refuses.
        Model::new(self.name(), machine, parts)
    }

    /// Fills `phi` (length [`parameter_count`](Self::parameter_count)) with the regressors of
    /// the error of `axis` for one cycle: error_axis = Σ θ_p · φ_p. Inputs are checked as in
    /// [`evaluate`](Self::evaluate). Allocates nothing.
    pub fn regressors(
        &self,
        input: &CycleInput<'_>,
        axis: usize,
        phi: &mut [f64],
    ) -> Result<(), EvalError> {
        // The same checks as a cycle: a regressor row is never built from a bad value.
        self.evaluate(input)?;
        let ratio = |a: usize| {
            let ax = &self.axes[a];
            ((input.positions[a] - ax.travel_min) / ax.length).clamp(0.0, 1.0)
        };
        let mut k = 0;
        let mut put = |k: &mut usize, v: f64| {
            if let Some(slot) = phi.get_mut(*k) {
                *slot = v;
            }
            *k += 1;
        };
        for p in self.parts() {
            for s in &p.summands {
                let on_axis = s.axis == axis;
                let dt = if on_axis {
                    let d = &self.difference_inputs[self
                        .used_differences
                        .iter()
                        .position(|&u| u == s.difference)
                        .unwrap_or(0)];
                    let reference = match d.minus {
                        Reference::Sensor(r) => input.temperatures_c[r],
                        Reference::Fixed(t) => t,
                    };
                    let bed = s
                        .bed_multiplier
                        .map_or(1.0, |b| PositionFactor::BedFactor.of_ratio(ratio(b)));
                    (input.temperatures_c[d.plus] - reference) * bed
                } else {
                    0.0
                };
                put(&mut k, dt);
                for t in &s.position_terms {
                    put(
                        &mut k,
                        if on_axis {
                            dt * t.factor.of_ratio(ratio(t.axis))
                        } else {
                            0.0
                        },
                    );
                }
            }
            for c in &p.constants_um {
                put(&mut k, if c.0 == axis { 1.0 } else { 0.0 });
            }
        }
        Ok(())
    }
}
