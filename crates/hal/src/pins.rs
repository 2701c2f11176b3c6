//! The pins of the `truepos` HAL component, named the way LinuxCNC names its own
//! (`axis.x.eoffset-counts` → `truepos.axis.x.eoffset-counts`).
//!
//! | pin | type | dir | meaning |
//! |---|---|---|---|
//! | `truepos.enable` | bit | in | compensate (false: ramp the offsets to zero) |
//! | `truepos.model-select` | s32 | in | model to use, index of `--model` (0-based) |
//! | `truepos.axis.<a>.pos` | float | in | nominal axis position, mm (net `axis.<a>.pos-cmd`) |
//! | `truepos.axis.<a>.path` | s32 | in | path the axis belongs to now, 0 none (default: machine file) |
//! | `truepos.temp.<id>` | float | in | measured temperature channel of the machine file, °C (lagged channels have no pin) |
//! | `truepos.operating.<id>` | float | in | operating channel (spindle speed, …) |
//! | `truepos.axis.<a>.offset-um` | float | out | compensation sent, µm (−error) |
//! | `truepos.axis.<a>.eoffset-counts` | s32 | out | net to `axis.<a>.eoffset-counts` |
//! | `truepos.axis.<a>.eoffset-scale` | float | out | net to `axis.<a>.eoffset-scale` |
//! | `truepos.axis.<a>.eoffset-enable` | bit | out | net to `axis.<a>.eoffset-enable` |
//! | `truepos.axis.<a>.eoffset-request` | float | in | net from `axis.<a>.eoffset-request` |
//! | `truepos.motion-enabled` | bit | in | net from `motion.motion-enabled` |
//! | `truepos.all-homed` | bit | in | net from `motion.is-all-homed` |
//! | `truepos.status` | s32 | out | 0 disabled, 1 active, 2 holding, 3 no model |
//! | `truepos.path.<n>.model` | s32 | out | model in effect on path n (index of `--model`), −1 none |
//! | `truepos.clamped` | bit | out | the safety envelope limited an axis this cycle |
//! | `truepos.extrapolating` | bit | out | a model's input is beyond its training envelope (clamped, the output capped) |
//! | `truepos.cycle-us` | float | out | duration of the last cycle's work, µs |
//! | `truepos.cycles` | s32 | out | cycles run (wraps) |
//! | `truepos.probe.trigger` | bit | in | a rising edge is one probe event (a probe measurement) |
//! | `truepos.probe.pos-N` | float | in | probed position of machine axis N (0-based, machine order), mm |
//! | `truepos.probe.dev-N` | float | in | measured error of axis N at that position, µm (actual − nominal) |
//! | `truepos.probe.measured-N` | bit | in | axis N was measured by this event (`setp` for the probe's directions) |
//! | `truepos.model.reload` | bit | in | a rising edge reloads the `--model` files without a restart |
//! | `truepos.model.reloads` | s32 | out | models reloaded so far (a failed reload leaves it and the model as they were) |
//!
//! Axis names are lower-cased (`X` → `x`, as in LinuxCNC); channel ids are used as written.

use truepos_model::Machine;
use truepos_runtime::CompensationState;

use crate::ffi::{BitPin, Component, Direction, FloatPin, HalError, S32Pin};

/// The pin-name suffix of an axis (`X` → `axis.x`).
pub fn axis_prefix(name: &str) -> String {
    format!("axis.{}", name.to_lowercase())
}

/// The pin-name suffix of a temperature channel (`ambient` → `temp.ambient`).
pub fn temperature_pin(id: &str) -> String {
    format!("temp.{id}")
}

/// The pin-name suffix of an operating channel (`spindle_rpm` → `operating.spindle_rpm`).
pub fn operating_pin(id: &str) -> String {
    format!("operating.{id}")
}

/// The pin-name suffix of the compensation an axis is sent (`X` → `axis.x.offset-um`).
pub fn offset_um_pin(axis: &str) -> String {
    format!("{}.offset-um", axis_prefix(axis))
}

