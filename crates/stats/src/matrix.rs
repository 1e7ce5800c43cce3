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
    /// Number of independent samples (sub-paths) behind the estimate.
    pub samples: u64,
}

impl MatrixEstimate {
    /// Entry `(i, j)` and its standard error.
    pub fn get(&self, i: usize, j: usize) -> (Complex64, Complex64) {
        (self.value.get(i, j), self.std_error.get(i, j))
    }

    /// Combines two independent estimates of the same quantity (for example two runs with
    /// different seeds) into their sample-weighted mean: `(n1 v1 + n2 v2) / (n1 + n2)` with
    /// standard error `sqrt(n1^2 se1^2 + n2^2 se2^2) / (n1 + n2)`. Panics if the shapes differ.
    pub fn merge(&self, other: &Self) -> Self {
        assert_eq!(
            (self.value.rows(), self.value.cols()),
            (other.value.rows(), other.value.cols()),
            "MatrixEstimate::merge: shapes differ"
        );
        let (n1, n2) = (self.samples as f64, other.samples as f64);
        let n = n1 + n2;
        let (w1, w2) = (n1 / n, n2 / n);
        let value = self
            .value
            .as_slice()
            .iter()
            .zip(other.value.as_slice())
            .map(|(a, b)| a * w1 + b * w2);
        let se = self
            .std_error
            .as_slice()
            .iter()
            .zip(other.std_error.as_slice())
            .map(|(a, b)| {
                Complex64::new((w1 * a.re).hypot(w2 * b.re), (w1 * a.im).hypot(w2 * b.im))
            });
        let (r, c) = (self.value.rows(), self.value.cols());
        Self {
            value: CMatrix::from_vec(r, c, value.collect()),
            std_error: CMatrix::from_vec(r, c, se.collect()),
            samples: self.samples + other.samples,
        }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn merge_is_the_sample_weighted_mean() {
        let c = |re: f64, im: f64| Complex64::new(re, im);
        let a = MatrixEstimate {
            value: CMatrix::from_vec(1, 1, vec![c(1.0, 2.0)]),
            std_error: CMatrix::from_vec(1, 1, vec![c(0.3, 0.4)]),
            samples: 100,
        };
        let b = MatrixEstimate {
            value: CMatrix::from_vec(1, 1, vec![c(4.0, -1.0)]),
            std_error: CMatrix::from_vec(1, 1, vec![c(0.6, 0.8)]),
            samples: 300,
        };
        let m = a.merge(&b);
        assert_eq!(m.samples, 400);
        assert!((m.value.get(0, 0) - c(3.25, -0.25)).norm() < 1e-15);
        let se = m.std_error.get(0, 0);
        assert!((se.re - (0.075f64.powi(2) + 0.45f64.powi(2)).sqrt()).abs() < 1e-15);
        assert!((se.im - (0.1f64.powi(2) + 0.6f64.powi(2)).sqrt()).abs() < 1e-15);
    }
}
