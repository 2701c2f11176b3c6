//! The reference machine: a 3-axis vertical machining centre, its thermal network, heat
//! sources, sensor spots and its serial kinematic chain.
//!
//! ## Layout (world axes: x to the right, y to the rear, z up; mm; origin on the bed's top
//! face under the spindle)
//! ```text
//!            ┌──┐ Z motor                    tool side:  bed → column → Z head → spindle → tool
//!            │  │ column (1600 high)          work side:  bed → Y saddle → X table → workpiece
//!       ┌────┤  │
//!       │head│  │  Z: head slides on the column front, Z = 0 … 500 (tool up = +Z)
//!       └─┬──┤  │
//!         │spindle
//!   ┌─────┴───────┐  X table (1000 × 450 × 120) on the saddle, X = 0 … 800
//!   ├─────────────┤  Y saddle (1000 × 450 × 150) on the bed,   Y = 0 … 500
//! ══╧═════════════╧══ bed (1200 long in y, 800 wide, 300 high) on two feet
//! ```
//! Axis positions are the nominal tool position relative to the workpiece: X moves the table to
//! −x (the tool goes +X over the workpiece), Y moves the saddle to −y (the tool goes +Y), Z lifts
//! the head. X rests on Y (serial), Y and Z on the bed. Positions are read by linear scales that
//! follow the carrying part, so a carried part sits at the carrier's material point that the
//! reading names; ball-screw growth does not enter. Each carried part takes the pose of its
//! carrier's guideway at its carriage (a bent guideway tilts and lifts whatever rides on it).
//!
//! The error is the tool tip's displacement minus the displacement of the workpiece point that
//! is nominally under the tool (a 100 mm steel block on the table, kept at the table top's
//! pose), in µm: error = actual − nominal.

use crate::beam::{Beam, Material, Shape, Support};
use crate::deviation::{sub, Deviation, Vec3};
use crate::network::{Network, Stepper};
use crate::params::TwinParams;

/// Axis names in control order.
pub const AXES: [&str; 3] = ["X", "Y", "Z"];

/// Power law of an axis drive's heat: `P = p0 + c1·|v| + c2·v²`, v in m/min.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriveHeat {
    /// Power with the servo on at standstill (motor holding current), W.
    pub p0_w: f64,
    /// Linear friction coefficient, W per m/min.
    pub c1_w_per_m_min: f64,
    /// Quadratic (viscous) coefficient, W per (m/min)².
    pub c2_w_per_m_min2: f64,
}

impl DriveHeat {
    /// Friction power (W) at `v_mm_min` (excluding `p0`).
    pub fn friction_w(&self, v_mm_min: f64) -> f64 {
        let v = v_mm_min.abs() / 1000.0;
        self.c1_w_per_m_min * v + self.c2_w_per_m_min2 * v * v
    }
}

/// Power laws of the spindle: bearings and motor, `P = a·n + b·n²`, n in 1000/min.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpindleHeat {
    /// Front bearing set, linear term (W per 1000/min).
    pub front_a: f64,
    /// Front bearing set, quadratic term (W per (1000/min)²).
    pub front_b: f64,
    /// Rear bearing losses as a share of the front's.
    pub rear_share: f64,
    /// Motor losses, linear term (W per 1000/min).
    pub motor_a: f64,
    /// Motor losses, quadratic term (W per (1000/min)²).
    pub motor_b: f64,
    /// Share of the motor losses that heats the rotor (shaft); the rest heats the stator.
    pub rotor_share: f64,
}

/// Where a sensor reads.
#[derive(Debug, Clone, PartialEq)]
pub enum Spot {
    /// The mean of these network nodes.
    Nodes(Vec<usize>),
    /// The ambient air.
    Ambient,
    /// The coolant.
    Coolant,
}

/// A temperature sensor of the twin.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorSpec {
    /// Identifier (the CSV column).
    pub id: String,
    /// Where it sits, for people.
    pub location: String,
    /// What it reads.
    pub spot: Spot,
    /// Time constant of its first-order lag in s (a sensor in a bore lags the metal).
    pub tau_s: f64,
}

