//! Dense complex matrices with per-entry standard errors.

use num_complex::Complex64;

/// A dense row-major complex matrix.
#[derive(Debug, Clone, PartialEq)]
pub struct CMatrix {
    rows: usize,
    cols: usize,
    data: Vec<Complex64>,
}

impl CMatrix {
    /// A zero matrix.
    pub fn zeros(rows: usize, cols: usize) -> Self {
        Self {
            rows,
            cols,
            data: vec![Complex64::new(0.0, 0.0); rows * cols],
        }
    }

    /// A matrix from row-major data; panics if the length is not `rows * cols`.
    pub fn from_vec(rows: usize, cols: usize, data: Vec<Complex64>) -> Self {
        assert_eq!(data.len(), rows * cols, "CMatrix::from_vec: wrong length");
        Self { rows, cols, data }
    }

    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Number of columns.
    pub fn cols(&self) -> usize {
        self.cols
    }

    /// Row-major entries.
    pub fn as_slice(&self) -> &[Complex64] {
        &self.data
    }

    /// Row-major entries, mutable.
    pub fn as_mut_slice(&mut self) -> &mut [Complex64] {
        &mut self.data
    }

    /// Entry `(i, j)`.
    #[inline]
    pub fn get(&self, i: usize, j: usize) -> Complex64 {
        self.data[i * self.cols + j]
    }

    /// The diagonal.
    pub fn diagonal(&self) -> Vec<Complex64> {
        (0..self.rows.min(self.cols))
            .map(|i| self.get(i, i))
            .collect()
    }
}

/// A matrix estimate with the standard errors of the real and imaginary part of every entry.
#[derive(Debug, Clone, PartialEq)]
pub struct MatrixEstimate {
    /// The estimate.
    pub value: CMatrix,
    /// Standard error of each entry: real part holds the standard error of the real part,
    /// imaginary part that of the imaginary part.
    pub std_error: CMatrix,
}

impl MatrixEstimate {
    /// Entry `(i, j)` and its standard error.
    pub fn get(&self, i: usize, j: usize) -> (Complex64, Complex64) {
        (self.value.get(i, j), self.std_error.get(i, j))
    }

    /// Number of standard errors by which entry `(i, j)` differs from `expected`, the larger of
    /// the real and imaginary parts (an infinite standard error never rejects; a zero one rejects
    /// any difference).
    pub fn z_score(&self, i: usize, j: usize, expected: Complex64) -> f64 {
        let (v, se) = self.get(i, j);
        let z = |d: f64, s: f64| if d == 0.0 { 0.0 } else { d.abs() / s };
        z(v.re - expected.re, se.re).max(z(v.im - expected.im, se.im))
    }
}
