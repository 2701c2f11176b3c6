//! Property tests of the canonical-command parser: arbitrary text (and mutations of real
//! lines) never panics; every command printed as rs274 prints it parses back to itself and
//! prints identically.

use proptest::prelude::*;
use truepos_gcode::canon::{Arc, Canon, CanonLine, PathMode, Plain, Plane, Units};
use truepos_gcode::program;

/// A number as rs274 prints it: four decimals (a value on a 1e-4 grid).
fn num() -> impl Strategy<Value = f64> {
    (-99_999_999i64..99_999_999).prop_map(|v| v as f64 / 1e4)
}

fn pos6() -> impl Strategy<Value = [f64; 6]> {
    prop::array::uniform6(num())
}

fn text() -> impl Strategy<Value = String> {
    "[ -~]{0,40}"
}

fn command() -> impl Strategy<Value = Canon> {
    prop_oneof![
        pos6().prop_map(Canon::StraightTraverse),
        pos6().prop_map(Canon::StraightFeed),
        pos6().prop_map(Canon::StraightProbe),
        (
            num(),
            num(),
            num(),
            num(),
            -5i32..5,
            num(),
            prop::array::uniform3(num())
        )
            .prop_map(|(a, b, c, d, rotation, e, abc)| Canon::ArcFeed(Arc {
                first_end: a,
                second_end: b,
                first_axis: c,
                second_axis: d,
                rotation,
                axis_end: e,
                abc,
            })),
        num().prop_map(Canon::SetFeedRate),
        (0i32..3, 0i32..3).prop_map(|(spindle, mode)| Canon::SetFeedMode { spindle, mode }),
        prop_oneof![Just(Units::Mm), Just(Units::Inches), Just(Units::Cm)]
            .prop_map(Canon::UseLengthUnits),
        (1i32..10, pos6()).prop_map(|(index, offset)| Canon::SetG5xOffset { index, offset }),
        pos6().prop_map(Canon::SetG92Offset),
        num().prop_map(Canon::SetXyRotation),
        prop_oneof![
            Just(Plane::Xy),
            Just(Plane::Yz),
            Just(Plane::Xz),
            Just(Plane::Uv)
        ]
        .prop_map(Canon::SelectPlane),
        prop::array::uniform9(num()).prop_map(Canon::UseToolLengthOffset),
        (
            prop_oneof![
                Just(PathMode::ExactStop),
                Just(PathMode::ExactPath),
                Just(PathMode::Continuous)
            ],
            prop::option::of((0i64..10_000_000).prop_map(|v| v as f64 / 1e6))
        )
            .prop_map(|(mode, tolerance)| Canon::SetMotionControlMode { mode, tolerance }),
        (0i32..4, num()).prop_map(|(spindle, speed)| Canon::SetSpindleSpeed { spindle, speed }),
        (0i32..4).prop_map(Canon::StartSpindleClockwise),
        (0i32..4).prop_map(Canon::StopSpindleTurning),
        num().prop_map(Canon::Dwell),
        text().prop_map(Canon::Comment),
        text().prop_map(Canon::Message),
        (0i32..100).prop_map(Canon::ChangeTool),
        ((0i64..1_000_000).prop_map(|v| v as f64 / 1e6), 0i32..2).prop_map(
            |(feed_per_rev, velocity_mode)| Canon::StartSpeedFeedSync {
                feed_per_rev,
                velocity_mode
            }
        ),
        prop::array::uniform3(num()).prop_map(Canon::RigidTap),
        prop_oneof![
            Just(Plain::FloodOn),
            Just(Plain::ProgramEnd),
            Just(Plain::OnReset)
        ]
        .prop_map(Canon::Plain),
        ("[A-Z][A-Z0-9_]{0,20}", "[ -'*-~]{0,30}").prop_filter_map(
            "a name the parser types",
            |(name, args)| {
                let c = Canon::Other { name, args };
                // Names with a typed variant parse into it, not into `Other`.
                match CanonLine::parse(&format!("    1 N..... {c}")) {
                    Ok(l) if l.command == c => Some(c),
                    _ => None,
                }
            }
        ),
    ]
}

fn line() -> impl Strategy<Value = CanonLine> {
    (
        0u64..10_000_000,
        prop::option::of(prop_oneof![
            (0u64..1_000_000).prop_map(|v| (v, v.to_string().len() as u8)),
            (1u64..99_999).prop_map(|v| (v, 5u8)),
            (1u64..10_000_000).prop_map(|v| (program::LINE_BASE + v, 10u8)),
        ]),
        command(),
    )
        .prop_map(|(counter, n, command)| CanonLine {
            counter,
            n,
            command,
        })
}

proptest! {
    #[test]
    fn printed_commands_parse_back_to_themselves(l in line()) {
        let printed = l.to_string();
        let back = CanonLine::parse(&printed)
            .map_err(|e| TestCaseError::fail(format!("`{printed}`: {e}")))?;
        prop_assert_eq!(&back, &l, "`{}`", printed);
        prop_assert_eq!(back.to_string(), printed);
    }

    #[test]
    fn arbitrary_text_never_panics(s in "\\PC{0,200}") {
        let _ = CanonLine::parse(&s);
    }

    #[test]
    fn mutated_lines_never_panic(l in line(), cut in 0usize..200, insert in "\\PC{0,3}") {
        let printed = l.to_string();
        let mut at = cut.min(printed.len());
        while !printed.is_char_boundary(at) {
            at -= 1;
        }
        let mutated = format!("{}{}{}", &printed[..at], insert, &printed[at..]);
        let _ = CanonLine::parse(&mutated);
        let _ = CanonLine::parse(&printed[..at]);
    }
}
