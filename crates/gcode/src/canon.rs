//! The text protocol of `rs274 -g`: one canonical machining command a line,
//!
//! ```text
//!    26 N1000000024STRAIGHT_FEED(53.0000, -56.1280, -25.3720, 0.0000, 0.0000, 0.0000)
//!     7 N..... COMMENT("and Cutter is assumed to be a 10mm ball nose ")
//! ```
//!
//! — rs274's own counter, the N word of the source line it was interpreting (`N.....` when the
//! line has none; digits padded to six places with blanks), then the command and its arguments
//! as LinuxCNC's standalone canon (`saicanon.cc`) prints them: lengths and angles with four
//! decimals, in the program's units at that moment and in its current coordinate system.
//!
//! [`CanonLine::parse`] reads one line into a typed [`Canon`] (one variant per argument shape;
//! commands whose arguments truepos never reads keep their text in [`Canon::Other`]), and
//! [`CanonLine`]'s `Display` prints it back exactly as rs274 does, so that printed → parsed →
//! printed is the identity (property test). A line that does not have this shape is a
//! [`ParseError`] naming the column, never a panic.

use std::fmt;

/// Six axis values `X Y Z A B C` as rs274 prints them (its build has no U V W).
pub type Pos6 = [f64; 6];

/// Length units of `USE_LENGTH_UNITS`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Units {
    Mm,
    Inches,
    Cm,
}

impl Units {
    /// Millimetres per unit.
    pub fn mm(self) -> f64 {
        match self {
            Units::Mm => 1.0,
            Units::Inches => 25.4,
            Units::Cm => 10.0,
        }
    }

    fn name(self) -> &'static str {
        match self {
            Units::Mm => "CANON_UNITS_MM",
            Units::Inches => "CANON_UNITS_INCHES",
            Units::Cm => "CANON_UNITS_CM",
        }
    }
}

/// The plane of `ARC_FEED` (`SELECT_PLANE`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Plane {
    Xy,
    Yz,
    Xz,
    Uv,
    Vw,
    Uw,
}

impl Plane {
    fn name(self) -> &'static str {
        match self {
            Plane::Xy => "CANON_PLANE_XY",
            Plane::Yz => "CANON_PLANE_YZ",
            Plane::Xz => "CANON_PLANE_XZ",
            Plane::Uv => "CANON_PLANE_UV",
            Plane::Vw => "CANON_PLANE_VW",
            Plane::Uw => "CANON_PLANE_UW",
        }
    }
}

/// Path control of `SET_MOTION_CONTROL_MODE` (G61, G61.1, G64).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PathMode {
    ExactStop,
    ExactPath,
    Continuous,
}

impl PathMode {
    fn name(self) -> &'static str {
        match self {
            PathMode::ExactStop => "CANON_EXACT_STOP",
            PathMode::ExactPath => "CANON_EXACT_PATH",
            PathMode::Continuous => "CANON_CONTINUOUS",
        }
    }
}

/// An arc in the selected plane: end and centre in the plane's (first, second) coordinates,
/// `rotation` turns (positive counter-clockwise from first towards second; ±1 less than one
/// turn), the end on the plane's normal axis and the rotary axes' ends.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Arc {
    pub first_end: f64,
    pub second_end: f64,
    pub first_axis: f64,
    pub second_axis: f64,
    pub rotation: i32,
    pub axis_end: f64,
    pub abc: [f64; 3],
}

