//! On-line re-identification of an existing model (probing re-identification, see
//! docs/glossary.md): probe measurements logged during operation re-estimate the model's
//! parameters by recursive least squares with forgetting, and the re-estimated parameters
//! replace the running ones only when the running model's recent error exceeds a threshold and
//! the candidate is clearly better ([`truepos_model::SwitchRule`]).
//!
//! Only the parameters change: the structure (which summands, which position terms) is the
//! model's own ("a working compensation model already exists; only its parameters are
//! re-estimated").

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

    /// The recursive estimate now, as a model: what the rule would switch to next. It keeps
    /// learning after a switch, while [`Reidentifier::running`] holds the parameters of the
    /// last switch. `None` if the estimate does not make a valid model.
    pub fn latest(&self, machine: &Machine) -> Option<Model> {
        self.running.with_parameters(machine, self.rls.theta()).ok()
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

impl Reidentifier {
    /// The switch rule's state now (recent RMS errors, samples since the last switch).
    pub fn rule(&self) -> &SwitchRule {
        &self.rule
    }
}

/// One probe event as the control logged it or a probe file holds it: the inputs of its cycle
/// (every machine temperature channel, lagged ones computed), the probed position per axis and
/// the measured error per axis (`None`: the axis was not measured).
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeEvent {
    /// Time of the event in s (service time or the run's `time_s`).
    pub time_s: f64,
    /// Where it came from, for messages (`probes.csv:14`, `service.sqlite: probes row 3`).
    pub place: String,
    /// Temperature per machine channel (°C).
    pub temperatures_c: Vec<f64>,
    /// Operating state per machine channel.
    pub operating: Vec<f64>,
    /// Probed position per machine axis (mm or degrees).
    pub position_mm: Vec<f64>,
    /// Measured error per machine axis (µm; µrad on a rotary axis).
    pub measured_um: Vec<Option<f64>>,
}

/// How re-identification runs over a sequence of probe events.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// Forgetting factor λ of the recursive least squares (0.5 … 1).
    pub lambda: f64,
    /// Recent RMS error (µm) of the running model above which the rule considers a switch.
    pub threshold_um: f64,
    /// Measurements of the most recent window on which the re-estimated model must be better
    /// than the old one.
    pub window: usize,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            lambda: 0.999,
            threshold_um: 3.0,
            window: 30,
        }
    }
}

/// Whether a re-identification produced a model to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// The rule switched and the re-estimated model is better on the most recent window.
    Switched,
    /// The running model stays; [`Outcome::reason`] says why.
    Kept,
}

/// RMS errors of the old and the re-estimated model on the most recent measurements.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WindowFigures {
    /// Measurements in the window.
    pub measurements: usize,
    /// RMS of measured − predicted by the model re-identification started from (µm).
    pub old_rmse_um: f64,
    /// The same for the model re-identification ends with (µm); equals the old one when no
    /// switch happened.
    pub new_rmse_um: f64,
}

/// What re-identification over a sequence of probe events did.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// Switched or kept.
    pub verdict: Verdict,
    /// Why, in a sentence.
    pub reason: String,
    /// The re-estimated model when the verdict is [`Verdict::Switched`].
    pub model: Option<Model>,
    /// Probe events given.
    pub events: usize,
    /// Axis measurements used (an event gives one per measured axis).
    pub measurements: usize,
    /// Measurements the model could not take (an input outside its valid range, a position
    /// outside travel): their places.
    pub skipped: Vec<String>,
    /// Time of the first and the last event used (s).
    pub first_time_s: f64,
    /// See `first_time_s`.
    pub last_time_s: f64,
    /// Switches the rule made along the sequence.
    pub switches: usize,
    /// The rule's recent RMS errors (running, candidate) at the end (µm).
    pub recent_rms_um: (f64, f64),
    /// The old and the re-estimated model on the most recent window.
    pub window: WindowFigures,
}

