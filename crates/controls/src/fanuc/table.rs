//! FANUC pitch error compensation: the per-axis parameters 3620–3624 and the compensation
//! data, in the parameter tape format, read into exactly what the tape says ([`FanucPitch`])
//! and converted to and from [`CompTable`].
//!
//! What is relied on (FANUC parameter manuals: Series 0i-D B-64310EN / 0i-F B-64490EN, section
//! "Parameters of pitch error compensation"; Series 15i parameter manual B-63330EN, chapter 3
//! "Inputting and outputting parameters using external input/output devices"):
//!
//! * 3620 the compensation point number of the reference position, 3621 the number of the
//!   most negative point, 3622 of the most positive point, 3623 the magnification, 3624 the
//!   interval between points (mm); point k lies at (k − [3620]) × [3624] from the reference
//!   position.
//! * The value of point k is the compensation for the section between points k − 1 and k,
//!   incremental, in detection units × magnification, at most ±7 per point; the control's
//!   absolute compensation is zero at the reference position (it is re-established by the
//!   reference return), so an error there is not carried.
//! * The tape: a record starts and ends with `%`; axis-type parameters are blocks
//!   `N03620A1P40A2P40;` (N the parameter number, A the axis number, P its value), the
//!   compensation data blocks `N10000P1;` (data number 10000 + the point number). `;` ends a
//!   block (LF in ISO code).
//!
//! Not verified from a public document, and said so in docs/controls.md: whether a series
//! takes 3624 as a real in mm (written so here, `P50.0`) or as an integer in detection units
//! (older series); the ±7 range (newer series document wider ranges: `--fanuc-max-step`).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use truepos_kinematics::table::{CompTable, Direction, Interpolation, Wrap};

use crate::table::ExportError;
use truepos_files::InputError;

/// The pitch error parameters of one axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FanucAxis {
    /// 3620: the point number of the reference position.
    pub reference: u32,
    /// 3621: the most negative point number.
    pub negative: u32,
    /// 3622: the most positive point number.
    pub positive: u32,
    /// 3623: the magnification (0 means 1).
    pub magnification: u32,
    /// 3624: the interval between points, mm.
    pub interval: f64,
}

/// A parameter tape of pitch error compensation exactly as written.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FanucPitch {
    /// Per axis number (1-based `A`), its parameters.
    pub axes: BTreeMap<u32, FanucAxis>,
    /// Per point number, its incremental value.
    pub points: BTreeMap<u32, i32>,
}

/// How an error table is put on the FANUC grid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FanucGrid {
    /// Axis number (1-based).
    pub axis: u32,
    /// 3620: the point number at the reference position.
    pub reference: u32,
    /// 3624 in mm; `None`: the table's own step (its support points must be equidistant and
    /// on the grid through the reference position).
    pub interval: Option<f64>,
    /// 3623; `None`: the smallest that keeps every value within `max_step`.
    pub magnification: Option<u32>,
    /// The detection unit in mm (0.001 for an IS-B axis).
    pub detection_unit: f64,
    /// The largest value of one point (7).
    pub max_step: i32,
}

/// What the grid loses against the table: the largest difference between the table and the
/// quantised compensation at the points (µm), and the table's error at the reference
/// position, which the control's compensation cannot carry (it is zero there).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FanucLoss {
    /// Largest |table − tape| at the points, relative to the reference position, µm.
    pub quantisation_um: f64,
    /// The table's error at the reference position, µm.
    pub at_reference_um: f64,
    /// The magnification used.
    pub magnification: u32,
}

/// The number of parameter 3620's neighbours (3620–3624) and of the data blocks.
const DATA_BASE: u32 = 10_000;
/// Most point numbers the data numbers can hold (points 0–1023 on the 0i).
const MAX_POINT: u32 = 1023;

