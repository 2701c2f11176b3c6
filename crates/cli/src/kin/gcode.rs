//! `truepos kin gcode`: rewrites G0/G1 moves whose axis words are nominal axis positions into
//! compensated axis positions, line by line — read the program, split each line into code and
//! comments, parse its words, compensate the move, write the line back with its comments.
//! A line that cannot be rewritten is copied as it is and named in the problems.

use std::fmt::Write as _;

use truepos_kinematics::{Chain, Directions, Geometry, KinError};

use super::{emit, geometry, load, start_positions, tool_length, Common};
use crate::error::CliError;

pub(super) fn gcode(c: &Common) -> Result<(), CliError> {
    let k = load(&c.kinematics, c.machine.as_deref())?;
    let tool = tool_length(c, &k)?;
    let text =
        std::fs::read_to_string(&c.input).map_err(CliError::file(&c.input, Some("cannot read")))?;
    let mut program = Program::new(&k.chain, tool, geometry(c));
    let mut out_text = String::new();
    for (i, raw) in text.lines().enumerate() {
        let loc = format!("{}:{}", c.input.display(), i + 1);
        let line = program.line(raw, &loc);
        out_text.push_str(line.as_deref().unwrap_or(raw));
        out_text.push('\n');
    }
    let Program {
        moves,
        problems,
        warnings,
        ..
    } = program;
    let summary = serde_json::json!({
        "moves_rewritten": moves, "problems": problems, "warnings": warnings,
    });
    let mut txt = format!(
        "{moves} moves rewritten; {} problem(s), {} warning(s)",
        problems.len(),
        warnings.len()
    );
    for p in problems.iter().chain(&warnings) {
        txt.push('\n');
        txt.push_str(p);
    }
    emit(c, &out_text, summary, txt)?;
    if problems.is_empty() {
        Ok(())
    } else {
        Err(CliError::refused(format!(
            "{} line(s) could not be rewritten",
            problems.len()
        )))
    }
}

/// A line split into its code and its comments.
struct Split {
    /// The line without its comments.
    code: String,
    /// `( … )` comments, each with the length of the code before it.
    comments: Vec<(usize, String)>,
    /// A `;` comment to the end of the line.
    rest_comment: Option<String>,
}

/// Splits code from comments: `( … )` anywhere and `;` to the end of the line; `None` when a
/// `(` is never closed.
fn split_comments(raw: &str) -> Option<Split> {
    let mut code = String::new();
    let mut comments: Vec<(usize, String)> = Vec::new();
    let mut depth = 0;
    let mut current = String::new();
    let mut rest_comment: Option<String> = None;
    for (ci, ch) in raw.char_indices() {
        if depth == 0 && ch == ';' {
            rest_comment = Some(raw[ci..].to_string());
            break;
        }
        if ch == '(' {
            depth += 1;
        }
        if depth > 0 {
            current.push(ch);
            if ch == ')' {
                depth -= 1;
                if depth == 0 {
                    comments.push((code.len(), std::mem::take(&mut current)));
                }
            }
        } else {
            code.push(ch);
        }
    }
    (depth == 0).then_some(Split {
        code,
        comments,
        rest_comment,
    })
}

/// The words of a line's code, letter upper-cased and number text without blanks, up to the
/// first character that cannot start a word (returned with them, if any).
fn words(code: &str) -> (Vec<(char, String)>, Option<char>) {
    let mut words: Vec<(char, String)> = Vec::new();
    let chars: Vec<char> = code.chars().collect();
    let mut p = 0;
    while p < chars.len() {
        let ch = chars[p];
        if ch.is_whitespace() {
            p += 1;
            continue;
        }
        if !ch.is_ascii_alphabetic() {
            return (words, Some(ch));
        }
        let mut q = p + 1;
        while q < chars.len()
            && (chars[q].is_ascii_digit() || matches!(chars[q], '.' | '-' | '+' | ' '))
        {
            q += 1;
        }
        let num: String = chars[p + 1..q]
            .iter()
            .filter(|c| !c.is_whitespace())
            .collect();
        words.push((ch.to_ascii_uppercase(), num));
        p = q;
    }
    (words, None)
}

/// The state carried from line to line of a program, and what the rewrite found.
struct Program<'a> {
    chain: &'a Chain,
    tool: f64,
    geometry: Geometry,
    /// Program axis words: the chain's axes named by one letter.
    letters: Vec<char>,
    /// The programmed (nominal) axis positions so far; modal words keep their last value.
    nominal: Vec<f64>,
    dirs: Directions,
    /// The modal motion, once a G0 or G1 was seen.
    motion: Option<u32>,
    /// Compensated set-points of the last rewritten move.
    out: Vec<f64>,
    moves: usize,
    problems: Vec<String>,
    warnings: Vec<String>,
}

impl<'a> Program<'a> {
    fn new(chain: &'a Chain, tool: f64, geometry: Geometry) -> Self {
        let n = chain.axes().len();
        Program {
            chain,
            tool,
            geometry,
            letters: chain
                .axes()
                .iter()
                .map(|a| a.name.chars().next().unwrap_or(' '))
                .collect(),
            nominal: start_positions(chain),
            dirs: Directions(0),
            motion: None,
            out: vec![0.0; n],
            moves: 0,
            problems: Vec::new(),
            warnings: Vec::new(),
        }
    }

