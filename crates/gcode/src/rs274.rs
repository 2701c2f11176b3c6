//! Running LinuxCNC's standalone interpreter `rs274 -g` as a child process: its canonical
//! commands streamed line by line through a FIFO into a callback (never buffered whole), its
//! standard error kept (bounded) for the reason of a refusal, a time limit after which it is
//! killed.
//!
//! rs274 runs in a working directory of its own, which is also its `HOME`, on copies of the
//! tool table and the parameter file: the interpreter saves its parameters into the parameter
//! file when it stops, and creates its tool data file `$HOME/.tool.mmap` truncated — the
//! user's files, and a LinuxCNC running beside, must not change because a program was
//! compensated.

use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStderr, Command, Stdio};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use crate::canon::CanonLine;
use crate::error::{Error, Place};
use crate::program;

/// How to run rs274.
#[derive(Debug, Clone)]
pub struct Interpreter {
    /// The executable (`rs274`, found on `PATH`, by default).
    pub rs274: PathBuf,
    /// Tool table (`-t`); rs274's built-in default without one.
    pub tool_table: Option<PathBuf>,
    /// Parameter file (`-v`), e.g. the machine's `linuxcnc.var` with its work offsets.
    pub var_file: Option<PathBuf>,
    /// rs274 is killed after this long.
    pub time_limit: Duration,
}

impl Default for Interpreter {
    fn default() -> Self {
        Interpreter {
            rs274: PathBuf::from("rs274"),
            tool_table: None,
            var_file: None,
            time_limit: Duration::from_secs(3600),
        }
    }
}

/// What the callback wants after a command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flow {
    Continue,
    /// Stop reading: rs274 is killed (the program was refused, or ended).
    Stop,
}

/// The longest canonical line read (rs274's lines are bounded by its 255-character input
/// lines; a longer one is not rs274's protocol).
const MAX_CANON_LINE: u64 = 16 * 1024;
/// Standard error kept for the reason of a refusal.
const MAX_STDERR: u64 = 64 * 1024;

impl Interpreter {
    /// Numbers `input` into `workdir` ([`program::number`]), runs rs274 on the copy and hands
    /// every canonical command, parsed, to `each` with the source line it names. Returns when
    /// rs274 ended well or `each` said [`Flow::Stop`]; rs274's refusal, a line that is not a
    /// canonical command, the time limit and `each`'s own errors are errors.
    pub fn run(
        &self,
        input: &Path,
        workdir: &Path,
        mut each: impl FnMut(CanonLine, Place) -> Result<Flow, Error>,
    ) -> Result<(), Error> {
        let copy = workdir.join("program.ngc");
        program::number(input, &copy)?;
        let (mut cmd, fifo) = self.command(workdir, &copy)?;
        let mut child = cmd.spawn().map_err(|source| Error::Rs274Missing {
            program: self.rs274.clone(),
            source,
        })?;
        let stderr = child.stderr.take().expect("stderr is piped");
        let err_reader = keep_stderr(stderr);
        let child = Arc::new(Mutex::new(child));
        let (done, wait) = mpsc::channel::<()>();
        let monitor = watch(Arc::clone(&child), self.time_limit, fifo.clone(), wait);
        let read = std::fs::File::open(&fifo)
            .map_err(Error::file(&fifo, "cannot read rs274's output from"))
            .and_then(|out| read_lines(input, out, &mut each));
        if read.is_err() || matches!(read, Ok(Flow::Stop)) {
            let _ = lock(&child).kill();
        }
        let _ = done.send(());
        let timed_out = monitor.join().unwrap_or(false);
        let status = lock(&child)
            .wait()
            .map_err(Error::file(&self.rs274, "cannot wait for rs274"))?;
        let stderr = err_reader.join().unwrap_or_default();
        if timed_out {
            return Err(Error::TimedOut {
                file: input.to_path_buf(),
                seconds: self.time_limit.as_secs_f64(),
            });
        }
        match read? {
            Flow::Stop => Ok(()),
            Flow::Continue if status.success() => Ok(()),
            Flow::Continue => Err(refusal(input, &copy, &stderr, status)),
        }
    }

    /// rs274's command line for the numbered copy `copy` in `workdir`: the tool table and the
    /// parameter file copied beside it (an empty one without `var_file`), the output into a FIFO
    /// (returned with the command) and a home of its own.
    fn command(&self, workdir: &Path, copy: &Path) -> Result<(Command, PathBuf), Error> {
        let mut cmd = Command::new(&self.rs274);
        cmd.arg("-g");
        if let Some(t) = &self.tool_table {
            let c = workdir.join("tool.tbl");
            std::fs::copy(t, &c).map_err(Error::file(t, "cannot read the tool table"))?;
            cmd.arg("-t").arg(c);
        }
        let var = workdir.join("params.var");
        match &self.var_file {
            Some(v) => {
                std::fs::copy(v, &var).map_err(Error::file(v, "cannot read the parameter file"))?;
            }
            None => {
                std::fs::write(&var, b"").map_err(Error::file(&var, "cannot write"))?;
            }
        }
        // rs274 writes its commands to stdout unbuffered (several write calls a line, each
        // waking the reader of a pipe: slower than the interpreting itself), but to an output
        // file through a buffered stream: the output file is a FIFO read as it is written.
        let fifo = workdir.join("canon.fifo");
        nix::unistd::mkfifo(
            &fifo,
            nix::sys::stat::Mode::S_IRUSR | nix::sys::stat::Mode::S_IWUSR,
        )
        .map_err(|e| Error::file(&fifo, "cannot create a FIFO")(e.into()))?;
        cmd.arg("-v").arg(&var).arg(copy).arg(&fifo);
        // LinuxCNC 2.9's tool data lives in `$HOME/.tool.mmap`, which rs274 creates with
        // O_TRUNC: two interpreters sharing it crash each other (SIGBUS), and one beside a
        // running LinuxCNC would truncate the control's tool data. Each run gets its own.
        cmd.env("HOME", workdir)
            .current_dir(workdir)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        Ok((cmd, fifo))
    }
}

