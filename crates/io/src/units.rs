//! Units taken from column names, so that a run is read in the project's units (µm for measured
//! errors, °C for temperatures, mm for linear axis positions) whatever the file was written in.
//!
//! A name carries its unit either as a suffix after the last `_` (`dz_mm`, `t1_f`) or in
//! brackets at its end (`dz (µm)`, `t1 [°F]`). A suffix counts only when it is one of the known
//! units (`spindle_rpm` has none: `rpm` is no unit here), because a suffix cannot be told apart
//! from part of a name; brackets are explicit, so an unknown unit in brackets is an error. A
//! name without a unit keeps the meaning it always had: µm, °C or mm by its role.
//!
//! ```
//! use truepos_io::units::{Role, unit_of};
//! let u = unit_of("dz_mm").unwrap().unwrap();
//! assert_eq!(u.convert(0.03, Role::Error).unwrap(), 30.0);
//! let f = unit_of("spindle (°F)").unwrap().unwrap();
//! assert!((f.convert(212.0, Role::Temperature).unwrap() - 100.0).abs() < 1e-12);
//! assert_eq!(unit_of("spindle_rpm"), Ok(None));
//! assert!(unit_of("dz (furlong)").is_err());
//! ```

/// A unit a column name can state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Unit {
    /// nm.
    Nanometre,
    /// µm.
    Micrometre,
    /// mm.
    Millimetre,
    /// m.
    Metre,
    /// inch (25.4 mm).
    Inch,
    /// °C.
    Celsius,
    /// °F.
    Fahrenheit,
    /// K.
    Kelvin,
    /// degree of angle (rotary axes).
    Degree,
    /// Revolutions per minute (a spindle or feed speed; operating state).
    PerMinute,
    /// Percent (a load or override; operating state).
    Percent,
    /// Kilowatt (a spindle or drive power; operating state).
    Kilowatt,
}

/// What a column is used as, which fixes the unit it is converted to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// A measured error (a target): µm.
    Error,
    /// A temperature: °C.
    Temperature,
    /// A linear axis position: mm.
    Position,
    /// A rotary axis position: degrees.
    Angle,
}

impl Role {
    /// The unit values of this role are given in.
    pub fn unit(self) -> Unit {
        match self {
            Role::Error => Unit::Micrometre,
            Role::Temperature => Unit::Celsius,
            Role::Position => Unit::Millimetre,
            Role::Angle => Unit::Degree,
        }
    }

    fn what(self) -> &'static str {
        match self {
            Role::Error => "a measured error (a length)",
            Role::Temperature => "a temperature",
            Role::Position => "a linear axis position (a length)",
            Role::Angle => "a rotary axis position (an angle)",
        }
    }
}

/// The units a name may carry, as written in brackets.
const BRACKETED: &[(&str, Unit)] = &[
    ("nm", Unit::Nanometre),
    ("µm", Unit::Micrometre),
    ("μm", Unit::Micrometre),
    ("um", Unit::Micrometre),
    ("mm", Unit::Millimetre),
    ("m", Unit::Metre),
    ("in", Unit::Inch),
    ("inch", Unit::Inch),
    ("°C", Unit::Celsius),
    ("℃", Unit::Celsius),
    ("C", Unit::Celsius),
    ("degC", Unit::Celsius),
    ("°F", Unit::Fahrenheit),
    ("℉", Unit::Fahrenheit),
    ("F", Unit::Fahrenheit),
    ("degF", Unit::Fahrenheit),
    ("K", Unit::Kelvin),
    ("°", Unit::Degree),
    ("deg", Unit::Degree),
    ("1/min", Unit::PerMinute),
    ("U/min", Unit::PerMinute),
    ("u/min", Unit::PerMinute),
    ("r/min", Unit::PerMinute),
    ("rev/min", Unit::PerMinute),
    ("rpm", Unit::PerMinute),
    ("min⁻¹", Unit::PerMinute),
    ("min-1", Unit::PerMinute),
    ("%", Unit::Percent),
    ("kW", Unit::Kilowatt),
];

/// The units a name may carry as a suffix after its last `_` (compared in lower case).
const SUFFIXES: &[(&str, Unit)] = &[
    ("nm", Unit::Nanometre),
    ("um", Unit::Micrometre),
    ("µm", Unit::Micrometre),
    ("mm", Unit::Millimetre),
    ("m", Unit::Metre),
    ("in", Unit::Inch),
    ("c", Unit::Celsius),
    ("f", Unit::Fahrenheit),
    ("k", Unit::Kelvin),
    ("deg", Unit::Degree),
];

