//! The figures of one end-to-end run, as text or JSON.

use super::invariant::InvariantReport;
use super::CheckConfig;

/// The figures of one end-to-end run.
#[derive(Debug, Clone, PartialEq)]
pub struct CheckReport {
    /// Servo cycles recorded.
    pub samples: usize,
    /// Cycles compared with the model (active, settled).
    pub compared: usize,
    /// Largest |joint(k) − (nominal + applied offset)(k − d)|, mm: LinuxCNC added the offset to
    /// the joint, `joint_delay_cycles` = d servo cycles later (its interpolator's pipeline).
    pub joint_mismatch_mm: f64,
    /// The pipeline delay d between axis commands and joint feedback that fits best, cycles.
    pub joint_delay_cycles: usize,
    /// Largest |applied − model| over compared cycles, µm.
    pub max_diff_um: f64,
    /// RMS of applied − model over compared cycles, µm.
    pub rms_diff_um: f64,
    /// Largest |applied − model| / span of the position-dependent terms, over cycles where
    /// the component and the servo thread ran in step (no update gap, see below).
    pub max_lag_fraction: f64,
    /// The same over every compared cycle, update gaps included.
    pub max_lag_fraction_all: f64,
    /// Moving cycles inside or just after an update gap of more than 2 cycles, as a fraction of
    /// the moving cycles.
    pub gap_fraction: f64,
    /// Moving cycles compared with the model in step (outside update gaps): what
    /// `max_lag_fraction` rests on.
    pub in_step_moving_cycles: usize,
    /// Longest run of servo cycles in which an axis moved but the offsets truepos sent did not
    /// change (an update gap: the component or LinuxCNC's servo thread was held up), cycles.
    pub longest_update_gap_cycles: usize,
    /// Largest |applied offset| seen, µm.
    pub max_offset_um: f64,
    /// Largest axis speed reached, mm/min.
    pub max_feed_mm_per_min: f64,
    /// Largest offset rate per axis over the rate window, µm/s.
    pub max_rate_um_per_s: Vec<f64>,
    /// The envelope's rate per axis, µm/s.
    pub rate_limit_um_per_s: Vec<f64>,
    /// Cycles with status "holding" (a sensor fault).
    pub holding_samples: usize,
    /// Changes of the model in effect on path 1 (`truepos.path.1.model`).
    pub model_switches: usize,
    /// Changes of the axis configuration (`truepos.axis.L.path`).
    pub axis_switches: usize,
    /// Settled, active cycles in which the component used another model than the
    /// axis-combination rule selects.
    pub wrong_model_cycles: usize,
    /// Settled, active cycles compared with a fitted dynamic model (stepped through the
    /// recorded cycles), among `compared`.
    pub dynamic_compared: usize,
    /// Largest distance of an applied offset from the dynamic model's compensation over the
    /// cycles it may stem from, µm (see `CheckConfig::max_dynamic_excess_um`).
    pub max_dynamic_excess_um: f64,
    /// Largest |applied offset| on an axis in no path (settled cycles), µm.
    pub max_parked_offset_um: f64,
    /// The output invariant on the applied offsets, every cycle.
    pub invariant: InvariantReport,
    /// What failed (empty: the run passed).
    pub failures: Vec<String>,
}

impl CheckReport {
    /// Whether every check passed.
    pub fn passed(&self) -> bool {
        self.failures.is_empty()
    }

