//! Malformed machine and model files: each gets one exact message naming file, line, column,
//! key and what was expected.

use std::path::Path;

use truepos_io::machine_file;
use truepos_io::model_file::{filtered, position};

mod support;
use support::machine_of;

const MACHINE: &str = r#"[machine]
name = "two-axis"

[[axis]]
name = "X"
kind = "linear"
travel = [0.0, 500.0]

[[axis]]
name = "Y"
kind = "linear"
travel = [0.0, 400.0]
carried_by = "X"

[[temperature]]
id = "x_bottom"
valid_range = [0.0, 80.0]

[[temperature]]
id = "x_top"
valid_range = [0.0, 80.0]

[[difference]]
name = "dT_x"
plus = "x_bottom"
minus = "x_top"
"#;

const MODEL: &str = r#"format = "truepos-model"
version = 1
name = "bend"
machine = "two-axis"

[[inputs.axes]]
name = "X"
travel = [0.0, 500.0]

[[inputs.axes]]
name = "Y"
travel = [0.0, 400.0]

[[inputs.differences]]
name = "dT_x"
plus = "x_bottom"
minus = "x_top"

[[part]]
name = "structure"
form = "position-dependent"

[[part.term]]
axis = "Y"
difference = "dT_x"
k0_um_per_k = 2.0
position = [{ axis = "X", factor = "ratio", k_um_per_k = 4.0 }]
"#;

fn machine_error(text: &str) -> String {
    machine_file::parse(Path::new("m.toml"), text)
        .expect_err("the file must be refused")
        .to_string()
}

fn model_error(text: &str) -> String {
    position::parse(Path::new("k.toml"), text, &machine_of(MACHINE))
        .expect_err("the file must be refused")
        .to_string()
}

/// Replaces exactly one occurrence, so that a fixture cannot silently stop applying.
fn edit(text: &str, from: &str, to: &str) -> String {
    assert_eq!(text.matches(from).count(), 1, "`{from}` must occur once");
    text.replacen(from, to, 1)
}

#[test]
fn the_unedited_files_are_accepted() {
    let m = machine_file::parse(Path::new("m.toml"), MACHINE).unwrap();
    assert_eq!(m.machine.axes[1].carried_by, Some(0));
    position::parse(Path::new("k.toml"), MODEL, &m.machine).unwrap();
}

// ---- machine files ----

#[test]
fn m01_toml_syntax_error() {
    let text = edit(
        MACHINE,
        "kind = \"linear\"\ntravel = [0.0, 500.0]",
        "kind = \"linear\ntravel = [0.0, 500.0]",
    );
    assert_eq!(machine_error(&text), "m.toml:6:15: invalid basic string");
}

#[test]
fn m02_travel_not_positive() {
    let text = edit(MACHINE, "travel = [0.0, 400.0]", "travel = [400.0, 400.0]");
    assert_eq!(
        machine_error(&text),
        "m.toml:12:10: `axis[1].travel`: expected [min, max] with max > min (travel > 0), got [400, 400]"
    );
}

#[test]
fn m03_unknown_axis_kind() {
    let text = edit(
        MACHINE,
        "name = \"Y\"\nkind = \"linear\"",
        "name = \"Y\"\nkind = \"linaer\"",
    );
    assert_eq!(
        machine_error(&text),
        "m.toml:11:8: `axis[1].kind`: unknown variant `linaer`, expected `linear` or `rotary`"
    );
}

#[test]
fn m04_duplicate_axis_name() {
    let text = edit(MACHINE, "name = \"Y\"", "name = \"X\"");
    assert_eq!(
        machine_error(&text),
        "m.toml:10:8: `axis[1].name`: duplicate axis `X` (first defined as axis[0]); names must be unique"
    );
}

#[test]
fn m05_unknown_sensor_in_difference() {
    let text = edit(MACHINE, "minus = \"x_top\"", "minus = \"x_tpo\"");
    assert_eq!(
        machine_error(&text),
        "m.toml:26:9: `difference[0].minus`: unknown temperature sensor `x_tpo`; expected one of: x_bottom, x_top"
    );
}

