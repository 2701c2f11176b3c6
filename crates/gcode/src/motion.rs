//! The state machine: canonical commands in program coordinates → blocks in machine
//! coordinates.
//!
//! rs274 prints every move in the program's current coordinate system and units; the
//! offsets come as their own commands. LinuxCNC's canon (`emccanon.cc`) turns a point into
//! machine coordinates as
//!
//! ```text
//! machine = rotate_xy(units·p + g92, xy_rotation) + g5x + tool_length_offset
//! ```
//!
//! (rotary axes in degrees, unscaled), each offset converted to mm with the units in force
//! when it was set — and so does [`Motion`]. Arcs are linearised in program coordinates (the
//! map above is rigid, so chords stay within the tolerance) into feed moves whose ends lie on
//! the arc. Commands that would change what the machine does and that truepos cannot carry
//! over faithfully are refused with the reason; commands that do not move the machine
//! (spindle, coolant, dwell, stops, tool change, comments) become [`Block::Code`] so the
//! compensated program still machines the part.

use std::f64::consts::TAU;

use crate::canon::{Arc, Canon, PathMode, Plain, Plane, Pos6, Units};

/// What the writer writes, in order.
#[derive(Debug, Clone, PartialEq)]
pub enum Block {
    /// A move to `machine` (mm for X Y Z, degrees for A B C).
    Move {
        rapid: bool,
        machine: Pos6,
        /// Feed in mm per minute (or per revolution) for feed moves, converted with the units
        /// in force when it was set, as LinuxCNC's canon does.
        feed: f64,
        /// The tool length offset's Z in mm, for the tool length the chain uses.
        tool_offset_z: f64,
        /// Whether this is the end of a canonical command (false for the inner chord ends of
        /// a linearised arc).
        end: bool,
    },
    /// A rigid tap (G33.1) from the current point to `machine` and back, `pitch_mm` per
    /// spindle revolution.
    Tap {
        machine: Pos6,
        pitch_mm: f64,
        tool_offset_z: f64,
    },
    /// The program's length units changed (the writer follows them).
    Units(Units),
    /// Words that do not move the axes, in G-code (`M3`, `S1600`, `G4 P2`, `(text)` …).
    Code(String),
}

/// Refusal of a command, the reason in a sentence.
pub type Refusal = String;

/// The interpreter state the blocks depend on.
#[derive(Debug, Clone)]
pub struct Motion {
    units: Units,
    g5x: Pos6,
    g92: Pos6,
    rotation_deg: f64,
    tool: Pos6,
    feed: f64,
    feed_mode: i32,
    plane: Plane,
    /// Machine position after the last move (`None` before the first one).
    position: Option<Pos6>,
    chord_tolerance_mm: f64,
    flood: bool,
    mist: bool,
    /// A PALLET_SHUTTLE waiting for the stop or end that follows it (M60, M30).
    pallet: bool,
    /// Pitch (mm per revolution) while spindle-synchronised motion is on.
    sync_mm: Option<f64>,
    /// Arcs linearised so far.
    pub arcs: u64,
}

/// The most segments one arc becomes (beyond, the tolerance is unreasonably fine).
const MAX_SEGMENTS: f64 = 1e6;

impl Motion {
    /// A fresh interpreter state; arcs are split into chords deviating at most
    /// `chord_tolerance_mm` from the arc.
    pub fn new(chord_tolerance_mm: f64) -> Motion {
        Motion {
            units: Units::Mm,
            g5x: [0.0; 6],
            g92: [0.0; 6],
            rotation_deg: 0.0,
            tool: [0.0; 6],
            feed: 0.0,
            feed_mode: 0,
            plane: Plane::Xy,
            position: None,
            chord_tolerance_mm,
            flood: false,
            mist: false,
            sync_mm: None,
            pallet: false,
            arcs: 0,
        }
    }

    /// The current units.
    pub fn units(&self) -> Units {
        self.units
    }