/// One canonical command.
#[derive(Debug, Clone, PartialEq)]
pub enum Canon {
    StraightTraverse(Pos6),
    StraightFeed(Pos6),
    StraightProbe(Pos6),
    ArcFeed(Arc),
    /// `START_SPEED_FEED_SYNC(feed_per_rev,velocity_mode)`: spindle-synchronised motion
    /// (G33, G33.1, G76) from here; the pitch in program units per revolution.
    StartSpeedFeedSync {
        feed_per_rev: f64,
        velocity_mode: i32,
    },
    /// `RIGID_TAP(x, y, z)`: tap to this point (program coordinates) and back (G33.1).
    RigidTap([f64; 3]),
    SetFeedRate(f64),
    /// `SET_FEED_MODE(spindle, mode)`: 0 units per minute (G94), 1 inverse time (G93),
    /// 2 units per revolution (G95).
    SetFeedMode {
        spindle: i32,
        mode: i32,
    },
    UseLengthUnits(Units),
    /// `SET_G5X_OFFSET(index, x, y, z, a, b, c)`: index 1–9 for G54–G59.3.
    SetG5xOffset {
        index: i32,
        offset: Pos6,
    },
    SetG92Offset(Pos6),
    /// Rotation of the XY plane in degrees (G10 L2 R).
    SetXyRotation(f64),
    SelectPlane(Plane),
    /// `USE_TOOL_LENGTH_OFFSET(x y z, a b c, u v w)`.
    UseToolLengthOffset([f64; 9]),
    /// The tolerance is printed for `CANON_CONTINUOUS` only.
    SetMotionControlMode {
        mode: PathMode,
        tolerance: Option<f64>,
    },
    SetSpindleSpeed {
        spindle: i32,
        speed: f64,
    },
    StartSpindleClockwise(i32),
    StartSpindleCounterclockwise(i32),
    StopSpindleTurning(i32),
    Dwell(f64),
    Comment(String),
    Message(String),
    SelectTool(i32),
    ChangeTool(i32),
    ChangeToolNumber(i32),
    /// Commands without arguments that truepos distinguishes (`FLOOD_ON()`, `PROGRAM_END()` …).
    Plain(Plain),
    /// Any other command, its arguments as printed.
    Other {
        name: String,
        args: String,
    },
}

/// Commands without arguments.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Plain {
    FloodOn,
    FloodOff,
    MistOn,
    MistOff,
    ProgramStop,
    OptionalProgramStop,
    ProgramEnd,
    StartChange,
    OnReset,
    Finish,
}

const PLAIN: [(Plain, &str); 10] = [
    (Plain::FloodOn, "FLOOD_ON"),
    (Plain::FloodOff, "FLOOD_OFF"),
    (Plain::MistOn, "MIST_ON"),
    (Plain::MistOff, "MIST_OFF"),
    (Plain::ProgramStop, "PROGRAM_STOP"),
    (Plain::OptionalProgramStop, "OPTIONAL_PROGRAM_STOP"),
    (Plain::ProgramEnd, "PROGRAM_END"),
    (Plain::StartChange, "START_CHANGE"),
    (Plain::OnReset, "ON_RESET"),
    (Plain::Finish, "FINISH"),
];

/// One line of rs274's output.
#[derive(Debug, Clone, PartialEq)]
pub struct CanonLine {
    /// rs274's counter of the command (its first column).
    pub counter: u64,
    /// The N word of the source line being interpreted: its value and the number of digits
    /// printed (leading zeros kept); `None` for `N.....`.
    pub n: Option<(u64, u8)>,
    pub command: Canon,
}

/// Why a line is not a canonical command: the 1-based character column and the expectation.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ParseError {
    pub column: usize,
    pub message: String,
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "column {}: {}", self.column, self.message)
    }
}

impl std::error::Error for ParseError {}

fn err(column: usize, message: impl Into<String>) -> ParseError {
    ParseError {
        column: column + 1,
        message: message.into(),
    }
}