/// Indices of the spindle cartridge's nodes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpindleNodes {
    /// Front bearing set and housing.
    pub front: usize,
    /// Rear bearing set.
    pub rear: usize,
    /// Shaft (rotor).
    pub shaft: usize,
    /// Motor stator.
    pub motor: usize,
}

/// The thermal twin of one machine: structure, network, heat sources and sensors.
#[derive(Debug, Clone)]
pub struct Twin {
    /// Machine name (matches `examples/twin/machine.toml`).
    pub name: String,
    /// Lumped thermal network.
    pub network: Network,
    /// Bed (along y).
    pub bed: Beam,
    /// Column (along z, front = −y).
    pub column: Beam,
    /// Y saddle (along x), carries the X table.
    pub saddle: Beam,
    /// X table (along x), carries the workpiece.
    pub table: Beam,
    /// Z spindle head (along z, front = −y).
    pub head: Beam,
    /// Spindle cartridge nodes.
    pub spindle: SpindleNodes,
    /// Travel of X, Y, Z in mm: `[min, max]`.
    pub travel_mm: [[f64; 2]; 3],
    /// Heat of the X, Y and Z drives.
    pub drives: [DriveHeat; 3],
    /// Heat of the spindle.
    pub spindle_heat: SpindleHeat,
    /// Conductance between the coolant and the table top when the coolant flows, W/K.
    pub coolant_w_per_k: f64,
    /// Steady rise of the coolant tank above ambient while the pump runs, K.
    pub coolant_rise_k: f64,
    /// Time constant of the coolant tank, s.
    pub coolant_tau_s: f64,
    /// Temperature at which the machine has its nominal geometry (ISO 1: 20 °C).
    pub t_ref_c: f64,
    /// Length from the front bearing to the tool tip that grows with the shaft, mm.
    pub spindle_growth_length_mm: f64,
    /// Tool tip below the head's bottom face, mm (spindle nose 120 + tool 100).
    pub tool_below_head_mm: f64,
    /// Height of the workpiece above the table top, mm.
    pub workpiece_height_mm: f64,
    /// Sensors.
    pub sensors: Vec<SensorSpec>,
}

/// Splits `power` over the slices of `beam` that overlap `[from, to]` (mm), by overlap, and over
/// the corners selected by `h` / `w` (`None` = both faces).
pub fn spread(
    beam: &Beam,
    from: f64,
    to: f64,
    h: Option<bool>,
    w: Option<bool>,
    power: f64,
    out: &mut Vec<(usize, f64)>,
) {
    let (from, to) = (from.max(0.0), to.min(beam.length_mm));
    let l = beam.slice_mm();
    let hs: &[bool] = match h {
        Some(true) => &[true],
        Some(false) => &[false],
        None => &[false, true],
    };
    let ws: &[bool] = match w {
        Some(true) => &[true],
        Some(false) => &[false],
        None => &[false, true],
    };
    let corners = (hs.len() * ws.len()) as f64;
    if to <= from {
        // A point load: the slice containing it.
        let seg = beam.slice_at(from);
        for &hh in hs {
            for &ww in ws {
                out.push((beam.node(seg, hh, ww), power / corners));
            }
        }
        return;
    }
    for seg in 0..beam.segments {
        let (a, b) = (seg as f64 * l, (seg + 1) as f64 * l);
        let overlap = (b.min(to) - a.max(from)).max(0.0);
        if overlap > 0.0 {
            let p = power * overlap / (to - from) / corners;
            for &hh in hs {
                for &ww in ws {
                    out.push((beam.node(seg, hh, ww), p));
                }
            }
        }
    }
}

/// Links every node of `a` to every node of `b` with a share of `total` W/K.
fn joint(net: &mut Network, a: &[usize], b: &[usize], total_w_per_k: f64) {
    let g = total_w_per_k / (a.len() * b.len()) as f64;
    for &i in a {
        for &j in b {
            net.link(i, j, g);
        }
    }
}

/// The nodes of `beam` on face `h` (`None` = all) in slices `segs`.
fn face(beam: &Beam, segs: std::ops::Range<usize>, h: Option<bool>) -> Vec<usize> {
    let mut v = Vec::new();
    for seg in segs {
        for hh in [false, true] {
            if h.is_none_or(|x| x == hh) {
                for w in [false, true] {
                    v.push(beam.node(seg, hh, w));
                }
            }
        }
    }
    v
}

