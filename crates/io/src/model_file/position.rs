//! The model file's position form: a model that is a function of this cycle's values.
//!
//! A model file is versioned (`format = "truepos-model"`, `version = 2`) and says its form
//! (`form = "position"` here; the filtered form is [`super::filtered`]; version 1,
//! without `form`, still loads as the position form). It names the machine it
//! belongs to, lists the inputs it was made for (axes with their travel, temperature differences
//! with their definitions) and holds its parts and coefficients, plus free-form provenance and
//! validation tables. Loading binds it to a machine description and refuses any mismatch: a
//! model fitted with `dT_x = x_bottom − x_top` must not silently run on a machine where `dT_x`
//! means something else, and a ratio r = pos / length changes meaning when the travel changes.
//!
//! TOML is the native form (errors name line, column and key); JSON with the same structure is
//! accepted too (syntax errors name line and column, the other errors the key).
//!
//! ```toml
//! format = "truepos-model"
//! version = 2
//! form = "position"
//! name = "vmc3-structure"
//! machine = "vmc-3axis"
//!
//! [[inputs.axes]]
//! name = "X"
//! travel = [0.0, 800.0]
//!
//! [[inputs.differences]]
//! name = "dT_x_slide"
//! plus = "x_slide_bottom"
//! minus = "x_slide_top"
//!
//! [[part]]
//! name = "structure"
//! form = "position-dependent"
//! [[part.term]]
//! axis = "Z"                      # error direction n
//! difference = "dT_x_slide"       # ΔT_m
//! k0_um_per_k = 2.0               # K_nm0
//! position = [{ axis = "X", factor = "ratio", k_um_per_k = 4.0 }]   # K_nmj · r_j
//! ```

use std::path::Path;

use serde::{Deserialize, Serialize};
use toml::Spanned;
use truepos_model::{
    Carriage, Machine, Model, Part, PartForm, PositionFactor, PositionTerm, Reference, Summand,
};

use super::envelope::EnvelopeEntry;
use crate::error::{parse_toml, read_text};
use truepos_files::InputError;

mod write;

/// The `format`, `version` and `form`s of the model file ([`super`]), of which this is the
/// position form.
pub use super::{FORMAT, FORM_FILTERED, FORM_POSITION, VERSION};

/// A model file as written: names, not indices. Build one from a bound model with
/// [`ModelFile::from_model`], write it with [`ModelFile::to_toml`], read one with [`load`].
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ModelFile {
    /// Always [`FORMAT`].
    pub format: Spanned<String>,
    /// [`VERSION`], or 1 in files written before forms were named.
    pub version: Spanned<u32>,
    /// [`FORM_POSITION`] (absent in version 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub form: Option<Spanned<String>>,
    /// The model's name.
    pub name: Spanned<String>,
    /// The machine it belongs to (`[machine] name` of the machine description).
    pub machine: Spanned<String>,
    /// Free text.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub description: String,
    /// The axis-combination index (b_i = 100·path + axis number) this model serves.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axis_index: Option<Vec<u32>>,
    /// The inputs it was made for.
    pub inputs: Inputs,
    /// Its parts.
    #[serde(default)]
    pub part: Vec<PartEntry>,
    /// Where it came from (tool, data, date): free-form.
    #[serde(default, skip_serializing_if = "toml::Table::is_empty")]
    pub provenance: toml::Table,
    /// How it was validated and what it achieved: free-form.
    #[serde(default, skip_serializing_if = "toml::Table::is_empty")]
    pub validation: toml::Table,
    /// Where it was trained (`truepos_model::envelope`); absent: not known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub training_envelope: Option<EnvelopeEntry>,
}

/// The inputs a model was made for.
#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Inputs {
    /// Axes whose positions the model reads or whose error it describes.
    #[serde(default)]
    pub axes: Vec<InputAxis>,
    /// Temperature differences it reads.
    #[serde(default)]
    pub differences: Vec<InputDifference>,
}