impl CanonLine {
    /// Reads one line (without its line break).
    pub fn parse(line: &str) -> Result<CanonLine, ParseError> {
        let b = line.as_bytes();
        let mut p = 0;
        while p < b.len() && b[p] == b' ' {
            p += 1;
        }
        let start = p;
        while p < b.len() && b[p].is_ascii_digit() {
            p += 1;
        }
        if p == start || p - start > 18 {
            return Err(err(start, "expected rs274's command counter (digits)"));
        }
        let counter: u64 = line[start..p]
            .parse()
            .map_err(|_| err(start, "expected rs274's command counter (digits)"))?;
        if b.get(p) != Some(&b' ') || b.get(p + 1) != Some(&b'N') {
            return Err(err(p, "expected ` N` and the source line's N word"));
        }
        p += 2;
        let n = if line[p..].starts_with(".....") {
            p += 5;
            if b.get(p) != Some(&b' ') {
                return Err(err(p, "expected a blank after `N.....`"));
            }
            p += 1;
            None
        } else {
            let d = p;
            while p < b.len() && b[p].is_ascii_digit() {
                p += 1;
            }
            if p == d || p - d > 18 {
                return Err(err(
                    d,
                    "expected the N word's digits (at most 18) or `.....`",
                ));
            }
            let v: u64 = line[d..p]
                .parse()
                .map_err(|_| err(d, "expected the N word's digits"))?;
            let width = p - d;
            let pad = 6usize.saturating_sub(width);
            if b.len() < p + pad || b[p..p + pad].iter().any(|&c| c != b' ') {
                return Err(err(
                    p,
                    "expected the N word padded to six places with blanks",
                ));
            }
            p += pad;
            Some((v, width as u8))
        };
        let command = parse_command(line, p)?;
        Ok(CanonLine {
            counter,
            n,
            command,
        })
    }
}

impl fmt::Display for CanonLine {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:5} ", self.counter)?;
        match self.n {
            None => f.write_str("N..... ")?,
            Some((v, width)) => {
                write!(f, "N{v:0w$}", w = usize::from(width))?;
                for _ in usize::from(width)..6 {
                    f.write_str(" ")?;
                }
            }
        }
        write!(f, "{}", self.command)
    }
}

/// The command from column `p`: `NAME(ARGS)` to the end of the line.
fn parse_command(line: &str, p: usize) -> Result<Canon, ParseError> {
    let (name, a) = split_command(line, p)?;
    Ok(match name {
        "STRAIGHT_TRAVERSE" => Canon::StraightTraverse(a.numbers6()?),
        "STRAIGHT_FEED" => Canon::StraightFeed(a.numbers6()?),
        "STRAIGHT_PROBE" => Canon::StraightProbe(a.numbers6()?),
        "ARC_FEED" => Canon::ArcFeed(a.arc()?),
        "SET_FEED_RATE" => Canon::SetFeedRate(a.number(a.list(1)?[0])?),
        "START_SPEED_FEED_SYNC" => {
            let v = a.list(2)?;
            Canon::StartSpeedFeedSync {
                feed_per_rev: a.number(v[0])?,
                velocity_mode: a.integer(v[1])?,
            }
        }
        "RIGID_TAP" => {
            let v = a.list(3)?;
            Canon::RigidTap([a.number(v[0])?, a.number(v[1])?, a.number(v[2])?])
        }
        "SET_FEED_MODE" => {
            let v = a.list(2)?;
            Canon::SetFeedMode {
                spindle: a.integer(v[0])?,
                mode: a.integer(v[1])?,
            }
        }
        "USE_LENGTH_UNITS" => {
            Canon::UseLengthUnits(a.keyword(&[Units::Mm, Units::Inches, Units::Cm], |u| u.name())?)
        }
        "SET_G5X_OFFSET" => a.g5x_offset()?,
        "SET_G92_OFFSET" => Canon::SetG92Offset(a.numbers6()?),
        "SET_XY_ROTATION" => Canon::SetXyRotation(a.number(a.list(1)?[0])?),
        "SELECT_PLANE" => Canon::SelectPlane(a.keyword(
            &[
                Plane::Xy,
                Plane::Yz,
                Plane::Xz,
                Plane::Uv,
                Plane::Vw,
                Plane::Uw,
            ],
            |p| p.name(),
        )?),
        "USE_TOOL_LENGTH_OFFSET" => Canon::UseToolLengthOffset(a.tool_offset()?),
        "SET_MOTION_CONTROL_MODE" => a.motion_control_mode()?,
        "SET_SPINDLE_SPEED" => {
            let v = a.list(2)?;
            Canon::SetSpindleSpeed {
                spindle: a.integer(v[0])?,
                speed: a.number(v[1])?,
            }
        }
        "START_SPINDLE_CLOCKWISE" => Canon::StartSpindleClockwise(a.integer(a.list(1)?[0])?),
        "START_SPINDLE_COUNTERCLOCKWISE" => {
            Canon::StartSpindleCounterclockwise(a.integer(a.list(1)?[0])?)
        }
        "STOP_SPINDLE_TURNING" => Canon::StopSpindleTurning(a.integer(a.list(1)?[0])?),
        "DWELL" => Canon::Dwell(a.number(a.list(1)?[0])?),
        "COMMENT" => Canon::Comment(a.quoted()?),
        "MESSAGE" => Canon::Message(a.quoted()?),
        "SELECT_TOOL" => Canon::SelectTool(a.integer(a.list(1)?[0])?),
        "CHANGE_TOOL" => Canon::ChangeTool(a.integer(a.list(1)?[0])?),
        "CHANGE_TOOL_NUMBER" => Canon::ChangeToolNumber(a.integer(a.list(1)?[0])?),
        _ => a.plain_or_other(name)?,
    })
}