/// Operating state over one step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Operating {
    /// Spindle speed, 1/min.
    pub spindle_rpm: f64,
    /// Axis positions (mm) in the middle of the step.
    pub position_mm: [f64; 3],
    /// Axis speeds (mm/min, magnitude).
    pub speed_mm_min: [f64; 3],
    /// Whether the coolant flows.
    pub coolant_on: bool,
    /// Whether the servos are on (drive holding losses).
    pub servo_on: bool,
}

impl Twin {
    /// The built-in reference machine (`twin-vmc3`, described for the other tools in
    /// `examples/twin/machine.toml`): 84 nodes, 16 sensors.
    pub fn reference() -> Self {
        Self::from_params(&TwinParams::default())
    }

    /// The reference topology with the given physical parameters (see [`TwinParams`]).
    pub fn from_params(p: &TwinParams) -> Self {
        let mut parts = Parts::reference(p);
        // Convection and radiation lumped: 9 W/(m²·K); exposed shares [−h, +h, −w, +w, ends].
        let h_conv = p.convection_w_m2k;
        let mut net = Network::default();
        parts
            .bed
            .add_to(&mut net, h_conv, [0.1, 0.5, 1.0, 1.0, 1.0]);
        parts
            .column
            .add_to(&mut net, h_conv, [1.0, 0.6, 1.0, 1.0, 0.5]);
        parts
            .saddle
            .add_to(&mut net, h_conv, [0.2, 0.4, 1.0, 1.0, 1.0]);
        parts
            .table
            .add_to(&mut net, h_conv, [0.3, 1.0, 1.0, 1.0, 1.0]);
        parts
            .head
            .add_to(&mut net, h_conv, [0.2, 1.0, 1.0, 1.0, 1.0]);
        let steel = 7850.0 * 470.0; // J/(m³·K)
        let spindle = SpindleNodes {
            front: net.add_node("spindle.front_bearing", 12.0 * 470.0, 1.5),
            rear: net.add_node("spindle.rear_bearing", 8.0 * 470.0, 0.5),
            shaft: net.add_node("spindle.shaft", 0.0011 * steel, 1.5),
            motor: net.add_node("spindle.motor", 30.0 * 470.0, 3.0),
        };
        parts.join(&mut net, &spindle, p);
        let sensors = parts.sensor_specs(&spindle, p);
        let Parts {
            bed,
            column,
            saddle,
            table,
            head,
        } = parts;
        Twin {
            name: p.name.clone(),
            network: net,
            bed,
            column,
            saddle,
            table,
            head,
            spindle,
            travel_mm: [[0.0, 800.0], [0.0, 500.0], [0.0, 500.0]],
            drives: p.drives,
            spindle_heat: p.spindle,
            coolant_w_per_k: p.coolant.w_per_k,
            coolant_rise_k: p.coolant.rise_k,
            coolant_tau_s: p.coolant.tau_s,
            t_ref_c: p.reference_temperature_c,
            spindle_growth_length_mm: 150.0,
            tool_below_head_mm: 220.0,
            workpiece_height_mm: 100.0,
            sensors,
        }
    }

    /// Number of thermal nodes.
    pub fn node_count(&self) -> usize {
        self.network.len()
    }

    /// The discretised network for a step of `h_s` seconds.
    pub fn stepper(&self, h_s: f64) -> Stepper {
        self.network.discretise(h_s)
    }

