//! The mapping of a received value onto a machine channel of the frame, resolved against the
//! machine description.

use truepos_model::Machine;

use crate::frame::Frame;
use truepos_files::InputError;

/// The machine channel a received value feeds, resolved against the machine description.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    /// A temperature channel (index into `Machine::temperatures`), °C.
    Temperature(usize),
    /// An axis position (index into `Machine::axes`), mm or degrees.
    Position(usize),
    /// An operating-state channel (index into `Machine::operating`).
    Operating(usize),
}

impl Target {
    /// Resolves the configured channel names (exactly one of them must be given) against the
    /// machine; `key` names the configuration entry in errors.
    pub fn resolve(
        machine: &Machine,
        key: &str,
        temperature: Option<&str>,
        axis: Option<&str>,
        operating: Option<&str>,
    ) -> Result<Self, InputError> {
        let list = |names: Vec<&str>| names.join(", ");
        match (temperature, axis, operating) {
            (Some(id), None, None) => machine
                .temperature_index(id)
                .map(Target::Temperature)
                .ok_or_else(|| {
                    InputError::at_key(
                        format!("{key}.temperature"),
                        format!(
                            "expected a temperature channel of machine `{}` ({}), found `{id}`",
                            machine.name,
                            list(machine.temperatures.iter().map(|t| t.id.as_str()).collect())
                        ),
                    )
                }),
            (None, Some(name), None) => {
                machine
                    .axis_index(name)
                    .map(Target::Position)
                    .ok_or_else(|| {
                        InputError::at_key(
                            format!("{key}.axis"),
                            format!(
                                "expected an axis of machine `{}` ({}), found `{name}`",
                                machine.name,
                                list(machine.axes.iter().map(|a| a.name.as_str()).collect())
                            ),
                        )
                    })
            }
            (None, None, Some(id)) => machine
                .operating_index(id)
                .map(Target::Operating)
                .ok_or_else(|| {
                    InputError::at_key(
                        format!("{key}.operating"),
                        format!(
                            "expected an operating channel of machine `{}` ({}), found `{id}`",
                            machine.name,
                            list(machine.operating.iter().map(|o| o.id.as_str()).collect())
                        ),
                    )
                }),
            _ => Err(InputError::at_key(
                key,
                "expected exactly one of `temperature`, `axis` or `operating` naming the machine \
                 channel this value feeds",
            )),
        }
    }

    /// Writes a value and its stamp into the frame (no allocation; out-of-range indices are
    /// ignored, as the frame was built for the same machine).
    pub fn write(self, frame: &mut Frame, value: f64, stamp_s: f64) {
        let (values, stamps, i) = match self {
            Target::Temperature(i) => {
                (&mut frame.temperatures_c, &mut frame.temperature_stamp_s, i)
            }
            Target::Position(i) => (&mut frame.positions, &mut frame.position_stamp_s, i),
            Target::Operating(i) => (&mut frame.operating, &mut frame.operating_stamp_s, i),
        };
        if let (Some(v), Some(s)) = (values.get_mut(i), stamps.get_mut(i)) {
            *v = value;
            *s = stamp_s;
        }
    }
}

/// Refuses two configuration entries that feed the same machine channel.
pub fn check_unique_targets(targets: &[Target], keys: &[String]) -> Result<(), InputError> {
    for (j, t) in targets.iter().enumerate() {
        if let Some(i) = targets[..j].iter().position(|u| u == t) {
            return Err(InputError::at_key(
                keys[j].clone(),
                format!(
                    "expected each machine channel to be fed once; {} feeds the same one",
                    keys[i]
                ),
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn targets_write_value_and_stamp() {
        let mut f = Frame::new(2, 3, 1);
        Target::Temperature(1).write(&mut f, 21.5, 4.0);
        Target::Position(2).write(&mut f, 120.0, 5.0);
        Target::Operating(0).write(&mut f, 8000.0, 6.0);
        Target::Position(9).write(&mut f, 1.0, 1.0); // ignored
        assert_eq!((f.temperatures_c[1], f.temperature_stamp_s[1]), (21.5, 4.0));
        assert_eq!((f.positions[2], f.position_stamp_s[2]), (120.0, 5.0));
        assert_eq!((f.operating[0], f.operating_stamp_s[0]), (8000.0, 6.0));
        assert!(f.temperatures_c[0].is_nan());
    }
}
