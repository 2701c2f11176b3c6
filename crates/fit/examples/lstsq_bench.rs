//! The solver against numpy.linalg.lstsq on the same matrix (driven by
//! `scripts/lstsq_vs_numpy.sh`).
//!
//! `lstsq_bench gen DIR ROWS COLS` writes `A.npy` (ROWS × COLS, row-major float64) and `b.npy`
//! deterministically; `lstsq_bench solve DIR` reads them, times the fit (best of 3: blocked QR
//! on every core, column scaling, SVD of the triangle), writes `x_truepos.npy` and prints
//! `{"truepos_seconds": …, "rows": …, "cols": …, "rank": …, "condition": …}`.

use std::io::{Read, Write};
use std::path::Path;
use std::time::Instant;

use faer::MatRef;
use truepos_fit::least_squares::{Accumulator, SolveOptions};

/// splitmix64: a deterministic stream of well-mixed 64-bit numbers.
fn splitmix(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

fn uniform(state: &mut u64) -> f64 {
    (splitmix(state) >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
}

fn write_npy(path: &Path, rows: usize, cols: usize, data: &[f64]) -> std::io::Result<()> {
    let shape = if cols == 1 {
        format!("({rows},)")
    } else {
        format!("({rows}, {cols})")
    };
    let mut header = format!("{{'descr': '<f8', 'fortran_order': False, 'shape': {shape}, }}");
    // Magic (6) + version (2) + header length (2) + header, padded to 64 bytes with a newline.
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut f = std::io::BufWriter::new(std::fs::File::create(path)?);
    f.write_all(b"\x93NUMPY\x01\x00")?;
    f.write_all(&(header.len() as u16).to_le_bytes())?;
    f.write_all(header.as_bytes())?;
    for v in data {
        f.write_all(&v.to_le_bytes())?;
    }
    f.flush()
}

fn read_npy(path: &Path) -> Result<(Vec<usize>, Vec<f64>), String> {
    let mut bytes = Vec::new();
    std::fs::File::open(path)
        .and_then(|mut f| f.read_to_end(&mut bytes))
        .map_err(|e| format!("{}: {e}", path.display()))?;
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" || bytes[6] != 1 {
        return Err(format!("{}: not a version-1 .npy file", path.display()));
    }
    let hlen = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let header = std::str::from_utf8(&bytes[10..10 + hlen]).map_err(|e| e.to_string())?;
    if !header.contains("'<f8'") || !header.contains("'fortran_order': False") {
        return Err(format!(
            "{}: expected C-ordered <f8, got {header}",
            path.display()
        ));
    }
    let shape_txt = header
        .split("'shape': (")
        .nth(1)
        .and_then(|s| s.split(')').next())
        .ok_or("no shape")?;
    let shape: Vec<usize> = shape_txt
        .split(',')
        .filter(|s| !s.trim().is_empty())
        .map(|s| {
            s.trim()
                .parse()
                .map_err(|_| format!("bad shape {shape_txt}"))
        })
        .collect::<Result<_, _>>()?;
    let data: Vec<f64> = bytes[10 + hlen..]
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
        .collect();
    if data.len() != shape.iter().product::<usize>() {
        return Err(format!("{}: data does not match shape", path.display()));
    }
    Ok((shape, data))
}

fn generate(dir: &Path, rows: usize, cols: usize) -> std::io::Result<()> {
    // Columns of very different scales (1e-3 … 1e3) and mild correlation between neighbours,
    // the first column the intercept: what a feature matrix of temperatures and speeds looks like.
    let scale = |j: usize| 10f64.powi((j % 7) as i32 - 3);
    // True coefficients ±1 … ±11 (none near zero, so that an element-wise relative comparison
    // of two solvers is meaningful), in the units of each column.
    let truth: Vec<f64> = (0..cols)
        .map(|j| {
            let sign = if j % 2 == 0 { 1.0 } else { -1.0 };
            sign * (1 + j * 37 % 11) as f64 / scale(j)
        })
        .collect();
    let mut a = vec![0.0; rows * cols];
    let mut b = vec![0.0; rows];
    let mut state = 0x7275_6570_6f73_u64;
    for i in 0..rows {
        let row = &mut a[i * cols..(i + 1) * cols];
        let mut prev = 0.0;
        for (j, v) in row.iter_mut().enumerate() {
            let u = uniform(&mut state);
            *v = if j == 0 {
                1.0
            } else {
                scale(j) * (u + 0.5 * prev)
            };
            prev = u;
        }
        b[i] = row.iter().zip(&truth).map(|(x, t)| x * t).sum::<f64>() + 0.01 * uniform(&mut state);
    }
    std::fs::create_dir_all(dir)?;
    write_npy(&dir.join("A.npy"), rows, cols, &a)?;
    write_npy(&dir.join("b.npy"), rows, 1, &b)
}

fn solve(dir: &Path) -> Result<(), String> {
    let (shape, a) = read_npy(&dir.join("A.npy"))?;
    let (_, b) = read_npy(&dir.join("b.npy"))?;
    let (rows, cols) = (shape[0], shape[1]);
    let am = MatRef::from_row_major_slice(&a, rows, cols);
    let bm = MatRef::from_column_major_slice(&b, rows, 1);
    let mut best = f64::INFINITY;
    let mut solution = None;
    for _ in 0..3 {
        let start = Instant::now();
        let s = Accumulator::from_matrix(am, bm, None)
            .and_then(|acc| acc.finish().solve(&SolveOptions::default()))
            .map_err(|e| e.to_string())?;
        best = best.min(start.elapsed().as_secs_f64());
        solution = Some(s);
    }
    let s = solution.expect("three runs");
    write_npy(&dir.join("x_truepos.npy"), cols, 1, &s.coefficients[0])
        .map_err(|e| e.to_string())?;
    println!(
        "{{\"truepos_seconds\": {best}, \"rows\": {rows}, \"cols\": {cols}, \"rank\": {}, \"condition\": {}, \"threads\": {}}}",
        s.rank,
        s.condition,
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    Ok(())
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let result = match args.get(1).map(String::as_str) {
        Some("gen") if args.len() == 5 => {
            match (args[3].parse::<usize>(), args[4].parse::<usize>()) {
                (Ok(rows), Ok(cols)) if rows > 0 && cols > 0 => {
                    generate(Path::new(&args[2]), rows, cols).map_err(|e| e.to_string())
                }
                _ => Err("ROWS and COLS must be positive integers".into()),
            }
        }
        Some("solve") if args.len() == 3 => solve(Path::new(&args[2])),
        _ => Err("usage: lstsq_bench gen DIR ROWS COLS | lstsq_bench solve DIR".into()),
    };
    if let Err(e) = result {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