    /// The XY rotation in force, degrees.
    pub fn rotation_deg(&self) -> f64 {
        self.rotation_deg
    }

    /// Program coordinates → machine coordinates.
    pub fn to_machine(&self, p: &Pos6) -> Pos6 {
        let s = self.units.mm();
        let mut m = [p[0] * s, p[1] * s, p[2] * s, p[3], p[4], p[5]];
        for (v, o) in m.iter_mut().zip(&self.g92) {
            *v += o;
        }
        if self.rotation_deg != 0.0 {
            let (sin, cos) = self.rotation_deg.to_radians().sin_cos();
            let (x, y) = (m[0], m[1]);
            m[0] = x * cos - y * sin;
            m[1] = x * sin + y * cos;
        }
        for (k, v) in m.iter_mut().enumerate() {
            *v += self.g5x[k] + self.tool[k];
        }
        m
    }

    /// Machine coordinates → program coordinates (the inverse of [`Motion::to_machine`]).
    pub fn to_program(&self, m: &Pos6) -> Pos6 {
        let mut p = *m;
        for (k, v) in p.iter_mut().enumerate() {
            *v -= self.g5x[k] + self.tool[k];
        }
        if self.rotation_deg != 0.0 {
            let (sin, cos) = self.rotation_deg.to_radians().sin_cos();
            let (x, y) = (p[0], p[1]);
            p[0] = x * cos + y * sin;
            p[1] = -x * sin + y * cos;
        }
        for (v, o) in p.iter_mut().zip(&self.g92) {
            *v -= o;
        }
        let s = self.units.mm();
        for v in &mut p[..3] {
            *v /= s;
        }
        p
    }

    fn scaled(&self, v: &[f64]) -> Pos6 {
        let s = self.units.mm();
        [v[0] * s, v[1] * s, v[2] * s, v[3], v[4], v[5]]
    }

    fn go(&mut self, rapid: bool, p: &Pos6, end: bool, out: &mut impl FnMut(Block)) {
        let machine = self.to_machine(p);
        self.position = Some(machine);
        out(Block::Move {
            rapid,
            machine,
            feed: self.feed,
            tool_offset_z: self.tool[2],
            end,
        });
    }

    fn check_feed_mode(&self) -> Result<(), Refusal> {
        if self.sync_mm.is_some() {
            return Err("spindle-synchronised motion (G33, G76) follows the spindle's angle along a path truepos cannot write in machine coordinates (only rigid tapping, G33.1, is rewritten)".into());
        }
        if self.feed_mode == 1 {
            return Err("inverse-time feed (G93): a move split or changed by compensation would not keep the program's time per move; truepos rewrites programs in G94 or G95 only".into());
        }
        Ok(())
    }