#[test]
fn m06_difference_references_itself() {
    let text = edit(MACHINE, "minus = \"x_top\"", "minus = \"x_bottom\"");
    assert_eq!(
        machine_error(&text),
        "m.toml:26:9: `difference[0].minus`: difference `dT_x` references itself (`x_bottom` minus `x_bottom`); expected another sensor or minus_fixed"
    );
}

#[test]
fn m07_unknown_carrying_axis() {
    let text = edit(MACHINE, "carried_by = \"X\"", "carried_by = \"W\"");
    assert_eq!(
        machine_error(&text),
        "m.toml:13:14: `axis[1].carried_by`: unknown axis `W`; expected one of: X, Y"
    );
}

#[test]
fn m08_axes_carry_each_other() {
    let text = edit(
        MACHINE,
        "travel = [0.0, 500.0]\n",
        "travel = [0.0, 500.0]\ncarried_by = \"Y\"\n",
    );
    assert_eq!(
        machine_error(&text),
        "m.toml:8:14: `carried_by`: axis `X` rests on itself through carried_by; the axes must form a chain from the base"
    );
}

#[test]
fn m09_unknown_key() {
    let text = edit(
        MACHINE,
        "valid_range = [0.0, 80.0]\n\n[[difference]]",
        "valid_range = [0.0, 80.0]\nunit = \"K\"\n\n[[difference]]",
    );
    assert_eq!(
        machine_error(&text),
        "m.toml:22:1: `temperature[1].unit`: unknown field `unit`, expected one of `id`, `location`, `valid_range`, `max_rate_k_per_min`, `max_age_s`, `stuck_after_s`, `noise_k`, `recover_after_s`, `lag_of`, `lag_s`, `gain_k_per_unit`, `power`"
    );
}

#[test]
fn m10_missing_travel() {
    let text = edit(MACHINE, "travel = [0.0, 400.0]\n", "");
    assert_eq!(
        machine_error(&text),
        "m.toml:9:1: `axis[1]`: missing field `travel`"
    );
}

#[test]
fn m11_valid_range_reversed() {
    let text = edit(
        MACHINE,
        "id = \"x_top\"\nvalid_range = [0.0, 80.0]",
        "id = \"x_top\"\nvalid_range = [80.0, 0.0]",
    );
    assert_eq!(
        machine_error(&text),
        "m.toml:21:15: `temperature[1].valid_range`: expected [min, max] in °C with max > min, got [80, 0]"
    );
}

#[test]
fn m12_both_minus_and_minus_fixed() {
    let text = edit(
        MACHINE,
        "minus = \"x_top\"",
        "minus = \"x_top\"\nminus_fixed = 20.0",
    );
    assert_eq!(
        machine_error(&text),
        "m.toml:27:15: `difference[0].minus_fixed`: expected either `minus` (a sensor) or `minus_fixed` (°C), not both"
    );
}

#[test]
fn m13_travel_is_not_a_pair_of_numbers() {
    let text = edit(MACHINE, "travel = [0.0, 500.0]", "travel = \"0..500\"");
    assert_eq!(
        machine_error(&text),
        "m.toml:7:10: `axis[0].travel`: invalid type: string \"0..500\", expected an array of length 2"
    );
}

#[test]
fn m14_no_axes() {
    let text = "[machine]\nname = \"empty\"\n";
    assert_eq!(
        machine_error(text),
        "m.toml:1:1: `axis`: expected at least one [[axis]] table"
    );
}

#[test]
fn m15_envelope_not_positive() {
    let text = edit(
        MACHINE,
        "carried_by = \"X\"",
        "carried_by = \"X\"\nmax_rate_um_per_s = -5.0",
    );
    assert_eq!(
        machine_error(&text),
        "m.toml:14:21: `axis[1].max_rate_um_per_s`: expected a finite number > 0, got -5"
    );
}

#[test]
fn m16_two_axes_with_one_seed_d_code() {
    let text = edit(
        MACHINE,
        "carried_by = \"X\"",
        "carried_by = \"X\"\nnumber = 1",
    );
    assert_eq!(
        machine_error(&text),
        "m.toml:14:10: `axis[1].number`: axis `Y` has path 1 number 1, like axis `X`; each axis needs its own"
    );
}

