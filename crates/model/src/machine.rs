//! The machine description in its checked, in-memory form: axes, temperature channels, the
//! temperature differences built from them, and operating-state channels.
//!
//! Files are parsed by `truepos-io`; this module only holds what the cycle path needs and
//! checks the structural rules that hold whatever the file format.

use alloc::string::String;
use alloc::vec::Vec;
use core::fmt;

/// Most axes a machine (and so a correction) may have. Outputs live in fixed arrays of this size
/// so that evaluation never allocates.
pub const MAX_AXES: usize = 9;

/// Whether an axis translates (travel in mm) or rotates (travel in degrees).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AxisKind {
    /// Travel in millimetres.
    Linear,
    /// Travel in degrees.
    Rotary,
}

/// How an axis' slide is carried, which selects the natural position factor g of the
/// position-dependent model.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Carriage {
    /// The slide is held at one end and reaches out (a ram, a column slide): the error grows from
    /// one end, so the ratio r = position / length describes it.
    Cantilever,
    /// The slide moves on a bed supported along its length: the bed bends and the error is
    /// smallest in the middle, so the bed factor KFA = (position − L/2) / (L/2) describes it.
    Bed,
}

/// One machine axis.
#[derive(Debug, Clone, PartialEq)]
pub struct Axis {
    /// Name as the control knows it (`X`, `Z1`, `C`).
    pub name: String,
    /// Linear or rotary.
    pub kind: AxisKind,
    /// Lower end of travel (mm or degrees).
    pub travel_min: f64,
    /// Upper end of travel (mm or degrees).
    pub travel_max: f64,
    /// Index of the axis this one rests on (serial stacking: axis 2 rests on axis 1), `None` for
    /// an axis on the machine base.
    pub carried_by: Option<usize>,
    /// How the slide is carried.
    pub carriage: Carriage,
}

impl Axis {
    /// Length of travel, `travel_max − travel_min`.
    pub fn length(&self) -> f64 {
        self.travel_max - self.travel_min
    }

    /// The name of this axis' position wherever positions are columns (runs, logs): the axis
    /// name with its unit, `<axis>_mm` or `<axis>_deg`.
    pub fn position_column(&self) -> String {
        match self.kind {
            AxisKind::Linear => alloc::format!("{}_mm", self.name),
            AxisKind::Rotary => alloc::format!("{}_deg", self.name),
        }
    }

    /// The dimensionless position r = (position − travel_min) / length, 0 at the lower end of
    /// travel and 1 at the upper end (docs/glossary.md: r).
    pub fn ratio(&self, position: f64) -> f64 {
        (position - self.travel_min) / self.length()
    }
}

/// One temperature sensor on the machine.
#[derive(Debug, Clone, PartialEq)]
pub struct TemperatureChannel {
    /// Identifier used in runs and models (`x_slide_bottom`).
    pub id: String,
    /// Where on the machine it sits, for people.
    pub location: String,
    /// Lowest plausible reading in °C; anything below is a fault (open circuit, wrong wiring).
    pub valid_min_c: f64,
    /// Highest plausible reading in °C.
    pub valid_max_c: f64,
    /// `Some` for a channel the control computes as the lag of another sensor (see
    /// [`crate::lag`]) instead of reading it from hardware.
    pub lag: Option<crate::lag::Lag>,
}

/// What a temperature difference is taken against.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Reference {
    /// Another sensor: the opposite side of the same part (top/bottom, front/rear) or a shared
    /// reference such as ambient or a reference spot on the machine.
    Sensor(usize),
    /// A fixed reference temperature in °C.
    Fixed(f64),
}

/// A temperature difference ΔT = T_plus − T_reference, the input of every thermal term.
#[derive(Debug, Clone, PartialEq)]
pub struct TemperatureDifference {
    /// Name used by models (`dT_y_slide`).
    pub name: String,
    /// Index of the sensor whose reading is taken.
    pub plus: usize,
    /// What it is taken against.
    pub minus: Reference,
}

/// What an operating-state channel measures.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OperatingKind {
    /// Spindle speed in 1/min.
    SpindleSpeed,
    /// Axis speed in mm/min or degrees/min.
    AxisSpeed,
    /// Motor torque in N·m.
    Torque,
    /// Motor power in W.
    Power,
    /// Anything else the control knows (coolant on/off, …).
    Other,
}

/// An operating-state channel (spindle speed, axis speed, torque, …).
#[derive(Debug, Clone, PartialEq)]
pub struct OperatingChannel {
    /// Identifier used in runs and models.
    pub id: String,
    /// What it measures.
    pub kind: OperatingKind,
    /// The axis it belongs to, for axis speeds and torques.
    pub axis: Option<usize>,
}

/// A checked machine description.
#[derive(Debug, Clone, PartialEq)]
pub struct Machine {
    /// Name that model files refer to.
    pub name: String,
    /// Axes in control order.
    pub axes: Vec<Axis>,
    /// Temperature sensors.
    pub temperatures: Vec<TemperatureChannel>,
    /// Temperature differences built from the sensors.
    pub differences: Vec<TemperatureDifference>,
    /// Operating-state channels.
    pub operating: Vec<OperatingChannel>,
}