    /// Handles one command, passing the blocks it makes to `out`.
    pub fn step(&mut self, c: &Canon, out: &mut impl FnMut(Block)) -> Result<(), Refusal> {
        match c {
            Canon::StraightTraverse(p) => self.go(true, p, true, out),
            Canon::StraightFeed(p) => {
                self.check_feed_mode()?;
                self.go(false, p, true, out);
            }
            Canon::ArcFeed(a) => {
                self.check_feed_mode()?;
                self.arc(a, out)?;
            }
            Canon::StraightProbe(_) => return Err("a probing move (G38.x) stops where the probe trips, which no rewrite can know in advance; truepos does not compensate probing programs".into()),
            Canon::SetFeedRate(f) => self.feed = *f * self.units.mm(),
            Canon::StartSpeedFeedSync { feed_per_rev, .. } => {
                self.sync_mm = Some(feed_per_rev * self.units.mm());
            }
            Canon::RigidTap(p) => {
                let Some(pitch_mm) = self.sync_mm else {
                    return Err("RIGID_TAP without a spindle synchronisation (START_SPEED_FEED_SYNC) before it".into());
                };
                let Some(start) = self.position else {
                    return Err("a rigid tap as the first move: it starts from a position the program never commanded".into());
                };
                let here = self.to_program(&start);
                let end = [p[0], p[1], p[2], here[3], here[4], here[5]];
                // The tap returns to where it started: the position stays.
                out(Block::Tap {
                    machine: self.to_machine(&end),
                    pitch_mm,
                    tool_offset_z: self.tool[2],
                });
            }
            Canon::SetFeedMode { mode, .. } => {
                self.feed_mode = *mode;
                match mode {
                    0 => out(Block::Code("G94".into())),
                    2 => out(Block::Code("G95".into())),
                    1 => {}
                    m => return Err(format!("unknown feed mode {m} (SET_FEED_MODE); expected 0 (G94), 1 (G93) or 2 (G95)")),
                }
            }
            Canon::UseLengthUnits(u) => {
                self.units = *u;
                out(Block::Units(*u));
            }
            Canon::SetG5xOffset { offset, .. } => self.g5x = self.scaled(offset),
            Canon::SetG92Offset(o) => self.g92 = self.scaled(o),
            Canon::SetXyRotation(r) => self.rotation_deg = *r,
            Canon::SelectPlane(p) => self.plane = *p,
            Canon::UseToolLengthOffset(v) => self.tool = self.scaled(&v[..6]),
            Canon::SetMotionControlMode { mode, tolerance } => out(Block::Code(match mode {
                PathMode::ExactStop => "G61.1".into(),
                PathMode::ExactPath => "G61".into(),
                PathMode::Continuous => match tolerance {
                    Some(t) if *t > 0.0 => format!("G64 P{t}"),
                    _ => "G64".into(),
                },
            })),
            Canon::SetSpindleSpeed { spindle, speed } => out(Block::Code(spindle_word(format!("S{speed}"), *spindle))),
            Canon::StartSpindleClockwise(s) => out(Block::Code(spindle_word("M3".into(), *s))),
            Canon::StartSpindleCounterclockwise(s) => out(Block::Code(spindle_word("M4".into(), *s))),
            Canon::StopSpindleTurning(s) => out(Block::Code(spindle_word("M5".into(), *s))),
            Canon::Dwell(t) => out(Block::Code(format!("G4 P{t}"))),
            Canon::Comment(t) => out(Block::Code(format!("({})", comment_text(t)))),
            Canon::Message(t) => out(Block::Code(format!("(MSG,{})", comment_text(t)))),
            Canon::SelectTool(t) => out(Block::Code(format!("T{t}"))),
            Canon::ChangeTool(_) => out(Block::Code("M6".into())),
            Canon::ChangeToolNumber(t) => out(Block::Code(format!("M61 Q{t}"))),
            Canon::Plain(p) => self.plain(*p, out),
            Canon::Other { name, .. } if name == "STOP_SPEED_FEED_SYNCH" => self.sync_mm = None,
            Canon::Other { name, .. } if name == "PALLET_SHUTTLE" => self.pallet = true,
            Canon::Other { name, args } => other(name, args)?,
        }
        Ok(())
    }

    fn plain(&mut self, p: Plain, out: &mut impl FnMut(Block)) {
        let code = match p {
            Plain::FloodOn => {
                self.flood = true;
                "M8"
            }
            Plain::MistOn => {
                self.mist = true;
                "M7"
            }
            // M9 turns both off; the other one, if still on, is turned on again.
            Plain::FloodOff | Plain::MistOff => {
                if p == Plain::FloodOff {
                    self.flood = false;
                } else {
                    self.mist = false;
                }
                out(Block::Code("M9".into()));
                if self.flood {
                    out(Block::Code("M8".into()));
                }
                if self.mist {
                    out(Block::Code("M7".into()));
                }
                return;
            }
            // rs274 prints M60 as PALLET_SHUTTLE + PROGRAM_STOP and M30 as PALLET_SHUTTLE +
            // PROGRAM_END.
            Plain::ProgramStop if std::mem::take(&mut self.pallet) => "M60",
            Plain::ProgramEnd if std::mem::take(&mut self.pallet) => "M30",
            Plain::ProgramStop => "M0",
            Plain::OptionalProgramStop => "M1",
            Plain::ProgramEnd => "M2",
            Plain::StartChange | Plain::OnReset | Plain::Finish => return,
        };
        out(Block::Code(code.into()));
    }

