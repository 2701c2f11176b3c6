//! Each machine-coordinate point through the kinematics table: the nominal machine would put
//! the tool at `fwd_nominal(q)`; the set-points `q'` that make the *real* machine, through its
//! error tables, put it there are the compensated point (`inverse_near`, the programmed
//! position choosing the rotary branch and turn, as `kin inv` does).

use truepos_kinematics::{Chain, Directions, Geometry, KinAxis, KinError};
use truepos_model::AxisKind;

use crate::canon::Pos6;

/// Letters of the six positions rs274 prints.
pub const LETTERS: [char; 6] = ['X', 'Y', 'Z', 'A', 'B', 'C'];

/// The chain and what it has done so far.
pub struct Compensator<'a> {
    chain: &'a Chain,
    geometry: Geometry,
    /// Tool length in mm with no tool length offset active.
    base_tool_mm: f64,
    /// For each chain axis, its index in rs274's six positions.
    slot: Vec<usize>,
    /// rs274's positions no chain axis takes and that are not passed through.
    absent: Vec<usize>,
    /// rs274's positions written unchanged after the chain's axes (`Options::pass_axes`).
    pass: Vec<usize>,
    /// Compensated chain set-points followed by the passed axes.
    full: Vec<f64>,
    nominal: Vec<f64>,
    dirs: Directions,
    out: Vec<f64>,
    /// Points compensated.
    pub points: u64,
    /// Largest |compensated − nominal| per chain axis (mm or degrees).
    pub largest: Vec<f64>,
    /// Points where the real tool direction could not be reached exactly (TCP exact), and
    /// the largest remaining direction error in rad.
    pub direction_misses: u64,
    pub largest_direction_miss_rad: f64,
}

impl<'a> Compensator<'a> {
    /// Fails when a chain axis is not one of X Y Z A B C (rs274 prints no other), or a passed
    /// axis is one of the chain's.
    pub fn new(
        chain: &'a Chain,
        geometry: Geometry,
        base_tool_mm: f64,
        pass_axes: &[char],
    ) -> Result<Self, String> {
        let mut slot = Vec::new();
        for a in chain.axes() {
            let letter = a.name.chars().next().unwrap_or(' ').to_ascii_uppercase();
            match LETTERS.iter().position(|&l| l == letter) {
                Some(k) if a.name.len() == 1 && !slot.contains(&k) => slot.push(k),
                _ => {
                    return Err(format!(
                        "axis `{}` of the kinematics table is not one of X Y Z A B C, the axes LinuxCNC's interpreter prints",
                        a.name
                    ))
                }
            }
        }
        let mut pass = Vec::new();
        for &l in pass_axes {
            match LETTERS.iter().position(|&m| m == l.to_ascii_uppercase()) {
                Some(k) if !slot.contains(&k) && !pass.contains(&k) => pass.push(k),
                _ => {
                    return Err(format!(
                        "axis `{l}` cannot be passed through: expected one of X Y Z A B C that the kinematics table does not have, once"
                    ))
                }
            }
        }
        let absent = (0..6)
            .filter(|k| !slot.contains(k) && !pass.contains(k))
            .collect();
        let full = vec![0.0; slot.len() + pass.len()];
        let n = chain.axes().len();
        let nominal = chain.axes().iter().map(KinAxis::start_position).collect();
        Ok(Compensator {
            chain,
            geometry,
            base_tool_mm,
            slot,
            absent,
            pass,
            full,
            nominal,
            dirs: Directions(0),
            out: vec![0.0; n],
            points: 0,
            largest: vec![0.0; n],
            direction_misses: 0,
            largest_direction_miss_rad: 0.0,
        })
    }

    /// The letters of what [`Compensator::apply`] returns: the chain's axes in set-point
    /// order, then the passed axes.
    pub fn letters(&self) -> Vec<char> {
        self.slot
            .iter()
            .chain(&self.pass)
            .map(|&k| LETTERS[k])
            .collect()
    }

    /// Whether value `j` of what [`Compensator::apply`] returns is an angle.
    pub fn rotary(&self, j: usize) -> bool {
        match self.chain.axes().get(j) {
            Some(a) => a.kind == AxisKind::Rotary,
            None => self.pass[j - self.slot.len()] >= 3,
        }
    }

    /// The tool length the chain uses with tool length offset Z `tool_offset_z` (mm): the
    /// reference length plus the offset (LinuxCNC's offset is the tool's length beyond the
    /// reference tool the machine's Z is measured with).
    pub fn tool_mm(&self, tool_offset_z: f64) -> f64 {
        self.base_tool_mm + tool_offset_z
    }

    /// The nominal set-points of a machine point, checked: an axis the machine does not have
    /// must stay at 0, every axis within its travel.
    pub fn nominal_of(&self, machine: &Pos6) -> Result<Vec<f64>, String> {
        for &k in &self.absent {
            if machine[k].abs() > 1e-9 {
                return Err(format!(
                    "the program moves {} to {}, an axis this machine does not have",
                    LETTERS[k], machine[k]
                ));
            }
        }
        let mut q = Vec::with_capacity(self.slot.len());
        for (a, &k) in self.chain.axes().iter().zip(&self.slot) {
            let v = machine[k];
            if v < a.travel_min || v > a.travel_max {
                return Err(format!(
                    "the program moves {} to {v:.4} (machine coordinates), outside its travel {} … {}",
                    a.name, a.travel_min, a.travel_max
                ));
            }
            q.push(v);
        }
        Ok(q)
    }

    /// Compensated set-points of a machine point (one value per chain axis), then the passed
    /// axes' positions unchanged.
    pub fn apply(&mut self, machine: &Pos6, tool_offset_z: f64) -> Result<&[f64], String> {
        let q = self.nominal_of(machine)?;
        for (j, (now, was)) in q.iter().zip(&self.nominal).enumerate() {
            if now > was {
                self.dirs.0 &= !(1 << j);
            } else if now < was {
                self.dirs.0 |= 1 << j;
            }
        }
        self.nominal = q;
        let tool = self.tool_mm(tool_offset_z);
        let target = self
            .chain
            .forward(&self.nominal, tool, self.dirs, Geometry::Nominal)
            .map_err(|e| format!("forward transform: {e}"))?;
        let solved = self.chain.inverse_near(
            &target,
            tool,
            &self.nominal,
            self.dirs,
            self.geometry,
            &mut self.out,
        );
        match solved {
            Ok(_) => {}
            // At the pole a real machine may not point the tool exactly where the nominal
            // one does (a tilt in the plane of the swivel axis): TCP exact, direction as
            // close as it gets, counted and reported.
            Err(KinError::NotConverged {
                position_mm,
                direction_rad,
            }) if position_mm < 1e-6 => {
                self.direction_misses += 1;
                self.largest_direction_miss_rad =
                    self.largest_direction_miss_rad.max(direction_rad);
            }
            Err(KinError::OutsideTravel { axis, value }) => {
                let a = &self.chain.axes()[axis];
                return Err(format!(
                    "the compensated {} would be {value:.6}, outside its travel {} … {}",
                    a.name, a.travel_min, a.travel_max
                ));
            }
            Err(e) => return Err(format!("no compensated set-points: {e}")),
        }
        for (j, (c, n)) in self.out.iter().zip(&self.nominal).enumerate() {
            self.largest[j] = self.largest[j].max((c - n).abs());
        }
        self.points += 1;
        let n = self.out.len();
        self.full[..n].copy_from_slice(&self.out);
        for (f, &k) in self.full[n..].iter_mut().zip(&self.pass) {
            *f = machine[k];
        }
        Ok(&self.full)
    }
}
