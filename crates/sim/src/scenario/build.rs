//! From the file form to a checked [`Scenario`], section by section in file order: step and
//! sample, ambient and its events, phases and their motions, probing and its grid, sensor noise,
//! faults. Each value is checked where it is read, so its error names its key.

use super::checker::{Checker, Seg};
use super::file::{
    AmbientFile, EventFile, FaultFile, File, Head, MotionFile, PhaseFile, ProbingFile, SensorsFile,
};
use super::{
    Ambient, AmbientEvent, Fault, FaultKind, Motion, Pattern, Phase, Probing, Scenario,
    MAX_DURATION_S, MAX_SAMPLES, MAX_STEPS,
};
use crate::twin::AXES;
use truepos_files::InputError;

impl Checker<'_> {
    /// The bounds of [`Scenario::check_size`], reported at the key that crosses them: the
    /// phase whose end passes [`MAX_DURATION_S`], else `sample_s` or `step_s`.
    fn check_size(
        &self,
        phases: &[Phase],
        step_s: f64,
        sample_s: f64,
        h: &Head,
    ) -> Result<(), InputError> {
        use Seg::{Index as I, Key as K};
        let mut end_s = 0.0;
        for (i, p) in phases.iter().enumerate() {
            end_s += p.duration_s;
            if end_s > MAX_DURATION_S {
                return Err(self.err(
                    &[K("phase"), I(i), K("duration_min")],
                    format!(
                        "phases lasting at most {} min (30 days) in all; this one ends at {} min",
                        MAX_DURATION_S / 60.0,
                        end_s / 60.0
                    ),
                ));
            }
        }
        // Point at the key when it is written, else at the head of the file.
        let at = |key: &'static str, given: bool| {
            if given {
                vec![K("scenario"), K(key)]
            } else {
                vec![K("scenario")]
            }
        };
        if end_s / sample_s > MAX_SAMPLES {
            return Err(self.err(
                &at("sample_s", h.sample_s.is_some()),
                format!(
                    "sample_s ≥ {} s: {end_s} s sampled every {sample_s} s gives more than {MAX_SAMPLES} rows",
                    end_s / MAX_SAMPLES
                ),
            ));
        }
        if end_s / step_s > MAX_STEPS {
            return Err(self.err(
                &at("step_s", h.step_s.is_some()),
                format!(
                    "step_s ≥ {} s: {end_s} s in steps of {step_s} s gives more than {MAX_STEPS} steps",
                    end_s / MAX_STEPS
                ),
            ));
        }
        Ok(())
    }

    fn axis(&self, path: &[Seg], name: &str) -> Result<usize, InputError> {
        AXES.iter()
            .position(|a| *a == name)
            .ok_or_else(|| self.err(path, format!("one of the axes X, Y, Z, got \"{name}\"")))
    }

    /// Checks a parsed scenario section by section, in file order, and builds it; `travel`
    /// (mm per axis X, Y, Z) bounds every position.
    pub(super) fn build(&self, f: File, travel: [[f64; 2]; 3]) -> Result<Scenario, InputError> {
        use Seg::Key as K;
        let h = &f.scenario;
        let (step_s, sample_s) = self.step_and_sample(h)?;
        let start_hour = match h.start_hour {
            Some(v) => self.within(
                &[K("scenario"), K("start_hour")],
                v,
                0.0,
                24.0,
                "a clock hour",
            )?,
            None => 8.0,
        };
        let initial_c = match h.initial_c {
            Some(v) => Some(self.within(
                &[K("scenario"), K("initial_c")],
                v,
                -20.0,
                60.0,
                "a temperature in °C",
            )?),
            None => None,
        };
        let ambient = match &f.ambient {
            None => Ambient {
                mean_c: 20.0,
                daily_amplitude_c: 0.0,
                daily_peak_hour: 15.0,
                drift_c_per_h: 0.0,
                events: vec![],
            },
            Some(a) => self.ambient(a)?,
        };
        if f.phase.is_empty() {
            return Err(self.err(&[K("phase")], "at least one [[phase]]"));
        }
        let mut phases = Vec::new();
        for (i, ph) in f.phase.iter().enumerate() {
            phases.push(self.phase(i, ph, travel)?);
        }
        self.check_size(&phases, step_s, sample_s, h)?;
        let probing = match &f.probing {
            None => None,
            Some(p) => Some(self.probing(p, travel)?),
        };
        let (sensor_noise_c, sensor_resolution_c) = self.sensor_noise(&f.sensors)?;
        let mut faults = Vec::new();
        for (i, ft) in f.fault.iter().enumerate() {
            faults.push(self.fault(i, ft, sample_s)?);
        }
        Ok(Scenario {
            name: h.name.clone(),
            description: h.description.clone(),
            step_s,
            sample_s,
            start_hour,
            initial_c,
            ambient,
            phases,
            probing,
            sensor_noise_c,
            sensor_resolution_c,
            faults,
        })
    }

    /// The integration step (default 1 s) and the sampling period (default 10 s, at least the
    /// step), the latter a whole multiple of the former so that samples fall on steps.
    fn step_and_sample(&self, h: &Head) -> Result<(f64, f64), InputError> {
        use Seg::Key as K;
        let step_s = match h.step_s {
            Some(v) => self.within(&[K("scenario"), K("step_s")], v, 0.01, 600.0, "a step in s")?,
            None => 1.0,
        };
        let sample_s = match h.sample_s {
            Some(v) => {
                let v = self.within(
                    &[K("scenario"), K("sample_s")],
                    v,
                    step_s,
                    86_400.0,
                    "a sampling period in s (at least step_s)",
                )?;
                let ratio = v / step_s;
                if (ratio - ratio.round()).abs() > 1e-9 {
                    return Err(self.err(
                        &[K("scenario"), K("sample_s")],
                        format!("a whole multiple of step_s = {step_s} s, got {v}"),
                    ));
                }
                v
            }
            None => 10.0_f64.max(step_s),
        };
        Ok((step_s, sample_s))
    }

    /// The ambient temperature: mean, daily swing, drift and events, each within a plausible
    /// range for a workshop.
    fn ambient(&self, a: &AmbientFile) -> Result<Ambient, InputError> {
        use Seg::Key as K;
        let p = |k| [K("ambient"), K(k)];
        let mut events = Vec::new();
        for (i, e) in a.event.iter().enumerate() {
            events.push(self.ambient_event(i, e)?);
        }
        Ok(Ambient {
            mean_c: self.within(&p("mean_c"), a.mean_c, -20.0, 50.0, "a temperature in °C")?,
            daily_amplitude_c: self.within(
                &p("daily_amplitude_c"),
                a.daily_amplitude_c,
                0.0,
                20.0,
                "an amplitude in K",
            )?,
            daily_peak_hour: self.within(
                &p("daily_peak_hour"),
                a.daily_peak_hour.unwrap_or(15.0),
                0.0,
                24.0,
                "a clock hour",
            )?,
            drift_c_per_h: self.within(
                &p("drift_c_per_h"),
                a.drift_c_per_h,
                -5.0,
                5.0,
                "a drift in K/h",
            )?,
            events,
        })
    }

    /// Ambient event `i`: a step of at most ±30 K at a time ≥ 0, optionally held for a while and
    /// recovering over a time ≥ 0.
    fn ambient_event(&self, i: usize, e: &EventFile) -> Result<AmbientEvent, InputError> {
        use Seg::{Index as I, Key as K};
        let pe = |k| [K("ambient"), K("event"), I(i), K(k)];
        Ok(AmbientEvent {
            at_s: 60.0 * self.non_negative(&pe("at_min"), e.at_min)?,
            delta_c: self.within(&pe("delta_c"), e.delta_c, -30.0, 30.0, "a change in K")?,
            duration_s: match e.duration_min {
                Some(d) => Some(60.0 * self.positive(&pe("duration_min"), d)?),
                None => None,
            },
            recovery_s: 60.0
                * self.non_negative(&pe("recovery_min"), e.recovery_min.unwrap_or(0.0))?,
        })
    }

    /// Phase `i`: its motions, a positive duration and a spindle speed up to 60 000 1/min.
    fn phase(&self, i: usize, ph: &PhaseFile, travel: [[f64; 2]; 3]) -> Result<Phase, InputError> {
        use Seg::{Index as I, Key as K};
        let pp = |k| [K("phase"), I(i), K(k)];
        let mut motion: Vec<Motion> = Vec::new();
        for (j, m) in ph.motion.iter().enumerate() {
            let next = self.motion(i, j, m, &motion, travel)?;
            motion.push(next);
        }
        Ok(Phase {
            name: ph.name.clone(),
            duration_s: 60.0 * self.positive(&pp("duration_min"), ph.duration_min)?,
            spindle_rpm: self.within(
                &pp("spindle_rpm"),
                ph.spindle_rpm,
                0.0,
                60_000.0,
                "a speed in 1/min",
            )?,
            coolant: ph.coolant,
            probe: ph.probe.unwrap_or(true),
            servo_on: ph.servo_on.unwrap_or(true),
            motion,
        })
    }

    /// Motion `j` of phase `i`: an axis not yet moved in this phase (`earlier`), a known
    /// pattern, range and position inside the travel, and a feed unless the axis holds.
    fn motion(
        &self,
        i: usize,
        j: usize,
        m: &MotionFile,
        earlier: &[Motion],
        travel: [[f64; 2]; 3],
    ) -> Result<Motion, InputError> {
        use Seg::{Index as I, Key as K};
        let pm = |k| [K("phase"), I(i), K("motion"), I(j), K(k)];
        let axis = self.axis(&pm("axis"), &m.axis)?;
        if earlier.iter().any(|o| o.axis == axis) {
            return Err(self.err(
                &pm("axis"),
                format!("each axis once per phase; {} appears twice", m.axis),
            ));
        }
        let pattern = match m.pattern.as_str() {
            "sweep" => Pattern::Sweep,
            "random" => Pattern::Random,
            "hold" => Pattern::Hold,
            other => {
                return Err(self.err(
                    &pm("pattern"),
                    format!("one of \"sweep\", \"random\", \"hold\", got \"{other}\""),
                ))
            }
        };
        let [lo, hi] = travel[axis];
        let range_mm = match m.range_mm {
            Some([a, b]) => {
                if !(a.is_finite() && b.is_finite() && a < b && a >= lo && b <= hi) {
                    return Err(self.err(&pm("range_mm"), format!("[min, max] with min < max inside the travel [{lo}, {hi}] mm, got [{a}, {b}]")));
                }
                Some([a, b])
            }
            None => None,
        };
        let at_mm = match m.at_mm {
            Some(v) => Some(self.within(
                &pm("at_mm"),
                v,
                lo,
                hi,
                "a position inside the travel in mm",
            )?),
            None => None,
        };
        let feed_mm_min = match (m.feed_mm_min, pattern) {
            (Some(v), _) => {
                self.within(&pm("feed_mm_min"), v, 1.0, 120_000.0, "a feed in mm/min")?
            }
            (None, Pattern::Hold) => 10_000.0,
            (None, _) => {
                return Err(self.err(
                    &[K("phase"), I(i), K("motion"), I(j)],
                    "feed_mm_min for a moving axis",
                ))
            }
        };
        Ok(Motion {
            axis,
            pattern,
            feed_mm_min,
            range_mm,
            at_mm,
            dwell_s: self.non_negative(&pm("dwell_s"), m.dwell_s)?,
        })
    }

    /// The probing cycle: a grid of positions inside the travel (unless probing in place), its
    /// period, dwell, feed and repeatability.
    fn probing(&self, p: &ProbingFile, travel: [[f64; 2]; 3]) -> Result<Probing, InputError> {
        use Seg::{Index as I, Key as K};
        let pk = |k| [K("probing"), K(k)];
        let mut lists = Vec::new();
        for (a, (name, list)) in [("X", &p.x), ("Y", &p.y), ("Z", &p.z)]
            .into_iter()
            .enumerate()
        {
            if list.is_empty() && !p.in_place {
                return Err(self.err(
                    &[K("probing")],
                    format!("a list of {name} positions (mm) for the probing grid"),
                ));
            }
            for (k, v) in list.iter().enumerate() {
                self.within(
                    &[K("probing"), K(name), I(k)],
                    *v,
                    travel[a][0],
                    travel[a][1],
                    "a position inside the travel in mm",
                )?;
            }
            lists.push(list.clone());
        }
        Ok(Probing {
            every_s: 60.0 * self.positive(&pk("every_min"), p.every_min)?,
            points: probing_grid(&lists),
            in_place: p.in_place,
            dwell_s: self.non_negative(&pk("dwell_s"), p.dwell_s.unwrap_or(3.0))?,
            feed_mm_min: self.within(
                &pk("feed_mm_min"),
                p.feed_mm_min.unwrap_or(10_000.0),
                1.0,
                120_000.0,
                "a feed in mm/min",
            )?,
            stop_spindle: p.stop_spindle.unwrap_or(!p.in_place),
            noise_um: self.within(
                &pk("noise_um"),
                p.noise_um.unwrap_or(0.5),
                0.0,
                100.0,
                "a repeatability in µm",
            )?,
        })
    }

    /// The temperature sensors' noise σ and resolution in K (defaults 0.02 and 0.01).
    fn sensor_noise(&self, s: &Option<SensorsFile>) -> Result<(f64, f64), InputError> {
        use Seg::Key as K;
        Ok(match s {
            None => (0.02, 0.01),
            Some(s) => (
                self.within(
                    &[K("sensors"), K("noise_c")],
                    s.noise_c.unwrap_or(0.02),
                    0.0,
                    5.0,
                    "a noise σ in K",
                )?,
                self.within(
                    &[K("sensors"), K("resolution_c")],
                    s.resolution_c.unwrap_or(0.01),
                    0.0,
                    5.0,
                    "a resolution in K",
                )?,
            ),
        })
    }

    /// Fault `i`: a time window (an end after the start, if any) and a known kind with the
    /// settings that kind needs; a spike rate becomes a probability per sample.
    fn fault(&self, i: usize, ft: &FaultFile, sample_s: f64) -> Result<Fault, InputError> {
        use Seg::{Index as I, Key as K};
        let pf = |k| [K("fault"), I(i), K(k)];
        let start_s = 60.0 * self.non_negative(&pf("start_min"), ft.start_min)?;
        let end_s = match ft.end_min {
            Some(e) if e * 60.0 > start_s && e.is_finite() => Some(e * 60.0),
            Some(e) => {
                return Err(self.err(
                    &pf("end_min"),
                    format!("an end after start_min = {}, got {e}", ft.start_min),
                ))
            }
            None => None,
        };
        let need = |k: &'static str, v: Option<f64>| {
            v.ok_or_else(|| {
                self.err(
                    &[K("fault"), I(i)],
                    format!("`{k}` for a {} fault", ft.kind),
                )
            })
        };
        let kind = match ft.kind.as_str() {
            "open-circuit" => FaultKind::OpenCircuit {
                // What an open input reads: a rail far outside any valid range, but a number.
                rail_c: self.within(
                    &pf("rail_c"),
                    ft.rail_c.unwrap_or(850.0),
                    -1.0e4,
                    1.0e4,
                    "an open-circuit reading in °C",
                )?,
            },
            "stuck" => FaultKind::Stuck,
            "drift" => FaultKind::Drift {
                c_per_h: self.within(
                    &pf("c_per_h"),
                    need("c_per_h", ft.c_per_h)?,
                    -50.0,
                    50.0,
                    "a drift in K/h",
                )?,
            },
            "spikes" => {
                let per_hour = self.positive(&pf("per_hour"), need("per_hour", ft.per_hour)?)?;
                FaultKind::Spikes {
                    amplitude_c: self.within(
                        &pf("amplitude_c"),
                        need("amplitude_c", ft.amplitude_c)?,
                        -500.0,
                        500.0,
                        "a spike height in K",
                    )?,
                    probability: (per_hour * sample_s / 3600.0).min(1.0),
                }
            }
            other => {
                return Err(self.err(
                    &pf("kind"),
                    format!(
                    "one of \"open-circuit\", \"stuck\", \"drift\", \"spikes\", got \"{other}\""
                ),
                ))
            }
        };
        Ok(Fault {
            sensor: ft.sensor.clone(),
            kind,
            start_s,
            end_s,
        })
    }
}

/// The probing points from the X, Y and Z lists, in serpentine order: Y rows alternate their
/// X direction, which keeps the moves short.
fn probing_grid(lists: &[Vec<f64>]) -> Vec<[f64; 3]> {
    let mut points = Vec::new();
    for &z in &lists[2] {
        for (yi, &y) in lists[1].iter().enumerate() {
            let xs: Vec<f64> = if yi % 2 == 0 {
                lists[0].clone()
            } else {
                lists[0].iter().rev().copied().collect()
            };
            for x in xs {
                points.push([x, y, z]);
            }
        }
    }
    points
}
