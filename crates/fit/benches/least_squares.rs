//! Least squares through the streaming QR: rows per second for feature-matrix shapes.

use faer::Mat;
use truepos_fit::least_squares::{Accumulator, SolveOptions};

fn main() {
    divan::main();
}

fn matrix(rows: usize, cols: usize) -> (Mat<f64>, Mat<f64>) {
    let a = Mat::<f64>::from_fn(rows, cols, |i, j| {
        if j == 0 {
            1.0
        } else {
            ((i * (j + 7)) as f64 * 1e-3).sin() * (j as f64)
        }
    });
    let b = Mat::<f64>::from_fn(rows, 1, |i, _| (i as f64 * 1e-4).cos());
    (a, b)
}

/// A whole matrix on every core (TSQR), then the SVD solve of the triangle.
#[divan::bench(args = [(100_000, 20), (100_000, 100)])]
fn fit_matrix(bencher: divan::Bencher, (rows, cols): (usize, usize)) {
    let (a, b) = matrix(rows, cols);
    bencher.bench(|| {
        Accumulator::from_matrix(a.as_ref(), b.as_ref(), None)
            .unwrap()
            .finish()
            .solve(&SolveOptions::default())
            .unwrap()
    });
}

/// Row by row, as the fitting pipeline feeds it.
#[divan::bench(args = [(20_000, 100)])]
fn push_rows(bencher: divan::Bencher, (rows, cols): (usize, usize)) {
    let (a, b) = matrix(rows, cols);
    let row: Vec<Vec<f64>> = (0..rows)
        .map(|i| (0..cols).map(|j| a[(i, j)]).collect())
        .collect();
    bencher.bench(|| {
        let mut acc = Accumulator::new(cols, 1);
        for (i, r) in row.iter().enumerate() {
            acc.push_row(r, &[b[(i, 0)]], 1.0).unwrap();
        }
        acc.finish()
    });
}
