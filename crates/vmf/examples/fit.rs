//! A vMF mixture fitted to a Henyey-Greenstein amplitude, and a complex vMF's sphere integral
//! in closed form against quadrature.
//!
//! `cargo run -p speckle-vmf --example fit`

use speckle_vmf::glam::DVec3;
use speckle_vmf::num_complex::Complex64;
use speckle_vmf::{ComplexVmf, FitOptions, fit_amplitude};

#[allow(dead_code)] // tools/outside includes this file as a module
fn main() {
    let g: f64 = 0.9;
    let rho = |mu: f64| {
        (1.0 - g * g) / (4.0 * std::f64::consts::PI * (1.0 + g * g - 2.0 * g * mu).powf(1.5))
    };
    let fit = fit_amplitude(|mu| rho(mu).sqrt(), g, &FitOptions::default()).unwrap();
    println!(
        "HG g = {g}: {} lobes, residual {:.2e}, mean cosine of the fit {:.4}",
        fit.components, fit.residual, fit.g_fit
    );
    // exp(i 3 z + 2 x): its integral over the sphere, closed form (Eq. 29) and quadrature.
    let h = ComplexVmf::new(
        Complex64::ZERO,
        [
            Complex64::new(2.0, 0.0),
            Complex64::ZERO,
            Complex64::new(0.0, 3.0),
        ],
    );
    let q = sphere_quadrature(&h, 400, 800);
    println!(
        "sphere integral: closed form {:.6}, quadrature {q:.6}",
        h.sphere_integral()
    );
}

/// `int_{S^2} h dw` by the midpoint rule on `nt` cosines and `np` azimuths.
pub fn sphere_quadrature(h: &ComplexVmf, nt: usize, np: usize) -> Complex64 {
    let mut q = Complex64::ZERO;
    for i in 0..nt {
        let mu = -1.0 + 2.0 * (i as f64 + 0.5) / nt as f64;
        let s = (1.0 - mu * mu).sqrt();
        for j in 0..np {
            let phi = std::f64::consts::TAU * (j as f64 + 0.5) / np as f64;
            q += h.eval(DVec3::new(s * phi.cos(), s * phi.sin(), mu));
        }
    }
    q * (4.0 * std::f64::consts::PI / (nt * np) as f64)
}