/// The name and the arguments of `NAME(ARGS)` from column `p`, the name checked as rs274
/// writes one (capitals, digits, `_`) so that a garbled line is refused, not passed on.
fn split_command(line: &str, p: usize) -> Result<(&str, Args<'_>), ParseError> {
    let rest = &line[p..];
    let open = rest
        .find('(')
        .ok_or_else(|| err(p, "expected a command `NAME(…)`"))?;
    let name = &rest[..open];
    if !name.starts_with(|c: char| c.is_ascii_uppercase())
        || !name
            .bytes()
            .all(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || c == b'_')
    {
        return Err(err(
            p,
            "expected a command name of capitals, digits and `_`",
        ));
    }
    if !rest.ends_with(')') || rest.len() < open + 2 {
        return Err(err(line.len(), "expected `)` at the end of the line"));
    }
    let args = &rest[open + 1..rest.len() - 1];
    let at = p + open + 1;
    Ok((name, Args { text: args, at }))
}

/// The argument text of a command and its column in the line.
struct Args<'a> {
    text: &'a str,
    at: usize,
}

impl<'a> Args<'a> {
    fn at_of(&self, part: &str) -> usize {
        self.at + (part.as_ptr() as usize - self.text.as_ptr() as usize)
    }

    /// Exactly `n` comma-separated parts, blanks around them removed.
    fn list(&self, n: usize) -> Result<Vec<&'a str>, ParseError> {
        let v: Vec<&str> = self.text.split(',').map(str::trim).collect();
        if v.len() != n {
            return Err(err(
                self.at,
                format!("expected {n} argument(s), got {}", v.len()),
            ));
        }
        Ok(v)
    }

    fn number(&self, s: &str) -> Result<f64, ParseError> {
        match s.parse::<f64>() {
            Ok(v) if v.is_finite() && is_decimal(s) => Ok(v),
            _ => Err(err(
                self.at_of(s),
                format!("expected a finite decimal number, got `{s}`"),
            )),
        }
    }

    fn integer(&self, s: &str) -> Result<i32, ParseError> {
        s.parse::<i32>()
            .map_err(|_| err(self.at_of(s), format!("expected an integer, got `{s}`")))
    }

    fn numbers6(&self) -> Result<Pos6, ParseError> {
        let v = self.list(6)?;
        let mut out = [0.0; 6];
        for (o, s) in out.iter_mut().zip(&v) {
            *o = self.number(s)?;
        }
        Ok(out)
    }

    /// `x y z, a b c, u v w`.
    fn tool_offset(&self) -> Result<[f64; 9], ParseError> {
        let groups = self.list(3)?;
        let mut out = [0.0; 9];
        for (g, group) in groups.iter().enumerate() {
            let parts: Vec<&str> = group.split(' ').filter(|s| !s.is_empty()).collect();
            if parts.len() != 3 {
                return Err(err(
                    self.at_of(group),
                    "expected three numbers separated by blanks",
                ));
            }
            for (k, s) in parts.iter().enumerate() {
                out[3 * g + k] = self.number(s)?;
            }
        }
        Ok(out)
    }

    fn keyword<T: Copy>(
        &self,
        all: &[T],
        name: impl Fn(T) -> &'static str,
    ) -> Result<T, ParseError> {
        let t = self.text.trim();
        all.iter().copied().find(|v| name(*v) == t).ok_or_else(|| {
            let names: Vec<&str> = all.iter().map(|v| name(*v)).collect();
            err(
                self.at,
                format!("expected one of {}, got `{t}`", names.join(", ")),
            )
        })
    }

    /// `ARC_FEED`'s nine arguments (see [`Arc`]).
    fn arc(&self) -> Result<Arc, ParseError> {
        let v = self.list(9)?;
        Ok(Arc {
            first_end: self.number(v[0])?,
            second_end: self.number(v[1])?,
            first_axis: self.number(v[2])?,
            second_axis: self.number(v[3])?,
            rotation: self.integer(v[4])?,
            axis_end: self.number(v[5])?,
            abc: [self.number(v[6])?, self.number(v[7])?, self.number(v[8])?],
        })
    }

    /// `SET_G5X_OFFSET`: the coordinate system's index, then its six offsets.
    fn g5x_offset(&self) -> Result<Canon, ParseError> {
        let v = self.list(7)?;
        let mut offset = [0.0; 6];
        for (o, s) in offset.iter_mut().zip(&v[1..]) {
            *o = self.number(s)?;
        }
        Ok(Canon::SetG5xOffset {
            index: self.integer(v[0])?,
            offset,
        })
    }

    /// `SET_MOTION_CONTROL_MODE`: the path mode and, when given, its tolerance.
    fn motion_control_mode(&self) -> Result<Canon, ParseError> {
        let v: Vec<&str> = self.text.split(',').map(str::trim).collect();
        if v.len() > 2 {
            return Err(err(
                self.at,
                format!("expected 1 or 2 argument(s), got {}", v.len()),
            ));
        }
        let mode = Args {
            text: v[0],
            at: self.at_of(v[0]),
        }
        .keyword(
            &[
                PathMode::ExactStop,
                PathMode::ExactPath,
                PathMode::Continuous,
            ],
            |m| m.name(),
        )?;
        Ok(Canon::SetMotionControlMode {
            mode,
            tolerance: v.get(1).map(|t| self.number(t)).transpose()?,
        })
    }

    /// A command without arguments named in [`Plain`], or any other command kept as its name
    /// and argument text.
    fn plain_or_other(&self, name: &str) -> Result<Canon, ParseError> {
        Ok(match PLAIN.iter().find(|(_, n)| *n == name) {
            Some((plain, _)) => {
                if !self.text.is_empty() {
                    return Err(err(self.at, format!("{name} takes no arguments")));
                }
                Canon::Plain(*plain)
            }
            None => Canon::Other {
                name: name.to_string(),
                args: self.text.to_string(),
            },
        })
    }

    /// `"text"`: everything between the first and the last quote.
    fn quoted(&self) -> Result<String, ParseError> {
        let t = self.text;
        if t.len() >= 2 && t.starts_with('"') && t.ends_with('"') {
            Ok(t[1..t.len() - 1].to_string())
        } else {
            Err(err(self.at, "expected a quoted text `\"…\"`"))
        }
    }
}

