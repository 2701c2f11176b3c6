//! On-line re-identification of an existing model (seed C, section 4; the re-learning of seed
//! D's prior art): probe measurements logged during operation re-estimate the model's
//! parameters by recursive least squares with forgetting, and the re-estimated parameters
//! replace the running ones only when the running model's recent error exceeds a threshold and
//! the candidate is clearly better ([`truepos_model::SwitchRule`]).
//!
//! Only the parameters change: the structure (which summands, which position terms) is the
//! model's own, as seed C prescribes ("a working compensation model already exists; only its
//! parameters are re-estimated").

use truepos_model::{CycleInput, Machine, Model, Rls, SwitchRule};

/// Re-identification of one model from probe measurements.
#[derive(Debug, Clone)]
pub struct Reidentifier {
    running: Model,
    rls: Rls,
    rule: SwitchRule,
    phi: Vec<f64>,
    switches: usize,
}

/// What one probe measurement did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    /// Error of the running model on this measurement (µm), before any switch.
    pub running_error_um: f64,
    /// Error of the re-estimated parameters on it, before their update (µm).
    pub candidate_error_um: f64,
    /// Whether the re-estimated parameters replaced the running ones after it.
    pub switched: bool,
}

impl Reidentifier {
    /// Starts from a running model. `lambda` is the forgetting factor (0.98 forgets with a time
    /// constant of about 50 measurements); `threshold_um` the recent RMS error above which a
    /// switch is considered.
    pub fn new(model: Model, lambda: f64, threshold_um: f64) -> Self {
        let theta = model.parameters();
        // P₀ small relative to the parameters' scale: the existing model is a good prior, the
        // measurements correct it rather than replace it from nothing.
        Self {
            rls: Rls::new(&theta, 10.0, lambda),
            rule: SwitchRule::new(threshold_um),
            phi: vec![0.0; theta.len()],
            running: model,
            switches: 0,
        }
    }

    /// The model in use now.
    pub fn running(&self) -> &Model {
        &self.running
    }

    /// How many times the parameters were switched.
    pub fn switches(&self) -> usize {
        self.switches
    }

    /// One probe measurement: the measured error of `axis` at the inputs of that instant (the
    /// probe's position as the axis positions). Invalid inputs are ignored (`None`).
    pub fn observe(
        &mut self,
        machine: &Machine,
        input: &CycleInput<'_>,
        axis: usize,
        measured_um: f64,
    ) -> Option<Step> {
        if !measured_um.is_finite() {
            return None;
        }
        self.running.regressors(input, axis, &mut self.phi).ok()?;
        let running = measured_um - dot(&self.phi, &self.running.parameters());
        let candidate = self.rls.update(&self.phi, measured_um)?;
        self.rule.record(running, candidate);
        let mut switched = false;
        if self.rule.should_switch() {
            if let Ok(m) = self.running.with_parameters(machine, self.rls.theta()) {
                self.running = m;
                self.rule.switched();
                self.switches += 1;
                switched = true;
            }
        }
        Some(Step {
            running_error_um: running,
            candidate_error_um: candidate,
            switched,
        })
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}