impl FanucPitch {
    /// The tape of the error table `t` (µm over mm from the reference position) on `grid`,
    /// and what the grid loses. Refused (no tape): a directional table, a table off the grid,
    /// a grid beyond the point numbers, a value beyond `max_step` at every magnification.
    pub fn from_table(t: &CompTable, grid: &FanucGrid) -> Result<(Self, FanucLoss), ExportError> {
        let bad = |why: String| Err(ExportError::Fanuc(why));
        if t.reverse().is_some() {
            return bad("a directional (forward/reverse) table needs FANUC's bidirectional pitch error compensation (3605#0, 3626, 3627), which truepos does not write; write one direction".into());
        }
        if grid.max_step < 1 {
            return bad(format!(
                "largest value per point {}; expected at least 1",
                grid.max_step
            ));
        }
        if !(grid.detection_unit > 0.0 && grid.detection_unit.is_finite()) {
            return bad(format!(
                "detection unit {} mm; expected a positive number",
                grid.detection_unit
            ));
        }
        let p = t.positions();
        let span = p[p.len() - 1] - p[0];
        let interval = match grid.interval {
            Some(iv) if iv > 0.0 && iv.is_finite() => iv,
            Some(iv) => return bad(format!("interval {iv} mm; expected a positive number")),
            None => {
                let Some(step) = t.step(1e-9 * (1.0 + span.abs())) else {
                    return bad("the table's support points are not equidistant; give the interval (3624) to resample it".into());
                };
                let off = p[0] / step;
                if (off - off.round()).abs() > 1e-6 {
                    return bad(format!("the support points are not on a grid through the reference position (0 mm) with interval {step} mm; give the interval (3624) to resample"));
                }
                step
            }
        };
        // The grid covers the table and the reference position (3621 ≤ 3620 ≤ 3622); the
        // first point's value is the section before it, so the grid starts one point lower.
        let lo = ((p[0] / interval).floor() as i64).min(0) - 1;
        let hi = ((p[p.len() - 1] / interval).ceil() as i64).max(0);
        let r = i64::from(grid.reference);
        if r + lo < 0 || r + hi > i64::from(MAX_POINT) {
            return bad(format!(
                "the table needs points {} to {} around reference point {}; expected point numbers 0 to {MAX_POINT} (choose another reference point number or a larger interval)",
                r + lo,
                r + hi,
                grid.reference
            ));
        }
        let at_reference_um = t.value(0.0, Direction::Forward);
        // Absolute compensation (−error relative to the reference position), µm, per point.
        let comp: Vec<f64> = (lo..=hi)
            .map(|k| -(t.value(k as f64 * interval, Direction::Forward) - at_reference_um))
            .collect();
        let quantise = |mag: u32| -> (Vec<i64>, f64) {
            let unit_um = grid.detection_unit * 1000.0 * f64::from(mag);
            let counts: Vec<i64> = comp.iter().map(|c| (c / unit_um).round() as i64).collect();
            let err = comp
                .iter()
                .zip(&counts)
                .map(|(c, &n)| (c - n as f64 * unit_um).abs())
                .fold(0.0, f64::max);
            (counts, err)
        };
        let fits = |counts: &[i64]| {
            counts
                .windows(2)
                .all(|w| (w[1] - w[0]).abs() <= i64::from(grid.max_step))
        };
        let (mag, counts, err) = match grid.magnification {
            Some(m) if (1..=100).contains(&m) => {
                let (c, e) = quantise(m);
                if !fits(&c) {
                    return bad(format!("a step between two points exceeds ±{} at magnification {m}; raise the magnification (3623) or shorten the interval", grid.max_step));
                }
                (m, c, e)
            }
            Some(m) => return bad(format!("magnification {m}; expected 1 to 100")),
            None => {
                let Some((m, (c, e))) = (1..=100)
                    .map(|m| (m, quantise(m)))
                    .find(|(_, (c, _))| fits(c))
                else {
                    return bad(format!("a step between two points exceeds ±{} even at magnification 100; shorten the interval", grid.max_step));
                };
                (m, c, e)
            }
        };
        let mut points = BTreeMap::new();
        for (i, w) in counts.windows(2).enumerate() {
            let k = (r + lo + 1 + i as i64) as u32;
            points.insert(k, (w[1] - w[0]) as i32);
        }
        let axis = FanucAxis {
            reference: grid.reference,
            negative: (r + lo + 1) as u32,
            positive: (r + hi) as u32,
            magnification: mag,
            interval,
        };
        let tape = Self {
            axes: BTreeMap::from([(grid.axis, axis)]),
            points,
        };
        let loss = FanucLoss {
            quantisation_um: err,
            at_reference_um,
            magnification: mag,
        };
        Ok((tape, loss))
    }

