//! The model as a file: [`ModelFile::from_model`] lists the inputs a bound model reads and
//! writes each part in the entries of its form; binding is the inverse.

use super::*;

impl ModelFile {
    /// Describes a bound model as a file: the inputs are the axes and differences it reads.
    pub fn from_model(model: &Model, machine: &Machine) -> Self {
        let axis_name = |a: usize| spanned(machine.axes[a].name.clone());
        let mut used_diffs: Vec<usize> = model.used_differences().to_vec();
        used_diffs.sort_unstable();
        let part = model
            .parts()
            .iter()
            .map(|p| match p.form {
                PartForm::Regression if regression_shaped(p) => regression_entry(p, machine),
                _ => position_entry(p, machine),
            })
            .collect();
        ModelFile {
            format: spanned(FORMAT.into()),
            version: spanned(VERSION),
            form: Some(spanned(FORM_POSITION.to_string())),
            name: spanned(model.name().into()),
            machine: spanned(machine.name.clone()),
            description: String::new(),
            axis_index: None,
            inputs: Inputs {
                axes: axes_used(model)
                    .iter()
                    .map(|&a| InputAxis {
                        name: axis_name(a),
                        travel: spanned([machine.axes[a].travel_min, machine.axes[a].travel_max]),
                    })
                    .collect(),
                differences: used_diffs
                    .iter()
                    .map(|&d| input_difference(machine, d))
                    .collect(),
            },
            part,
            provenance: toml::Table::new(),
            validation: toml::Table::new(),
            training_envelope: model
                .envelope()
                .map(|env| EnvelopeEntry::from_envelope(env, machine)),
        }
    }

    /// The file as TOML text, its checksum on the first line.
    pub fn to_toml(&self) -> String {
        match toml::to_string_pretty(self) {
            Ok(text) => with_checksum(&text),
            Err(e) => format!("# cannot serialise: {e}\n"),
        }
    }
}

/// The axes a model reads, in the machine's order: every term's axis, position axes, bed
/// multipliers and constants' axes. The file lists them as the model's inputs.
fn axes_used(model: &Model) -> Vec<usize> {
    let mut axes_used: Vec<usize> = Vec::new();
    let mut use_axis = |a: usize| {
        if !axes_used.contains(&a) {
            axes_used.push(a);
        }
    };
    for p in model.parts() {
        for s in &p.summands {
            use_axis(s.axis);
            s.position_terms.iter().for_each(|t| use_axis(t.axis));
            if let Some(b) = s.bed_multiplier {
                use_axis(b);
            }
        }
        p.constants_um.iter().for_each(|c| use_axis(c.0));
    }
    axes_used.sort_unstable();
    axes_used
}

/// A reference-sensor regression written in its own short form: one axis, a coefficient per
/// difference and a constant.
fn regression_entry(p: &Part, machine: &Machine) -> PartEntry {
    let axis_name = |a: usize| spanned(machine.axes[a].name.clone());
    let diff_name = |d: usize| spanned(machine.differences[d].name.clone());
    PartEntry {
        name: spanned(p.name.clone()),
        form: FormEntry::Regression,
        enabled: p.enabled,
        term: vec![],
        constant: vec![],
        axis: p
            .summands
            .first()
            .map(|s| s.axis)
            .or(p.constants_um.first().map(|c| c.0))
            .map(axis_name),
        terms: p
            .summands
            .iter()
            .map(|s| RegressionTermEntry {
                difference: diff_name(s.difference),
                k_um_per_k: s.k0_um_per_k,
            })
            .collect(),
        constant_um: p.constants_um.first().map(|c| c.1),
    }
}

/// A position-dependent part: per term its axis, difference, coefficient, position factors
/// and bed multiplier, then the per-axis constants.
fn position_entry(p: &Part, machine: &Machine) -> PartEntry {
    let axis_name = |a: usize| spanned(machine.axes[a].name.clone());
    let diff_name = |d: usize| spanned(machine.differences[d].name.clone());
    let factor = |f: PositionFactor| match f {
        PositionFactor::Ratio => FactorEntry::Ratio,
        PositionFactor::RatioSquared => FactorEntry::RatioSquared,
        PositionFactor::BedFactor => FactorEntry::Bed,
    };
    PartEntry {
        name: spanned(p.name.clone()),
        form: FormEntry::PositionDependent,
        enabled: p.enabled,
        term: p
            .summands
            .iter()
            .map(|s| TermEntry {
                axis: axis_name(s.axis),
                difference: diff_name(s.difference),
                k0_um_per_k: s.k0_um_per_k,
                position: s
                    .position_terms
                    .iter()
                    .map(|t| PositionEntry {
                        axis: axis_name(t.axis),
                        factor: Some(factor(t.factor)),
                        k_um_per_k: t.k_um_per_k,
                    })
                    .collect(),
                bed_multiplier: s.bed_multiplier.map(axis_name),
            })
            .collect(),
        constant: p
            .constants_um
            .iter()
            .map(|&(a, v)| ConstantEntry {
                axis: axis_name(a),
                value_um: v,
            })
            .collect(),
        axis: None,
        terms: vec![],
        constant_um: None,
    }
}

/// Difference `d` as the file states it: by its sensors' ids (or a fixed reference) and
/// their lag filters, so that loading can check it against the machine file in use.
fn input_difference(machine: &Machine, d: usize) -> InputDifference {
    let def = &machine.differences[d];
    let (minus, minus_fixed) = match def.minus {
        Reference::Sensor(s) => (Some(spanned(machine.temperatures[s].id.clone())), None),
        Reference::Fixed(t) => (None, Some(spanned(t))),
    };
    InputDifference {
        name: spanned(def.name.clone()),
        plus: spanned(machine.temperatures[def.plus].id.clone()),
        minus,
        minus_fixed,
        plus_lag: lag_text(machine, def.plus).map(spanned),
        minus_lag: match def.minus {
            Reference::Sensor(s) => lag_text(machine, s).map(spanned),
            Reference::Fixed(_) => None,
        },
    }
}

/// A regression part has one axis, no position terms, no bed multiplier and at most one constant.
fn regression_shaped(p: &Part) -> bool {
    let axis = p
        .summands
        .first()
        .map(|s| s.axis)
        .or(p.constants_um.first().map(|c| c.0));
    p.constants_um.len() <= 1
        && p.summands.iter().all(|s| {
            Some(s.axis) == axis && s.position_terms.is_empty() && s.bed_multiplier.is_none()
        })
        && p.constants_um.iter().all(|c| Some(c.0) == axis)
}