/// An axis as the model knows it.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct InputAxis {
    /// Axis name.
    pub name: Spanned<String>,
    /// Travel [min, max] the position factors were computed with.
    pub travel: Spanned<[f64; 2]>,
}

/// A temperature difference as the model knows it.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct InputDifference {
    /// Difference name.
    pub name: Spanned<String>,
    /// Sensor taken.
    pub plus: Spanned<String>,
    /// Sensor it is taken against…
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub minus: Option<Spanned<String>>,
    /// …or fixed reference in °C.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub minus_fixed: Option<Spanned<f64>>,
    /// When `plus` is a lagged channel: what it lags (see [`lag_text`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plus_lag: Option<Spanned<String>>,
    /// When `minus` is a lagged channel: what it lags.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub minus_lag: Option<Spanned<String>>,
}

/// The definition of a lagged channel as model files record it (`spindle_front, 1800 s` or
/// `spindle_rpm^2 × 1e-7 K, 300 s`), so that a model is refused by a machine whose lag differs.
pub fn lag_text(machine: &Machine, channel: usize) -> Option<String> {
    let lag = machine.temperatures.get(channel)?.lag?;
    Some(match lag.source {
        truepos_model::LagSource::Temperature(s) => {
            format!("{}, {} s", machine.temperatures[s].id, lag.tau_s)
        }
        truepos_model::LagSource::Operating {
            channel,
            gain_k_per_unit,
            power,
        } => format!(
            "{}{} × {gain_k_per_unit} K, {} s",
            machine.operating[channel].id,
            if power == 2 { "^2" } else { "" },
            lag.tau_s
        ),
    })
}

/// The form of a part in the file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum FormEntry {
    /// The general position-dependent form.
    PositionDependent,
    /// The regression against a reference sensor.
    Regression,
}

/// A part in the file.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PartEntry {
    /// Part name.
    pub name: Spanned<String>,
    /// Its form.
    pub form: FormEntry,
    /// Whether it contributes at start.
    #[serde(default = "yes")]
    pub enabled: bool,
    /// Position-dependent form: its summands.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub term: Vec<TermEntry>,
    /// Position-dependent form: constant errors per axis.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub constant: Vec<ConstantEntry>,
    /// Regression form: the axis (error direction) Y of Y = Σ k_i·ΔT_i + c.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axis: Option<Spanned<String>>,
    /// Regression form: the k_i·ΔT_i.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub terms: Vec<RegressionTermEntry>,
    /// Regression form: the constant c in µm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub constant_um: Option<f64>,
}

fn yes() -> bool {
    true
}

/// One summand ΔT_m · [K_nm0 + Σ K_nmj·g_j] (· KFA_b).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct TermEntry {
    /// Error direction n.
    pub axis: Spanned<String>,
    /// ΔT_m.
    pub difference: Spanned<String>,
    /// K_nm0 in µm/K.
    #[serde(default)]
    pub k0_um_per_k: f64,
    /// The K_nmj·g_j.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub position: Vec<PositionEntry>,
    /// The bed-factor family: multiply the summand by KFA of this axis.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bed_multiplier: Option<Spanned<String>>,
}

/// The position factor in a file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum FactorEntry {
    /// r.
    Ratio,
    /// r².
    RatioSquared,
    /// KFA.
    Bed,
}

/// One K_nmj·g_j.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PositionEntry {
    /// Axis j.
    pub axis: Spanned<String>,
    /// g_j; when left out, the axis' natural factor: ratio for a cantilevered slide, bed factor
    /// for a slide on a bed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub factor: Option<FactorEntry>,
    /// K_nmj in µm/K.
    pub k_um_per_k: f64,
}

/// A constant error of an axis.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ConstantEntry {
    /// Axis.
    pub axis: Spanned<String>,
    /// Value in µm.
    pub value_um: f64,
}