    /// The report as JSON.
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({
            "samples": self.samples,
            "compared": self.compared,
            "joint_mismatch_mm": self.joint_mismatch_mm,
            "joint_delay_cycles": self.joint_delay_cycles,
            "max_diff_um": self.max_diff_um,
            "rms_diff_um": self.rms_diff_um,
            "max_lag_fraction": self.max_lag_fraction,
            "max_lag_fraction_all": self.max_lag_fraction_all,
            "gap_fraction": self.gap_fraction,
            "in_step_moving_cycles": self.in_step_moving_cycles,
            "longest_update_gap_cycles": self.longest_update_gap_cycles,
            "max_offset_um": self.max_offset_um,
            "max_feed_mm_per_min": self.max_feed_mm_per_min,
            "max_rate_um_per_s": self.max_rate_um_per_s,
            "rate_limit_um_per_s": self.rate_limit_um_per_s,
            "holding_samples": self.holding_samples,
            "model_switches": self.model_switches,
            "axis_switches": self.axis_switches,
            "wrong_model_cycles": self.wrong_model_cycles,
            "max_parked_offset_um": self.max_parked_offset_um,
            "dynamic_compared": self.dynamic_compared,
            "max_dynamic_excess_um": self.max_dynamic_excess_um,
            "invariant": {
                "nonfinite_cycles": self.invariant.nonfinite_cycles,
                "max_abs_um": self.invariant.max_abs_um,
                "max_step_um": self.invariant.max_step_um,
                "max_step_ratio": self.invariant.max_step_ratio,
                "max_bracket_excess_um": self.invariant.max_bracket_excess_um,
                "state_changes": self.invariant.state_changes,
                "target_kept_cycles": self.invariant.target_kept_cycles,
            },
            "passed": self.passed(),
            "failures": self.failures,
        })
    }
}

impl CheckReport {
    /// The report as the lines `truepos-hal-check check` prints, the verdict last; `config`
    /// gives the limits it names.
    pub fn text(&self, config: &CheckConfig) -> String {
        let mut out = format!(
            "{} servo cycles, {} compared with the model; joint = nominal + eoffset within {:.2e} mm\n",
            self.samples, self.compared, self.joint_mismatch_mm
        );
        out += &format!(
            "applied − model: max {:.4} µm, rms {:.4} µm; lag error {:.4} % of the position-dependent span at 1 kHz updates (limit {} %), {:.4} % including update gaps\n",
            self.max_diff_um,
            self.rms_diff_um,
            self.max_lag_fraction * 100.0,
            config.max_lag_fraction * 100.0,
            self.max_lag_fraction_all * 100.0
        );
        out += &format!(
            "largest offset {:.2} µm; fastest axis {:.0} mm/min; offset rate per axis {:?} µm/s (envelope {:?})\n",
            self.max_offset_um,
            self.max_feed_mm_per_min,
            self.max_rate_um_per_s
                .iter()
                .map(|r| (r * 100.0).round() / 100.0)
                .collect::<Vec<_>>(),
            self.rate_limit_um_per_s
        );
        out += &format!(
            "{} cycles holding after a sensor fault, {} model switch(es), {} axis switch(es) ({} settled cycles on another model than the axis-combination rule selects, {:.3} µm largest offset on an axis in no path); update gaps: {:.3} % of moving cycles, longest {} servo cycles; {} moving cycles in step\n",
            self.holding_samples,
            self.model_switches,
            self.axis_switches,
            self.wrong_model_cycles,
            self.max_parked_offset_um,
            self.gap_fraction * 100.0,
            self.longest_update_gap_cycles,
            self.in_step_moving_cycles
        );
        out += &format!(
            "fitted dynamic model (stepped through the recorded cycles): {} cycles compared; applied outside its compensation over the pipeline window by at most {:.4} µm (limit {} µm)\n",
            self.dynamic_compared, self.max_dynamic_excess_um, config.max_dynamic_excess_um
        );
        let inv = &self.invariant;
        let round = |v: &[f64], k: f64| v.iter().map(|x| (x * k).round() / k).collect::<Vec<_>>();
        out += &format!(
            "output invariant on the applied offsets, per axis: largest |offset| {:?} µm; largest step {:?} µm, {:?} of the envelope's rate over the real time; outside the bracket (from, target) by at most {:?} µm (limit {} µm); {} non-finite; {} changes of state; {} cycles kept the previous target\n",
            round(&inv.max_abs_um, 1000.0),
            round(&inv.max_step_um, 1000.0),
            round(&inv.max_step_ratio, 1000.0),
            round(&inv.max_bracket_excess_um, 1000.0),
            config.max_bracket_excess_um,
            inv.nonfinite_cycles,
            inv.state_changes,
            inv.target_kept_cycles
        );
        for f in &self.failures {
            out += &format!("FAIL: {f}\n");
        }
        out += if self.passed() { "PASS\n" } else { "FAIL\n" };
        out
    }
}