    /// The error table in µm (relative to the reference position, where it is zero) of axis
    /// `axis` with detection unit `detection_unit` mm. Errors name the file.
    pub fn to_table(
        &self,
        path: &Path,
        axis: u32,
        detection_unit: f64,
        interpolation: Interpolation,
    ) -> Result<CompTable, InputError> {
        if !(detection_unit > 0.0 && detection_unit.is_finite()) {
            return Err(InputError::file(
                path,
                format!("detection unit {detection_unit} mm; expected a positive number"),
            ));
        }
        let Some(a) = self.axes.get(&axis) else {
            let have: Vec<String> = self.axes.keys().map(|k| format!("A{k}")).collect();
            return Err(InputError::file(
                path,
                format!(
                    "no pitch error parameters 3620–3624 for axis A{axis}; the tape has {}",
                    if have.is_empty() {
                        "none".into()
                    } else {
                        have.join(", ")
                    }
                ),
            ));
        };
        if !(a.negative <= a.reference && a.reference <= a.positive) {
            return Err(InputError::file(
                path,
                format!(
                    "A{axis}: expected 3621 ≤ 3620 ≤ 3622, got {} , {}, {}",
                    a.negative, a.reference, a.positive
                ),
            ));
        }
        let unit_um = detection_unit * 1000.0 * f64::from(a.magnification.max(1));
        let (mut pos, mut val) = (vec![], vec![]);
        let first = i64::from(a.negative) - 1;
        let mut count = 0i64;
        let mut at_ref = 0i64;
        for k in first..=i64::from(a.positive) {
            if k > first {
                let Some(&v) = self.points.get(&(k as u32)) else {
                    return Err(InputError::file(
                        path,
                        format!("A{axis}: no data for point {k} (N{}); expected every point from 3621 to 3622", DATA_BASE as i64 + k),
                    ));
                };
                count += i64::from(v);
            }
            if k == i64::from(a.reference) {
                at_ref = count;
            }
            pos.push((k - i64::from(a.reference)) as f64 * a.interval);
            val.push(count);
        }
        let values = val
            .iter()
            .map(|&c| -((c - at_ref) as f64) * unit_um)
            .collect();
        CompTable::new(pos, values, Wrap::Hold, interpolation)
            .map_err(|e| InputError::file(path, format!("A{axis}: {e}")))
    }

    /// The tape's text: `%`, the five parameters of each axis, the data, `%`.
    pub fn write(&self) -> String {
        let mut out = String::from("%\n");
        let interval = |a: &FanucAxis| {
            let s = a.interval.to_string();
            if s.contains('.') || s.contains('e') {
                s
            } else {
                format!("{s}.0")
            }
        };
        for n in 3620u32..=3624 {
            let _ = write!(out, "N{n:05}");
            for (axis, a) in &self.axes {
                let v = match n {
                    3620 => a.reference.to_string(),
                    3621 => a.negative.to_string(),
                    3622 => a.positive.to_string(),
                    3623 => a.magnification.to_string(),
                    _ => interval(a),
                };
                let _ = write!(out, "A{axis}P{v}");
            }
            out.push_str(";\n");
        }
        for (k, v) in &self.points {
            let _ = writeln!(out, "N{}P{v};", DATA_BASE + k);
        }
        out.push_str("%\n");
        out
    }
}

