//! What the host did to the cycle: a thread samples the hypervisor's *steal time*
//! (`/proc/stat`) and the kernel's CPU pressure (`/proc/pressure/cpu`) every few milliseconds,
//! so that every cycle that finished late can be set beside what the host did at that moment.
//!
//! On a virtual machine the hypervisor may run another guest on the physical CPU behind a
//! virtual one; the guest's clock goes on, its threads do not, and the kernel counts the lost
//! time as *steal* in `/proc/stat` (8th value of a `cpu` line). A userspace process cannot
//! prevent it, whatever its priority. The counter is in `USER_HZ` ticks (10 ms), so it
//! resolves steal only to 10 ms: a window in which it advanced certainly had steal, a window in
//! which it did not may still have lost up to 10 ms. [`HostRecord::around`] therefore widens
//! the window by a margin, and [`HostRecord::chance`] says how often a window of that width
//! sees steal anyway (the figure to weigh a coincidence against).

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;

use truepos_hal::ffi;

/// Length of one `/proc/stat` tick in ms (`USER_HZ` is 100 on every Linux architecture truepos
/// runs on).
pub const TICK_MS: f64 = 10.0;

/// The steal counters of `/proc/stat`: the sum over all CPUs and, if asked for, one CPU's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Steal {
    /// Ticks stolen from all CPUs together (the `cpu` line).
    pub all: u64,
    /// Ticks stolen from the watched CPU (its `cpuN` line), if one was asked for and listed.
    pub cpu: Option<u64>,
}

/// Reads the steal counters from the text of `/proc/stat`; `cpu` picks a `cpuN` line. `None`
/// when the `cpu` line is missing or has fewer than 8 values (kernels before 2.6.11).
pub fn parse_steal(text: &str, cpu: Option<usize>) -> Option<Steal> {
    let steal_of = |line: &str| line.split_whitespace().nth(8)?.parse::<u64>().ok();
    let mut all = None;
    let mut one = None;
    for line in text.lines() {
        let Some(name) = line.split_whitespace().next() else {
            continue;
        };
        if name == "cpu" {
            all = steal_of(line);
        } else if let (Some(want), Some(n)) = (cpu, name.strip_prefix("cpu")) {
            if n.parse::<usize>().ok() == Some(want) {
                one = steal_of(line);
            }
        } else if !name.starts_with("cpu") {
            break; // the cpu lines come first
        }
    }
    Some(Steal {
        all: all?,
        cpu: one,
    })
}

/// Reads the total time in µs during which some task waited for a CPU from the text of
/// `/proc/pressure/cpu` (`some … total=N`).
pub fn parse_pressure_some_us(text: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with("some "))?;
    line.split_whitespace()
        .find_map(|f| f.strip_prefix("total="))?
        .parse()
        .ok()
}

/// One sample of the host's counters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HostSample {
    /// `CLOCK_MONOTONIC` at the sample, ns.
    pub t_ns: u64,
    /// The steal counters, ticks.
    pub steal: Steal,
    /// Cumulative CPU pressure (`some`), µs, where the kernel reports it.
    pub pressure_some_us: Option<u64>,
}

/// What the host did in a window of time (the difference of two samples).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HostActivity {
    /// Ticks stolen from the watched CPU (all CPUs if none is watched).
    pub steal_ticks: u64,
    /// Ticks stolen from all CPUs together.
    pub steal_ticks_all: u64,
    /// Time some task of the guest waited for a CPU, µs (if reported).
    pub pressure_some_us: Option<u64>,
}

impl HostActivity {
    /// Whether the hypervisor certainly stole time (from the watched CPU) in the window.
    pub fn stole(&self) -> bool {
        self.steal_ticks > 0
    }
}

/// The samples of a run.
#[derive(Debug, Clone, Default)]
pub struct HostRecord {
    /// Samples in time order.
    pub samples: Vec<HostSample>,
    /// CPU time the sampling thread used, ns (measurement overhead, not the service's).
    pub sampler_cpu_ns: u64,
}

impl HostRecord {
    fn steal_of(s: &HostSample) -> u64 {
        s.steal.cpu.unwrap_or(s.steal.all)
    }