/// A lagged channel after `x_top` (lines 23–27 of the edited file).
fn with_lag(of: &str, tau: &str) -> String {
    edit(
        MACHINE,
        "id = \"x_top\"\nvalid_range = [0.0, 80.0]\n",
        &format!(
            "id = \"x_top\"\nvalid_range = [0.0, 80.0]\n\n[[temperature]]\nid = \"x_lag\"\nvalid_range = [0.0, 80.0]\n{of}{tau}"
        ),
    )
}

#[test]
fn lagged_channels_are_read() {
    let m = machine_file::parse(
        Path::new("m.toml"),
        &with_lag("lag_of = \"x_top\"\n", "lag_s = 3600.0\n"),
    )
    .unwrap();
    let lag = m.machine.temperatures[2].lag.unwrap();
    assert_eq!(
        (lag.source, lag.tau_s),
        (truepos_model::LagSource::Temperature(1), 3600.0)
    );
    assert!(m.machine.temperatures[1].lag.is_none());
}

#[test]
fn lags_of_operating_state_are_read() {
    let text = with_lag(
        "lag_of = \"spindle_rpm\"\n",
        "lag_s = 300.0\ngain_k_per_unit = 1e-7\npower = 2\n\n[[operating]]\nid = \"spindle_rpm\"\nkind = \"spindle-speed\"\n",
    );
    let m = machine_file::parse(Path::new("m.toml"), &text).unwrap();
    assert_eq!(
        m.machine.temperatures[2].lag,
        Some(truepos_model::Lag {
            source: truepos_model::LagSource::Operating {
                channel: 0,
                gain_k_per_unit: 1e-7,
                power: 2
            },
            tau_s: 300.0
        })
    );
    // Without a gain the channel would have no unit: refused at `lag_of` (line 26, column 10).
    let text = with_lag(
        "lag_of = \"spindle_rpm\"\n",
        "lag_s = 300.0\n\n[[operating]]\nid = \"spindle_rpm\"\nkind = \"spindle-speed\"\n",
    );
    assert_eq!(
        machine_error(&text),
        "m.toml:26:10: `temperature[2].gain_k_per_unit`: the lag of operating channel `spindle_rpm` needs `gain_k_per_unit`, the temperature rise in K per unit"
    );
}

#[test]
fn m17_lag_of_an_unknown_sensor() {
    // Line 26 `lag_of = "x_topp"`: the string starts in column 10.
    let text = with_lag("lag_of = \"x_topp\"\n", "lag_s = 3600.0\n");
    assert_eq!(
        machine_error(&text),
        "m.toml:26:10: `temperature[2].lag_of`: `x_topp` is neither a measured temperature sensor nor an operating channel; expected one of: x_bottom, x_top"
    );
}

#[test]
fn m18_lag_of_a_lagged_channel() {
    // A lag of a lag is refused: the source must be measured (line 26, column 10).
    let text = with_lag("lag_of = \"x_lag\"\n", "lag_s = 3600.0\n");
    assert_eq!(
        machine_error(&text),
        "m.toml:26:10: `temperature[2].lag_of`: `x_lag` is neither a measured temperature sensor nor an operating channel; expected one of: x_bottom, x_top"
    );
}

#[test]
fn m19_lag_time_constant_not_positive() {
    // Line 27 `lag_s = 0.0`: the number starts in column 9.
    let text = with_lag("lag_of = \"x_top\"\n", "lag_s = 0.0\n");
    assert_eq!(
        machine_error(&text),
        "m.toml:27:9: `temperature[2].lag_s`: expected a positive time constant in s, got 0"
    );
}

#[test]
fn m20_lag_without_time_constant() {
    let text = with_lag("lag_of = \"x_top\"\n", "");
    assert_eq!(
        machine_error(&text),
        "m.toml:26:10: `temperature[2].lag_s`: `lag_of` needs `lag_s`, the time constant of the lag in s"
    );
}

// ---- model files ----

#[test]
fn k01_wrong_machine() {
    let text = edit(MODEL, "machine = \"two-axis\"", "machine = \"lathe\"");
    assert_eq!(
        model_error(&text),
        "k.toml:4:11: `machine`: the model was made for machine `lathe`, but the machine description is `two-axis`"
    );
}

