//! # truepos-gcode — compensating G-code programs through LinuxCNC's own interpreter
//!
//! Offline compensation by program modification (ISO/TR 16907): a program's moves are
//! rewritten so that the real tool, through the machine's erroneous kinematic chain, lands
//! where the program says. The program is not parsed here: LinuxCNC's standalone interpreter
//! `rs274 -g` ([`rs274`]) resolves expressions, parameters, subroutines, canned cycles,
//! incremental moves, units, work and G92 offsets, cutter compensation and tool length
//! offsets exactly as the control will, and prints the canonical machining commands
//! ([`canon`]). [`motion::Motion`] turns them into machine coordinates and linearises arcs,
//! [`compensate::Compensator`] passes each point through the kinematics table, and
//! [`writer::Writer`] writes the compensated program: `G53` blocks whose N word is the
//! source line.
//!
//! [`rewrite_file`] writes to a temporary file beside the output and renames it only when the
//! whole program was compensated: a refused program (an interpreter error, an unsupported
//! command that would change motion, an unreachable pose, travel limits) leaves no output and
//! an [`Error`] naming the file and line.
//!
//! ```no_run
//! use std::path::Path;
//! use truepos_gcode::{rewrite_file, Options};
//! let k = truepos_io::kinematics_file::load(
//!     Path::new("examples/kinematics/sample-mill/kinematics.ktab"),
//!     None,
//! )?;
//! let summary = rewrite_file(
//!     Path::new("/usr/share/linuxcnc/ncfiles/3D_Chips.ngc"),
//!     &k.chain,
//!     &Options::new(k.tool_length_mm),
//!     Path::new("/tmp/3D_Chips.compensated.ngc"),
//! )?;
//! println!("{} moves, largest compensation {:?} mm", summary.moves, summary.largest);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![forbid(unsafe_code)]

pub mod canon;
pub mod compensate;
pub mod error;
pub mod motion;
pub mod program;
pub mod rs274;
pub mod writer;

use std::io::Write;
use std::path::Path;
use std::time::Instant;

use truepos_kinematics::{Chain, Geometry};

pub use error::{Error, Place};
pub use rs274::Interpreter;

use compensate::Compensator;
use motion::{Block, Motion};
use writer::Writer;

/// How to compensate a program.
#[derive(Debug, Clone)]
pub struct Options {
    pub interpreter: Interpreter,
    /// Largest distance of a chord from the arc it replaces, mm.
    pub chord_tolerance_mm: f64,
    /// [`Geometry::Actual`] compensates; [`Geometry::Nominal`] rewrites through the nominal
    /// chain (the moves stay the program's, in machine coordinates).
    pub geometry: Geometry,
    /// Tool length with no tool length offset active (the reference tool), mm.
    pub tool_length_mm: f64,
    /// Comment lines written at the top of the output.
    pub header: Vec<String>,
    /// Axes the kinematics table does not have that are written unchanged (`A`, `B`, `C`): a
    /// rotary table on the machine's base, whose own errors are not modelled, turns the
    /// workpiece but not the frame the linear axes' errors are corrected in. Without this, a
    /// program moving such an axis is refused.
    pub pass_axes: Vec<char>,
    /// Scale each feed move's F by its compensated over its programmed length (linear axes;
    /// moves that turn a rotary axis keep their F), so that every move takes the time the
    /// program gave it.
    pub correct_feed: bool,
}

impl Options {
    /// rs274 from `PATH` with its defaults, 1 µm chords, compensation through the error
    /// tables.
    pub fn new(tool_length_mm: f64) -> Options {
        Options {
            interpreter: Interpreter::default(),
            chord_tolerance_mm: 0.001,
            geometry: Geometry::Actual,
            tool_length_mm,
            header: Vec::new(),
            pass_axes: Vec::new(),
            correct_feed: false,
        }
    }
}