/// Keeps the first [`MAX_STDERR`] bytes of rs274's standard error, read on a thread of their own,
/// for the refusal's message.
fn keep_stderr(stderr: ChildStderr) -> std::thread::JoinHandle<Vec<u8>> {
    std::thread::spawn(move || {
        let mut kept = Vec::new();
        let mut s = stderr;
        let _ = (&mut s).take(MAX_STDERR).read_to_end(&mut kept);
        // Drain the rest so rs274 never blocks on a full pipe.
        let _ = std::io::copy(&mut s, &mut std::io::sink());
        kept
    })
}

/// The monitor kills rs274 at the time `limit`, and once rs274 is gone opens the FIFO for
/// writing for a moment: a reader still waiting to open it (rs274 died before opening its
/// output) then opens and sees the end instead of waiting for ever. A message on `wait` (or
/// its sender dropped) ends the watch early. Joins with whether the time ran out.
fn watch(
    child: Arc<Mutex<Child>>,
    limit: Duration,
    fifo: PathBuf,
    wait: mpsc::Receiver<()>,
) -> std::thread::JoinHandle<bool> {
    std::thread::spawn(move || {
        let start = std::time::Instant::now();
        let mut timed_out = false;
        loop {
            if lock(&child).try_wait().map_or(true, |s| s.is_some()) {
                break;
            }
            if start.elapsed() >= limit {
                let _ = lock(&child).kill();
                timed_out = true;
                break;
            }
            match wait.recv_timeout(Duration::from_millis(10)) {
                Err(mpsc::RecvTimeoutError::Timeout) => {}
                _ => break,
            }
        }
        use std::os::unix::fs::OpenOptionsExt;
        let _ = std::fs::OpenOptions::new()
            .write(true)
            .custom_flags(nix::fcntl::OFlag::O_NONBLOCK.bits())
            .open(&fifo);
        timed_out
    })
}

fn lock(child: &Mutex<Child>) -> std::sync::MutexGuard<'_, Child> {
    child.lock().unwrap_or_else(|p| p.into_inner())
}

/// Reads rs274's output until its end or until `each` stops.
fn read_lines(
    input: &Path,
    stdout: impl Read,
    each: &mut impl FnMut(CanonLine, Place) -> Result<Flow, Error>,
) -> Result<Flow, Error> {
    let mut r = BufReader::with_capacity(1 << 16, stdout);
    let mut buf = Vec::with_capacity(256);
    let mut last_line = None;
    loop {
        buf.clear();
        let n = (&mut r)
            .take(MAX_CANON_LINE)
            .read_until(b'\n', &mut buf)
            .map_err(Error::file(input, "cannot read rs274's output"))?;
        if n == 0 {
            return Ok(Flow::Continue);
        }
        if buf.last() == Some(&b'\n') {
            buf.pop();
        } else if n as u64 == MAX_CANON_LINE {
            return Err(Error::Refused {
                place: place(input, last_line, None),
                reason: format!(
                    "rs274 printed a line longer than {MAX_CANON_LINE} bytes; not a canonical command"
                ),
            });
        }
        let text = String::from_utf8_lossy(&buf);
        let line = CanonLine::parse(&text).map_err(|e| Error::Refused {
            place: place(input, last_line, None),
            reason: format!("rs274 printed `{text}`, not a canonical command: {e}"),
        })?;
        let here = program::source_line(line.n).or(last_line);
        last_line = here;
        let at = place(input, here, Some(line.counter));
        if each(line, at)? == Flow::Stop {
            return Ok(Flow::Stop);
        }
    }
}

fn place(input: &Path, line: Option<u64>, canon: Option<u64>) -> Place {
    Place {
        file: input.to_path_buf(),
        line,
        column: None,
        canon,
    }
}

/// rs274's refusal from its standard error: `executing`, the message, the line's text.
fn refusal(input: &Path, copy: &Path, stderr: &[u8], status: std::process::ExitStatus) -> Error {
    // The copy has the input's lines: messages naming it name the input.
    let text =
        String::from_utf8_lossy(stderr).replace(&*copy.to_string_lossy(), &input.to_string_lossy());
    let lines: Vec<&str> = text
        .lines()
        .map(str::trim_end)
        .filter(|l| !l.is_empty() && *l != "executing")
        .collect();
    let message = lines
        .first()
        .map(|s| s.to_string())
        .unwrap_or_else(|| format!("rs274 exited with {status} and no message"));
    let echoed = lines.get(1).map(|s| s.to_string());
    let line = echoed.as_deref().and_then(program::line_of_text);
    // The echoed text without the copy's N word: the user's line as written.
    let text = echoed.map(|t| {
        let lead = t.len() - t.trim_start_matches([' ', '\t', '/']).len();
        match line {
            Some(l) => {
                let word = format!("N{}", program::LINE_BASE + l);
                let rest = t[lead..].strip_prefix(&word).unwrap_or(&t[lead..]);
                format!("{}{}", &t[..lead], rest.trim_start())
            }
            None => t,
        }
    });
    Error::Interpreter {
        place: place(input, line, None),
        message,
        text,
    }
}
