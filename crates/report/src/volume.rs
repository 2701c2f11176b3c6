//! The error over the working volume as heat maps: for each error direction one figure, its
//! rows before and after compensation, its columns slices of the grid along the third axis
//! (first, middle and last plane). One symmetric colour scale per direction, shared by before
//! and after, so a pale "after" means a small residual — not a rescaled one.

use plotters::prelude::*;

use crate::style::{diverging, plot_err};
use crate::{ReportError, VolumeDirection, VolumeMap};

const PANEL: i32 = 180;
const LEFT: i32 = 70;
const TOP: i32 = 56;
const GAP_X: i32 = 90;
const GAP_Y: i32 = 76;
const KEY_W: i32 = 110;

impl VolumeMap {
    /// `n` evenly spaced positions from `lo` to `hi` (one, the middle, when `n` is 1).
    pub fn axis_positions(lo: f64, hi: f64, n: usize) -> Vec<f64> {
        match n {
            0 => Vec::new(),
            1 => vec![0.5 * (lo + hi)],
            _ => (0..n)
                .map(|k| lo + (hi - lo) * k as f64 / (n - 1) as f64)
                .collect(),
        }
    }

    /// Grid points in the order of [`VolumeDirection`]'s values: `(ix · ny + iy) · nz + iz`.
    pub fn points(&self) -> impl Iterator<Item = [f64; 3]> + '_ {
        let [x, y, z] = &self.coords;
        x.iter().flat_map(move |&a| {
            y.iter()
                .flat_map(move |&b| z.iter().map(move |&c| [a, b, c]))
        })
    }

    fn index(&self, ix: usize, iy: usize, iz: usize) -> usize {
        (ix * self.coords[1].len() + iy) * self.coords[2].len() + iz
    }

    /// The planes along the third axis that are drawn: first, middle and last.
    fn slices(&self) -> Vec<usize> {
        let nz = self.coords[2].len();
        let mut s = vec![0, nz / 2, nz.saturating_sub(1)];
        s.dedup();
        s.retain(|&k| k < nz);
        s
    }

    /// Whether the values fit the grid.
    pub(crate) fn check(&self) -> Result<(), ReportError> {
        let n: usize = self.coords.iter().map(Vec::len).product();
        if n == 0 {
            return Err(ReportError(
                "volume map: an axis of the grid has no position".into(),
            ));
        }
        for d in &self.directions {
            let bad = d.before.len() != n || d.after.as_ref().is_some_and(|a| a.len() != n);
            if bad {
                return Err(ReportError(format!(
                    "volume map `{}`: expected {n} values (the grid's points)",
                    d.name
                )));
            }
        }
        Ok(())
    }
}

/// Largest finite |value|.
pub(crate) fn max_abs(v: &[f64]) -> f64 {
    v.iter()
        .filter(|x| x.is_finite())
        .fold(0.0_f64, |m, x| m.max(x.abs()))
}

/// One figure per direction.
pub(crate) fn volume_figure(map: &VolumeMap, dir: &VolumeDirection) -> Result<String, ReportError> {
    let slices = map.slices();
    let rows: Vec<(&str, &[f64])> = std::iter::once((map.labels.0.as_str(), dir.before.as_slice()))
        .chain(
            dir.after
                .as_deref()
                .map(|a| (map.labels.1.as_deref().unwrap_or("after"), a)),
        )
        .collect();
    let cols = slices.len() as i32;
    let width = LEFT + cols * (PANEL + GAP_X) + KEY_W;
    let height = TOP + rows.len() as i32 * (PANEL + GAP_Y);
    let scale = max_abs(&dir.before).max(f64::MIN_POSITIVE);
    let mut svg = String::new();
    {
        let root =
            SVGBackend::with_string(&mut svg, (width as u32, height as u32)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let title = format!("{}: error over the working volume", dir.name);
        root.draw(&Text::new(title, (10, 8), ("sans-serif", 17)))
            .map_err(plot_err)?;
        for (r, (label, values)) in rows.iter().enumerate() {
            for (c, &iz) in slices.iter().enumerate() {
                let x0 = LEFT + c as i32 * (PANEL + GAP_X);
                let y0 = TOP + r as i32 * (PANEL + GAP_Y);
                panel(&root, map, values, iz, scale, (x0, y0), label)?;
            }
        }
        colour_key(&root, scale, (width - KEY_W + 20, TOP))?;
        root.present().map_err(plot_err)?;
    }
    Ok(svg)
}

/// One slice: cells coloured by value / scale, the first axis to the right, the second up.
fn panel<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    map: &VolumeMap,
    values: &[f64],
    iz: usize,
    scale: f64,
    (x0, y0): (i32, i32),
    label: &str,
) -> Result<(), ReportError> {
    let (nx, ny) = (map.coords[0].len(), map.coords[1].len());
    let (cw, ch) = (PANEL / nx as i32, PANEL / ny as i32);
    let mut worst = 0.0_f64;
    for ix in 0..nx {
        for iy in 0..ny {
            let v = values[map.index(ix, iy, iz)];
            if v.is_finite() {
                worst = worst.max(v.abs());
            }
            let x = x0 + ix as i32 * cw;
            let y = y0 + (ny - 1 - iy) as i32 * ch;
            root.draw(&Rectangle::new(
                [(x, y), (x + cw, y + ch)],
                diverging(v / scale).filled(),
            ))
            .map_err(plot_err)?;
        }
    }
    let frame = [(x0, y0), (x0 + cw * nx as i32, y0 + ch * ny as i32)];
    root.draw(&Rectangle::new(frame, BLACK.stroke_width(1)))
        .map_err(plot_err)?;
    let small = ("sans-serif", 12);
    let z = &map.coords[2];
    let head = format!("{label}, {} = {:.0} mm", map.axes[2], z[iz]);
    root.draw(&Text::new(head, (x0, y0 - 32), ("sans-serif", 13)))
        .map_err(plot_err)?;
    root.draw(&Text::new(
        format!("max |e| {worst:.2} µm"),
        (x0, y0 - 16),
        small,
    ))
    .map_err(plot_err)?;
    let (xs, ys) = (&map.coords[0], &map.coords[1]);
    let bottom = y0 + ch * ny as i32 + 4;
    let right = x0 + cw * nx as i32;
    for (text, at) in [
        (format!("{:.0}", xs[0]), (x0, bottom)),
        (format!("{:.0}", xs[nx - 1]), (right - 28, bottom)),
        (
            format!("{} / mm", map.axes[0]),
            (x0 + PANEL / 2 - 24, bottom + 14),
        ),
        (format!("{:.0}", ys[ny - 1]), (x0 - 44, y0)),
        (format!("{:.0}", ys[0]), (x0 - 44, y0 + ch * ny as i32 - 12)),
        (
            format!("{} / mm", map.axes[1]),
            (x0 - 66, y0 + PANEL / 2 - 6),
        ),
    ] {
        root.draw(&Text::new(text, at, small)).map_err(plot_err)?;
    }
    Ok(())
}

