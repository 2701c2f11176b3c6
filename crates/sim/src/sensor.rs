//! Temperature sensors: first-order lag, noise, quantisation and injectable faults.
//!
//! A sensor in a bore follows the metal with a first-order lag, `τ·dy/dt = T − y`, integrated
//! exactly over a step with the temperature held: `y ← y + (1 − e^{−h/τ})·(T − y)`. This lag
//! spoils the first minutes of a warm-up: the heat sources act at once, the sensor
//! spots warm later. A reading adds Gaussian noise (σ) and is rounded to the converter's
//! resolution; faults then replace or distort it.

use crate::scenario::{Fault, FaultKind};

/// The state of one sensor.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorState {
    /// The lagged (true sensor) temperature in °C.
    pub lagged_c: f64,
    gain: f64,
    stuck_at: Option<f64>,
}

impl SensorState {
    /// A sensor with time constant `tau_s`, stepped every `h_s`, starting at `t0_c`.
    pub fn new(tau_s: f64, h_s: f64, t0_c: f64) -> Self {
        let gain = if tau_s > 0.0 {
            1.0 - (-h_s / tau_s).exp()
        } else {
            1.0
        };
        Self {
            lagged_c: t0_c,
            gain,
            stuck_at: None,
        }
    }

    /// Advances the lag by one step towards the spot temperature `t_c`.
    pub fn step(&mut self, t_c: f64) {
        self.lagged_c += self.gain * (t_c - self.lagged_c);
    }

    /// A reading at time `t_s`: lagged value + noise, quantised, then the active faults.
    /// `noise` is a standard normal draw; `spike` a uniform draw in [0, 1) and `sign` ±1.
    pub fn read(&mut self, t_s: f64, noise: &Noise, draws: Draws, faults: &[&Fault]) -> f64 {
        let mut v = self.lagged_c + noise.sigma_c * draws.normal;
        if noise.resolution_c > 0.0 {
            v = (v / noise.resolution_c).round() * noise.resolution_c;
        }
        let mut stuck = false;
        for f in faults {
            if !f.active(t_s) {
                continue;
            }
            match f.kind {
                FaultKind::OpenCircuit { rail_c } => v = rail_c,
                FaultKind::Stuck => {
                    stuck = true;
                    v = *self.stuck_at.get_or_insert(v);
                }
                FaultKind::Drift { c_per_h } => v += c_per_h * (t_s - f.start_s) / 3600.0,
                FaultKind::Spikes {
                    amplitude_c,
                    probability,
                } => {
                    if draws.uniform < probability {
                        v += draws.sign * amplitude_c;
                    }
                }
            }
        }
        if !stuck {
            self.stuck_at = None;
        }
        v
    }
}

/// Noise and resolution of the sensors' converters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Noise {
    /// Standard deviation of the reading noise, K.
    pub sigma_c: f64,
    /// Resolution (quantisation step), K; 0 = none.
    pub resolution_c: f64,
}

/// Random draws for one reading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Draws {
    /// Standard normal.
    pub normal: f64,
    /// Uniform in [0, 1).
    pub uniform: f64,
    /// +1 or −1.
    pub sign: f64,
}

/// A standard normal draw (Box–Muller) from a seeded generator.
pub fn normal(rng: &mut fastrand::Rng) -> f64 {
    let u1 = 1.0 - rng.f64(); // (0, 1]
    let u2 = rng.f64();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

#[cfg(test)]
mod tests {
    use super::*;

    const QUIET: Noise = Noise {
        sigma_c: 0.0,
        resolution_c: 0.0,
    };
    const NO_DRAW: Draws = Draws {
        normal: 0.0,
        uniform: 1.0,
        sign: 1.0,
    };

    /// τ = 120 s, a 10 K step: after 120 s the sensor shows 10·(1 − e⁻¹) = 6.3212 K of it,
    /// whatever the step size.
    #[test]
    fn lag_reaches_63_percent_after_one_time_constant() {
        for h in [1.0, 10.0, 60.0] {
            let mut s = SensorState::new(120.0, h, 20.0);
            for _ in 0..(120.0 / h) as usize {
                s.step(30.0);
            }
            assert!((s.lagged_c - 26.321_205_588).abs() < 1e-8, "h {h}");
        }
    }

    /// 20.004 °C read with 0.01 K resolution gives 20.00; +1.7 σ of 0.02 K noise (0.034 K) gives
    /// 20.038 → 20.04.
    #[test]
    fn noise_and_quantisation() {
        let mut s = SensorState::new(0.0, 1.0, 20.004);
        let n = Noise {
            sigma_c: 0.02,
            resolution_c: 0.01,
        };
        assert!((s.read(0.0, &n, NO_DRAW, &[]) - 20.0).abs() < 1e-12);
        let d = Draws {
            normal: 1.7,
            ..NO_DRAW
        };
        assert!((s.read(0.0, &n, d, &[]) - 20.04).abs() < 1e-12);
    }

    #[test]
    fn faults_replace_or_distort_the_reading() {
        let fault = |kind| Fault {
            sensor: "s".into(),
            kind,
            start_s: 100.0,
            end_s: Some(200.0),
        };
        let mut s = SensorState::new(0.0, 1.0, 25.0);
        let open = fault(FaultKind::OpenCircuit { rail_c: 850.0 });
        assert_eq!(s.read(50.0, &QUIET, NO_DRAW, &[&open]), 25.0);
        assert_eq!(s.read(150.0, &QUIET, NO_DRAW, &[&open]), 850.0);
        assert_eq!(s.read(250.0, &QUIET, NO_DRAW, &[&open]), 25.0);
        // Stuck: holds the value it had when the fault began.
        let stuck = fault(FaultKind::Stuck);
        assert_eq!(s.read(120.0, &QUIET, NO_DRAW, &[&stuck]), 25.0);
        s.step(30.0);
        assert_eq!(s.read(130.0, &QUIET, NO_DRAW, &[&stuck]), 25.0);
        assert_eq!(s.read(230.0, &QUIET, NO_DRAW, &[&stuck]), 30.0);
        // Drift 0.5 K/h, 3600 s after its start: +0.5 K.
        let drift = Fault {
            end_s: None,
            ..fault(FaultKind::Drift { c_per_h: 0.5 })
        };
        assert!((s.read(3700.0, &QUIET, NO_DRAW, &[&drift]) - 30.5).abs() < 1e-12);
        let spikes = fault(FaultKind::Spikes {
            amplitude_c: 4.0,
            probability: 0.1,
        });
        let hit = Draws {
            uniform: 0.05,
            sign: -1.0,
            ..NO_DRAW
        };
        assert_eq!(s.read(150.0, &QUIET, hit, &[&spikes]), 26.0);
        assert_eq!(s.read(150.0, &QUIET, NO_DRAW, &[&spikes]), 30.0);
    }

    #[test]
    fn normal_draws_have_unit_variance() {
        let mut rng = fastrand::Rng::with_seed(7);
        let n = 20_000;
        let xs: Vec<f64> = (0..n).map(|_| normal(&mut rng)).collect();
        let mean = xs.iter().sum::<f64>() / n as f64;
        let var = xs.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / n as f64;
        assert!(
            mean.abs() < 0.03 && (var - 1.0).abs() < 0.05,
            "{mean} {var}"
        );
    }
}