impl Unit {
    /// Its symbol.
    pub fn symbol(self) -> &'static str {
        match self {
            Unit::Nanometre => "nm",
            Unit::Micrometre => "µm",
            Unit::Millimetre => "mm",
            Unit::Metre => "m",
            Unit::Inch => "in",
            Unit::Celsius => "°C",
            Unit::Fahrenheit => "°F",
            Unit::Kelvin => "K",
            Unit::Degree => "°",
            Unit::PerMinute => "1/min",
            Unit::Percent => "%",
            Unit::Kilowatt => "kW",
        }
    }

    /// µm per unit of a length (exact factors, so that mm and µm convert without a rounding
    /// step), `None` for other quantities.
    fn micrometres(self) -> Option<f64> {
        match self {
            Unit::Nanometre => Some(1e-3),
            Unit::Micrometre => Some(1.0),
            Unit::Millimetre => Some(1e3),
            Unit::Metre => Some(1e6),
            Unit::Inch => Some(25_400.0),
            _ => None,
        }
    }

    /// Whether this is a unit of operating state (a speed, a load, a power): a column stating it
    /// is operating state whatever its name, and is read as written.
    pub fn is_operating(self) -> bool {
        matches!(self, Unit::PerMinute | Unit::Percent | Unit::Kilowatt)
    }

    /// Whether values in this unit can be used in `role`.
    pub fn fits(self, role: Role) -> bool {
        match role {
            Role::Error | Role::Position => self.micrometres().is_some(),
            Role::Temperature => matches!(self, Unit::Celsius | Unit::Fahrenheit | Unit::Kelvin),
            Role::Angle => self == Unit::Degree,
        }
    }

    /// `value` in this unit, converted to `role`'s unit ([`Role::unit`]); an error sentence when
    /// the unit does not fit the role.
    pub fn convert(self, value: f64, role: Role) -> Result<f64, String> {
        if !self.fits(role) {
            return Err(format!(
                "the unit {} does not fit {}, expected {}",
                self.symbol(),
                role.what(),
                match role {
                    Role::Error | Role::Position => "nm, µm, mm, m or in",
                    Role::Temperature => "°C, °F or K",
                    Role::Angle => "degrees",
                }
            ));
        }
        Ok(match (self, role) {
            (Unit::Fahrenheit, _) => (value - 32.0) * 5.0 / 9.0,
            (Unit::Kelvin, _) => value - 273.15,
            (Unit::Celsius | Unit::Degree, _) => value,
            (_, Role::Error) => value * self.micrometres().unwrap_or(1.0),
            (Unit::Millimetre, _) => value,
            (_, _) => value * self.micrometres().unwrap_or(1.0) / 1e3,
        })
    }
}

/// The name without its unit, and the unit: `dz (µm)` → (`dz`, µm), `t1_f` → (`t1`, °F),
/// `spindle_rpm` → (`spindle_rpm`, none). An unknown unit in brackets is an error sentence.
pub fn split(name: &str) -> Result<(&str, Option<Unit>), String> {
    let name = name.trim();
    for (open, close) in [('(', ')'), ('[', ']')] {
        if let Some(body) = name.strip_suffix(close) {
            if let Some(at) = body.rfind(open) {
                let inner = body[at + open.len_utf8()..].trim();
                let base = body[..at].trim_end();
                return match BRACKETED.iter().find(|(s, _)| *s == inner) {
                    Some(&(_, u)) => Ok((base, Some(u))),
                    None => Err(format!(
                        "unknown unit `{inner}`; known: {}",
                        BRACKETED
                            .iter()
                            .map(|(s, _)| *s)
                            .collect::<Vec<_>>()
                            .join(", ")
                    )),
                };
            }
        }
    }
    if let Some((base, suffix)) = name.rsplit_once('_') {
        let lower = suffix.to_lowercase();
        if let Some(&(_, u)) = SUFFIXES.iter().find(|(s, _)| *s == lower) {
            if !base.is_empty() {
                return Ok((base, Some(u)));
            }
        }
    }
    Ok((name, None))
}

/// The unit of a column name, if it states one ([`split`]).
pub fn unit_of(name: &str) -> Result<Option<Unit>, String> {
    split(name).map(|(_, u)| u)
}

/// How column `name` converts to `role`: the unit it states, or the role's own when it states
/// none. The error sentence names the unit and the role (a temperature in mm, a target in °C).
pub fn for_role(name: &str, role: Role) -> Result<Unit, String> {
    let unit = unit_of(name)?.unwrap_or(role.unit());
    if unit.fits(role) {
        Ok(unit)
    } else {
        unit.convert(0.0, role).map(|_| unit)
    }
}