/// One k_i·ΔT_i of a regression.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct RegressionTermEntry {
    /// ΔT_i (sensor i minus the reference sensor).
    pub difference: Spanned<String>,
    /// k_i in µm/K.
    pub k_um_per_k: f64,
}

fn spanned<T>(value: T) -> Spanned<T> {
    Spanned::new(0..0, value)
}

/// A bound model with what the file says about where it serves.
#[derive(Debug, Clone)]
pub struct LoadedModel {
    /// The model.
    pub model: Model,
    /// The axis-combination index from the file, if it has one.
    pub axis_index: Option<Vec<u32>>,
}

/// Reads a model file like [`load`] and keeps its axis-combination index.
pub fn load_entry(path: &Path, machine: &Machine) -> Result<LoadedModel, InputError> {
    parse_entry(path, &read_text(path, truepos_files::MODEL)?, machine)
}

/// Parses a model file's text like [`load`] (`.json` as JSON, anything else as TOML; `path`
/// names it in errors) and keeps its axis-combination index.
pub fn parse_entry(path: &Path, text: &str, machine: &Machine) -> Result<LoadedModel, InputError> {
    let is_json = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    let axis_index = if is_json {
        serde_json::from_str::<serde_json::Value>(text)
            .ok()
            .and_then(|v| v.get("axis_index").cloned())
            .and_then(|v| serde_json::from_value(v).ok())
    } else {
        parse_toml::<ModelFile>(path, text)
            .ok()
            .and_then(|f| f.axis_index)
    };
    let model = if is_json {
        parse_json(path, text, machine)?
    } else {
        parse(path, text, machine)?
    };
    Ok(LoadedModel { model, axis_index })
}

/// Reads a model file (`.json` as JSON, anything else as TOML) and binds it to a machine.
pub fn load(path: &Path, machine: &Machine) -> Result<Model, InputError> {
    let text = read_text(path, truepos_files::MODEL)?;
    let is_json = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    if is_json {
        parse_json(path, &text, machine)
    } else {
        parse(path, &text, machine)
    }
}

/// The first line of a model file truepos writes: the SHA-256 of everything after it, so that a
/// file written in part — two writes, the first of which is valid TOML on its own — is refused
/// instead of loaded half. A file without the line (written by hand) is read as it is.
const CHECKSUM_PREFIX: &str = "# sha256 ";

/// The SHA-256 of `bytes` in lower-case hex (a model file's checksum line; reports name the
/// model file they describe by it).
pub fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::{Digest, Sha256};
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// `text` with its checksum line in front.
fn with_checksum(text: &str) -> String {
    format!("{CHECKSUM_PREFIX}{}\n{text}", sha256_hex(text.as_bytes()))
}

/// Refuses a file whose checksum line does not match what follows it.
fn check_checksum(path: &Path, text: &str) -> Result<(), InputError> {
    let Some(rest) = text.strip_prefix(CHECKSUM_PREFIX) else {
        return Ok(());
    };
    let (stated, body) = rest.split_once('\n').unwrap_or((rest, ""));
    if stated.trim() == sha256_hex(body.as_bytes()) {
        return Ok(());
    }
    Err(InputError::at(
        path,
        1,
        1,
        "",
        "the content does not match the checksum on its first line: the file was written in \
         part (or edited by hand — then remove that line to accept the edit)"
            .to_string(),
    ))
}

/// Reads model-file TOML text and binds it to a machine; `path` only names it in errors.
pub fn parse(path: &Path, text: &str, machine: &Machine) -> Result<Model, InputError> {
    check_checksum(path, text)?;
    let file: ModelFile = parse_toml(path, text)?;
    file.bind(machine)
        .map_err(|(span, key, message)| InputError::at_span(path, text, span, key, message))
}

