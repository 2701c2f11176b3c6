//! Testing without hardware: a recorded run replayed as a source, and a CSV file as a sink.

use std::path::{Path, PathBuf};

use crate::frame::Frame;
use crate::io_traits::{LinkError, Sink, Source};
use crate::output::{CompensationState, Output};
use truepos_model::RecordedRun;

/// Replays a recorded run: at service time t it delivers the last row whose run time, relative
/// to the first row, is ≤ t. Temperatures, positions and operating state that the run holds are
/// delivered; channels it lacks (NaN) are left untouched, so another source may feed them.
///
/// The replay has no speed of its own: service time is the run's time, so every time-dependent
/// state of the service (lags, rates, staleness, blends, a dynamic model's filters) follows the
/// data's clock. A caller that plays a run faster than real time paces the service's cycles
/// faster (`truepos run`'s `@SPEED`), never the replay against the service.
pub struct ReplaySource {
    name: String,
    run: RecordedRun,
    start_s: f64,
    next: usize,
    positions: bool,
}

impl ReplaySource {
    /// A replay of `run` on the service's clock (its first row at service time 0).
    pub fn new(name: impl Into<String>, run: RecordedRun) -> Self {
        let start_s = run.time_s.first().copied().unwrap_or(0.0);
        Self {
            name: name.into(),
            run,
            start_s,
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

    /// Run time in s covered by the replay, which is the service time it takes.
    pub fn duration_s(&self) -> f64 {
        self.run.time_s.last().copied().unwrap_or(0.0) - self.start_s
    }
}

impl Source for ReplaySource {
    fn name(&self) -> &str {
        &self.name
    }

    fn read(&mut self, frame: &mut Frame) -> Result<(), LinkError> {
        let run_time = self.start_s + frame.time_s;
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

/// A CSV sink's file that cannot be written.
#[derive(Debug)]
pub struct CsvSinkError {
    /// The file.
    pub file: PathBuf,
    /// Why.
    pub source: std::io::Error,
}

impl std::fmt::Display for CsvSinkError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: cannot write: {}", self.file.display(), self.source)
    }
}

impl std::error::Error for CsvSinkError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        Some(&self.source)
    }
}

/// Interval in s of service time between two writes of a CSV sink's buffered rows to its
/// file, and between two attempts while the file fails: a failure shows within this time.
pub const CSV_FLUSH_EVERY_S: f64 = 0.5;
/// Bytes of rows a CSV sink keeps while its file fails; rows beyond are dropped and counted.
pub const CSV_MAX_PENDING: usize = 4 << 20;

/// Writes every cycle's offsets to a CSV file: `time_s, <axis>_offset_um…, state, clamped`.
///
/// Rows are buffered and written every [`CSV_FLUSH_EVERY_S`] of service time. A failed write
/// (a full disk, `/dev/full`) keeps the unwritten bytes (a short write leaves no duplicate and
/// no gap), makes every call fail until a later attempt succeeds, and is retried at the same
/// interval — so the service sees one failure and one recovery, not a flicker per cycle.
pub struct CsvSink {
    name: String,
    file: std::fs::File,
    pending: Vec<u8>,
    axes: usize,
    every_s: f64,
    last_s: f64,
    last_flush_s: f64,
    failure: Option<LinkError>,
    rows_dropped: u64,
}

impl CsvSink {
    /// A CSV sink writing at most one row every `every_s` seconds (0: every cycle). The header
    /// goes out with the first rows, so a file that cannot take it fails in the service (an
    /// event and a state), not here. The file is opened through the one door for outputs
    /// ([`truepos_files::write::open_stream`]): a link, a FIFO, a directory, a block device or
    /// one of the run's `inputs` is refused; a character device (`/dev/null`) is written into.
    pub fn create(
        path: &Path,
        axis_names: &[String],
        every_s: f64,
        inputs: truepos_files::write::Inputs<'_>,
    ) -> Result<Self, CsvSinkError> {
        let fail = |source| CsvSinkError {
            file: path.to_path_buf(),
            source,
        };
        let file = truepos_files::write::open_stream(path, inputs).map_err(|e| CsvSinkError {
            file: path.to_path_buf(),
            source: e.source.unwrap_or_else(|| {
                let why = e
                    .message
                    .strip_prefix("cannot write: ")
                    .unwrap_or(&e.message);
                std::io::Error::other(why.to_string())
            }),
        })?;
        let mut header = csv::Writer::from_writer(Vec::new());
        let mut fields = vec!["time_s".to_string()];
        fields.extend(axis_names.iter().map(|a| format!("{a}_offset_um")));
        fields.push("state".into());
        fields.push("clamped".into());
        header.write_record(&fields).map_err(|e| fail(e.into()))?;
        let pending = header.into_inner().map_err(|e| fail(e.into_error()))?;
        Ok(Self {
            name: format!("csv {}", path.display()),
            file,
            pending,
            axes: axis_names.len(),
            every_s,
            last_s: f64::NEG_INFINITY,
            last_flush_s: f64::NEG_INFINITY,
            failure: None,
            rows_dropped: 0,
        })
    }

    /// Writes buffered rows to the file.
    pub fn flush(&mut self) -> std::io::Result<()> {
        while !self.pending.is_empty() {
            match std::io::Write::write(&mut self.file, &self.pending) {
                Ok(0) => return Err(std::io::ErrorKind::WriteZero.into()),
                Ok(n) => {
                    self.pending.drain(..n);
                }
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        Ok(())
    }

    /// Rows dropped because the buffer was full while the file failed.
    pub fn rows_dropped(&self) -> u64 {
        self.rows_dropped
    }

    fn push_row(&mut self, output: &Output) {
        use std::io::Write as _;
        if self.pending.len() >= CSV_MAX_PENDING {
            self.rows_dropped += 1;
            return;
        }
        // Numbers and state words need no quoting. A file sink formats text; it is meant for
        // replay, tests and monitoring, not for a 1 kHz control.
        let p = &mut self.pending;
        let _ = write!(p, "{:.4}", output.time_s);
        for v in &output.offset_um[..self.axes] {
            let _ = write!(p, ",{v:.4}");
        }
        let _ = writeln!(
            p,
            ",{},{}",
            state_name(output.state),
            u8::from(output.clamped)
        );
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
        if output.time_s - self.last_s >= self.every_s {
            self.last_s = output.time_s;
            self.push_row(output);
        }
        if output.time_s - self.last_flush_s >= CSV_FLUSH_EVERY_S {
            self.last_flush_s = output.time_s;
            self.failure = self.flush().err().map(|e| LinkError::Failed(e.to_string()));
        }
        match &self.failure {
            None => Ok(()),
            Some(e) => Err(e.clone()),
        }
    }
}

impl Drop for CsvSink {
    fn drop(&mut self) {
        let _ = self.flush();
    }
}
