//! The series: the coefficients `a_n`, `b_n` from the logarithmic derivatives `D_n(m x)` and
//! the Riccati-Bessel functions, with their recurrences' starting rules (module docs of
//! [`super`]).

use crate::Complex64;

/// `a_n, b_n` for `n = 1..=n_max` (BH Eq. 4.88), from `D_n(m x)`, `psi_n(x)` and `chi_n(x)`.
pub(super) fn coefficients(x: f64, m: Complex64, n_max: usize) -> (Vec<Complex64>, Vec<Complex64>) {
    let d = log_derivatives(m * x, n_max);
    let psi = riccati_psi(x, n_max);
    let mut a = Vec::with_capacity(n_max);
    let mut b = Vec::with_capacity(n_max);
    // chi_(n-2), chi_(n-1) for n = 1: chi_(-1) = -sin x, chi_0 = cos x.
    let (mut chi_2, mut chi_1) = (-x.sin(), x.cos());
    for n in 1..=n_max {
        let nf = n as f64;
        let chi = (2.0 * nf - 1.0) / x * chi_1 - chi_2;
        let xi = Complex64::new(psi[n], -chi);
        let xi_1 = Complex64::new(psi[n - 1], -chi_1);
        let da = d[n] / m + nf / x;
        let db = d[n] * m + nf / x;
        a.push((da * psi[n] - psi[n - 1]) / (da * xi - xi_1));
        b.push((db * psi[n] - psi[n - 1]) / (db * xi - xi_1));
        chi_2 = chi_1;
        chi_1 = chi;
    }
    (a, b)
}

/// Number of steps past the turning point that the downward recurrences start at.
pub(super) fn start_margin(turning: f64) -> usize {
    16 + (10.0 * turning.cbrt()).ceil() as usize
}

/// `D_n(z)` for `n = 0..=n_max` by downward recurrence (BH Eq. 4.89) from `D = 0` at
/// `max(n_max, ceil|z|) + 16 + ceil(10 |z|^(1/3))`.
pub(super) fn log_derivatives(z: Complex64, n_max: usize) -> Vec<Complex64> {
    let size = z.norm();
    log_derivatives_from(
        z,
        n_max,
        n_max.max(size.ceil() as usize) + start_margin(size),
    )
}

/// `D_n(z)` for `n = 0..=n_max` by downward recurrence from `D = 0` at `start >= n_max`.
pub(super) fn log_derivatives_from(z: Complex64, n_max: usize, start: usize) -> Vec<Complex64> {
    let mut d = vec![Complex64::ZERO; n_max + 1];
    let mut dn = Complex64::ZERO;
    for n in (1..=start).rev() {
        let nz = n as f64 / z;
        dn = nz - 1.0 / (dn + nz);
        if n - 1 <= n_max {
            d[n - 1] = dn;
        }
    }
    d
}

/// `psi_n(x)` for `n = 0..=n_max`: upward recurrence while `n <= x`, downward ratios above.
pub(super) fn riccati_psi(x: f64, n_max: usize) -> Vec<f64> {
    riccati_psi_from(x, n_max, n_max + start_margin(x))
}

/// `psi_n(x)` for `n = 0..=n_max`, the downward ratio recurrence started at `top >= n_max`.
pub(super) fn riccati_psi_from(x: f64, n_max: usize, top: usize) -> Vec<f64> {
    let mut psi = vec![0.0; n_max + 1];
    psi[0] = x.sin();
    let n_up = (x.floor() as usize).min(n_max);
    let mut psi_prev = x.cos();
    for n in 1..=n_up {
        let next = (2.0 * n as f64 - 1.0) / x * psi[n - 1] - psi_prev;
        psi_prev = psi[n - 1];
        psi[n] = next;
    }
    if n_up < n_max {
        // r_n = psi_n / psi_(n-1), stored in psi[n] first, then turned into psi_n upward.
        let mut r = 0.0;
        for n in (n_up + 1..=top).rev() {
            r = 1.0 / ((2.0 * n as f64 + 1.0) / x - r);
            if n <= n_max {
                psi[n] = r;
            }
        }
        for n in n_up + 1..=n_max {
            psi[n] *= psi[n - 1];
        }
    }
    psi
}