/// The colour key: +scale at the top, 0, −scale at the bottom, in µm.
fn colour_key<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    scale: f64,
    (x, y): (i32, i32),
) -> Result<(), ReportError> {
    let steps = 40;
    let h = PANEL / steps;
    for k in 0..steps {
        let r = 1.0 - 2.0 * (k as f64 + 0.5) / steps as f64;
        root.draw(&Rectangle::new(
            [(x, y + k * h), (x + 18, y + (k + 1) * h)],
            diverging(r).filled(),
        ))
        .map_err(plot_err)?;
    }
    let small = ("sans-serif", 12);
    for (text, dy) in [
        (format!("+{scale:.1} µm"), 0),
        ("0".to_string(), steps * h / 2 - 6),
        (format!("−{scale:.1} µm"), steps * h - 12),
    ] {
        root.draw(&Text::new(text, (x + 24, y + dy), small))
            .map_err(plot_err)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map(after: bool) -> VolumeMap {
        let coords = [
            VolumeMap::axis_positions(0.0, 500.0, 3),
            VolumeMap::axis_positions(0.0, 400.0, 2),
            VolumeMap::axis_positions(-300.0, 0.0, 3),
        ];
        let mut m = VolumeMap {
            moment: "test".into(),
            axes: ["X".into(), "Y".into(), "Z".into()],
            coords,
            labels: ("uncompensated".into(), after.then(|| "after".into())),
            directions: Vec::new(),
        };
        let before: Vec<f64> = m
            .points()
            .map(|[x, y, z]| 0.01 * x - 0.02 * y + 0.03 * z)
            .collect();
        let after_v = after.then(|| before.iter().map(|v| 0.1 * v).collect());
        m.directions.push(VolumeDirection {
            name: "dz (Z)".into(),
            before,
            after: after_v,
        });
        m
    }

    #[test]
    fn points_follow_the_documented_index() {
        let m = map(false);
        let p: Vec<[f64; 3]> = m.points().collect();
        assert_eq!(p.len(), 18);
        assert_eq!(p[m.index(2, 1, 0)], [500.0, 400.0, -300.0]);
        assert_eq!(p[m.index(1, 0, 2)], [250.0, 0.0, 0.0]);
        assert_eq!(VolumeMap::axis_positions(2.0, 4.0, 1), vec![3.0]);
    }

    #[test]
    fn one_row_per_state_one_column_per_slice() {
        let m = map(true);
        let svg = volume_figure(&m, &m.directions[0]).unwrap();
        // 3 slices × 2 states panels, each titled with its plane.
        assert_eq!(svg.matches("Z = -300 mm").count(), 2);
        assert_eq!(svg.matches("Z = 0 mm").count(), 2);
        assert!(svg.contains("uncompensated, Z = -150 mm"));
        assert!(svg.contains("after, Z = -150 mm"));
        // The worst before is at x=0, y=400, z=-300: −8 − 9 = −17 µm; after is a tenth.
        assert!(svg.contains("max |e| 17.00 µm"));
        assert!(svg.contains("max |e| 1.70 µm"));
        assert!(svg.contains("+17.0 µm"));
    }

    #[test]
    fn a_wrong_length_is_refused() {
        let mut m = map(false);
        m.directions[0].before.pop();
        assert!(m.check().unwrap_err().0.contains("expected 18 values"));
    }
}