/// The pin-name suffix of the path an axis belongs to (`X` → `axis.x.path`).
pub fn axis_path_pin(axis: &str) -> String {
    format!("{}.path", axis_prefix(axis))
}

/// The pin-name suffix of the compensation state ([`status_code`]).
pub const STATUS_PIN: &str = "status";

/// The pin-name suffix of the preferred model.
pub const MODEL_SELECT_PIN: &str = "model-select";

/// The value of `truepos.status` for a compensation state.
pub fn status_code(state: CompensationState) -> i32 {
    match state {
        CompensationState::Disabled => 0,
        CompensationState::Active => 1,
        CompensationState::Holding => 2,
        CompensationState::NoModel => 3,
    }
}

/// The pins by which the integrator controls the service.
#[derive(Debug)]
pub struct ControlPins {
    /// `truepos.enable`.
    pub enable: BitPin,
    /// `truepos.model-select`.
    pub model_select: S32Pin,
    /// `truepos.model.reload`.
    pub reload: BitPin,
    /// `truepos.model.reloads` (output).
    pub reloads: S32Pin,
}

/// The pin-name suffix of a path's model pin (path 1 → `path.1.model`).
pub fn path_model_pin(path: usize) -> String {
    format!("path.{path}.model")
}

/// The input pins of the cycle's data.
#[derive(Debug)]
pub struct InputPins {
    /// `truepos.axis.<a>.pos`, machine axis order.
    pub positions: Vec<FloatPin>,
    /// `truepos.axis.<a>.path`, machine axis order: the control's axis configuration (which axes
    /// each path drives).
    pub paths: Vec<S32Pin>,
    /// `truepos.temp.<id>` with its machine temperature channel, for the measured channels
    /// only: a lagged channel is computed by the service, never read from a pin.
    pub temperatures: Vec<(usize, FloatPin)>,
    /// `truepos.operating.<id>`, machine operating order.
    pub operating: Vec<FloatPin>,
    /// The probe event pins.
    pub probe: ProbePins,
}

/// `truepos.probe.*`: one probe event per rising edge of the trigger.
#[derive(Debug)]
pub struct ProbePins {
    /// `truepos.probe.trigger`.
    pub trigger: BitPin,
    /// `truepos.probe.pos-N`, machine axis order.
    pub positions: Vec<FloatPin>,
    /// `truepos.probe.dev-N`, machine axis order.
    pub deviations: Vec<FloatPin>,
    /// `truepos.probe.measured-N`, machine axis order.
    pub measured: Vec<BitPin>,
}

/// Names of axis N's probe pins: probed position, measured error, whether measured.
pub fn probe_pins(n: usize) -> [String; 3] {
    [
        format!("probe.pos-{n}"),
        format!("probe.dev-{n}"),
        format!("probe.measured-{n}"),
    ]
}

/// `truepos.model.reload`: a rising edge reloads the model files.
pub const MODEL_RELOAD_PIN: &str = "model.reload";
/// `truepos.model.reloads`: models reloaded so far.
pub const MODEL_RELOADS_PIN: &str = "model.reloads";

/// The output pins of one axis.
#[derive(Debug)]
pub struct AxisOutputPins {
    /// `truepos.axis.<a>.offset-um`.
    pub offset_um: FloatPin,
    /// `truepos.axis.<a>.eoffset-counts`.
    pub counts: S32Pin,
    /// `truepos.axis.<a>.eoffset-scale`.
    pub scale: FloatPin,
    /// `truepos.axis.<a>.eoffset-enable`.
    pub enable: BitPin,
    /// `truepos.axis.<a>.eoffset-request` (input: what LinuxCNC has requested so far, mm).
    pub request: FloatPin,
}