/// What a rewrite did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Summary {
    /// Canonical commands rs274 printed.
    pub commands: u64,
    /// Moves written (arcs count once per chord).
    pub moves: u64,
    /// Arcs linearised.
    pub arcs: u64,
    /// Axis letters, in the chain's set-point order.
    pub axes: Vec<char>,
    /// Largest |compensated − programmed| per axis, mm or degrees.
    pub largest: Vec<f64>,
    /// Points where the real tool direction could not be reached exactly (TCP exact), and
    /// the largest remaining direction error.
    pub direction_misses: u64,
    pub largest_direction_miss_rad: f64,
    pub seconds: f64,
}

/// Compensates `input` into `output` through the one door for outputs
/// ([`truepos_files::write::Pending`]): written to an exclusive temporary file in `output`'s
/// directory and renamed over `output` only on success; an output that is the input, a
/// device, a FIFO, a directory or a link is refused before rs274 runs.
pub fn rewrite_file(
    input: &Path,
    chain: &Chain,
    options: &Options,
    output: &Path,
) -> Result<Summary, Error> {
    let mut tmp = truepos_files::write::Pending::create(output, &[("--input", input)])?;
    let w = std::io::BufWriter::with_capacity(1 << 16, &mut tmp);
    let (summary, w) = rewrite(input, chain, options, w)?;
    w.into_inner()
        .map_err(|e| Error::file(output, "cannot write")(e.into_error()))?;
    tmp.commit()?;
    Ok(summary)
}

/// Compensates `input`, writing the program to `w`; returns `w` with the summary. On an
/// error `w` holds a partial program: [`rewrite_file`] is what never leaves one.
pub fn rewrite<W: Write>(
    input: &Path,
    chain: &Chain,
    options: &Options,
    w: W,
) -> Result<(Summary, W), Error> {
    let start = Instant::now();
    let refused = |place: &Place, reason: String| Error::Refused {
        place: place.clone(),
        reason,
    };
    let none = Place {
        file: input.to_path_buf(),
        ..Place::default()
    };
    if !(options.chord_tolerance_mm > 0.0 && options.chord_tolerance_mm.is_finite()) {
        return Err(refused(
            &none,
            format!(
                "chord tolerance {} mm: expected a positive number",
                options.chord_tolerance_mm
            ),
        ));
    }
    let comp = Compensator::new(
        chain,
        options.geometry,
        options.tool_length_mm,
        &options.pass_axes,
    )
    .map_err(|r| refused(&none, r))?;
    let letters = comp.letters();
    let rotary: Vec<bool> = (0..letters.len()).map(|j| comp.rotary(j)).collect();
    let writer = Writer::new(w, letters.clone(), rotary.clone(), &options.header)
        .map_err(Error::file(input, "cannot write the output for"))?;
    let workdir = tempfile::Builder::new()
        .prefix("truepos-rs274-")
        .tempdir()
        .map_err(Error::file(
            std::env::temp_dir(),
            "cannot create a working directory in",
        ))?;
    let mut motion = Motion::new(options.chord_tolerance_mm);
    let mut commands = 0u64;
    let mut blocks = Vec::new();
    let mut out = Output {
        comp,
        writer,
        letters,
        rotary,
        correct_feed: options.correct_feed,
        last: None,
    };
    options
        .interpreter
        .run(input, workdir.path(), |line, place| {
            commands += 1;
            blocks.clear();
            motion
                .step(&line.command, &mut |b| blocks.push(b))
                .map_err(|r| refused(&place, r))?;
            for b in blocks.drain(..) {
                out.block(b, &place, input)?;
            }
            Ok(rs274::Flow::Continue)
        })?;
    let Output { comp, writer, .. } = out;
    let moves = writer.moves;
    let w = writer
        .finish()
        .map_err(Error::file(input, "cannot write the output for"))?;
    let summary = Summary {
        commands,
        moves,
        arcs: motion.arcs,
        axes: comp.letters()[..chain.axes().len()].to_vec(),
        largest: comp.largest.clone(),
        direction_misses: comp.direction_misses,
        largest_direction_miss_rad: comp.largest_direction_miss_rad,
        seconds: start.elapsed().as_secs_f64(),
    };
    Ok((summary, w))
}

