//! Green's functions, the point scatterer's t-matrix and the far-field constants of 3D and
//! flatland scalar waves (see the crate docs for the derivation).

use crate::bessel::hankel1_0;
use num_complex::Complex64;
use speckle_phase::Dimension;
use std::f64::consts::{FRAC_PI_4, PI};

/// The free-space scalar wave physics of one dimension at one wavenumber: Green's function,
/// resonant point scatterer, far-field and point-source normalisations.
///
/// ```
/// use speckle_phase::Dimension;
/// use speckle_wave::Kernel;
/// let k = 2.0 * std::f64::consts::PI;
/// let kernel = Kernel::new(Dimension::Three, k);
/// // The resonant scatterer: f = i / k, cross-section 4 pi / k^2 (optical theorem).
/// let f = kernel.scattering_amplitude();
/// assert!((f - num_complex::Complex64::new(0.0, 1.0 / k)).norm() < 1e-15);
/// assert!((kernel.cross_section() - 4.0 * std::f64::consts::PI / (k * k)).abs() < 1e-15);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Kernel {
    dimension: Dimension,
    k: f64,
}

impl Kernel {
    /// The kernel of `dimension` at wavenumber `k` (finite and positive; not checked here, a
    /// [`speckle_scene::Scene`] guarantees it).
    pub fn new(dimension: Dimension, k: f64) -> Self {
        Self { dimension, k }
    }

    /// The dimension.
    pub fn dimension(&self) -> Dimension {
        self.dimension
    }

    /// The wavenumber `k`.
    pub fn wavenumber(&self) -> f64 {
        self.k
    }

    /// The outgoing Green's function of `(nabla^2 + k^2) G = -delta` at distance `r > 0`:
    /// `e^{ikr} / (4 pi r)` in 3D, `(i/4) H0^(1)(kr)` in flatland.
    #[inline]
    pub fn green(&self, r: f64) -> Complex64 {
        match self.dimension {
            Dimension::Three => Complex64::from_polar(1.0 / (4.0 * PI * r), self.k * r),
            Dimension::Two => {
                let h = hankel1_0(self.k * r);
                // (i/4)(J0 + i Y0) = (-Y0 + i J0) / 4
                Complex64::new(-0.25 * h.im, 0.25 * h.re)
            }
        }
    }

    /// `Im G(0) = lim_{r -> 0} Im G(r)`: `k / (4 pi)` in 3D, `1/4` in flatland.
    pub fn green_im_at_origin(&self) -> f64 {
        match self.dimension {
            Dimension::Three => self.k / (4.0 * PI),
            Dimension::Two => 0.25,
        }
    }

    /// The t-matrix of the lossless resonant isotropic point scatterer, `tau = i / Im G(0)`:
    /// `4 pi i / k` in 3D, `4 i` in flatland. It satisfies `Im(1/tau) = -Im G(0)` (energy
    /// conservation) with `Re(1/tau) = 0` (resonance: a purely imaginary forward amplitude).
    pub fn t_matrix(&self) -> Complex64 {
        Complex64::new(0.0, 1.0 / self.green_im_at_origin())
    }

    /// The far-field factor `g` of the Green's function: `G(R v - o) ~ g e^{-ik v.o} e^{ikR} /
    /// R^{(d-1)/2}` as `R -> infinity`: `1 / (4 pi)` in 3D, `e^{i pi/4} / sqrt(8 pi k)` in
    /// flatland (from `H0^(1)(x) ~ sqrt(2 / (pi x)) e^{i (x - pi/4)}`).
    pub fn far_field_factor(&self) -> Complex64 {
        match self.dimension {
            Dimension::Three => Complex64::new(1.0 / (4.0 * PI), 0.0),
            Dimension::Two => Complex64::from_polar(1.0 / (8.0 * PI * self.k).sqrt(), FRAC_PI_4),
        }
    }

    /// The far-field scattering amplitude `f = tau g` of one scatterer excited by a unit field:
    /// `i / k` in 3D, `4 i e^{i pi/4} / sqrt(8 pi k)` in flatland (`u = f e^{ikR} / sqrt(R)`).
    pub fn scattering_amplitude(&self) -> Complex64 {
        self.t_matrix() * self.far_field_factor()
    }

    /// The scattering cross-section `c_s = int |f|^2`: over the sphere `4 pi / k^2` in 3D, over
    /// the circle (a cross-width) `2 pi |f|^2 = 4 / k` in flatland.
    pub fn cross_section(&self) -> f64 {
        match self.dimension {
            Dimension::Three => 4.0 * PI / (self.k * self.k),
            Dimension::Two => 4.0 / self.k,
        }
    }