/// A structural rule of the machine description that does not hold.
#[derive(Debug, Clone, PartialEq)]
pub enum MachineError {
    /// The machine has no axis.
    NoAxes,
    /// More axes than [`MAX_AXES`].
    TooManyAxes(usize),
    /// Two items of the same list share a name.
    DuplicateName {
        /// `axis`, `temperature`, `difference` or `operating`.
        list: &'static str,
        /// The shared name.
        name: String,
    },
    /// travel_max ≤ travel_min, or a bound is not finite.
    BadTravel {
        /// The axis.
        axis: String,
    },
    /// A valid range with min ≥ max or a bound that is not finite.
    BadValidRange {
        /// The sensor.
        sensor: String,
    },
    /// An index that points past its list.
    BadIndex {
        /// Which reference.
        what: &'static str,
        /// The item holding it.
        item: String,
    },
    /// A difference taken against its own sensor.
    SelfReference {
        /// The difference.
        difference: String,
    },
    /// A fixed reference temperature that is not finite.
    BadFixedReference {
        /// The difference.
        difference: String,
    },
    /// The carried-by relation loops (A rests on B rests on A).
    CarriageLoop {
        /// An axis on the loop.
        axis: String,
    },
    /// A lagged channel whose source is missing, itself lagged, or whose τ is not a positive,
    /// finite number of seconds.
    BadLag {
        /// The lagged channel.
        sensor: String,
        /// What is wrong.
        reason: &'static str,
    },
}

impl fmt::Display for MachineError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NoAxes => write!(f, "the machine has no axis; expected at least one [[axis]]"),
            Self::TooManyAxes(n) => write!(f, "{n} axes; at most {MAX_AXES} are supported"),
            Self::DuplicateName { list, name } => {
                write!(f, "duplicate {list} name `{name}`; names must be unique")
            }
            Self::BadTravel { axis } => write!(
                f,
                "axis `{axis}`: travel must be [min, max] with finite values and max > min"
            ),
            Self::BadValidRange { sensor } => write!(
                f,
                "sensor `{sensor}`: valid range must be [min, max] with finite values and max > min"
            ),
            Self::BadIndex { what, item } => write!(f, "{item}: {what} refers to nothing"),
            Self::SelfReference { difference } => write!(
                f,
                "difference `{difference}` is taken against its own sensor; expected another sensor or a fixed temperature"
            ),
            Self::BadFixedReference { difference } => write!(
                f,
                "difference `{difference}`: the fixed reference temperature must be finite"
            ),
            Self::CarriageLoop { axis } => write!(
                f,
                "axis `{axis}` rests on itself through carried_by; the axes must form a chain from the base"
            ),
            Self::BadLag { sensor, reason } => write!(f, "lagged channel `{sensor}`: {reason}"),
        }
    }
}

impl core::error::Error for MachineError {}

fn find_duplicate<'a>(names: impl Iterator<Item = &'a str> + Clone) -> Option<&'a str> {
    let all = names.clone();
    for (i, a) in names.enumerate() {
        if all.clone().skip(i + 1).any(|b| b == a) {
            return Some(a);
        }
    }
    None
}

impl Machine {
    /// Checks the structural rules: unique names, sound travels and ranges, indices in range,
    /// no self-referencing difference and no loop in the carried-by chain.
    pub fn check(&self) -> Result<(), MachineError> {
        if self.axes.is_empty() {
            return Err(MachineError::NoAxes);
        }
        if self.axes.len() > MAX_AXES {
            return Err(MachineError::TooManyAxes(self.axes.len()));
        }
        self.check_names()?;
        self.check_axes()?;
        self.check_temperatures()?;
        self.check_differences()?;
        self.check_operating()
    }