/// Plain decimal notation only (`-12.5000`), as rs274 prints: no `inf`, `nan` or exponent.
fn is_decimal(s: &str) -> bool {
    let s = s.strip_prefix('-').unwrap_or(s);
    !s.is_empty() && s.bytes().all(|c| c.is_ascii_digit() || c == b'.')
}

fn write_numbers(f: &mut fmt::Formatter<'_>, v: &[f64]) -> fmt::Result {
    for (i, x) in v.iter().enumerate() {
        if i > 0 {
            f.write_str(", ")?;
        }
        write!(f, "{x:.4}")?;
    }
    Ok(())
}

impl fmt::Display for Canon {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Canon::StraightTraverse(p) => {
                f.write_str("STRAIGHT_TRAVERSE(")?;
                write_numbers(f, p)?;
            }
            Canon::StraightFeed(p) => {
                f.write_str("STRAIGHT_FEED(")?;
                write_numbers(f, p)?;
            }
            Canon::StraightProbe(p) => {
                f.write_str("STRAIGHT_PROBE(")?;
                write_numbers(f, p)?;
            }
            Canon::ArcFeed(a) => {
                f.write_str("ARC_FEED(")?;
                write_numbers(f, &[a.first_end, a.second_end, a.first_axis, a.second_axis])?;
                write!(f, ", {}, ", a.rotation)?;
                write_numbers(f, &[a.axis_end, a.abc[0], a.abc[1], a.abc[2]])?;
            }
            Canon::SetFeedRate(v) => write!(f, "SET_FEED_RATE({v:.4}")?,
            Canon::StartSpeedFeedSync {
                feed_per_rev,
                velocity_mode,
            } => write!(f, "START_SPEED_FEED_SYNC({feed_per_rev:.6},{velocity_mode}")?,
            Canon::RigidTap(p) => {
                f.write_str("RIGID_TAP(")?;
                write_numbers(f, p)?;
            }
            Canon::SetFeedMode { spindle, mode } => write!(f, "SET_FEED_MODE({spindle}, {mode}")?,
            Canon::UseLengthUnits(u) => write!(f, "USE_LENGTH_UNITS({}", u.name())?,
            Canon::SetG5xOffset { index, offset } => {
                write!(f, "SET_G5X_OFFSET({index}, ")?;
                write_numbers(f, offset)?;
            }
            Canon::SetG92Offset(p) => {
                f.write_str("SET_G92_OFFSET(")?;
                write_numbers(f, p)?;
            }
            Canon::SetXyRotation(v) => write!(f, "SET_XY_ROTATION({v:.4}")?,
            Canon::SelectPlane(p) => write!(f, "SELECT_PLANE({}", p.name())?,
            Canon::UseToolLengthOffset(v) => write!(
                f,
                "USE_TOOL_LENGTH_OFFSET({:.4} {:.4} {:.4}, {:.4} {:.4} {:.4}, {:.4} {:.4} {:.4}",
                v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8]
            )?,
            Canon::SetMotionControlMode { mode, tolerance } => {
                write!(f, "SET_MOTION_CONTROL_MODE({}", mode.name())?;
                if let Some(t) = tolerance {
                    write!(f, ", {t:.6}")?;
                }
            }
            Canon::SetSpindleSpeed { spindle, speed } => {
                write!(f, "SET_SPINDLE_SPEED({spindle}, {speed:.4}")?
            }
            Canon::StartSpindleClockwise(s) => write!(f, "START_SPINDLE_CLOCKWISE({s}")?,
            Canon::StartSpindleCounterclockwise(s) => {
                write!(f, "START_SPINDLE_COUNTERCLOCKWISE({s}")?
            }
            Canon::StopSpindleTurning(s) => write!(f, "STOP_SPINDLE_TURNING({s}")?,
            Canon::Dwell(v) => write!(f, "DWELL({v:.4}")?,
            Canon::Comment(t) => write!(f, "COMMENT(\"{t}\"")?,
            Canon::Message(t) => write!(f, "MESSAGE(\"{t}\"")?,
            Canon::SelectTool(t) => write!(f, "SELECT_TOOL({t}")?,
            Canon::ChangeTool(t) => write!(f, "CHANGE_TOOL({t}")?,
            Canon::ChangeToolNumber(t) => write!(f, "CHANGE_TOOL_NUMBER({t}")?,
            Canon::Plain(p) => {
                let name = PLAIN.iter().find(|(q, _)| q == p).map_or("", |(_, n)| n);
                write!(f, "{name}(")?;
            }
            Canon::Other { name, args } => write!(f, "{name}({args}")?,
        }
        f.write_str(")")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_the_shapes_rs274_prints() {
        let l = CanonLine::parse(
            "   26 N1000000024STRAIGHT_FEED(53.0000, -56.1280, -25.3720, 0.0000, 0.0000, 0.0000)",
        )
        .unwrap();
        assert_eq!(l.counter, 26);
        assert_eq!(l.n, Some((1_000_000_024, 10)));
        assert_eq!(
            l.command,
            Canon::StraightFeed([53.0, -56.128, -25.372, 0.0, 0.0, 0.0])
        );
        let l = CanonLine::parse("   13 N0030  USE_LENGTH_UNITS(CANON_UNITS_INCHES)").unwrap();
        assert_eq!(l.n, Some((30, 4)));
        assert_eq!(l.command, Canon::UseLengthUnits(Units::Inches));
        assert_eq!(
            l.to_string(),
            "   13 N0030  USE_LENGTH_UNITS(CANON_UNITS_INCHES)"
        );
        let l = CanonLine::parse(
            "  104 N..... USE_TOOL_LENGTH_OFFSET(0.0000 0.0000 0.5110, 0.0000 0.0000 0.0000, 0.0000 0.0000 0.0000)",
        )
        .unwrap();
        assert_eq!(l.n, None);
        let Canon::UseToolLengthOffset(v) = l.command else {
            panic!("{l:?}")
        };
        assert_eq!(v[2], 0.511);
        let l = CanonLine::parse(
            "   11 N104   ARC_FEED(2.0000, 3.0000, 2.0000, 2.0000, -1, 0.0000, 0.0000, 0.0000, 0.0000)",
        )
        .unwrap();
        assert!(matches!(
            l.command,
            Canon::ArcFeed(Arc { rotation: -1, .. })
        ));
        let l = CanonLine::parse("    7 N..... COMMENT(\"a \"quoted\" (text)\")").unwrap();
        assert_eq!(l.command, Canon::Comment("a \"quoted\" (text)".into()));
        let l = CanonLine::parse("    5 N..... SET_SPINDLE_MODE(0 0.0000)").unwrap();
        assert_eq!(l.to_string(), "    5 N..... SET_SPINDLE_MODE(0 0.0000)");
    }

    #[test]
    fn names_the_column_of_what_is_wrong() {
        let e = CanonLine::parse(
            "   26 N..... STRAIGHT_FEED(1.0000, nan, 0.0000, 0.0000, 0.0000, 0.0000)",
        )
        .unwrap_err();
        assert_eq!(e.column, 36, "{e}");
        assert!(e.message.contains("finite decimal"), "{e}");
        let e = CanonLine::parse("   26 N..... STRAIGHT_FEED(1.0000)").unwrap_err();
        assert!(e.message.contains("expected 6 argument(s), got 1"), "{e}");
        let e = CanonLine::parse("executing").unwrap_err();
        assert_eq!(e.column, 1);
        let e = CanonLine::parse("    1 N..... SELECT_PLANE(CANON_PLANE_QQ)").unwrap_err();
        assert!(e.message.contains("CANON_PLANE_XY"), "{e}");
        assert!(CanonLine::parse("    1 N..... FLOOD_ON(1)").is_err());
        assert!(CanonLine::parse("    1 N12 FLOOD_ON()").is_err());
        assert!(CanonLine::parse("    1 N..... FLOOD_ON(").is_err());
        assert!(CanonLine::parse("    1 N..... 1e5()").is_err());
    }
}
