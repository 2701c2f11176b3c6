//! Physical parameters of the twin, and the twin description file that overrides them.
//!
//! The topology and the dimensions are those of the reference machine (see [`crate::twin`]);
//! a twin description (`examples/twin/twin.toml` lists every parameter with its reference value)
//! changes materials, how the castings conduct and store heat, convection, joints, heat-source
//! laws, coolant and sensor lags — e.g. a machine with a spindle chiller
//! (`examples/twin/twin-chilled.toml`). Every key is optional; what is not given keeps its
//! reference value.
//!
//! ```toml
//! [twin]
//! name = "twin-vmc3-chilled"
//! convection_w_m2k = 9.0
//! [twin.head]                 # also bed, column, saddle, table
//! alpha_per_k = 10.5e-6
//! density_kg_m3 = 7200.0
//! specific_heat_j_kg_k = 460.0
//! conductivity_w_m_k = 48.0
//! fill = 0.4                  # metal share of the bounding box (heat capacity)
//! web = 0.15                  # share that conducts (ribs, walls)
//! [twin.joints]               # W/K
//! column_bed = 40.0
//! [twin.drive.X]              # P = p0 + c1·|v| + c2·v², v in m/min
//! p0_w = 6.0
//! [twin.spindle]              # P = a·n + b·n², n in 1000/min
//! front_a = 5.0
//! [twin.coolant]
//! w_per_k = 20.0
//! [twin.sensor_tau_s]         # first-order lag of individual sensors, s
//! spindle_front = 90.0
//! ```

use std::collections::BTreeMap;

use serde::Deserialize;

use crate::beam::Material;
use crate::scenario::checker::{toml_error, Checker, Seg};
use crate::twin::{DriveHeat, SpindleHeat};
use truepos_files::InputError;

/// Material and casting of one part.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PartParams {
    /// Material.
    pub material: Material,
    /// Metal share of the bounding box (heat capacity).
    pub fill: f64,
    /// Share of the section that conducts heat.
    pub web: f64,
}

/// Conductances of the joints between parts, W/K.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointParams {
    /// Column foot to bed.
    pub column_bed: f64,
    /// Saddle to bed (through the Y guides).
    pub saddle_bed: f64,
    /// Table to saddle (through the X guides).
    pub table_saddle: f64,
    /// Head to column (through the Z guides).
    pub head_column: f64,
    /// Spindle front bearing to the head's lower slice.
    pub spindle_front_head: f64,
    /// Spindle rear bearing to the head's middle slice.
    pub spindle_rear_head: f64,
    /// Spindle motor to the head's upper slice.
    pub spindle_motor_head: f64,
}

/// Coolant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CoolantParams {
    /// Exchange with the table top while it flows, W/K.
    pub w_per_k: f64,
    /// Steady rise of the tank above ambient while the pump runs, K.
    pub rise_k: f64,
    /// Time constant of the tank, s.
    pub tau_s: f64,
}

/// All physical parameters of the twin.
#[derive(Debug, Clone, PartialEq)]
pub struct TwinParams {
    /// Machine name.
    pub name: String,
    /// Convection and radiation from exposed faces, W/(m²·K).
    pub convection_w_m2k: f64,
    /// Temperature of the nominal geometry, °C.
    pub reference_temperature_c: f64,
    /// Bed.
    pub bed: PartParams,
    /// Column.
    pub column: PartParams,
    /// Y saddle.
    pub saddle: PartParams,
    /// X table.
    pub table: PartParams,
    /// Z head.
    pub head: PartParams,
    /// Joints.
    pub joints: JointParams,
    /// Drives X, Y, Z.
    pub drives: [DriveHeat; 3],
    /// Spindle losses.
    pub spindle: SpindleHeat,
    /// Coolant.
    pub coolant: CoolantParams,
    /// Sensor lags overriding the defaults, s, by sensor id.
    pub sensor_tau_s: BTreeMap<String, f64>,
}