    /// Splits an arc into chords within the tolerance.
    fn arc(&mut self, a: &Arc, out: &mut impl FnMut(Block)) -> Result<(), Refusal> {
        if !matches!(self.plane, Plane::Xy | Plane::Yz | Plane::Xz) {
            return Err(format!(
                "an arc in the {:?} plane: the machine has no U V W axes",
                self.plane
            ));
        }
        let Some(start) = self.position else {
            return Err(
                "an arc as the first move: it starts from a position the program never commanded"
                    .into(),
            );
        };
        if a.rotation == 0 {
            return Err("an arc of 0 turns (ARC_FEED rotation 0)".into());
        }
        let sp = self.to_program(&start);
        // (first, second, normal) of the plane, as rs274 gives the arc.
        let (i1, i2, i3) = match self.plane {
            Plane::Xy => (0, 1, 2),
            Plane::Yz => (1, 2, 0),
            _ => (2, 0, 1),
        };
        let (s1, s2, s3) = (sp[i1], sp[i2], sp[i3]);
        let (c1, c2) = (a.first_axis, a.second_axis);
        let r0 = (s1 - c1).hypot(s2 - c2);
        let r1 = (a.first_end - c1).hypot(a.second_end - c2);
        let a0 = (s2 - c2).atan2(s1 - c1);
        let a1 = (a.second_end - c2).atan2(a.first_end - c1);
        let mut sweep = a1 - a0;
        if a.rotation > 0 {
            if sweep <= 0.0 {
                sweep += TAU;
            }
            sweep += f64::from(a.rotation - 1) * TAU;
        } else {
            if sweep >= 0.0 {
                sweep -= TAU;
            }
            sweep += f64::from(a.rotation + 1) * TAU;
        }
        let tol = self.chord_tolerance_mm / self.units.mm();
        let r = r0.max(r1);
        let n = if r <= tol {
            1.0
        } else {
            let step = 2.0 * (1.0 - tol / r).acos();
            (sweep.abs() / step).ceil().max(1.0)
        };
        // NaN (a degenerate arc) is refused as well.
        if n.is_nan() || n > MAX_SEGMENTS {
            return Err(format!(
                "an arc of radius {r} would need more than {MAX_SEGMENTS} chords at the chord tolerance {} mm",
                self.chord_tolerance_mm
            ));
        }
        let n = n as u64;
        let mut end = [0.0; 6];
        end[i1] = a.first_end;
        end[i2] = a.second_end;
        end[i3] = a.axis_end;
        end[3..].copy_from_slice(&a.abc);
        for k in 1..=n {
            let p = if k == n {
                end
            } else {
                let t = k as f64 / n as f64;
                let th = a0 + sweep * t;
                let rad = r0 + (r1 - r0) * t;
                let mut p = [0.0; 6];
                p[i1] = c1 + rad * th.cos();
                p[i2] = c2 + rad * th.sin();
                p[i3] = s3 + (a.axis_end - s3) * t;
                for j in 3..6 {
                    p[j] = sp[j] + (a.abc[j - 3] - sp[j]) * t;
                }
                p
            };
            self.go(false, &p, k == n, out);
        }
        self.arcs += 1;
        Ok(())
    }
}

fn spindle_word(word: String, spindle: i32) -> String {
    if spindle == 0 {
        word
    } else {
        format!("{word} ${spindle}")
    }
}