    /// Heat input (node, W) for one step of operation. The coolant term is added separately.
    pub fn heat(&self, op: &Operating, out: &mut Vec<(usize, f64)>) {
        let [px, py, pz] = op.position_mm;
        let servo = if op.servo_on { 1.0 } else { 0.0 };
        // X: table carriages at table stations 400…600, the saddle's X guides under them
        // (saddle station 900 − X), the X motor on the saddle's +x end.
        let fx = self.drives[0].friction_w(op.speed_mm_min[0]);
        spread(&self.table, 400.0, 600.0, Some(false), None, 0.4 * fx, out);
        let sx = 900.0 - px;
        spread(
            &self.saddle,
            sx - 100.0,
            sx + 100.0,
            Some(true),
            None,
            0.4 * fx,
            out,
        );
        spread(
            &self.saddle,
            900.0,
            1000.0,
            None,
            Some(false),
            0.2 * fx + servo * self.drives[0].p0_w,
            out,
        );
        // Y: saddle carriages at saddle stations 150…850 underneath, bed guides under the
        // saddle (bed station 800 − Y), the Y motor at the bed's front end.
        let fy = self.drives[1].friction_w(op.speed_mm_min[1]);
        spread(&self.saddle, 150.0, 850.0, Some(false), None, 0.4 * fy, out);
        let sy = 800.0 - py;
        spread(
            &self.bed,
            sy - 225.0,
            sy + 225.0,
            Some(true),
            None,
            0.4 * fy,
            out,
        );
        spread(
            &self.bed,
            0.0,
            150.0,
            Some(true),
            None,
            0.2 * fy + servo * self.drives[1].p0_w,
            out,
        );
        // Z: head carriages at head stations 200…400 on its rear face, column guides behind
        // them (column station 890 + Z), the Z motor (holding the head's weight) on the column top.
        let fz = self.drives[2].friction_w(op.speed_mm_min[2]);
        spread(&self.head, 200.0, 400.0, Some(false), None, 0.4 * fz, out);
        let sz = 890.0 + pz;
        spread(
            &self.column,
            sz - 100.0,
            sz + 100.0,
            Some(true),
            None,
            0.4 * fz,
            out,
        );
        spread(
            &self.column,
            1400.0,
            1600.0,
            Some(true),
            None,
            0.2 * fz + servo * self.drives[2].p0_w,
            out,
        );
        // Spindle.
        let n = op.spindle_rpm.abs() / 1000.0;
        let sh = &self.spindle_heat;
        let bearing = sh.front_a * n + sh.front_b * n * n;
        let motor = sh.motor_a * n + sh.motor_b * n * n;
        out.push((self.spindle.front, bearing));
        out.push((self.spindle.rear, sh.rear_share * bearing));
        out.push((self.spindle.shaft, sh.rotor_share * motor));
        out.push((self.spindle.motor, (1.0 - sh.rotor_share) * motor));
    }

    /// Heat from the coolant (node, W) at the current temperatures: it exchanges heat with the
    /// table top while it flows. Explicit in time; stable for `h < C_node/G` (≈ 10⁴ s here).
    pub fn coolant_heat(&self, temps_c: &[f64], coolant_c: f64, out: &mut Vec<(usize, f64)>) {
        let nodes = face(&self.table, 0..self.table.segments, Some(true));
        let g = self.coolant_w_per_k / nodes.len() as f64;
        for i in nodes {
            out.push((i, g * (coolant_c - temps_c[i])));
        }
    }

    /// The deformed structure at the given node temperatures.
    pub fn deformation(&self, temps_c: &[f64]) -> Deformed<'_> {
        let t = self.t_ref_c;
        Deformed {
            twin: self,
            bed: self.bed.shape(temps_c, t),
            column: self.column.shape(temps_c, t),
            saddle: self.saddle.shape(temps_c, t),
            table: self.table.shape(temps_c, t),
            head: self.head.shape(temps_c, t),
            shaft_dt: temps_c[self.spindle.shaft] - t,
        }
    }

    /// Ground-truth tool-tip error (dx, dy, dz in µm) at axis positions `pos` (X, Y, Z in mm).
    pub fn error_um(&self, temps_c: &[f64], pos_mm: [f64; 3]) -> [f64; 3] {
        self.deformation(temps_c).error_um(pos_mm)
    }
}

/// A part as a beam: its name, its directions (`axes`: along its length, height and width),
/// its size (`dims`: length, height and width in mm), the segments it is cut into, its material
/// and section (`part`), how it is supported and its datum along its length (mm).
fn beam(
    name: &str,
    [e_len, e_h, e_w]: [Vec3; 3],
    dims: [f64; 3],
    segments: usize,
    part: &crate::params::PartParams,
    support: Support,
    datum_mm: f64,
) -> Beam {
    Beam {
        name: name.into(),
        e_len,
        e_h,
        e_w,
        length_mm: dims[0],
        height_mm: dims[1],
        width_mm: dims[2],
        segments,
        material: part.material,
        fill: part.fill,
        web: part.web,
        support,
        datum_mm,
        support_offset_mm: 0.0,
        first_node: 0,
    }
}

