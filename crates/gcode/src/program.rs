//! The program as rs274 gets it: checked line by line, and copied with every line's N word set
//! to [`LINE_BASE`] + its line number.
//!
//! rs274 prints, before each canonical command, the N word of the line it is interpreting
//! (`saicanon.cc` copies the digits after a leading `N` of the line's text). The copy gives
//! every line its own N word, so each command names its source line, through subroutine calls,
//! loops and canned cycles alike, and so does the line rs274 echoes with an error. N words have
//! no other meaning to the interpreter, so a program's own N words are replaced. The base of
//! 10⁹ tells these numbers from N words rs274 prints from elsewhere (a subroutine file of its
//! own, whose lines are not numbered).
//!
//! The check refuses, at line and column, what rs274 would not take or would take wrongly: a
//! control character other than tab or carriage return (a binary file; rs274 would stop
//! reading a line at a NUL byte), and a line longer than [`MAX_LINE`] characters (rs274 says
//! `Command too long`). It reads at most `MAX_LINE + 1` bytes of such a line before refusing,
//! so a 50 MB comment costs nothing.

use std::io::{BufRead, BufReader, BufWriter, Read, Write};
use std::path::Path;

use crate::error::{Error, Place};

/// N words of the numbered copy are this plus the source line number.
pub const LINE_BASE: u64 = 1_000_000_000;
/// The longest line rs274 reads (characters before the line break; its `LINELEN` 255 less
/// the line break and the terminating NUL).
pub const MAX_LINE: usize = 252;

/// The source line an N word printed by rs274 stands for, if it is one of the copy's.
pub fn source_line(n: Option<(u64, u8)>) -> Option<u64> {
    match n {
        Some((v, _)) if v > LINE_BASE => Some(v - LINE_BASE),
        _ => None,
    }
}

/// The source line of the text rs274 echoes after an error (`N1000000012 G1 W3`).
pub fn line_of_text(text: &str) -> Option<u64> {
    let t = text.trim_start_matches([' ', '\t', '/']);
    let t = t.strip_prefix(['N', 'n'])?;
    let digits: String = t.chars().take_while(char::is_ascii_digit).collect();
    source_line(Some((digits.parse().ok()?, 0)))
}

/// Checks `input` and writes the numbered copy to `copy`; returns the number of lines.
pub fn number(input: &Path, copy: &Path) -> Result<u64, Error> {
    let (f, _) = truepos_files::read::open(input, truepos_files::PROGRAM)?;
    let mut r = BufReader::with_capacity(1 << 16, f);
    let out = std::fs::File::create(copy).map_err(Error::file(copy, "cannot write"))?;
    let mut w = BufWriter::with_capacity(1 << 16, out);
    let mut buf = Vec::with_capacity(MAX_LINE + 2);
    let mut line = 0u64;
    loop {
        buf.clear();
        let n = (&mut r)
            .take(MAX_LINE as u64 + 2)
            .read_until(b'\n', &mut buf)
            .map_err(Error::file(input, "cannot read"))?;
        if n == 0 {
            break;
        }
        line += 1;
        let place = |column: usize| Place {
            file: input.to_path_buf(),
            line: Some(line),
            column: Some(column),
            canon: None,
        };
        let ended = buf.last() == Some(&b'\n');
        let mut text: &[u8] = if ended { &buf[..buf.len() - 1] } else { &buf };
        if text.last() == Some(&b'\r') {
            text = &text[..text.len() - 1];
        }
        if text.len() > MAX_LINE {
            return Err(Error::Refused {
                place: place(MAX_LINE + 1),
                reason: format!(
                    "line longer than {MAX_LINE} characters; LinuxCNC's interpreter reads no longer line (`Command too long`)"
                ),
            });
        }
        if let Some(c) = text
            .iter()
            .position(|&b| (b < 0x20 && b != b'\t' && b != b'\r') || b == 0x7f)
        {
            return Err(Error::Refused {
                place: place(c + 1),
                reason: format!(
                    "control character 0x{:02x}; a G-code program is text (is this a binary file?)",
                    text[c]
                ),
            });
        }
        let numbered = numbered_line(text, line);
        let io = |e| Error::file(copy, "cannot write")(e);
        w.write_all(numbered.as_deref().unwrap_or(text))
            .map_err(io)?;
        w.write_all(b"\n").map_err(io)?;
    }
    w.flush().map_err(Error::file(copy, "cannot write"))?;
    Ok(line)
}

/// The line with its N word set, or `None` to keep it as it is: blank lines, `%` lines, and
/// lines the N word would make too long (their commands then name no line).
fn numbered_line(text: &[u8], line: u64) -> Option<Vec<u8>> {
    let lead = text
        .iter()
        .take_while(|&&b| b == b' ' || b == b'\t' || b == b'/')
        .count();
    let rest = &text[lead..];
    if rest.iter().all(|b| b.is_ascii_whitespace()) || rest.first() == Some(&b'%') {
        return None;
    }
    // The program's own N word (`N 10` too: the interpreter drops blanks).
    let mut skip = 0;
    if matches!(rest.first(), Some(b'n' | b'N')) {
        let mut k = 1;
        while k < rest.len() && (rest[k] == b' ' || rest[k] == b'\t') {
            k += 1;
        }
        let d = k;
        while k < rest.len() && rest[k].is_ascii_digit() {
            k += 1;
        }
        if k > d {
            skip = k;
        }
    }
    let word = format!("N{} ", LINE_BASE + line);
    let len = lead + word.len() + rest.len() - skip;
    if len > MAX_LINE {
        return None;
    }
    let mut v = Vec::with_capacity(len);
    v.extend_from_slice(&text[..lead]);
    v.extend_from_slice(word.as_bytes());
    v.extend_from_slice(&rest[skip..]);
    Some(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_lines_and_replaces_their_own_n_words() {
        let n = |s: &str| numbered_line(s.as_bytes(), 7).map(|v| String::from_utf8(v).unwrap());
        assert_eq!(n("G1 X1").as_deref(), Some("N1000000007 G1 X1"));
        assert_eq!(n("N10 G1 X1").as_deref(), Some("N1000000007  G1 X1"));
        assert_eq!(n("  /n 0020G1").as_deref(), Some("  /N1000000007 G1"));
        assert_eq!(n("o100 sub").as_deref(), Some("N1000000007 o100 sub"));
        assert_eq!(n("%"), None);
        assert_eq!(n("   "), None);
        assert_eq!(n(&"(".repeat(250)), None);
        assert_eq!(line_of_text("N1000000012 G1 W3 Q"), Some(12));
        assert_eq!(line_of_text("  /N1000000012G1"), Some(12));
        assert_eq!(line_of_text("N12 G1"), None);
        assert_eq!(line_of_text("G1"), None);
    }
}