/// Reads model-file JSON text and binds it to a machine. Syntax errors name line and column;
/// the JSON is then read through the TOML data model, so other errors name the key only.
pub fn parse_json(path: &Path, text: &str, machine: &Machine) -> Result<Model, InputError> {
    let value: serde_json::Value = serde_json::from_str(text).map_err(|e| {
        // serde_json appends " at line L column C"; the position goes in front instead.
        let message = e.to_string();
        let message = message
            .rsplit_once(" at line ")
            .map_or(message.as_str(), |(m, _)| m)
            .to_string();
        InputError::at(path, e.line(), e.column(), "", message)
    })?;
    let as_toml = toml::to_string(&value).map_err(|e| {
        InputError::file(
            path,
            format!("cannot be represented as a model file (null values are not allowed): {e}"),
        )
    })?;
    let strip = |mut e: InputError| {
        e.position = None;
        e
    };
    let file: ModelFile = parse_toml(path, &as_toml).map_err(strip)?;
    file.bind(machine).map_err(|(_, key, message)| InputError {
        file: path.to_path_buf(),
        position: None,
        key: Some(key),
        message,
    })
}

type BindError = (std::ops::Range<usize>, String, String);

/// What a part's form contributes: its summands and its constants (axis, µm).
type PartTerms = (Vec<Summand>, Vec<(usize, f64)>);

impl ModelFile {
    /// Checks the file against a machine and builds the model.
    pub fn bind(&self, machine: &Machine) -> Result<Model, BindError> {
        self.check_header(machine)?;
        // The inputs the model was made for must be the machine's, exactly.
        self.check_input_axes(machine)?;
        for (i, d) in self.inputs.differences.iter().enumerate() {
            check_input_difference(machine, i, d)?;
        }
        let mut parts = Vec::new();
        for (pi, p) in self.part.iter().enumerate() {
            parts.push(self.bind_part(machine, pi, p)?);
        }
        let mut model = Model::new(self.name.get_ref().clone(), machine, parts)
            .map_err(|e| (self.name.span(), "part".into(), e.to_string()))?;
        if let Some(env) = &self.training_envelope {
            // The table has no position of its own here: the error points at the model's name
            // and names the key.
            let bound = env
                .bind(machine, |axis| machine.axis_index(axis))
                .map_err(|(key, message)| (self.name.span(), key, message))?;
            model.set_envelope(Some(bound));
        }
        Ok(model)
    }

    /// The file is a truepos model file of the version this build reads, made for this machine.
    fn check_header(&self, machine: &Machine) -> Result<(), BindError> {
        if self.format.get_ref() != FORMAT {
            return Err((
                self.format.span(),
                "format".into(),
                format!(
                    "expected \"{FORMAT}\", got \"{}\"; this is not a truepos model file",
                    self.format.get_ref()
                ),
            ));
        }
        let version = *self.version.get_ref();
        if version != 1 && version != VERSION {
            return Err((
                self.version.span(),
                "version".into(),
                format!(
                    "model file version {version} is not supported; this build reads versions 1 and {VERSION}"
                ),
            ));
        }
        match &self.form {
            Some(f) if f.get_ref() != FORM_POSITION => {
                return Err(err(
                    f,
                    "form".into(),
                    format!(
                        "expected \"{FORM_POSITION}\" in a TOML model file, got \"{}\" (a \"{FORM_FILTERED}\" model is a JSON file)",
                        f.get_ref()
                    ),
                ))
            }
            None if version == VERSION => {
                return Err((
                    self.version.span(),
                    "form".into(),
                    format!("expected `form = \"{FORM_POSITION}\"` in a version {VERSION} model file"),
                ))
            }
            _ => {}
        }
        if self.machine.get_ref() != &machine.name {
            return Err(err(
                &self.machine,
                "machine".into(),
                format!(
                    "the model was made for machine `{}`, but the machine description is `{}`",
                    self.machine.get_ref(),
                    machine.name
                ),
            ));
        }
        Ok(())
    }