/// The five structural parts of the reference machine, before they are put into a network.
struct Parts {
    bed: Beam,
    column: Beam,
    saddle: Beam,
    table: Beam,
    head: Beam,
}

impl Parts {
    /// The parts' geometry, supports and materials.
    fn reference(p: &TwinParams) -> Self {
        let (x, y, z) = ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]);
        let front = [0.0, -1.0, 0.0];
        let mut bed = beam(
            "bed",
            [y, z, x],
            [1200.0, 300.0, 800.0],
            4,
            &p.bed,
            Support::TwoPoint {
                a_mm: 150.0,
                b_mm: 1050.0,
            },
            600.0,
        );
        let column = beam(
            "column",
            [z, front, x],
            [1600.0, 400.0, 500.0],
            6,
            &p.column,
            Support::Clamped { at_mm: 0.0 },
            0.0,
        );
        let mut saddle = beam(
            "saddle",
            [x, z, y],
            [1000.0, 150.0, 450.0],
            3,
            &p.saddle,
            Support::TwoPoint {
                a_mm: 250.0,
                b_mm: 750.0,
            },
            500.0,
        );
        let mut table = beam(
            "table",
            [x, z, y],
            [1000.0, 120.0, 450.0],
            4,
            &p.table,
            Support::TwoPoint {
                a_mm: 400.0,
                b_mm: 600.0,
            },
            500.0,
        );
        let mut head = beam(
            "head",
            [z, front, x],
            [600.0, 350.0, 300.0],
            3,
            &p.head,
            Support::Clamped { at_mm: 300.0 },
            300.0,
        );

        // Bed, saddle and table rest on their bottom faces; the head is held at its rear face.
        bed.support_offset_mm = -bed.height_mm / 2.0;
        saddle.support_offset_mm = -saddle.height_mm / 2.0;
        table.support_offset_mm = -table.height_mm / 2.0;
        head.support_offset_mm = -head.height_mm / 2.0;
        Parts {
            bed,
            column,
            saddle,
            table,
            head,
        }
    }

    /// The thermal joints between the parts and the spindle's nodes (W/K).
    fn join(&self, net: &mut Network, spindle: &SpindleNodes, p: &TwinParams) {
        // Joints between parts (W/K).
        joint(
            net,
            &face(&self.column, 0..1, None),
            &face(&self.bed, 3..4, Some(true)),
            p.joints.column_bed,
        );
        joint(
            net,
            &face(&self.saddle, 0..3, Some(false)),
            &face(&self.bed, 0..4, Some(true)),
            p.joints.saddle_bed,
        );
        joint(
            net,
            &face(&self.table, 0..4, Some(false)),
            &face(&self.saddle, 0..3, Some(true)),
            p.joints.table_saddle,
        );
        joint(
            net,
            &face(&self.head, 0..3, Some(false)),
            &face(&self.column, 0..6, Some(true)),
            p.joints.head_column,
        );
        joint(
            net,
            &[spindle.front],
            &face(&self.head, 0..1, Some(true)),
            p.joints.spindle_front_head,
        );
        joint(
            net,
            &[spindle.rear],
            &face(&self.head, 1..2, Some(true)),
            p.joints.spindle_rear_head,
        );
        // The motor's terminal box and cable side sit on the head's +x side.
        net.link(
            spindle.motor,
            self.head.node(2, true, true),
            0.7 * p.joints.spindle_motor_head,
        );
        net.link(
            spindle.motor,
            self.head.node(2, true, false),
            0.3 * p.joints.spindle_motor_head,
        );
        net.link(spindle.shaft, spindle.front, 4.0);
        net.link(spindle.shaft, spindle.rear, 3.0);
        net.link(spindle.shaft, spindle.motor, 2.0);
    }

    /// The sensors: where each sits and its own time constant.
    fn sensor_specs(&self, spindle: &SpindleNodes, p: &TwinParams) -> Vec<SensorSpec> {
        let nodes = |b: &Beam, seg: usize, h: Option<bool>| Spot::Nodes(face(b, seg..seg + 1, h));
        let bore = 120.0;
        let s = |id: &str, location: &str, spot: Spot, tau_s: f64| SensorSpec {
            id: id.into(),
            location: location.into(),
            spot,
            tau_s,
        };
        let mut sensors = vec![
            s(
                "ambient",
                "air beside the machine, 1.5 m above the floor",
                Spot::Ambient,
                120.0,
            ),
            s(
                "bed_top",
                "bed, top face between the Y guides, centre",
                nodes(&self.bed, 1, Some(true)),
                bore,
            ),
            s(
                "bed_bottom",
                "bed, bottom flange, centre",
                nodes(&self.bed, 1, Some(false)),
                bore,
            ),
            s(
                "column_front",
                "column, front face between the Z guides, mid height",
                nodes(&self.column, 2, Some(true)),
                bore,
            ),
            s(
                "column_rear",
                "column, rear face, mid height",
                nodes(&self.column, 2, Some(false)),
                bore,
            ),
            s(
                "column_top",
                "column, top under the Z motor",
                nodes(&self.column, 5, None),
                bore,
            ),
            s(
                "y_saddle_top",
                "Y saddle, top under the X guides, centre",
                nodes(&self.saddle, 1, Some(true)),
                bore,
            ),
            s(
                "y_saddle_bottom",
                "Y saddle, underside near the Y ball-screw nut",
                nodes(&self.saddle, 1, Some(false)),
                bore,
            ),
            s(
                "x_table_top",
                "X table, top face edge, centre",
                nodes(&self.table, 2, Some(true)),
                bore,
            ),
            s(
                "x_table_bottom",
                "X table, underside near the X ball-screw nut",
                nodes(&self.table, 2, Some(false)),
                bore,
            ),
            s(
                "z_head_front",
                "spindle head, front face, mid height",
                nodes(&self.head, 1, Some(true)),
                bore,
            ),
            s(
                "z_head_rear",
                "spindle head, rear face near the Z guide carriages",
                nodes(&self.head, 1, Some(false)),
                bore,
            ),
            s(
                "spindle_front",
                "spindle housing at the front bearing set",
                Spot::Nodes(vec![spindle.front]),
                90.0,
            ),
            s(
                "spindle_rear",
                "spindle housing at the rear bearing",
                Spot::Nodes(vec![spindle.rear]),
                90.0,
            ),
            s(
                "spindle_motor",
                "spindle motor stator housing",
                Spot::Nodes(vec![spindle.motor]),
                90.0,
            ),
            s("coolant", "coolant return line", Spot::Coolant, 30.0),
        ];
        for sensor in &mut sensors {
            if let Some(tau) = p.sensor_tau_s.get(&sensor.id) {
                sensor.tau_s = *tau;
            }
        }
        sensors
    }
}