/// What a rewrite carries from block to block: the compensator, the writer, the axes' letters
/// and kinds, and the last compensated point with its machine point and tool offset (a rigid
/// tap starts there and returns).
struct Output<'c, W: Write> {
    comp: Compensator<'c>,
    writer: Writer<W>,
    letters: Vec<char>,
    rotary: Vec<bool>,
    correct_feed: bool,
    last: Option<(Vec<f64>, canon::Pos6, f64)>,
}

impl<W: Write> Output<'_, W> {
    /// Compensates and writes one block of the line at `place`: a move at its compensated
    /// set-point (its feed corrected for the compensated length with `correct_feed`), a rigid
    /// tap along the linear axes, or a code passed through.
    fn block(&mut self, b: Block, place: &Place, input: &Path) -> Result<(), Error> {
        let refused = |reason: String| Error::Refused {
            place: place.clone(),
            reason,
        };
        let io = |e| Error::file(input, "cannot write the output for")(e);
        match b {
            Block::Move {
                rapid,
                machine,
                feed,
                tool_offset_z,
                ..
            } => {
                let q = self.comp.apply(&machine, tool_offset_z).map_err(refused)?;
                let feed = match &self.last {
                    Some((from, start, _)) if self.correct_feed && !rapid => {
                        let (letters, rotary) = (&self.letters, &self.rotary);
                        feed * length_ratio(letters, rotary, start, &machine, from, q)
                    }
                    _ => feed,
                };
                self.writer.motion(place.line, rapid, q, feed).map_err(io)?;
                self.last = Some((q.to_vec(), machine, tool_offset_z));
            }
            Block::Tap {
                machine,
                pitch_mm,
                tool_offset_z,
            } => {
                let Some((from, start, start_tool)) = self.last.clone() else {
                    return Err(refused("a rigid tap before any move".into()));
                };
                let to = self
                    .comp
                    .apply(&machine, tool_offset_z)
                    .map_err(refused)?
                    .to_vec();
                for (j, (a, b)) in from.iter().zip(&to).enumerate() {
                    if self.rotary[j] && (a - b).abs() > 1e-9 {
                        return Err(refused(format!("a rigid tap that turns {}: truepos writes taps along the linear axes only", self.letters[j])));
                    }
                }
                self.writer
                    .tap(place.line, &from, &to, pitch_mm)
                    .map_err(io)?;
                // The tap retracts to its start: the compensation state follows.
                self.comp.apply(&start, start_tool).map_err(refused)?;
            }
            Block::Units(u) => self.writer.units(place.line, u).map_err(io)?,
            Block::Code(c) => self.writer.code(place.line, &c).map_err(io)?,
        }
        Ok(())
    }
}

/// Compensated over programmed length of a move (linear axes), 1 when a rotary axis turns or
/// the move is shorter than 1 nm.
fn length_ratio(
    letters: &[char],
    rotary: &[bool],
    start: &canon::Pos6,
    end: &canon::Pos6,
    from: &[f64],
    to: &[f64],
) -> f64 {
    let (mut nominal, mut compensated) = (0.0, 0.0);
    for (j, l) in letters.iter().enumerate() {
        let k = compensate::LETTERS.iter().position(|m| m == l).unwrap_or(0);
        let d = end[k] - start[k];
        if rotary[j] {
            if d.abs() > 1e-12 {
                return 1.0;
            }
            continue;
        }
        nominal += d * d;
        compensated += (to[j] - from[j]).powi(2);
    }
    if nominal < 1e-12 {
        1.0
    } else {
        (compensated / nominal).sqrt()
    }
}