/// Reads a parameter tape of pitch error compensation: `%`, blocks `N<number>A<axis>P<value>…;`
/// for 3620–3624 and `N1xxxx P<value>;` for the data, `%`. Other parameters are refused by
/// number (this reader holds pitch error compensation only).
pub fn parse_fanuc(path: &Path, text: &str) -> Result<FanucPitch, InputError> {
    let mut tape = FanucPitch::default();
    let mut params: Params = BTreeMap::new();
    let (mut opened, mut closed) = (false, false);
    for (i, raw) in text.lines().enumerate() {
        let n = i + 1;
        let line = raw.trim();
        if line.is_empty() {
            continue;
        }
        let col0 = raw.len() - raw.trim_start().len() + 1;
        let bad = |col: usize, key: &str, msg: String| InputError::at(path, n, col, key, msg);
        if closed {
            return Err(bad(
                col0,
                "%",
                "text after the closing `%`; expected the end of the tape".into(),
            ));
        }
        if line.trim_end_matches(';') == "%" {
            if opened {
                closed = true;
            }
            opened = true;
            continue;
        }
        if !opened {
            return Err(bad(col0, "%", "expected `%` opening the tape".into()));
        }
        let block = line.strip_suffix(';').ok_or_else(|| {
            bad(
                col0 + line.len(),
                "",
                "expected `;` ending the block".into(),
            )
        })?;
        let words = words(block).map_err(|(c, m)| bad(col0 + c, "", m))?;
        let Some(&('N', num_col, num)) = words.first() else {
            return Err(bad(
                col0,
                "N",
                "expected a block starting with N and the parameter number".into(),
            ));
        };
        let number: u32 = num.parse().map_err(|_| {
            bad(
                col0 + num_col,
                "N",
                format!("expected a parameter number, got `{num}`"),
            )
        })?;
        let at = Block {
            path,
            line: n,
            col0,
        };
        if (DATA_BASE..=DATA_BASE + MAX_POINT).contains(&number) {
            data_point(&at, number, &words, &mut tape)?;
        } else {
            parameter_block(&at, number, num_col, &words, &mut params)?;
        }
    }
    if !closed {
        return Err(InputError::file(
            path,
            "no closing `%`: the tape is cut short; expected `%` after the last block",
        ));
    }
    tape.axes = axes(path, &params)?;
    Ok(tape)
}

/// Where a block stands on the tape, so that its mistakes are named at their line and column.
struct Block<'a> {
    path: &'a Path,
    line: usize,
    /// 1-based column of the block's first character.
    col0: usize,
}

impl Block<'_> {
    fn bad(&self, col: usize, key: &str, msg: String) -> InputError {
        InputError::at(self.path, self.line, col, key, msg)
    }
}

/// A block of pitch error data, `N1xxxx P<value>`: one compensation point, each given once.
fn data_point(
    at: &Block,
    number: u32,
    words: &[Word],
    tape: &mut FanucPitch,
) -> Result<(), InputError> {
    let key = format!("N{number}");
    let [_, ('P', c, v)] = words else {
        return Err(at.bad(at.col0, &key, "expected `N1xxxxP<value>;`".into()));
    };
    let v: i32 = v.parse().map_err(|_| {
        at.bad(
            at.col0 + c,
            &key,
            format!("expected an integer compensation value, got `{v}`"),
        )
    })?;
    if tape.points.insert(number - DATA_BASE, v).is_some() {
        return Err(at.bad(at.col0, &key, "given twice".into()));
    }
    Ok(())
}

