//! The compensated program: every move a `G53` block (machine coordinates, so that no work
//! offset, G92 offset, rotation or tool length offset of the machine running it can shift
//! it), its N word the line of the original program it comes from, feeds where they change,
//! lengths in the units the original was in at that point (so that rs274 reading it back
//! prints the same digits where compensation is zero).

use std::fmt::Write as _;
use std::io::Write;

use crate::canon::Units;

/// Writes blocks to `W`.
pub struct Writer<W: Write> {
    w: W,
    letters: Vec<char>,
    rotary: Vec<bool>,
    units: Units,
    feed: Option<f64>,
    ended: bool,
    /// Whether the guard against a rotated coordinate system was written (before the first
    /// tap).
    tap_guard: bool,
    line: String,
    /// Moves written (a rigid tap counts once).
    pub moves: u64,
}

impl<W: Write> Writer<W> {
    /// A writer for a chain whose axes are `letters` (set-point order), `rotary` saying which
    /// are rotary; `header` lines become comments at the top.
    pub fn new(
        w: W,
        letters: Vec<char>,
        rotary: Vec<bool>,
        header: &[String],
    ) -> std::io::Result<Self> {
        let mut wr = Writer {
            w,
            letters,
            rotary,
            units: Units::Mm,
            feed: None,
            ended: false,
            tap_guard: false,
            line: String::with_capacity(128),
            moves: 0,
        };
        for h in header {
            writeln!(wr.w, "({})", h.replace('(', "[").replace(')', "]"))?;
        }
        // No cutter compensation (G53 refuses it; rs274 already applied it), no canned
        // cycle, absolute positions.
        writeln!(wr.w, "G17 G40 G49 G80 G90")?;
        Ok(wr)
    }

    fn n_word(&mut self, n: Option<u64>) {
        self.line.clear();
        if let Some(n) = n {
            let _ = write!(self.line, "N{n} ");
        }
    }

    fn flush_line(&mut self) -> std::io::Result<()> {
        self.line.push('\n');
        self.w.write_all(self.line.as_bytes())
    }

    /// The program's length units from here on.
    pub fn units(&mut self, n: Option<u64>, u: Units) -> std::io::Result<()> {
        self.units = u;
        self.feed = None;
        self.code(n, if u == Units::Inches { "G20" } else { "G21" })
    }

    /// Words that do not move the axes.
    pub fn code(&mut self, n: Option<u64>, code: &str) -> std::io::Result<()> {
        self.ended = code == "M2" || code == "M30";
        self.n_word(n);
        self.line.push_str(code);
        self.flush_line()
    }

    /// One move to compensated set-points `q` (mm, degrees); `feed` in mm per minute (or per
    /// revolution), written in the program's units.
    pub fn motion(
        &mut self,
        n: Option<u64>,
        rapid: bool,
        q: &[f64],
        feed: f64,
    ) -> std::io::Result<()> {
        self.ended = false;
        self.n_word(n);
        self.line.push_str(if rapid { "G53 G0" } else { "G53 G1" });
        // Inches are written with 8 decimals (2.5e-7 mm), mm with 7, degrees with 8: far below
        // the 1 nm the compensation is solved to.
        let per = if self.units == Units::Inches {
            25.4
        } else {
            1.0
        };
        for (j, v) in q.iter().enumerate() {
            let l = self.letters[j];
            let _ = if self.rotary[j] {
                write!(self.line, " {l}{v:.8}")
            } else if per == 1.0 {
                write!(self.line, " {l}{v:.7}")
            } else {
                write!(self.line, " {l}{:.8}", v / per)
            };
        }
        if !rapid && self.feed != Some(feed) {
            let f = format!("{:.6}", feed / per);
            let f = f.trim_end_matches('0').trim_end_matches('.');
            let _ = write!(self.line, " F{f}");
            self.feed = Some(feed);
        }
        self.moves += 1;
        self.flush_line()
    }

    /// A rigid tap (G33.1) from the compensated point `from` to `to`, `pitch_mm` per
    /// revolution. G33.1 takes no G53, so the tap is written as an increment (G91), which no
    /// work or G92 offset or tool length offset changes; an XY rotation of the coordinate
    /// system the program runs in would turn it, so the program aborts before its first tap
    /// if the active coordinate system is rotated (`#[5210 + 20·#5220]`, its R).
    pub fn tap(
        &mut self,
        n: Option<u64>,
        from: &[f64],
        to: &[f64],
        pitch_mm: f64,
    ) -> std::io::Result<()> {
        self.ended = false;
        let per = if self.units == Units::Inches {
            25.4
        } else {
            1.0
        };
        if !self.tap_guard {
            self.tap_guard = true;
            writeln!(
                self.w,
                "o<truepos_tap> if [#[5210 + 20 * #5220] NE 0]\n(abort, truepos: the rigid taps of this program are increments and need a coordinate system without rotation)\no<truepos_tap> endif"
            )?;
        }
        self.n_word(n);
        self.line.push_str("G91 G33.1");
        for (j, (a, b)) in from.iter().zip(to).enumerate() {
            let l = self.letters[j];
            let _ = write!(self.line, " {l}{:.8}", (b - a) / per);
        }
        let _ = write!(self.line, " K{:.8}", pitch_mm / per);
        self.line.push_str("\nG90");
        self.moves += 1;
        self.flush_line()
    }

    /// Ends the program with `M2` unless it just ended (M2, M30), and returns the output.
    pub fn finish(mut self) -> std::io::Result<W> {
        if !self.ended {
            writeln!(self.w, "M2")?;
        }
        self.w.flush()?;
        Ok(self.w)
    }
}