/// The column of `columns` that holds channel `id` (a temperature sensor's id, an axis name):
/// the column named exactly `id`, else the first whose name without its unit is `id` (`t1 (°F)`
/// for `t1`, `X_in` for `X`).
pub fn find_channel(columns: &[String], id: &str) -> Option<usize> {
    columns.iter().position(|c| c == id).or_else(|| {
        columns
            .iter()
            .position(|c| matches!(split(c), Ok((base, Some(_))) if base == id))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_state_their_units() {
        let cases = [
            ("dz_um", "dz", Some(Unit::Micrometre)),
            ("dz_mm", "dz", Some(Unit::Millimetre)),
            ("dz_m", "dz", Some(Unit::Metre)),
            ("dz_in", "dz", Some(Unit::Inch)),
            ("t1_c", "t1", Some(Unit::Celsius)),
            ("t1_F", "t1", Some(Unit::Fahrenheit)),
            ("t1_k", "t1", Some(Unit::Kelvin)),
            ("dz (µm)", "dz", Some(Unit::Micrometre)),
            ("dz(um)", "dz", Some(Unit::Micrometre)),
            ("X [mm]", "X", Some(Unit::Millimetre)),
            ("t1 (°C)", "t1", Some(Unit::Celsius)),
            ("t1 (°F)", "t1", Some(Unit::Fahrenheit)),
            ("t1 (K)", "t1", Some(Unit::Kelvin)),
            ("A_deg", "A", Some(Unit::Degree)),
            ("S [1/min]", "S", Some(Unit::PerMinute)),
            ("Spindel (U/min)", "Spindel", Some(Unit::PerMinute)),
            ("n [min⁻¹]", "n", Some(Unit::PerMinute)),
            ("S [rpm]", "S", Some(Unit::PerMinute)),
            ("Last [%]", "Last", Some(Unit::Percent)),
            ("Spindel vorne [°C]", "Spindel vorne", Some(Unit::Celsius)),
            ("Z-Drift [µm]", "Z-Drift", Some(Unit::Micrometre)),
            ("spindle_rpm", "spindle_rpm", None),
            ("time_s", "time_s", None),
            ("_mm", "_mm", None),
            ("probe", "probe", None),
        ];
        for (name, base, unit) in cases {
            assert_eq!(split(name), Ok((base, unit)), "{name}");
        }
        assert_eq!(
            split("dz (furlong)").unwrap_err(),
            format!(
                "unknown unit `furlong`; known: {}",
                BRACKETED
                    .iter()
                    .map(|(s, _)| *s)
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        );
    }

    #[test]
    fn values_convert_to_the_roles_unit() {
        let c = |name: &str, v: f64, role| for_role(name, role).unwrap().convert(v, role).unwrap();
        assert_eq!(c("dz_mm", 0.03, Role::Error), 30.0);
        assert!((c("dz_in", 0.001, Role::Error) - 25.4).abs() < 1e-9);
        assert!((c("dz_nm", 500.0, Role::Error) - 0.5).abs() < 1e-12);
        assert_eq!(c("dz", 7.0, Role::Error), 7.0);
        assert!((c("t (°F)", 68.0, Role::Temperature) - 20.0).abs() < 1e-12);
        assert!((c("t_k", 293.15, Role::Temperature) - 20.0).abs() < 1e-9);
        assert_eq!(c("t", 20.0, Role::Temperature), 20.0);
        assert!((c("X_in", 1.0, Role::Position) - 25.4).abs() < 1e-12);
        assert_eq!(c("X_mm", 12.5, Role::Position), 12.5);
        assert_eq!(
            for_role("t1_mm", Role::Temperature).unwrap_err(),
            "the unit mm does not fit a temperature, expected °C, °F or K"
        );
        assert_eq!(
            for_role("dz_c", Role::Error).unwrap_err(),
            "the unit °C does not fit a measured error (a length), expected nm, µm, mm, m or in"
        );
        assert!(for_role("A_mm", Role::Angle).is_err());
    }

    #[test]
    fn channels_are_found_with_or_without_their_unit() {
        let cols: Vec<String> = ["time_s", "t1 (°F)", "X_in", "t2", "t2_c"]
            .map(String::from)
            .to_vec();
        assert_eq!(find_channel(&cols, "t1"), Some(1));
        assert_eq!(find_channel(&cols, "X"), Some(2));
        assert_eq!(find_channel(&cols, "t2"), Some(3));
        assert_eq!(find_channel(&cols, "t2_c"), Some(4));
        assert_eq!(find_channel(&cols, "Y"), None);
    }

    proptest::proptest! {
        /// Any name splits without a panic, and a name that splits keeps its base inside it.
        #[test]
        fn any_name_splits(name in "\\PC{0,16}") {
            if let Ok((base, _)) = split(&name) {
                proptest::prop_assert!(name.contains(base));
            }
        }
    }
}