    /// What the host did between the last sample at or before `start_ns − margin_ns` and the
    /// first at or after `end_ns + margin_ns`; `None` if the samples do not cover that window.
    pub fn around(&self, start_ns: u64, end_ns: u64, margin_ns: u64) -> Option<HostActivity> {
        let from = start_ns.saturating_sub(margin_ns);
        let to = end_ns.saturating_add(margin_ns);
        // Index of the first sample after `from`; the one before it is the window's start.
        let i = self
            .samples
            .partition_point(|s| s.t_ns <= from)
            .checked_sub(1)?;
        let j = self.samples.partition_point(|s| s.t_ns < to);
        let (a, b) = (self.samples.get(i)?, self.samples.get(j)?);
        Some(HostActivity {
            steal_ticks: Self::steal_of(b).saturating_sub(Self::steal_of(a)),
            steal_ticks_all: b.steal.all.saturating_sub(a.steal.all),
            pressure_some_us: match (a.pressure_some_us, b.pressure_some_us) {
                (Some(x), Some(y)) => Some(y.saturating_sub(x)),
                _ => None,
            },
        })
    }

    /// The share of windows `[t, t + width_ns]`, `t` every `step_ns` over the record, in which
    /// [`around`](Self::around) (with the same margin) finds steal: how likely a late cycle is to
    /// coincide with steal by chance alone.
    pub fn chance(&self, width_ns: u64, margin_ns: u64, step_ns: u64) -> f64 {
        let (Some(first), Some(last)) = (self.samples.first(), self.samples.last()) else {
            return 0.0;
        };
        let mut t = first.t_ns + margin_ns;
        let (mut windows, mut with_steal) = (0u64, 0u64);
        while t + width_ns + margin_ns <= last.t_ns {
            if let Some(a) = self.around(t, t + width_ns, margin_ns) {
                windows += 1;
                with_steal += u64::from(a.stole());
            }
            t += step_ns.max(1);
        }
        if windows == 0 {
            0.0
        } else {
            with_steal as f64 / windows as f64
        }
    }

    /// Totals over the whole record.
    pub fn total(&self) -> Option<HostActivity> {
        let (a, b) = (self.samples.first()?, self.samples.last()?);
        self.around(a.t_ns, b.t_ns, 0)
    }

    /// Time the record covers, ns.
    pub fn span_ns(&self) -> u64 {
        match (self.samples.first(), self.samples.last()) {
            (Some(a), Some(b)) => b.t_ns - a.t_ns,
            _ => 0,
        }
    }
}

/// A procfs file kept open and re-read from the start (cheaper than opening it every time).
struct ProcFile {
    file: File,
    text: String,
}

impl ProcFile {
    fn open(path: &str) -> Option<Self> {
        Some(Self {
            file: File::open(path).ok()?,
            text: String::with_capacity(8192),
        })
    }

    fn read(&mut self) -> Option<&str> {
        self.text.clear();
        self.file.seek(SeekFrom::Start(0)).ok()?;
        self.file.read_to_string(&mut self.text).ok()?;
        Some(&self.text)
    }
}

/// The sampling thread; [`stop`](Self::stop) ends it and returns its record.
#[derive(Debug)]
pub struct HostSampler {
    stop: Arc<AtomicBool>,
    handle: JoinHandle<HostRecord>,
}

impl HostSampler {
    /// Starts sampling every `interval_ns`, watching `watched_cpu`'s steal (the CPU the cycle is
    /// bound to; all CPUs if `None`). The thread runs at normal priority on the CPUs of the
    /// calling thread (start it before binding that to the cycle's CPU: see
    /// [`truepos_hal::pacer::keep_off_cpu`]). Fails if `/proc/stat` cannot be read.
    pub fn start(interval_ns: u64, watched_cpu: Option<usize>) -> Result<Self, String> {
        let mut stat = ProcFile::open("/proc/stat").ok_or("cannot open /proc/stat")?;
        let first = stat
            .read()
            .and_then(|t| parse_steal(t, watched_cpu))
            .ok_or("/proc/stat holds no steal time")?;
        if watched_cpu.is_some() && first.cpu.is_none() {
            return Err(format!(
                "/proc/stat lists no cpu{}",
                watched_cpu.unwrap_or(0)
            ));
        }
        let mut pressure = ProcFile::open("/proc/pressure/cpu");
        let stop = Arc::new(AtomicBool::new(false));
        let flag = Arc::clone(&stop);
        let handle = std::thread::Builder::new()
            .name("truepos-host".into())
            .spawn(move || {
                let cpu0 = ffi::thread_cpu_ns();
                let mut samples = Vec::with_capacity(1 << 17);
                let mut next = ffi::monotonic_ns();
                loop {
                    let t_ns = ffi::monotonic_ns();
                    if let Some(steal) = stat.read().and_then(|t| parse_steal(t, watched_cpu)) {
                        let pressure_some_us = pressure
                            .as_mut()
                            .and_then(ProcFile::read)
                            .and_then(parse_pressure_some_us);
                        samples.push(HostSample {
                            t_ns,
                            steal,
                            pressure_some_us,
                        });
                    }
                    // Checked after sampling, so the last sample follows the cycle's end.
                    if flag.load(Ordering::Relaxed) {
                        break;
                    }
                    next += interval_ns;
                    ffi::sleep_until_ns(next.max(ffi::monotonic_ns()));
                }
                HostRecord {
                    samples,
                    sampler_cpu_ns: ffi::thread_cpu_ns() - cpu0,
                }
            })
            .map_err(|e| format!("cannot start the sampling thread: {e}"))?;
        Ok(Self { stop, handle })
    }