/// The output pins.
#[derive(Debug)]
pub struct OutputPins {
    /// Per machine axis.
    pub axes: Vec<AxisOutputPins>,
    /// `truepos.status`.
    pub status: S32Pin,
    /// `truepos.path.<n>.model`, per path (path 1 first).
    pub path_models: Vec<S32Pin>,
    /// `truepos.clamped`.
    pub clamped: BitPin,
    /// `truepos.extrapolating`.
    pub extrapolating: BitPin,
    /// `truepos.cycle-us`.
    pub cycle_us: FloatPin,
    /// `truepos.cycles`.
    pub cycles: S32Pin,
    /// `truepos.motion-enabled` (input).
    pub motion_enabled: BitPin,
    /// `truepos.all-homed` (input).
    pub all_homed: BitPin,
}

/// Every pin of the component.
#[derive(Debug)]
pub struct Pins {
    /// Enable and model selection.
    pub control: ControlPins,
    /// Positions, temperatures, operating values.
    pub inputs: InputPins,
    /// Offsets and status.
    pub outputs: OutputPins,
}

/// Whether `id` can stand in a pin name that `halcmd` and HAL files take: letters, digits and
/// `_`, `-`, `.`, nothing else (a space ends a word in a HAL file; brackets, `#` and `$` are
/// syntax), within HAL's 47 bytes once the component's prefix is added.
pub fn check_pin_id(what: &str, id: &str, pin: &str) -> Result<(), HalError> {
    let full = format!("truepos.{pin}");
    let chars_ok = !id.is_empty()
        && id
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.'));
    if chars_ok && full.len() <= 47 {
        return Ok(());
    }
    Err(HalError::NotAPinName(format!(
        "{what} `{id}` would be the HAL pin `{full}`, which HAL cannot take ({}); give the \
         channel an id such as `{}` in the machine file",
        if chars_ok {
            "longer than 47 bytes"
        } else {
            "only letters, digits, `_`, `-` and `.`"
        },
        suggested_id(id)
    )))
}

/// A pin-safe id for a column name like `Spindel vorne [°C]`: lower case, the unit in brackets
/// dropped, every other character an `_`, at most 30 bytes.
fn suggested_id(id: &str) -> String {
    let base = id.split(['[', '(']).next().unwrap_or(id);
    let mut out = String::new();
    for c in base.trim().chars() {
        let c = c.to_ascii_lowercase();
        if c.is_ascii_alphanumeric() {
            out.push(c);
        } else if !out.ends_with('_') {
            out.push('_');
        }
    }
    let out = out.trim_matches('_');
    let out: String = out.chars().take(30).collect();
    if out.is_empty() {
        "sensor_1".into()
    } else {
        out
    }
}

/// Every measured temperature and operating channel of `machine` makes a valid pin name.
pub fn check_names(machine: &Machine) -> Result<(), HalError> {
    for t in machine.temperatures.iter().filter(|t| t.lag.is_none()) {
        check_pin_id("temperature channel", &t.id, &temperature_pin(&t.id))?;
    }
    for o in &machine.operating {
        check_pin_id("operating channel", &o.id, &operating_pin(&o.id))?;
    }
    Ok(())
}