    /// Every input axis exists in the machine with the travel the model was made for.
    fn check_input_axes(&self, machine: &Machine) -> Result<(), BindError> {
        for (i, a) in self.inputs.axes.iter().enumerate() {
            let key = format!("inputs.axes[{i}]");
            let Some(ax) = machine.axis_index(a.name.get_ref()) else {
                return Err(err(
                    &a.name,
                    format!("{key}.name"),
                    format!(
                        "the model needs axis `{}`, which machine `{}` does not have",
                        a.name.get_ref(),
                        machine.name
                    ),
                ));
            };
            let axis = &machine.axes[ax];
            let [lo, hi] = *a.travel.get_ref();
            if lo != axis.travel_min || hi != axis.travel_max {
                return Err((
                    a.travel.span(),
                    format!("{key}.travel"),
                    format!(
                        "the model was made for axis `{}` with travel [{lo}, {hi}], but the machine has [{}, {}]",
                        axis.name, axis.travel_min, axis.travel_max
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The machine index of an axis a part references; it must be listed in `[[inputs.axes]]`.
    fn listed_axis(
        &self,
        machine: &Machine,
        s: &Spanned<String>,
        key: String,
    ) -> Result<usize, BindError> {
        let names = self.inputs.axes.iter().map(|a| &a.name);
        require_listed(names, s, key, "axis", "[[inputs.axes]]")?;
        Ok(machine.axis_index(s.get_ref()).expect("checked above"))
    }

    /// The machine index of a temperature difference a part references; it must be listed in
    /// `[[inputs.differences]]`.
    fn listed_difference(
        &self,
        machine: &Machine,
        s: &Spanned<String>,
        key: String,
    ) -> Result<usize, BindError> {
        let names = self.inputs.differences.iter().map(|d| &d.name);
        require_listed(
            names,
            s,
            key,
            "temperature difference",
            "[[inputs.differences]]",
        )?;
        Ok(machine
            .difference_index(s.get_ref())
            .expect("checked above"))
    }

    /// Part `pi`: its name is unique and its entries are those of its form.
    fn bind_part(&self, machine: &Machine, pi: usize, p: &PartEntry) -> Result<Part, BindError> {
        let pkey = format!("part[{pi}]");
        if let Some(first) = self.part[..pi]
            .iter()
            .position(|q| q.name.get_ref() == p.name.get_ref())
        {
            return Err(err(
                &p.name,
                format!("{pkey}.name"),
                format!(
                    "duplicate part `{}` (first defined as part[{first}]); names must be unique",
                    p.name.get_ref()
                ),
            ));
        }
        let (summands, constants_um) = match p.form {
            FormEntry::PositionDependent => self.position_dependent(machine, pkey, p)?,
            FormEntry::Regression => self.regression(machine, pkey, p)?,
        };
        Ok(Part {
            name: p.name.get_ref().clone(),
            enabled: p.enabled,
            form: match p.form {
                FormEntry::PositionDependent => PartForm::PositionDependent,
                FormEntry::Regression => PartForm::Regression,
            },
            summands,
            constants_um,
        })
    }

    /// The summands and constants of a position-dependent part: `[[part.term]]` and
    /// `[[part.constant]]` only, each referencing listed inputs with finite coefficients.
    fn position_dependent(
        &self,
        machine: &Machine,
        pkey: String,
        p: &PartEntry,
    ) -> Result<PartTerms, BindError> {
        if p.axis.is_some() || !p.terms.is_empty() || p.constant_um.is_some() {
            return Err(err(
                &p.name,
                pkey,
                "a position-dependent part takes [[part.term]] and [[part.constant]]; `axis`, `terms` and `constant_um` belong to form = \"regression\"".into(),
            ));
        }
        let mut summands = Vec::new();
        for (ti, t) in p.term.iter().enumerate() {
            let tkey = format!("{pkey}.term[{ti}]");
            summands.push(self.position_dependent_term(machine, tkey, t)?);
        }
        let mut constants_um = Vec::new();
        for (ci, c) in p.constant.iter().enumerate() {
            let ckey = format!("{pkey}.constant[{ci}]");
            let axis = self.listed_axis(machine, &c.axis, format!("{ckey}.axis"))?;
            let v = finite(c.value_um, &c.axis, format!("{ckey}.value_um"))?;
            constants_um.push((axis, v));
        }
        Ok((summands, constants_um))
    }

    /// One `[[part.term]]`: a position-dependent summand with its position terms; a position term
    /// without a factor takes the one its axis's carriage implies.
    fn position_dependent_term(
        &self,
        machine: &Machine,
        tkey: String,
        t: &TermEntry,
    ) -> Result<Summand, BindError> {
        let axis = self.listed_axis(machine, &t.axis, format!("{tkey}.axis"))?;
        let difference =
            self.listed_difference(machine, &t.difference, format!("{tkey}.difference"))?;
        let k0 = finite(t.k0_um_per_k, &t.axis, format!("{tkey}.k0_um_per_k"))?;
        let mut position_terms = Vec::new();
        for (ji, j) in t.position.iter().enumerate() {
            let jkey = format!("{tkey}.position[{ji}]");
            let ja = self.listed_axis(machine, &j.axis, format!("{jkey}.axis"))?;
            let factor = match j.factor {
                Some(FactorEntry::Ratio) => PositionFactor::Ratio,
                Some(FactorEntry::RatioSquared) => PositionFactor::RatioSquared,
                Some(FactorEntry::Bed) => PositionFactor::BedFactor,
                None => match machine.axes[ja].carriage {
                    Carriage::Cantilever => PositionFactor::Ratio,
                    Carriage::Bed => PositionFactor::BedFactor,
                },
            };
            let k = finite(j.k_um_per_k, &j.axis, format!("{jkey}.k_um_per_k"))?;
            position_terms.push(PositionTerm {
                axis: ja,
                factor,
                k_um_per_k: k,
            });
        }
        let bed_multiplier = match &t.bed_multiplier {
            Some(b) => Some(self.listed_axis(machine, b, format!("{tkey}.bed_multiplier"))?),
            None => None,
        };
        Ok(Summand {
            axis,
            difference,
            k0_um_per_k: k0,
            position_terms,
            bed_multiplier,
        })
    }

    /// The summands and constant of a regression part: `axis`, `terms` and `constant_um` only,
    /// all on the one listed axis, with finite coefficients.
    fn regression(
        &self,
        machine: &Machine,
        pkey: String,
        p: &PartEntry,
    ) -> Result<PartTerms, BindError> {
        if !p.term.is_empty() || !p.constant.is_empty() {
            return Err(err(
                &p.name,
                pkey,
                "a regression part takes `axis`, `terms` and `constant_um`; [[part.term]] and [[part.constant]] belong to form = \"position-dependent\"".into(),
            ));
        }
        let Some(axis_name) = &p.axis else {
            return Err(err(
                &p.name,
                format!("{pkey}.axis"),
                "a regression part needs `axis`, the direction of the error it describes".into(),
            ));
        };
        let axis = self.listed_axis(machine, axis_name, format!("{pkey}.axis"))?;
        let mut summands = Vec::new();
        for (ti, t) in p.terms.iter().enumerate() {
            let tkey = format!("{pkey}.terms[{ti}]");
            let difference =
                self.listed_difference(machine, &t.difference, format!("{tkey}.difference"))?;
            let k = finite(t.k_um_per_k, &t.difference, format!("{tkey}.k_um_per_k"))?;
            summands.push(Summand {
                axis,
                difference,
                k0_um_per_k: k,
                position_terms: Vec::new(),
                bed_multiplier: None,
            });
        }
        let mut constants_um = Vec::new();
        if let Some(c) = p.constant_um {
            constants_um.push((axis, finite(c, axis_name, format!("{pkey}.constant_um"))?));
        }
        Ok((summands, constants_um))
    }
}

/// A name a part references must be one of those its model lists in `section`; the error names
/// what is listed, so the fix is visible without opening the file.
fn require_listed<'a>(
    names: impl Iterator<Item = &'a Spanned<String>> + Clone,
    s: &Spanned<String>,
    key: String,
    what: &str,
    section: &str,
) -> Result<(), BindError> {
    if names.clone().any(|n| n.get_ref() == s.get_ref()) {
        return Ok(());
    }
    let listed: Vec<&str> = names.map(|n| n.get_ref().as_str()).collect();
    let listed = if listed.is_empty() {
        "none".into()
    } else {
        listed.join(", ")
    };
    Err(err(
        s,
        key,
        format!(
            "{what} `{}` is not listed in {section} (listed: {listed})",
            s.get_ref()
        ),
    ))
}

/// An error at the span of `s`.
fn err(s: &Spanned<String>, key: String, msg: String) -> BindError {
    (s.span(), key, msg)
}

/// A coefficient must be finite; an error points at `s`, the entry it belongs to.
fn finite(v: f64, s: &Spanned<String>, key: String) -> Result<f64, BindError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(err(s, key, "expected a finite coefficient".into()))
    }
}

/// Input difference `i` is the machine's: same sensors, same lags, same reference.
fn check_input_difference(
    machine: &Machine,
    i: usize,
    d: &InputDifference,
) -> Result<(), BindError> {
    let key = format!("inputs.differences[{i}]");
    let Some(di) = machine.difference_index(d.name.get_ref()) else {
        return Err(err(
            &d.name,
            format!("{key}.name"),
            format!(
                "the model needs temperature difference `{}`, which machine `{}` does not define",
                d.name.get_ref(),
                machine.name
            ),
        ));
    };
    let def = &machine.differences[di];
    let machine_plus = &machine.temperatures[def.plus].id;
    let machine_minus = match def.minus {
        Reference::Sensor(s) => machine.temperatures[s].id.clone(),
        Reference::Fixed(t) => format!("{t} °C"),
    };
    let model_minus = match (&d.minus, &d.minus_fixed) {
        (Some(m), None) => m.get_ref().clone(),
        (None, Some(t)) => format!("{} °C", t.get_ref()),
        _ => {
            return Err(err(
                &d.name,
                key,
                "expected exactly one of `minus` (a sensor) or `minus_fixed` (°C)".into(),
            ))
        }
    };
    let lag_of = |l: &Option<Spanned<String>>| l.as_ref().map(|s| s.get_ref().clone());
    let machine_lags = (
        lag_text(machine, def.plus),
        match def.minus {
            Reference::Sensor(s) => lag_text(machine, s),
            Reference::Fixed(_) => None,
        },
    );
    if (lag_of(&d.plus_lag), lag_of(&d.minus_lag)) != machine_lags {
        let show = |l: &Option<String>| l.clone().unwrap_or_else(|| "measured".into());
        return Err(err(
            &d.name,
            format!("{key}.plus_lag"),
            format!(
                "the model was made for `{}` with channels ({}; {}), but the machine defines them as ({}; {})",
                d.name.get_ref(),
                show(&lag_of(&d.plus_lag)),
                show(&lag_of(&d.minus_lag)),
                show(&machine_lags.0),
                show(&machine_lags.1),
            ),
        ));
    }
    if d.plus.get_ref() != machine_plus || model_minus != machine_minus {
        return Err(err(
            &d.name,
            format!("{key}.name"),
            format!(
                "the model was made for `{}` = {} − {}, but the machine defines it as {} − {}",
                d.name.get_ref(),
                d.plus.get_ref(),
                model_minus,
                machine_plus,
                machine_minus
            ),
        ));
    }
    Ok(())
}
