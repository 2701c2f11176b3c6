//! Testing without hardware: a recorded run replayed as a source, and a CSV file as a sink.

use std::path::Path;

use truepos_io::cycles::Cycles;
use truepos_io::InputError;

use crate::frame::Frame;
use crate::io_traits::{LinkError, Sink, Source};
use crate::output::{CompensationState, Output};

/// Replays a recorded run: at service time t it delivers the last row whose run time (relative
/// to the first row, scaled by `speed`) is ≤ t. Temperatures, positions and operating state
/// that the run holds are delivered; channels it lacks (NaN) are left untouched, so another
/// source may feed them.
pub struct ReplaySource {
    name: String,
    run: Cycles,
    start_s: f64,
    speed: f64,
    next: usize,
    positions: bool,
}

impl ReplaySource {
    /// A replay of `run` at `speed` × real time (1 = as recorded).
    pub fn new(name: impl Into<String>, run: Cycles, speed: f64) -> Self {
        let start_s = run.time_s.first().copied().unwrap_or(0.0);
        Self {
            name: name.into(),
            run,
            start_s,
            speed: if speed > 0.0 { speed } else { 1.0 },
            next: 0,
            positions: true,
        }
    }

    /// Delivers temperatures and operating state only, leaving the axis positions to another
    /// source (the control): the twin in the loop.
    pub fn without_positions(mut self) -> Self {
        self.positions = false;
        self
    }

    /// Run time in s covered by the replay at `speed` 1.
    pub fn duration_s(&self) -> f64 {
        self.run.time_s.last().copied().unwrap_or(0.0) - self.start_s
    }
}

impl Source for ReplaySource {
    fn name(&self) -> &str {
        &self.name
    }

    fn read(&mut self, frame: &mut Frame) -> Result<(), LinkError> {
        let run_time = self.start_s + frame.time_s * self.speed;
        let mut row = None;
        while self.next < self.run.time_s.len() && self.run.time_s[self.next] <= run_time {
            row = Some(self.next);
            self.next += 1;
        }
        // Re-deliver the current row so that values stay fresh between recorded samples, as a
        // sensor that is polled every cycle would.
        let current = row.or(self.next.checked_sub(1));
        if let Some(i) = current {
            for (c, &v) in self.run.temperatures_c[i].iter().enumerate() {
                if !v.is_nan() || row.is_some() {
                    frame.set_temperature(c, v);
                }
            }
            if self.positions {
                for (a, &v) in self.run.positions[i].iter().enumerate() {
                    frame.set_position(a, v);
                }
            }
            for (o, &v) in self.run.operating[i].iter().enumerate() {
                if !v.is_nan() {
                    frame.set_operating(o, v);
                }
            }
        }
        if self.next >= self.run.time_s.len() {
            return Err(LinkError::Finished);
        }
        Ok(())
    }
}

/// Writes every cycle's offsets to a CSV file: `time_s, <axis>_offset_um…, state, clamped`.
pub struct CsvSink {
    name: String,
    out: csv::Writer<std::io::BufWriter<std::fs::File>>,
    axes: usize,
    every_s: f64,
    last_s: f64,
    line: Vec<String>,
}

impl CsvSink {
    /// A CSV sink writing at most one row every `every_s` seconds (0: every cycle).
    pub fn create(path: &Path, axis_names: &[String], every_s: f64) -> Result<Self, InputError> {
        let file = std::fs::File::create(path)
            .map_err(|e| InputError::file(path, format!("cannot write: {e}")))?;
        let mut out = csv::Writer::from_writer(std::io::BufWriter::new(file));
        let mut header = vec!["time_s".to_string()];
        header.extend(axis_names.iter().map(|a| format!("{a}_offset_um")));
        header.push("state".into());
        header.push("clamped".into());
        out.write_record(&header)
            .map_err(|e| InputError::file(path, format!("cannot write: {e}")))?;
        Ok(Self {
            name: format!("csv {}", path.display()),
            out,
            axes: axis_names.len(),
            every_s,
            last_s: f64::NEG_INFINITY,
            line: Vec::with_capacity(axis_names.len() + 3),
        })
    }

    /// Flushes buffered rows to the file.
    pub fn flush(&mut self) -> std::io::Result<()> {
        self.out.flush()
    }
}

/// The word for a state in files and status lines.
pub fn state_name(state: CompensationState) -> &'static str {
    match state {
        CompensationState::Active => "active",
        CompensationState::Holding => "holding",
        CompensationState::Disabled => "disabled",
        CompensationState::NoModel => "no-model",
    }
}

impl Sink for CsvSink {
    fn name(&self) -> &str {
        &self.name
    }

    fn write(&mut self, output: &Output) -> Result<(), LinkError> {
        if output.time_s - self.last_s < self.every_s {
            return Ok(());
        }
        self.last_s = output.time_s;
        // A file sink formats text; it is meant for replay and tests, not for a 1 kHz control.
        self.line.clear();
        self.line.push(format!("{:.4}", output.time_s));
        for v in &output.offset_um[..self.axes] {
            self.line.push(format!("{v:.4}"));
        }
        self.line.push(state_name(output.state).into());
        self.line.push(u8::from(output.clamped).to_string());
        self.out
            .write_record(&self.line)
            .map_err(|e| LinkError::Failed(e.to_string()))
    }
}

impl Drop for CsvSink {
    fn drop(&mut self) {
        let _ = self.out.flush();
    }
}