#[test]
fn k02_unsupported_version() {
    let text = edit(MODEL, "version = 1", "version = 7");
    assert_eq!(
        model_error(&text),
        "k.toml:2:11: `version`: model file version 7 is not supported; this build reads versions 1 and 2"
    );
}

/// Version 2 names its form; a TOML file of the filtered form, or a version 2 file without
/// one, is named at its key. Version 1 (no form) still loads.
#[test]
fn k03_the_form_of_a_version_2_file() {
    let v2 = edit(MODEL, "version = 1", "version = 2\nform = \"filtered\"");
    let e = model_error(&v2);
    assert!(
        e.contains("`form`") && e.contains("expected \"position\""),
        "{e}"
    );
    let e = model_error(&edit(MODEL, "version = 1", "version = 2"));
    assert!(e.contains("`form`") && e.contains("version 2"), "{e}");
}

#[test]
fn k03_travel_mismatch() {
    let text = edit(MODEL, "travel = [0.0, 400.0]", "travel = [0.0, 600.0]");
    assert_eq!(
        model_error(&text),
        "k.toml:12:10: `inputs.axes[1].travel`: the model was made for axis `Y` with travel [0, 600], but the machine has [0, 400]"
    );
}

#[test]
fn k04_difference_defined_otherwise() {
    let text = edit(MODEL, "minus = \"x_top\"", "minus_fixed = 20.0");
    assert_eq!(
        model_error(&text),
        "k.toml:15:8: `inputs.differences[0].name`: the model was made for `dT_x` = x_bottom − 20 °C, but the machine defines it as x_bottom − x_top"
    );
}

#[test]
fn k05_term_uses_unlisted_difference() {
    let text = edit(MODEL, "difference = \"dT_x\"", "difference = \"dT_y\"");
    assert_eq!(
        model_error(&text),
        "k.toml:25:14: `part[0].term[0].difference`: temperature difference `dT_y` is not listed in [[inputs.differences]] (listed: dT_x)"
    );
}

#[test]
fn k06_unknown_factor() {
    let text = edit(MODEL, "factor = \"ratio\"", "factor = \"cubic\"");
    assert_eq!(
        model_error(&text),
        "k.toml:27:36: `part[0].term[0].position[0].factor`: unknown variant `cubic`, expected one of `ratio`, `ratio-squared`, `bed`"
    );
}

#[test]
fn k07_axis_the_machine_lacks() {
    let text = edit(MODEL, "name = \"Y\"\ntravel", "name = \"Z\"\ntravel");
    assert_eq!(
        model_error(&text),
        "k.toml:11:8: `inputs.axes[1].name`: the model needs axis `Z`, which machine `two-axis` does not have"
    );
}

#[test]
fn k08_not_a_model_file() {
    let text = edit(MODEL, "format = \"truepos-model\"", "format = \"klipper\"");
    assert_eq!(
        model_error(&text),
        "k.toml:1:10: `format`: expected \"truepos-model\", got \"klipper\"; this is not a truepos model file"
    );
}

#[test]
fn k09_regression_without_axis() {
    let text = format!(
        "{MODEL}\n[[part]]\nname = \"spindle\"\nform = \"regression\"\nterms = [{{ difference = \"dT_x\", k_um_per_k = 1.0 }}]\n"
    );
    assert_eq!(
        model_error(&text),
        "k.toml:30:8: `part[1].axis`: a regression part needs `axis`, the direction of the error it describes"
    );
}

#[test]
fn k10_duplicate_part() {
    let text =
        format!("{MODEL}\n[[part]]\nname = \"structure\"\nform = \"regression\"\naxis = \"X\"\n");
    assert_eq!(
        model_error(&text),
        "k.toml:30:8: `part[1].name`: duplicate part `structure` (first defined as part[0]); names must be unique"
    );
}

#[test]
fn k11_json_syntax_error() {
    let machine = machine_file::parse(Path::new("m.toml"), MACHINE)
        .unwrap()
        .machine;
    let err = position::parse_json(
        Path::new("k.json"),
        "{\n  \"format\": \"truepos-model\",\n  \"version\": 1,,\n}",
        &machine,
    )
    .unwrap_err()
    .to_string();
    assert_eq!(err, "k.json:3:16: key must be a string");
}