    /// The rewritten line, or `None` when the line stays as it is (no move, or a problem).
    fn line(&mut self, raw: &str, loc: &str) -> Option<String> {
        let Some(split) = split_comments(raw) else {
            self.problems.push(format!("{loc}: unclosed comment `(`"));
            return None;
        };
        let (words, stray) = words(&split.code);
        if let Some(ch) = stray {
            self.problems.push(format!(
                "{loc}: unexpected `{ch}`; expected a word such as G1 or X10.5"
            ));
        }
        let (axis_words, unsupported) = self.check_words(&words, loc);
        if !axis_words || unsupported || stray.is_some() {
            return None;
        }
        if self.motion.is_none() {
            self.problems
                .push(format!("{loc}: axis words before any G0/G1"));
            return None;
        }
        self.compensate(&words, loc)?;
        self.moves += 1;
        Some(self.rewrite(&words, &split))
    }

    /// Takes the modal motion from the G words and checks every word: whether the line has
    /// axis words, and whether any word is one this rewrite does not support.
    fn check_words(&mut self, words: &[(char, String)], loc: &str) -> (bool, bool) {
        let mut axis_words = false;
        let mut unsupported = false;
        for (l, num) in words {
            match l {
                'G' => match num.parse::<f64>().ok() {
                    Some(g) if g == 0.0 || g == 1.0 => self.motion = Some(g as u32),
                    Some(g)
                        if matches!(g as i64, 17 | 21 | 40 | 49 | 54 | 80 | 90 | 94)
                            && g.fract() == 0.0 => {}
                    _ => {
                        self.problems.push(format!(
                            "{loc}: G{num} is not supported (only G0/G1 moves in absolute mm, G90)"
                        ));
                        unsupported = true;
                    }
                },
                'N' | 'F' | 'S' | 'M' | 'T' | 'H' | 'D' => {}
                l if self.letters.contains(l) => {
                    axis_words = true;
                    if num.parse::<f64>().ok().filter(|v| v.is_finite()).is_none() {
                        self.problems
                            .push(format!("{loc}: `{l}{num}`: expected a number"));
                        unsupported = true;
                    }
                }
                _ => {
                    self.problems
                        .push(format!("{loc}: word `{l}{num}` is not supported here"));
                    unsupported = true;
                }
            }
        }
        (axis_words, unsupported)
    }

    /// Moves the nominal axes to the line's words and finds the compensated set-points into
    /// `self.out`; `None` (with a problem) when there are none.
    fn compensate(&mut self, words: &[(char, String)], loc: &str) -> Option<()> {
        let before = self.nominal.clone();
        for (l, num) in words {
            if let Some(j) = self.letters.iter().position(|c| c == l) {
                self.nominal[j] = num.parse().unwrap_or(self.nominal[j]);
            }
        }
        // Travel directions from the programmed motion (for directional tables).
        for (j, (now, was)) in self.nominal.iter().zip(&before).enumerate() {
            if now > was {
                self.dirs.0 &= !(1 << j);
            } else if now < was {
                self.dirs.0 |= 1 << j;
            }
        }
        // The nominal machine would put the tool here; find set-points that put the real tool
        // there, on the branch the program chose.
        let target =
            match self
                .chain
                .forward(&self.nominal, self.tool, self.dirs, Geometry::Nominal)
            {
                Ok(t) => t,
                Err(e) => {
                    self.problems.push(format!("{loc}: {e}"));
                    return None;
                }
            };
        let solved = self.chain.inverse_near(
            &target,
            self.tool,
            &self.nominal,
            self.dirs,
            self.geometry,
            &mut self.out,
        );
        match solved {
            Ok(_) => Some(()),
            Err(KinError::NotConverged {
                position_mm,
                direction_rad,
            }) if position_mm < 1e-6 => {
                // The real machine cannot point the tool exactly there (e.g. at the pole, a tilt
                // in the plane of the swivel axis): TCP exact, direction as close as it gets.
                self.warnings.push(format!(
                    "{loc}: the real tool direction stays {:.1} µrad off (not reachable with these errors); TCP exact",
                    direction_rad * 1e6
                ));
                Some(())
            }
            Err(e) => {
                self.problems.push(format!("{loc}: {e}"));
                None
            }
        }
    }

    /// Every word as it was, axis words of this line with compensated values, axis words that
    /// changed through compensation but were modal added at the end, then the comments.
    fn rewrite(&self, words: &[(char, String)], split: &Split) -> String {
        let mut line = String::new();
        let mut written = vec![false; self.letters.len()];
        for (l, num) in words {
            if !line.is_empty() {
                line.push(' ');
            }
            if let Some(j) = self.letters.iter().position(|c| c == l) {
                let _ = write!(line, "{l}{:.6}", self.out[j]);
                written[j] = true;
            } else {
                let _ = write!(line, "{l}{num}");
            }
        }
        for (j, done) in written.iter().enumerate() {
            if !done {
                let _ = write!(line, " {}{:.6}", self.letters[j], self.out[j]);
            }
        }
        for (_, cmt) in &split.comments {
            line.push(' ');
            line.push_str(cmt);
        }
        if let Some(cmt) = &split.rest_comment {
            line.push(' ');
            line.push_str(cmt);
        }
        line
    }
}