/// The structure deformed at one instant; evaluates the error anywhere in the working volume.
#[derive(Debug, Clone)]
pub struct Deformed<'a> {
    twin: &'a Twin,
    bed: Shape,
    column: Shape,
    saddle: Shape,
    table: Shape,
    head: Shape,
    shaft_dt: f64,
}

impl Deformed<'_> {
    /// Deviation of the workpiece point under the tool at axis positions `pos`.
    pub fn workpiece(&self, pos_mm: [f64; 3]) -> Deviation {
        let tw = self.twin;
        let [px, py, _] = pos_mm;
        let y_sc = 250.0 - py; // saddle centre (y)
        let x_tc = 400.0 - px; // table centre (x)
                               // Saddle on the bed's guides: bed top face at station 800 − Y.
        let s_bed = 800.0 - py;
        let base = Deviation::none_at([0.0; 3]);
        let on_bed = base.then(&self.bed.deviation(
            s_bed,
            tw.bed.height_mm / 2.0,
            0.0,
            [0.0, y_sc, 0.0],
        ));
        // Table on the saddle's X guides: saddle top face at station 900 − X.
        let s_saddle = 900.0 - px;
        let on_saddle = on_bed.then(&self.saddle.deviation(
            s_saddle,
            tw.saddle.height_mm / 2.0,
            0.0,
            [x_tc, y_sc, tw.saddle.height_mm],
        ));
        // Workpiece point: table station 100 + X, across the table by Y − 250, on top of the block.
        let top = tw.saddle.height_mm + tw.table.height_mm + tw.workpiece_height_mm;
        on_saddle.then(&self.table.deviation(
            100.0 + px,
            tw.table.height_mm / 2.0 + tw.workpiece_height_mm,
            py - 250.0,
            [0.0, 0.0, top],
        ))
    }

    /// Displacement of the tool tip at axis position Z (mm, world axes).
    pub fn tool(&self, pos_mm: [f64; 3]) -> Vec3 {
        let tw = self.twin;
        let pz = pos_mm[2];
        let base = Deviation::none_at([0.0; 3]);
        let col_foot = base.then(&self.bed.deviation(
            1000.0,
            tw.bed.height_mm / 2.0,
            0.0,
            [0.0, 450.0, 0.0],
        ));
        let s_col = 890.0 + pz;
        let head_mount = col_foot.then(&self.column.deviation(
            s_col,
            tw.column.height_mm / 2.0,
            0.0,
            [0.0, 250.0, s_col],
        ));
        let z_bottom = 590.0 + pz;
        let head_bottom =
            head_mount.then(&self.head.deviation(0.0, 75.0, 0.0, [0.0, 0.0, z_bottom]));
        let tip = [0.0, 0.0, z_bottom - tw.tool_below_head_mm];
        let mut d = head_bottom.displacement_of(tip);
        // The shaft grows from its front bearing towards the tool.
        d[2] -= Material::STEEL.alpha_per_k * self.shaft_dt * tw.spindle_growth_length_mm;
        d
    }

    /// Tool-tip error relative to the workpiece (µm): tool displacement − workpiece displacement.
    pub fn error_um(&self, pos_mm: [f64; 3]) -> [f64; 3] {
        let w = self.workpiece(pos_mm);
        // The workpiece frame, evaluated where the tool tip nominally is.
        let tip_nominal = [0.0, 0.0, w.at_mm[2] + pos_mm[2]];
        let e = sub(self.tool(pos_mm), w.displacement_of(tip_nominal));
        [e[0] * 1e3, e[1] * 1e3, e[2] * 1e3]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::beam::curvature;

    /// The whole machine 5 K above 20 °C (α = 10.5e-6 cast iron, 11.5e-6 steel shaft).
    /// Work side: bed top 300·αΔT up, saddle 150·αΔT, table to the workpiece top 220·αΔT:
    /// z = 670·αΔT; along x the saddle and table growths cancel; along y −50·αΔT.
    /// Tool side: bed top at the column 300·αΔT, column to the head carriages (890 + Z)·αΔT, head
    /// below its carriages −300·αΔT, shaft −150·α_s·ΔT: z = (890 + Z)·αΔT − 150·α_s·ΔT;
    /// y: bed +400, column front face −200, head rear face to the spindle −250 → −50·αΔT.
    /// dz = (220 + Z)·52.5e-6 mm − 8.625 µm = 2.925 µm at Z = 0 and 29.175 µm at Z = 500;
    /// dx = dy = 0 everywhere.
    #[test]
    fn uniform_heating_of_the_machine() {
        let twin = Twin::reference();
        let temps = vec![25.0; twin.node_count()];
        for (pos, dz) in [
            ([0.0, 0.0, 0.0], 2.925),
            ([800.0, 500.0, 500.0], 29.175),
            ([123.0, 321.0, 250.0], 16.05),
        ] {
            let e = twin.error_um(&temps, pos);
            assert!(e[0].abs() < 1e-9 && e[1].abs() < 1e-9, "{pos:?}: {e:?}");
            assert!((e[2] - dz).abs() < 1e-9, "{pos:?}: {} vs {dz}", e[2]);
        }
    }

    /// Tilt: a bent slide S1 tilts the axis that rests on it, so moving that axis
    /// shifts the tool along S1's axis. S1: 500 mm along x, clamped at x = 0, 100 mm high across
    /// y, its +y face 2 K warmer: curvature c = 2α/(100·(1 + 2α)) = 2.29995e-7 /mm (α =
    /// 11.5e-6); its tip turns by −c·500 about z. Axis 2 (along +y) rests on the tip; moving it by
    /// d = 300 mm moves the tool by +c·500·300 = 34.499 µm along +x: towards the longer face's end,
    /// i.e. the axis tilts away from the warm side.
    #[test]
    fn a_bent_slide_tilts_the_axis_resting_on_it_away_from_its_warm_side() {
        let mut s1 = Beam {
            name: "s1".into(),
            e_len: [1.0, 0.0, 0.0],
            e_h: [0.0, 1.0, 0.0],
            e_w: [0.0, 0.0, 1.0],
            length_mm: 500.0,
            height_mm: 100.0,
            width_mm: 100.0,
            segments: 5,
            material: Material::STEEL,
            fill: 1.0,
            web: 1.0,
            support: Support::Clamped { at_mm: 0.0 },
            datum_mm: 0.0,
            support_offset_mm: 0.0,
            first_node: 0,
        };
        let mut net = Network::default();
        s1.add_to(&mut net, 0.0, [0.0; 5]);
        let mut temps = vec![20.0; net.len()];
        for seg in 0..5 {
            for w in [false, true] {
                temps[s1.node(seg, true, w)] = 22.0;
            }
        }
        let shape = s1.shape(&temps, 20.0);
        let tip =
            Deviation::none_at([0.0; 3]).then(&shape.deviation(500.0, 0.0, 0.0, [500.0, 0.0, 0.0]));
        let at = |d: f64| tip.displacement_of([500.0, d, 0.0]);
        let c = curvature(100.0, 100.0, 11.5e-6, 2.0, 0.0);
        assert!((c - 2.299_947e-7).abs() < 1e-12);
        let shift_um = (at(300.0)[0] - at(0.0)[0]) * 1e3;
        assert!((shift_um - c * 500.0 * 300.0 * 1e3).abs() < 1e-9);
        assert!((shift_um - 34.499).abs() < 1e-3, "{shift_um}");
    }

    /// The same on the reference machine: the column's front face (where the head's heat goes)
    /// 2 K warmer than its rear bends the column rearwards and tilts the Z axis; moving Z from 0
    /// to 500 then shifts the tool to +y by c·[(1390² − 890²)/2 − 520·500] = 310 000·c with
    /// c = 2α/(400·(1 + 2α)) = 5.24989e-8 /mm (α = 10.5e-6): 16.2747 µm. (The head carriages sit
    /// at column station 890 + Z; the tool tip is 520 mm below them.)
    #[test]
    fn a_warm_column_front_tilts_z_towards_the_rear() {
        let twin = Twin::reference();
        let mut temps = vec![20.0; twin.node_count()];
        for seg in 0..twin.column.segments {
            for w in [false, true] {
                temps[twin.column.node(seg, true, w)] = 22.0;
            }
        }
        let dy = |z: f64| twin.error_um(&temps, [400.0, 250.0, z])[1];
        let c = curvature(400.0, 400.0, 10.5e-6, 2.0, 0.0);
        let expect = 310_000.0 * c * 1e3;
        assert!((expect - 16.275).abs() < 1e-3);
        assert!(
            (dy(500.0) - dy(0.0) - expect).abs() < 1e-6,
            "{} vs {expect}",
            dy(500.0) - dy(0.0)
        );
    }

    /// A warm spindle alone pushes the tool down (−z) towards the table: the head grows below its
    /// carriages and the shaft grows from its front bearing.
    #[test]
    fn warm_spindle_pushes_the_tool_down() {
        let twin = Twin::reference();
        let mut temps = vec![20.0; twin.node_count()];
        temps[twin.spindle.shaft] = 30.0;
        let e = twin.error_um(&temps, [400.0, 250.0, 250.0]);
        // 150 mm · 11.5e-6 · 10 K = 17.25 µm
        assert!((e[2] + 17.25).abs() < 1e-9, "{e:?}");
    }
}