/// Re-identifies `model` over `events` in order: recursive least squares
/// with forgetting on the model's own structure, the switch rule along the way, and at the end
/// the check that the re-estimated parameters are better than the old ones on the most recent
/// `settings.window` measurements. Only a model that passes both is returned; its parameters
/// are the estimate after the last event (or those of the rule's last switch, should they do
/// better on the window).
pub fn reidentify(
    model: &Model,
    machine: &Machine,
    events: &[ProbeEvent],
    settings: Settings,
) -> Outcome {
    let mut re = Reidentifier::new(model.clone(), settings.lambda, settings.threshold_um);
    let mut used: Vec<(usize, usize)> = Vec::new();
    let mut skipped = Vec::new();
    let (mut first, mut last) = (f64::NAN, f64::NAN);
    for (i, ev) in events.iter().enumerate() {
        let input = CycleInput {
            temperatures_c: &ev.temperatures_c,
            positions: &ev.position_mm,
            operating: &ev.operating,
        };
        for (axis, m) in ev.measured_um.iter().enumerate() {
            let Some(m) = m else { continue };
            if re.observe(machine, &input, axis, *m).is_some() {
                used.push((i, axis));
                if first.is_nan() {
                    first = ev.time_s;
                }
                last = ev.time_s;
            } else {
                skipped.push(format!("{} ({})", ev.place, axis_name(machine, axis)));
            }
        }
    }
    let window_start = used.len().saturating_sub(settings.window.max(1));
    let recent = &used[window_start..];
    // Once the rule has switched, the estimate went on learning from every later probe, while
    // the parameters of the last switch saw only the probes before it (after a switch that
    // brings the error under the threshold the rule never switches again, so on a long log those
    // are the parameters of its first few measurements). The latest estimate is written unless
    // it does worse on the window than the last switch's.
    let new = (re.switches() > 0).then(|| {
        let switched = re.running().clone();
        match re.latest(machine) {
            Some(latest)
                if window_rmse(&latest, events, recent)
                    <= window_rmse(&switched, events, recent) =>
            {
                latest
            }
            _ => switched,
        }
    });
    let window = WindowFigures {
        measurements: recent.len(),
        old_rmse_um: window_rmse(model, events, recent),
        new_rmse_um: window_rmse(new.as_ref().unwrap_or(model), events, recent),
    };
    let rule = *re.rule();
    let (run, cand) = rule.recent_rms_um();
    let (verdict, reason) = verdict(new.is_some(), used.len(), &rule, &window, re.switches());
    Outcome {
        model: new.filter(|_| verdict == Verdict::Switched),
        verdict,
        reason,
        events: events.len(),
        measurements: used.len(),
        skipped,
        first_time_s: first,
        last_time_s: last,
        switches: re.switches(),
        recent_rms_um: (run, cand),
        window,
    }
}

/// Whether the re-estimated model replaces the old one, and why in a sentence: it must exist
/// (the switch rule switched, which needs enough measurements and a running error above the
/// threshold) and do better than the old model on the most recent window.
fn verdict(
    switched: bool,
    used: usize,
    rule: &SwitchRule,
    window: &WindowFigures,
    switches: usize,
) -> (Verdict, String) {
    let (run, cand) = rule.recent_rms_um();
    match switched {
        _ if used == 0 => (Verdict::Kept, "no usable probe measurement".to_string()),
        false if used < rule.min_samples as usize => (
            Verdict::Kept,
            format!(
                "{} probe measurements; the switch rule needs {} before it decides",
                used,
                rule.min_samples
            ),
        ),
        false if run <= rule.threshold_um => (
            Verdict::Kept,
            format!(
                "the running model's recent RMS error {run:.2} µm is not above the threshold {:.2} µm",
                rule.threshold_um
            ),
        ),
        false => (
            Verdict::Kept,
            format!(
                "the re-estimated parameters' recent RMS error {cand:.2} µm is not below {:.0} % of the running model's {run:.2} µm",
                100.0 * rule.margin
            ),
        ),
        true
            if window.new_rmse_um.partial_cmp(&window.old_rmse_um)
                != Some(core::cmp::Ordering::Less) =>
        {
            (
            Verdict::Kept,
            format!(
                "the re-estimated model is not better on the last {} measurements: {:.2} µm against the old model's {:.2} µm",
                window.measurements, window.new_rmse_um, window.old_rmse_um
            ),
        )
        }
        true => (
            Verdict::Switched,
            format!(
                "the rule switched {} time(s); on the last {} measurements the RMS error falls from {:.2} to {:.2} µm",
                switches,
                window.measurements,
                window.old_rmse_um,
                window.new_rmse_um
            ),
        ),
    }
}

fn axis_name(machine: &Machine, axis: usize) -> &str {
    machine.axes.get(axis).map_or("?", |a| a.name.as_str())
}

/// RMS of measured − predicted by `model` over the (event, axis) measurements listed.
fn window_rmse(model: &Model, events: &[ProbeEvent], which: &[(usize, usize)]) -> f64 {
    let mut se = 0.0;
    let mut n = 0usize;
    for &(i, axis) in which {
        let ev = &events[i];
        let input = CycleInput {
            temperatures_c: &ev.temperatures_c,
            positions: &ev.position_mm,
            operating: &ev.operating,
        };
        let (Ok(c), Some(Some(m))) = (model.evaluate(&input), ev.measured_um.get(axis)) else {
            continue;
        };
        if let Some(p) = c.error_um().get(axis) {
            se += (m - p).powi(2);
            n += 1;
        }
    }
    if n == 0 {
        f64::NAN
    } else {
        (se / n as f64).sqrt()
    }
}