/// Creates every pin of `machine` on `component` (before [`Component::ready`]); `paths` is the
/// number of paths of the control (one `path.<n>.model` pin each).
pub fn create(component: &Component, machine: &Machine, paths: usize) -> Result<Pins, HalError> {
    check_names(machine)?;
    let mut positions = Vec::new();
    let mut axis_paths = Vec::new();
    let mut axes = Vec::new();
    for axis in &machine.axes {
        let p = axis_prefix(&axis.name);
        positions.push(component.float_pin(&format!("{p}.pos"), Direction::In)?);
        axis_paths.push(component.s32_pin(&axis_path_pin(&axis.name), Direction::In)?);
        axes.push(AxisOutputPins {
            offset_um: component.float_pin(&offset_um_pin(&axis.name), Direction::Out)?,
            counts: component.s32_pin(&format!("{p}.eoffset-counts"), Direction::Out)?,
            scale: component.float_pin(&format!("{p}.eoffset-scale"), Direction::Out)?,
            enable: component.bit_pin(&format!("{p}.eoffset-enable"), Direction::Out)?,
            request: component.float_pin(&format!("{p}.eoffset-request"), Direction::In)?,
        });
    }
    let temperatures = machine
        .temperatures
        .iter()
        .enumerate()
        .filter(|(_, t)| t.lag.is_none())
        .map(|(c, t)| {
            Ok((
                c,
                component.float_pin(&temperature_pin(&t.id), Direction::In)?,
            ))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let operating = machine
        .operating
        .iter()
        .map(|o| component.float_pin(&operating_pin(&o.id), Direction::In))
        .collect::<Result<Vec<_>, _>>()?;
    let control = ControlPins {
        enable: component.bit_pin("enable", Direction::In)?,
        model_select: component.s32_pin(MODEL_SELECT_PIN, Direction::In)?,
        reload: component.bit_pin(MODEL_RELOAD_PIN, Direction::In)?,
        reloads: component.s32_pin(MODEL_RELOADS_PIN, Direction::Out)?,
    };
    let mut probe = ProbePins {
        trigger: component.bit_pin("probe.trigger", Direction::In)?,
        positions: Vec::new(),
        deviations: Vec::new(),
        measured: Vec::new(),
    };
    for n in 0..machine.axes.len() {
        let [pos, dev, measured] = probe_pins(n);
        probe
            .positions
            .push(component.float_pin(&pos, Direction::In)?);
        probe
            .deviations
            .push(component.float_pin(&dev, Direction::In)?);
        probe
            .measured
            .push(component.bit_pin(&measured, Direction::In)?);
    }
    let inputs = InputPins {
        positions,
        paths: axis_paths,
        temperatures,
        operating,
        probe,
    };
    let outputs = OutputPins {
        axes,
        status: component.s32_pin(STATUS_PIN, Direction::Out)?,
        path_models: (1..=paths)
            .map(|n| component.s32_pin(&path_model_pin(n), Direction::Out))
            .collect::<Result<Vec<_>, _>>()?,
        clamped: component.bit_pin("clamped", Direction::Out)?,
        extrapolating: component.bit_pin("extrapolating", Direction::Out)?,
        cycle_us: component.float_pin("cycle-us", Direction::Out)?,
        cycles: component.s32_pin("cycles", Direction::Out)?,
        motion_enabled: component.bit_pin("motion-enabled", Direction::In)?,
        all_homed: component.bit_pin("all-homed", Direction::In)?,
    };
    Ok(Pins {
        control,
        inputs,
        outputs,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_follow_linuxcnc() {
        assert_eq!(axis_prefix("X"), "axis.x");
        assert_eq!(temperature_pin("x_slide_top"), "temp.x_slide_top");
        assert!(check_pin_id("t", "x_slide_top", &temperature_pin("x_slide_top")).is_ok());
        let e = check_pin_id(
            "temperature channel",
            "Spindel vorne [°C]",
            &temperature_pin("Spindel vorne [°C]"),
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("temperature channel `Spindel vorne [°C]`") && e.contains("`spindel_vorne`"),
            "{e}"
        );
        let long = "a".repeat(40);
        let e = check_pin_id("t", &long, &temperature_pin(&long))
            .unwrap_err()
            .to_string();
        assert!(e.contains("longer than 47 bytes"), "{e}");
        assert_eq!(operating_pin("spindle_rpm"), "operating.spindle_rpm");
        assert_eq!(status_code(CompensationState::Active), 1);
        assert_eq!(status_code(CompensationState::NoModel), 3);
        assert_eq!(path_model_pin(1), "path.1.model");
        assert_eq!(
            probe_pins(2),
            ["probe.pos-2", "probe.dev-2", "probe.measured-2"].map(String::from)
        );
    }
}