    /// The extinction cross-section from the optical theorem, `(4 pi / k) Im f` in 3D and
    /// `sqrt(8 pi / k) Im(f e^{-i pi/4})` in flatland; equal to [`Kernel::cross_section`] for
    /// this lossless scatterer.
    pub fn extinction_cross_section(&self) -> f64 {
        let f = self.scattering_amplitude();
        match self.dimension {
            Dimension::Three => 4.0 * PI / self.k * f.im,
            Dimension::Two => {
                (8.0 * PI / self.k).sqrt() * (f * Complex64::from_polar(1.0, -FRAC_PI_4)).im
            }
        }
    }

    /// The field of a unit point source at distance `r > 0`: `e^{ikr} / r` in 3D, and in
    /// flatland `sqrt(pi k / 2) e^{i pi/4} H0^(1)(kr)`, which tends to `e^{ikr} / sqrt(r)` (the
    /// Monte Carlo's flatland point source). Both are `c G` with a constant `c`, so a point
    /// source's far-field amplitude in the direction `v` is `e^{-ik v.p}`.
    #[inline]
    pub fn point_source(&self, r: f64) -> Complex64 {
        match self.dimension {
            Dimension::Three => Complex64::from_polar(1.0 / r, self.k * r),
            Dimension::Two => {
                Complex64::from_polar((0.5 * PI * self.k).sqrt(), FRAC_PI_4) * hankel1_0(self.k * r)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    #[test]
    fn constants_of_the_resonant_scatterer() {
        let k = TAU / 0.7;
        let k3 = Kernel::new(Dimension::Three, k);
        assert!((k3.t_matrix() - Complex64::new(0.0, 4.0 * PI / k)).norm() < 1e-15);
        assert!((k3.scattering_amplitude() - Complex64::new(0.0, 1.0 / k)).norm() < 1e-15);
        let k2 = Kernel::new(Dimension::Two, k);
        assert_eq!(k2.t_matrix(), Complex64::new(0.0, 4.0));
        let f = k2.scattering_amplitude();
        assert!((f.norm_sqr() - 2.0 / (PI * k)).abs() < 1e-15);
        for kernel in [k3, k2] {
            // Optical theorem for one scatterer: extinction = scattering.
            let (ext, sca) = (kernel.extinction_cross_section(), kernel.cross_section());
            assert!(
                (ext - sca).abs() < 1e-14 * sca,
                "{kernel:?}: {ext} vs {sca}"
            );
            // 1 / tau = -i Im G(0): lossless and resonant.
            let inv = 1.0 / kernel.t_matrix();
            assert!(inv.re.abs() < 1e-15 && (inv.im + kernel.green_im_at_origin()).abs() < 1e-15);
        }
        let sca2 = TAU * f.norm_sqr();
        assert!((sca2 - k2.cross_section()).abs() < 1e-14);
    }

    #[test]
    fn green_functions_tend_to_their_far_fields() {
        let k = 3.0;
        for dim in [Dimension::Three, Dimension::Two] {
            let kernel = Kernel::new(dim, k);
            let r: f64 = 1e5;
            let spread = match dim {
                Dimension::Three => r,
                Dimension::Two => r.sqrt(),
            };
            let far = kernel.far_field_factor() * Complex64::from_polar(1.0 / spread, k * r);
            let g = kernel.green(r);
            assert!((g - far).norm() < 1e-5 * far.norm(), "{dim}: {g} vs {far}");
            let p = kernel.point_source(r);
            let expect = Complex64::from_polar(1.0 / spread, k * r);
            assert!(
                (p - expect).norm() < 1e-5 * expect.norm(),
                "{dim}: {p} vs {expect}"
            );
        }
    }

    #[test]
    fn flatland_green_function_solves_the_helmholtz_equation() {
        // Radial Laplacian G'' + G'/r + k^2 G = 0 away from the source, by finite differences.
        let (k, h) = (2.0, 1e-3);
        let kernel = Kernel::new(Dimension::Two, k);
        for r in [0.3, 1.7, 9.0, 15.0] {
            let g = |s: f64| kernel.green(s);
            let d2 = (g(r + h) - 2.0 * g(r) + g(r - h)) / (h * h);
            let d1 = (g(r + h) - g(r - h)) / (2.0 * h);
            let res = d2 + d1 / r + k * k * g(r);
            assert!(res.norm() < 1e-5 * (k * k * g(r).norm()), "r = {r}: {res}");
        }
    }
}