/// A comment's text that cannot end or nest the comment it is written into.
fn comment_text(t: &str) -> String {
    t.replace('(', "[").replace(')', "]")
}

/// Commands carried in [`Canon::Other`]: ignored where they change nothing the rewrite
/// writes, refused with the reason where they would change motion.
fn other(name: &str, args: &str) -> Result<(), Refusal> {
    const NO_MOTION: [&str; 19] = [
        "SET_FEED_REFERENCE",
        "SET_NAIVECAM_TOLERANCE",
        "SET_SPINDLE_MODE",
        "TURN_PROBE_ON",
        "TURN_PROBE_OFF",
        "LOG",
        "LOGOPEN",
        "LOGAPPEND",
        "LOGCLOSE",
        "ENABLE_FEED_OVERRIDE",
        "DISABLE_FEED_OVERRIDE",
        "ENABLE_SPEED_OVERRIDE",
        "DISABLE_SPEED_OVERRIDE",
        "ENABLE_ADAPTIVE_FEED",
        "DISABLE_ADAPTIVE_FEED",
        "ENABLE_FEED_HOLD",
        "DISABLE_FEED_HOLD",
        "SET_TRAVERSE_RATE",
        "INIT_CANON",
    ];
    if NO_MOTION.contains(&name) {
        return Ok(());
    }
    let why = match name {
        "NURBS_FEED" | "SPLINE_FEED" => {
            "a NURBS or spline move (G5, G5.1, G5.2) is not linearised by truepos"
        }
        _ => {
            return Err(format!(
                "canonical command {name}({args}) is not one truepos knows; it may change how the machine moves, so the program is refused"
            ))
        }
    };
    Err(format!("{name}: {why}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(m: &mut Motion, cmds: &[Canon]) -> Vec<Block> {
        let mut v = Vec::new();
        for c in cmds {
            m.step(c, &mut |b| v.push(b)).unwrap();
        }
        v
    }

    fn moves(v: &[Block]) -> Vec<Pos6> {
        v.iter()
            .filter_map(|b| match b {
                Block::Move { machine, .. } => Some(*machine),
                _ => None,
            })
            .collect()
    }

    #[test]
    fn offsets_units_and_tool_length_give_machine_coordinates() {
        let mut m = Motion::new(0.001);
        let v = run(
            &mut m,
            &[
                Canon::SetG5xOffset {
                    index: 1,
                    offset: [10.0, 20.0, 30.0, 0.0, 0.0, 5.0],
                },
                Canon::UseLengthUnits(Units::Inches),
                Canon::SetG92Offset([1.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
                Canon::UseToolLengthOffset([0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
                Canon::StraightTraverse([1.0, 2.0, 3.0, 0.0, 0.0, 1.0]),
            ],
        );
        let p = moves(&v)[0];
        let want = [
            10.0 + 25.4 + 25.4,
            20.0 + 50.8,
            30.0 + 76.2 + 50.8,
            0.0,
            0.0,
            6.0,
        ];
        for (a, b) in p.iter().zip(&want) {
            assert!((a - b).abs() < 1e-12, "{p:?} vs {want:?}");
        }
        let back = m.to_program(&p);
        assert!((back[0] - 1.0).abs() < 1e-12 && (back[2] - 3.0).abs() < 1e-12);
    }

    #[test]
    fn rotation_turns_the_program_about_the_work_origin() {
        let mut m = Motion::new(0.001);
        let v = run(
            &mut m,
            &[
                Canon::SetXyRotation(90.0),
                Canon::StraightTraverse([1.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
            ],
        );
        let p = moves(&v)[0];
        assert!(p[0].abs() < 1e-12 && (p[1] - 1.0).abs() < 1e-12, "{p:?}");
    }

    #[test]
    fn arcs_become_chords_within_the_tolerance_on_every_plane() {
        for (plane, axes) in [
            (Plane::Xy, (0, 1)),
            (Plane::Yz, (1, 2)),
            (Plane::Xz, (2, 0)),
        ] {
            let mut m = Motion::new(0.001);
            let v = run(
                &mut m,
                &[
                    Canon::SelectPlane(plane),
                    Canon::SetFeedRate(100.0),
                    Canon::StraightFeed([0.0; 6]),
                ],
            );
            assert_eq!(moves(&v).len(), 1);
            // A half circle of radius 10 from the start (0 in the plane) around (10, 0),
            // counter-clockwise, rising 5 along the normal.
            let v = run(
                &mut m,
                &[Canon::ArcFeed(Arc {
                    first_end: 20.0,
                    second_end: 0.0,
                    first_axis: 10.0,
                    second_axis: 0.0,
                    rotation: 1,
                    axis_end: 5.0,
                    abc: [0.0; 3],
                })],
            );
            let pts = moves(&v);
            // θ per chord 2·acos(1 − 0.001/10) → ⌈π / 0.02828⌉ = 112 chords.
            assert_eq!(pts.len(), 112, "{plane:?}");
            let mut prev = [0.0, 0.0];
            for p in &pts {
                let (u, w) = (p[axes.0], p[axes.1]);
                assert!(((u - 10.0).hypot(w) - 10.0).abs() < 1e-9, "{plane:?} {p:?}");
                // Counter-clockwise from (0,0) around (10,0) goes through negative second.
                assert!(w <= 1e-12, "{plane:?} {p:?}");
                let mid = ((u + prev[0]) / 2.0 - 10.0).hypot((w + prev[1]) / 2.0);
                assert!(
                    10.0 - mid <= 0.001 + 1e-12,
                    "{plane:?}: chord error {}",
                    10.0 - mid
                );
                prev = [u, w];
            }
            assert_eq!(pts.last().unwrap()[axes.0], 20.0);
        }
    }

    #[test]
    fn stops_and_ends_keep_their_pallet_shuttle() {
        let mut m = Motion::new(0.001);
        let shuttle = Canon::Other {
            name: "PALLET_SHUTTLE".into(),
            args: String::new(),
        };
        let v = run(
            &mut m,
            &[
                shuttle.clone(),
                Canon::Plain(Plain::ProgramStop),
                Canon::Plain(Plain::ProgramStop),
                shuttle,
                Canon::Plain(Plain::ProgramEnd),
            ],
        );
        let codes: Vec<&str> = v
            .iter()
            .filter_map(|b| match b {
                Block::Code(c) => Some(c.as_str()),
                _ => None,
            })
            .collect();
        assert_eq!(codes, ["M60", "M0", "M30"]);
    }

    #[test]
    fn refuses_what_it_cannot_carry_over() {
        let mut m = Motion::new(0.001);
        let mut sink = |_b: Block| {};
        let arc = Canon::ArcFeed(Arc {
            first_end: 1.0,
            second_end: 0.0,
            first_axis: 0.5,
            second_axis: 0.0,
            rotation: 1,
            axis_end: 0.0,
            abc: [0.0; 3],
        });
        assert!(m.step(&arc, &mut sink).unwrap_err().contains("first move"));
        assert!(m
            .step(&Canon::StraightProbe([0.0; 6]), &mut sink)
            .unwrap_err()
            .contains("probing"));
        let e = m
            .step(
                &Canon::Other {
                    name: "SET_AUX_OUTPUT_BIT".into(),
                    args: "1".into(),
                },
                &mut sink,
            )
            .unwrap_err();
        assert!(e.contains("SET_AUX_OUTPUT_BIT(1)"), "{e}");
        m.step(
            &Canon::SetFeedMode {
                spindle: 0,
                mode: 1,
            },
            &mut sink,
        )
        .unwrap();
        assert!(m
            .step(&Canon::StraightFeed([0.0; 6]), &mut sink)
            .unwrap_err()
            .contains("G93"));
    }
}