/// A block of one of the parameters 3620–3624, `N<number>` then pairs `A<axis>P<value>`: each
/// axis' value kept with its place, for [`axes`] to check; any other parameter is refused.
fn parameter_block(
    at: &Block,
    number: u32,
    num_col: usize,
    words: &[Word],
    params: &mut Params,
) -> Result<(), InputError> {
    let col0 = at.col0;
    if !(3620..=3624).contains(&number) {
        return Err(at.bad(
            col0 + num_col,
            "N",
            format!(
                "parameter {number}; expected 3620–3624 or pitch error data N10000–N{}",
                DATA_BASE + MAX_POINT
            ),
        ));
    }
    let key = format!("N{number}");
    let rest = &words[1..];
    if rest.is_empty() || !rest.len().is_multiple_of(2) {
        return Err(at.bad(col0, &key, "expected pairs A<axis>P<value>".into()));
    }
    for pair in rest.chunks(2) {
        let [('A', ac, a), ('P', pc, v)] = pair else {
            return Err(at.bad(col0 + pair[0].1, &key, "expected A<axis>P<value>".into()));
        };
        let axis: u32 = a.parse().ok().filter(|&x| x >= 1).ok_or_else(|| {
            at.bad(
                col0 + ac,
                &key,
                format!("expected an axis number ≥ 1, got `{a}`"),
            )
        })?;
        if params
            .insert((axis, number), (v.to_string(), at.line, col0 + pc))
            .is_some()
        {
            return Err(at.bad(col0 + ac, &key, format!("axis A{axis} given twice")));
        }
    }
    Ok(())
}

/// Each axis' parameters 3620–3624 from the tape's values, every one present and a number.
fn axes(path: &Path, params: &Params) -> Result<BTreeMap<u32, FanucAxis>, InputError> {
    let mut out = BTreeMap::new();
    let axes: std::collections::BTreeSet<u32> = params.keys().map(|k| k.0).collect();
    for axis in axes {
        let get = |num: u32| -> Result<&(String, usize, usize), InputError> {
            params.get(&(axis, num)).ok_or_else(|| {
                InputError::file(
                    path,
                    format!("axis A{axis} has no parameter {num}; expected 3620–3624"),
                )
            })
        };
        let int = |num: u32| -> Result<u32, InputError> {
            let (v, l, c) = get(num)?;
            v.parse().map_err(|_| {
                InputError::at(
                    path,
                    *l,
                    *c,
                    format!("N{num}"),
                    format!("expected a non-negative integer, got `{v}`"),
                )
            })
        };
        let (iv, l, c) = get(3624)?;
        let interval = iv
            .parse::<f64>()
            .ok()
            .filter(|x| *x > 0.0 && x.is_finite())
            .ok_or_else(|| {
                InputError::at(
                    path,
                    *l,
                    *c,
                    "N3624",
                    format!("expected a positive interval in mm, got `{iv}`"),
                )
            })?;
        out.insert(
            axis,
            FanucAxis {
                reference: int(3620)?,
                negative: int(3621)?,
                positive: int(3622)?,
                magnification: int(3623)?,
                interval,
            },
        );
    }
    Ok(out)
}

/// A word of a block: its letter, the 0-based column of its value, the value.
type Word<'a> = (char, usize, &'a str);

/// Per (axis, parameter number), the value's text, line and column.
type Params = BTreeMap<(u32, u32), (String, usize, usize)>;

/// The words of a block: a letter and its value, each with its 0-based column.
fn words(block: &str) -> Result<Vec<Word<'_>>, (usize, String)> {
    let mut out = Vec::new();
    let mut it = block.char_indices().peekable();
    while let Some((i, c)) = it.next() {
        if c == ' ' {
            continue;
        }
        if !c.is_ascii_alphabetic() {
            return Err((
                i,
                format!("expected an address letter (N, A, P), got `{c}`"),
            ));
        }
        let start = i + c.len_utf8();
        let mut end = start;
        while let Some(&(j, d)) = it.peek() {
            if d.is_ascii_digit() || d == '.' || d == '-' || d == '+' || d == 'e' || d == 'E' {
                end = j + d.len_utf8();
                it.next();
            } else {
                break;
            }
        }
        if end == start {
            return Err((i, format!("address `{c}` without a value")));
        }
        out.push((c.to_ascii_uppercase(), start, &block[start..end]));
    }
    Ok(out)
}