impl Default for TwinParams {
    /// The reference machine's values.
    fn default() -> Self {
        let part = |fill, web| PartParams {
            material: Material::CAST_IRON,
            fill,
            web,
        };
        TwinParams {
            name: "twin-vmc3".into(),
            convection_w_m2k: 9.0,
            reference_temperature_c: 20.0,
            bed: part(0.35, 0.12),
            column: part(0.3, 0.1),
            saddle: part(0.4, 0.12),
            table: part(0.45, 0.12),
            head: part(0.4, 0.15),
            joints: JointParams {
                column_bed: 40.0,
                saddle_bed: 12.0,
                table_saddle: 10.0,
                head_column: 8.0,
                spindle_front_head: 10.0,
                spindle_rear_head: 6.0,
                spindle_motor_head: 5.0,
            },
            drives: [
                DriveHeat {
                    p0_w: 6.0,
                    c1_w_per_m_min: 5.0,
                    c2_w_per_m_min2: 0.3,
                },
                DriveHeat {
                    p0_w: 8.0,
                    c1_w_per_m_min: 6.0,
                    c2_w_per_m_min2: 0.4,
                },
                DriveHeat {
                    p0_w: 35.0,
                    c1_w_per_m_min: 5.0,
                    c2_w_per_m_min2: 0.3,
                },
            ],
            spindle: SpindleHeat {
                front_a: 5.0,
                front_b: 0.9,
                rear_share: 0.5,
                motor_a: 6.0,
                motor_b: 0.8,
                rotor_share: 0.2,
            },
            coolant: CoolantParams {
                w_per_k: 20.0,
                rise_k: 3.0,
                tau_s: 3600.0,
            },
            sensor_tau_s: BTreeMap::new(),
        }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileRoot {
    twin: FileTwin,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct FileTwin {
    name: Option<String>,
    convection_w_m2k: Option<f64>,
    reference_temperature_c: Option<f64>,
    bed: Option<FilePart>,
    column: Option<FilePart>,
    saddle: Option<FilePart>,
    table: Option<FilePart>,
    head: Option<FilePart>,
    joints: Option<BTreeMap<String, f64>>,
    drive: Option<BTreeMap<String, BTreeMap<String, f64>>>,
    spindle: Option<BTreeMap<String, f64>>,
    coolant: Option<BTreeMap<String, f64>>,
    sensor_tau_s: Option<BTreeMap<String, f64>>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct FilePart {
    alpha_per_k: Option<f64>,
    density_kg_m3: Option<f64>,
    specific_heat_j_kg_k: Option<f64>,
    conductivity_w_m_k: Option<f64>,
    fill: Option<f64>,
    web: Option<f64>,
}

/// Sensor ids of the reference machine (the keys `sensor_tau_s` accepts).
pub const SENSOR_IDS: [&str; 16] = [
    "ambient",
    "bed_top",
    "bed_bottom",
    "column_front",
    "column_rear",
    "column_top",
    "y_saddle_top",
    "y_saddle_bottom",
    "x_table_top",
    "x_table_bottom",
    "z_head_front",
    "z_head_rear",
    "spindle_front",
    "spindle_rear",
    "spindle_motor",
    "coolant",
];

impl TwinParams {
    /// Reads a twin description; errors name the file, line, column, key and what was expected.
    pub fn parse(src: &str, file: &str) -> Result<TwinParams, InputError> {
        use Seg::Key as K;
        let raw: FileRoot = toml::from_str(src).map_err(|e| toml_error(src, file, &e))?;
        let ck = &Checker::new(src, file);
        let t = raw.twin;
        let mut p = TwinParams::default();
        if let Some(n) = t.name {
            if n.trim().is_empty() {
                return Err(ck.err(&[K("twin"), K("name")], "a non-empty name"));
            }
            p.name = n;
        }
        set(
            ck,
            t.convection_w_m2k,
            &[K("twin"), K("convection_w_m2k")],
            0.0,
            1000.0,
            "a coefficient in W/(m²·K)",
            &mut p.convection_w_m2k,
        )?;
        set(
            ck,
            t.reference_temperature_c,
            &[K("twin"), K("reference_temperature_c")],
            -20.0,
            60.0,
            "a temperature in °C",
            &mut p.reference_temperature_c,
        )?;
        read_parts(
            ck,
            [
                ("bed", t.bed, &mut p.bed),
                ("column", t.column, &mut p.column),
                ("saddle", t.saddle, &mut p.saddle),
                ("table", t.table, &mut p.table),
                ("head", t.head, &mut p.head),
            ],
        )?;
        read_joints(ck, t.joints, &mut p.joints)?;
        read_spindle_and_coolant(ck, t.spindle, t.coolant, &mut p)?;
        read_drives(ck, t.drive, &mut p)?;
        read_sensor_taus(ck, t.sensor_tau_s, &mut p)?;
        Ok(p)
    }
}

/// Sets `into` from an optional value checked to lie within [lo, hi].
fn set(
    ck: &Checker,
    v: Option<f64>,
    path: &[Seg],
    lo: f64,
    hi: f64,
    what: &str,
    into: &mut f64,
) -> Result<(), InputError> {
    if let Some(v) = v {
        *into = ck.within(path, v, lo, hi, what)?;
    }
    Ok(())
}

/// A field of a keyed table: its key, where it goes, its range and what it is.
type Field<'a> = (&'a str, &'a mut f64, f64, f64, &'a str);

/// Reads the keyed table `[twin.TABLE]` into `fields`; an unknown key is named with the keys
/// it may have.
fn map_into(
    ck: &Checker,
    m: Option<BTreeMap<String, f64>>,
    table: &str,
    fields: &mut [Field<'_>],
) -> Result<(), InputError> {
    use Seg::Key as K;
    for (k, v) in m.unwrap_or_default() {
        let path = [K("twin"), K(table), K(k.as_str())];
        match fields.iter_mut().find(|f| f.0 == k) {
            Some(f) => *f.1 = ck.within(&path, v, f.2, f.3, f.4)?,
            None => {
                let names: Vec<&str> = fields.iter().map(|f| f.0).collect();
                return Err(ck.err(&path, format!("one of the keys {}", names.join(", "))));
            }
        }
    }
    Ok(())
}

/// The structural parts' materials and section shares.
fn read_parts(
    ck: &Checker,
    parts: [(&str, Option<FilePart>, &mut PartParams); 5],
) -> Result<(), InputError> {
    use Seg::Key as K;
    for (name, part, target) in parts {
        let Some(f) = part else { continue };
        let path = |k| [K("twin"), K(name), K(k)];
        set(
            ck,
            f.alpha_per_k,
            &path("alpha_per_k"),
            -1e-4,
            1e-4,
            "an expansion coefficient in 1/K",
            &mut target.material.alpha_per_k,
        )?;
        set(
            ck,
            f.density_kg_m3,
            &path("density_kg_m3"),
            100.0,
            30_000.0,
            "a density in kg/m³",
            &mut target.material.density_kg_m3,
        )?;
        set(
            ck,
            f.specific_heat_j_kg_k,
            &path("specific_heat_j_kg_k"),
            50.0,
            5000.0,
            "a specific heat in J/(kg·K)",
            &mut target.material.specific_heat_j_kg_k,
        )?;
        set(
            ck,
            f.conductivity_w_m_k,
            &path("conductivity_w_m_k"),
            0.01,
            1000.0,
            "a conductivity in W/(m·K)",
            &mut target.material.conductivity_w_m_k,
        )?;
        set(
            ck,
            f.fill,
            &path("fill"),
            0.01,
            1.0,
            "a share",
            &mut target.fill,
        )?;
        set(
            ck,
            f.web,
            &path("web"),
            0.001,
            1.0,
            "a share",
            &mut target.web,
        )?;
    }
    Ok(())
}

/// The conductances of the joints between parts (W/K).
fn read_joints(
    ck: &Checker,
    m: Option<BTreeMap<String, f64>>,
    j: &mut JointParams,
) -> Result<(), InputError> {
    map_into(
        ck,
        m,
        "joints",
        &mut [
            (
                "column_bed",
                &mut j.column_bed,
                0.0,
                1e5,
                "a conductance in W/K",
            ),
            (
                "saddle_bed",
                &mut j.saddle_bed,
                0.0,
                1e5,
                "a conductance in W/K",
            ),
            (
                "table_saddle",
                &mut j.table_saddle,
                0.0,
                1e5,
                "a conductance in W/K",
            ),
            (
                "head_column",
                &mut j.head_column,
                0.0,
                1e5,
                "a conductance in W/K",
            ),
            (
                "spindle_front_head",
                &mut j.spindle_front_head,
                0.0,
                1e5,
                "a conductance in W/K",
            ),
            (
                "spindle_rear_head",
                &mut j.spindle_rear_head,
                0.0,
                1e5,
                "a conductance in W/K",
            ),
            (
                "spindle_motor_head",
                &mut j.spindle_motor_head,
                0.0,
                1e5,
                "a conductance in W/K",
            ),
        ],
    )
}

/// The spindle's losses and the coolant.
fn read_spindle_and_coolant(
    ck: &Checker,
    spindle: Option<BTreeMap<String, f64>>,
    coolant: Option<BTreeMap<String, f64>>,
    p: &mut TwinParams,
) -> Result<(), InputError> {
    let s = &mut p.spindle;
    map_into(
        ck,
        spindle,
        "spindle",
        &mut [
            ("front_a", &mut s.front_a, 0.0, 1e4, "W per 1000/min"),
            ("front_b", &mut s.front_b, 0.0, 1e4, "W per (1000/min)²"),
            (
                "rear_share",
                &mut s.rear_share,
                0.0,
                10.0,
                "a share of the front bearing's losses",
            ),
            ("motor_a", &mut s.motor_a, 0.0, 1e4, "W per 1000/min"),
            ("motor_b", &mut s.motor_b, 0.0, 1e4, "W per (1000/min)²"),
            (
                "rotor_share",
                &mut s.rotor_share,
                0.0,
                1.0,
                "a share between 0 and 1",
            ),
        ],
    )?;
    let c = &mut p.coolant;
    map_into(
        ck,
        coolant,
        "coolant",
        &mut [
            ("w_per_k", &mut c.w_per_k, 0.0, 1e4, "a conductance in W/K"),
            (
                "rise_k",
                &mut c.rise_k,
                -20.0,
                20.0,
                "a temperature rise in K",
            ),
            ("tau_s", &mut c.tau_s, 1.0, 1e6, "a time constant in s"),
        ],
    )
}

/// The feed drives' losses per axis.
fn read_drives(
    ck: &Checker,
    drive: Option<BTreeMap<String, BTreeMap<String, f64>>>,
    p: &mut TwinParams,
) -> Result<(), InputError> {
    use Seg::Key as K;
    for (axis, fields) in drive.unwrap_or_default() {
        let Some(a) = ["X", "Y", "Z"].iter().position(|n| *n == axis) else {
            return Err(ck.err(
                &[K("twin"), K("drive"), K(axis.as_str())],
                "one of the axes X, Y, Z",
            ));
        };
        let d = &mut p.drives[a];
        for (k, v) in fields {
            let path = [K("twin"), K("drive"), K(axis.as_str()), K(k.as_str())];
            let (slot, what) = match k.as_str() {
                "p0_w" => (&mut d.p0_w, "a power in W"),
                "c1_w_per_m_min" => (&mut d.c1_w_per_m_min, "W per m/min"),
                "c2_w_per_m_min2" => (&mut d.c2_w_per_m_min2, "W per (m/min)²"),
                _ => {
                    return Err(ck.err(
                        &path,
                        "one of the keys p0_w, c1_w_per_m_min, c2_w_per_m_min2",
                    ))
                }
            };
            *slot = ck.within(&path, v, 0.0, 1e4, what)?;
        }
    }
    Ok(())
}

/// Sensor time constants that differ from the built-in ones.
fn read_sensor_taus(
    ck: &Checker,
    taus: Option<BTreeMap<String, f64>>,
    p: &mut TwinParams,
) -> Result<(), InputError> {
    use Seg::Key as K;
    for (id, v) in taus.unwrap_or_default() {
        let path = [K("twin"), K("sensor_tau_s"), K(id.as_str())];
        if !SENSOR_IDS.contains(&id.as_str()) {
            return Err(ck.err(&path, format!("a sensor id ({})", SENSOR_IDS.join(", "))));
        }
        let v = ck.within(&path, v, 0.0, 1e5, "a time constant in s")?;
        p.sensor_tau_s.insert(id, v);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overrides_and_errors() {
        let p = TwinParams::parse(
            "[twin]\nname = \"x\"\n[twin.head]\nweb = 0.3\n[twin.drive.Z]\np0_w = 0.0\n[twin.sensor_tau_s]\nspindle_front = 20\n",
            "t.toml",
        )
        .unwrap();
        assert_eq!(p.name, "x");
        assert_eq!(p.head.web, 0.3);
        assert_eq!(
            p.head.fill, 0.4,
            "unspecified keys keep the reference value"
        );
        assert_eq!(p.drives[2].p0_w, 0.0);
        assert_eq!(p.sensor_tau_s["spindle_front"], 20.0);

        let e = TwinParams::parse("[twin]\n[twin.table]\nfill = 1.5\n", "t.toml").unwrap_err();
        assert_eq!(
            (
                e.position.map_or(0, |p| p.0),
                e.key.as_deref().unwrap_or("")
            ),
            (3, "twin.table.fill")
        );
        assert!(e.message.contains("share"), "{e}");
        let e = TwinParams::parse("[twin]\n[twin.spindle]\nfront_c = 1\n", "t.toml").unwrap_err();
        assert_eq!(
            (
                e.position.map_or(0, |p| p.0),
                e.key.as_deref().unwrap_or("")
            ),
            (3, "twin.spindle.front_c")
        );
        assert!(e.message.contains("front_a"), "{e}");
        let e = TwinParams::parse(
            "[twin]\n\n[twin.sensor_tau_s]\nspindle_nose = 3\n",
            "t.toml",
        )
        .unwrap_err();
        assert_eq!(
            (
                e.position.map_or(0, |p| p.0),
                e.key.as_deref().unwrap_or("")
            ),
            (4, "twin.sensor_tau_s.spindle_nose")
        );
        let e = TwinParams::parse("[twin]\nconvection = 3\n", "t.toml").unwrap_err();
        assert_eq!(e.position.map_or(0, |p| p.0), 2);
        assert!(e.message.contains("unknown field"), "{e}");
    }
}