    /// Every name is unique within its list, since files and tables refer to channels by name.
    fn check_names(&self) -> Result<(), MachineError> {
        let lists: [(&'static str, alloc::vec::Vec<&str>); 4] = [
            ("axis", self.axes.iter().map(|a| a.name.as_str()).collect()),
            (
                "temperature",
                self.temperatures.iter().map(|t| t.id.as_str()).collect(),
            ),
            (
                "difference",
                self.differences.iter().map(|d| d.name.as_str()).collect(),
            ),
            (
                "operating",
                self.operating.iter().map(|o| o.id.as_str()).collect(),
            ),
        ];
        for (list, names) in &lists {
            if let Some(name) = find_duplicate(names.iter().copied()) {
                return Err(MachineError::DuplicateName {
                    list,
                    name: name.into(),
                });
            }
        }
        Ok(())
    }

    /// Every axis has a finite, non-empty travel and rests on an existing axis, and following
    /// carried_by from any axis reaches the base (a loop would make the chain endless).
    fn check_axes(&self) -> Result<(), MachineError> {
        for axis in &self.axes {
            if !(axis.travel_min.is_finite()
                && axis.travel_max.is_finite()
                && axis.travel_max > axis.travel_min)
            {
                return Err(MachineError::BadTravel {
                    axis: axis.name.clone(),
                });
            }
            if axis.carried_by.is_some_and(|c| c >= self.axes.len()) {
                return Err(MachineError::BadIndex {
                    what: "carried_by",
                    item: axis.name.clone(),
                });
            }
        }
        for (start, axis) in self.axes.iter().enumerate() {
            let mut at = axis.carried_by;
            let mut steps = 0;
            while let Some(i) = at {
                steps += 1;
                if i == start || steps > self.axes.len() {
                    return Err(MachineError::CarriageLoop {
                        axis: axis.name.clone(),
                    });
                }
                at = self.axes[i].carried_by;
            }
        }
        Ok(())
    }

    /// Every temperature channel has a finite, non-empty valid range and a sound lag filter.
    fn check_temperatures(&self) -> Result<(), MachineError> {
        for t in &self.temperatures {
            if !(t.valid_min_c.is_finite()
                && t.valid_max_c.is_finite()
                && t.valid_max_c > t.valid_min_c)
            {
                return Err(MachineError::BadValidRange {
                    sensor: t.id.clone(),
                });
            }
            if let Some(reason) = t.lag.and_then(|lag| self.lag_problem(&lag)) {
                return Err(MachineError::BadLag {
                    sensor: t.id.clone(),
                    reason,
                });
            }
        }
        Ok(())
    }

    /// What is wrong with a lagged channel's filter, if anything: its source must be a
    /// measured sensor (not another lagged channel) or an operating channel with a finite,
    /// non-zero gain and a power of 1 or 2, and its time constant positive and finite.
    fn lag_problem(&self, lag: &crate::lag::Lag) -> Option<&'static str> {
        let source = match lag.source {
            crate::lag::LagSource::Temperature(i) => match self.temperatures.get(i) {
                None => Err("its source refers to nothing"),
                Some(s) if s.lag.is_some() => {
                    Err("its source is itself lagged; expected a measured sensor")
                }
                _ => Ok(()),
            },
            crate::lag::LagSource::Operating {
                channel,
                gain_k_per_unit,
                power,
            } => {
                if channel >= self.operating.len() {
                    Err("its operating channel refers to nothing")
                } else if !(gain_k_per_unit.is_finite() && gain_k_per_unit != 0.0) {
                    Err("the gain must be a finite, non-zero number of K per unit")
                } else if !matches!(power, 1 | 2) {
                    Err("the power must be 1 or 2")
                } else {
                    Ok(())
                }
            }
        };
        match source {
            Err(reason) => Some(reason),
            Ok(()) if !(lag.tau_s.is_finite() && lag.tau_s > 0.0) => {
                Some("the time constant must be a positive, finite number of seconds")
            }
            Ok(()) => None,
        }
    }

    /// Every difference refers to existing sensors, never to itself, and a fixed reference
    /// is a finite temperature.
    fn check_differences(&self) -> Result<(), MachineError> {
        for d in &self.differences {
            if d.plus >= self.temperatures.len() {
                return Err(MachineError::BadIndex {
                    what: "plus",
                    item: d.name.clone(),
                });
            }
            match d.minus {
                Reference::Sensor(s) if s >= self.temperatures.len() => {
                    return Err(MachineError::BadIndex {
                        what: "minus",
                        item: d.name.clone(),
                    })
                }
                Reference::Sensor(s) if s == d.plus => {
                    return Err(MachineError::SelfReference {
                        difference: d.name.clone(),
                    })
                }
                Reference::Fixed(t) if !t.is_finite() => {
                    return Err(MachineError::BadFixedReference {
                        difference: d.name.clone(),
                    })
                }
                _ => {}
            }
        }
        Ok(())
    }

    /// Every operating channel tied to an axis names an existing one.
    fn check_operating(&self) -> Result<(), MachineError> {
        for o in &self.operating {
            if o.axis.is_some_and(|a| a >= self.axes.len()) {
                return Err(MachineError::BadIndex {
                    what: "axis",
                    item: o.id.clone(),
                });
            }
        }
        Ok(())
    }

    /// Index of the axis with this name.
    pub fn axis_index(&self, name: &str) -> Option<usize> {
        self.axes.iter().position(|a| a.name == name)
    }

    /// Index of the temperature channel with this id.
    pub fn temperature_index(&self, id: &str) -> Option<usize> {
        self.temperatures.iter().position(|t| t.id == id)
    }

    /// Index of the temperature difference with this name.
    pub fn difference_index(&self, name: &str) -> Option<usize> {
        self.differences.iter().position(|d| d.name == name)
    }

    /// Index of the operating-state channel with this id.
    pub fn operating_index(&self, id: &str) -> Option<usize> {
        self.operating.iter().position(|o| o.id == id)
    }
}