// ---- dynamic model files (JSON) ----

const DYNAMIC: &str = r#"{
  "format": "truepos-dynamic-model",
  "version": 1,
  "machine": "two-axis",
  "inputs": [
    {"name": "x_bottom", "kind": "temperature"},
    {"name": "spindle_rpm", "kind": "operating"}
  ],
  "temperature_rise": true,
  "temperature_taus_s": [900.0],
  "rate_taus_s": [],
  "operating_taus_s": [300.0],
  "operating_square": false,
  "features": ["rise(x_bottom)", "lp900(x_bottom)", "lp300(spindle_rpm)"],
  "outputs": [
    {"name": "dY_um", "intercept_um": 0.5, "coefficients": [1.0, 2.0, 0.001]}
  ],
  "provenance": {},
  "validation": {}
}
"#;

fn dynamic_machine() -> truepos_model::Machine {
    let text =
        format!("{MACHINE}\n[[operating]]\nid = \"spindle_rpm\"\nkind = \"spindle-speed\"\n");
    machine_of(&text)
}

fn dynamic_error(text: &str) -> String {
    filtered::parse(Path::new("d.json"), text, &dynamic_machine())
        .expect_err("the file must be refused")
        .to_string()
}

#[test]
fn the_unedited_dynamic_file_is_accepted() {
    let bound = filtered::parse(Path::new("d.json"), DYNAMIC, &dynamic_machine()).unwrap();
    assert_eq!(bound.axes(), vec![Some(1)]);
    assert_eq!(bound.model().bank().features().len(), 3);
}

#[test]
fn d01_json_syntax_error() {
    let text = edit(DYNAMIC, "\"version\": 1,", "\"version\": 1");
    assert_eq!(dynamic_error(&text), "d.json:4:3: expected `,` or `}`");
}

#[test]
fn d02_other_machine() {
    let text = edit(DYNAMIC, "\"two-axis\"", "\"three-axis\"");
    assert_eq!(
        dynamic_error(&text),
        "d.json:4:14: `machine`: expected `two-axis` (the machine it is loaded for), got `three-axis`"
    );
}

#[test]
fn d03_unknown_sensor() {
    let text = edit(DYNAMIC, "{\"name\": \"x_bottom\"", "{\"name\": \"x_botom\"");
    assert_eq!(
        dynamic_error(&text),
        "d.json:6:14: `inputs[0].name`: machine `two-axis` has no temperature channel `x_botom`; expected one of: x_bottom, x_top"
    );
}

#[test]
fn d04_bad_time_constant() {
    let text = edit(DYNAMIC, "[300.0]", "[-300.0]");
    assert_eq!(
        dynamic_error(&text),
        "d.json:12:24: `operating_taus_s[0]`: expected a positive time constant in s, got -300"
    );
}

#[test]
fn d05_wrong_number_of_coefficients() {
    let text = edit(DYNAMIC, "[1.0, 2.0, 0.001]", "[1.0, 2.0]");
    assert_eq!(
        dynamic_error(&text),
        "d.json:16:60: `outputs[0].coefficients`: expected 3 values (one per feature), got 2"
    );
}

#[test]
fn d06_wrong_type() {
    let text = edit(
        DYNAMIC,
        "\"intercept_um\": 0.5",
        "\"intercept_um\": \"0.5\"",
    );
    assert_eq!(
        dynamic_error(&text),
        "d.json:16:39: `outputs[0].intercept_um`: invalid type: string \"0.5\", expected f64"
    );
}

#[test]
fn d07_unknown_axis() {
    let text = edit(
        DYNAMIC,
        "\"intercept_um\"",
        "\"axis\": \"W\", \"intercept_um\"",
    );
    assert_eq!(
        dynamic_error(&text),
        "d.json:16:31: `outputs[0].axis`: machine `two-axis` has no axis `W`; expected one of: X, Y"
    );
}

#[test]
fn d08_wrong_version() {
    let text = edit(DYNAMIC, "\"version\": 1,", "\"version\": 2,");
    assert_eq!(
        dynamic_error(&text),
        "d.json:3:14: `version`: expected 1, got 2"
    );
}