    /// Stops sampling (after one last sample) and returns the record.
    pub fn stop(self) -> HostRecord {
        self.stop.store(true, Ordering::Relaxed);
        self.handle.join().unwrap_or_default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const STAT: &str = "cpu  1668675 5 98174 334885 1973 0 1169 40441 0 0\n\
cpu0 836640 0 48577 165287 1038 0 482 22803 0 0\n\
cpu1 832034 5 49596 169598 934 0 687 17637 0 0\n\
intr 123 4 5\n";

    #[test]
    fn steal_is_the_eighth_value() {
        assert_eq!(
            parse_steal(STAT, Some(1)),
            Some(Steal {
                all: 40441,
                cpu: Some(17637)
            })
        );
        assert_eq!(parse_steal(STAT, Some(7)).unwrap().cpu, None);
        assert_eq!(parse_steal(STAT, None).unwrap().all, 40441);
        assert_eq!(parse_steal("cpu 1 2 3 4\n", None), None);
        assert_eq!(parse_steal("", None), None);
    }

    #[test]
    fn pressure_total() {
        let text = "some avg10=2.19 avg60=1.23 avg300=2.48 total=4474666779\n\
full avg10=0.00 avg60=0.00 avg300=0.00 total=0\n";
        assert_eq!(parse_pressure_some_us(text), Some(4_474_666_779));
        assert_eq!(parse_pressure_some_us("full total=3\n"), None);
    }

    fn record(steal_at_ms: &[u64]) -> HostRecord {
        // A sample every 5 ms over 1 s; the counter advances by one tick at the given times.
        let samples = (0..=200u64)
            .map(|i| {
                let t = i * 5;
                let ticks = steal_at_ms.iter().filter(|&&s| s <= t).count() as u64;
                HostSample {
                    t_ns: t * 1_000_000,
                    steal: Steal {
                        all: ticks,
                        cpu: Some(ticks),
                    },
                    pressure_some_us: Some(t),
                }
            })
            .collect();
        HostRecord {
            samples,
            sampler_cpu_ns: 0,
        }
    }

    #[test]
    fn a_window_sees_steal_within_its_margin_only() {
        let r = record(&[500]);
        let ms = 1_000_000;
        // A late cycle at 490–495 ms: the tick at 500 ms lies within a 10 ms margin.
        assert!(r.around(490 * ms, 495 * ms, 10 * ms).unwrap().stole());
        // At 300 ms it does not.
        let quiet = r.around(300 * ms, 305 * ms, 10 * ms).unwrap();
        assert!(!quiet.stole());
        assert_eq!(quiet.pressure_some_us, Some(25));
        // Beyond the last sample there is no answer.
        assert_eq!(r.around(995 * ms, 999 * ms, 10 * ms), None);
        assert_eq!(r.total().unwrap().steal_ticks, 1);
        assert_eq!(r.span_ns(), 1000 * ms);
    }

    #[test]
    fn chance_counts_windows_with_steal() {
        let ms = 1_000_000;
        assert_eq!(record(&[]).chance(2 * ms, 10 * ms, ms), 0.0);
        // One tick: windows whose widened span (≈ 25–30 ms) contains 500 ms, out of ~975.
        let c = record(&[500]).chance(2 * ms, 10 * ms, ms);
        assert!(c > 0.02 && c < 0.04, "{c}");
    }
}
