//! Gaussian-apodized lens apertures as complex vMFs: the weighted aperture functions of Bar et
//! al. 2020, Eqs. 23-27, and the exact scattering connection `Upsilon`
//! of Eqs. 15-16 for a vMF-mixture amplitude (Eq. 28) when the path direction is known
//! (`B >= 2`).
//!
//! An aperture focused at `f` with optical axis `a` (the direction light propagates through the
//! focus) and concentration `gamma` weighs the plane wave of direction `w` by the mask
//! `m(w) = c e^(gamma a . w)` (Eq. 24) and the focusing phase `e^(-i k w . f)` (Eq. 10). At a
//! medium point `o` reached by that plane wave the weighted aperture is (Eqs. 17, 23, 26-27)
//!
//! `a~(w; o) = c e^(-tau) e^((gamma a + i k (o - f)) . w)`,
//!
//! a complex vMF in `w`, with `tau = sigma_t d / 2` the field attenuation along the axis
//! (the constant-attenuation approximation of Eq. 25, passed in by the caller as a number so that
//! this crate stays below the media). Everything is written in *source form*, as in
//! `speckle-endpoints`: a sensor focused at `v` and looking along `a_v` (light travelling along
//! `a_v` into it) reads, by reciprocity, the field of the source focused at `v` with axis `-a_v`;
//! its weighted aperture over the viewing direction `v^ = -w` is the paper's
//! `m(v^) e^(i k v^ . (v - o))` exactly.
//!
//! **Normalisation** (the paper's own normalisation differs): the mask has unit integral,
//! `c = C_3(gamma) = gamma / (4 pi sinh gamma)` (`C_2(gamma) = 1 / (2 pi I_0(gamma))` in
//! flatland), like the reference code's default and unlike the paper's peak-1 `e^(-gamma)`. In
//! absolute units (`docs/conventions.md`) this makes the vacuum field of the beam,
//! `u(x) = int m(w) e^(i k w . (x - f)) dw`, equal to 1 at the focus and tend to the unit plane
//! wave `e^(i k a . (x - f))` as `gamma -> inf` (the plane-wave limit), while `gamma = 0` is the
//! isotropic superposition `sin(k r) / (k r)` (3D) or `J_0(k r)` (flatland), whose outgoing half
//! is the point source `e^(i k r) / r` times `1 / (2 i k)` (3D).

use crate::algebra::ComplexVmf;
use crate::circle::{CircleVmf, ln_circle_normaliser};
use crate::mixture::VmfMixture;
use crate::{VmfError, ln_vmf_normaliser};
use glam::{DVec2, DVec3};
use num_complex::Complex64;

/// The largest aperture concentration: the angular width `1 / sqrt(gamma)` is then `3e-4` rad,
/// far narrower than any lens; the log-domain algebra is tested to `1e5`.
pub const MAX_APERTURE_GAMMA: f64 = 1e7;

/// The aperture concentration of a numerical aperture `na` in `(0, 1]`:
/// `gamma = 4 / na^2`, so that the mask's per-axis variance of the direction cosines,
/// `1 / gamma`, matches that of a uniform disk of radius `na` in direction-cosine space,
/// `na^2 / 4` (second-moment matching; the paper gives no rule).
/// `na = 0.5` gives `gamma = 16` (the paper's `sigma_a = 0.25`).
///
/// ```
/// use speckle_vmf::gamma_from_na;
/// assert_eq!(gamma_from_na(0.5).unwrap(), 16.0);
/// assert!(gamma_from_na(0.0).is_err() && gamma_from_na(1.2).is_err());
/// ```
pub fn gamma_from_na(na: f64) -> Result<f64, VmfError> {
    if !(na.is_finite() && na > 0.0 && na <= 1.0) {
        return Err(VmfError::InvalidOption {
            field: "numerical_aperture",
            reason: format!("must be in (0, 1] (got {na})"),
        });
    }
    let gamma = 4.0 / (na * na);
    if gamma > MAX_APERTURE_GAMMA {
        return Err(VmfError::InvalidOption {
            field: "numerical_aperture",
            reason: format!(
                "{na} gives a concentration above {MAX_APERTURE_GAMMA} (an aperture narrower than 3e-4 rad)"
            ),
        });
    }
    Ok(gamma)
}

/// Checks an aperture concentration: finite, `0 <= gamma <= MAX_APERTURE_GAMMA`.
fn checked_gamma(gamma: f64) -> Result<f64, VmfError> {
    if gamma.is_finite() && (0.0..=MAX_APERTURE_GAMMA).contains(&gamma) {
        Ok(gamma)
    } else {
        Err(VmfError::InvalidOption {
            field: "concentration",
            reason: format!("must be finite and in [0, {MAX_APERTURE_GAMMA}] (got {gamma})"),
        })
    }
}

/// A unit-integral Gaussian (vMF) aperture in 3D: concentration `gamma` about the unit optical
/// axis `axis` (source form: the direction the light propagates through the focus).
///
/// ```
/// use glam::DVec3;
/// use speckle_vmf::Aperture;
/// let a = Aperture::new(16.0, DVec3::Z).unwrap();
/// // Vacuum field at the focus: int m = 1.
/// let at_focus = a.weighted(2.0 * std::f64::consts::PI, DVec3::ZERO, DVec3::ZERO, 0.0);
/// assert!((at_focus.sphere_integral() - 1.0).norm() < 1e-14);
/// assert!(Aperture::new(-1.0, DVec3::Z).is_err() && Aperture::new(1.0, DVec3::ZERO).is_err());
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aperture {
    gamma: f64,
    axis: DVec3,
    ln_scale: f64,
}

impl Aperture {
    /// An aperture of concentration `gamma` (`0`: isotropic) about `axis` (normalised; it must
    /// be finite and non-zero). Errors name `concentration` or `axis`.
    pub fn new(gamma: f64, axis: DVec3) -> Result<Self, VmfError> {
        let gamma = checked_gamma(gamma)?;
        let len = axis.length();
        if !(axis.is_finite() && len > 0.0 && len.is_finite()) {
            return Err(VmfError::InvalidOption {
                field: "axis",
                reason: format!("must be finite and non-zero (got {axis})"),
            });
        }
        Ok(Self {
            gamma,
            axis: axis / len,
            ln_scale: ln_vmf_normaliser(gamma),
        })
    }

    /// The concentration `gamma`.
    pub fn gamma(&self) -> f64 {
        self.gamma
    }

    /// The unit optical axis.
    pub fn axis(&self) -> DVec3 {
        self.axis
    }

    /// The mask `m(w) = C_3(gamma) e^(gamma axis . w)` (Eq. 24, unit integral).
    pub fn mask(&self) -> ComplexVmf {
        ComplexVmf::real(self.ln_scale, self.gamma, self.axis)
    }

    /// The weighted aperture `a~(w; o) = m(w) e^(i k w . (o - focus)) e^(-tau)` (Eqs. 26-27 in
    /// source form), a complex vMF of the plane-wave direction `w`; `tau` is the field's optical
    /// half-depth `sigma_t d / 2` along the axis up to `o` (Eq. 25), `0` in vacuum. Its sphere
    /// integral is the beam's field at `o` (attenuated by `e^(-tau)`).
    pub fn weighted(&self, k: f64, focus: DVec3, o: DVec3, tau: f64) -> ComplexVmf {
        let g = self.gamma * self.axis;
        let p = k * (o - focus);
        ComplexVmf::new(
            Complex64::new(self.ln_scale - tau, 0.0),
            [
                Complex64::new(g.x, p.x),
                Complex64::new(g.y, p.y),
                Complex64::new(g.z, p.z),
            ],
        )
    }

    /// `ln Upsilon(w_out; o)`: the exact scattering connection of Eqs. 15-16,
    /// `int a~(w; o) s(w . w_out) dw = sum_m pi_m int a~(w; o) e^(gamma_m w_out . w) dw`, for
    /// the weighted aperture `weighted` and the normalised amplitude of `mixture` (Eq. 28,
    /// `int |s|^2 = 1`), summed in log form (a complex log-sum-exp). In source form `w_out` is
    /// the path direction leaving `o`; for a sensor (source form of axis `-a_v`) it is minus the
    /// direction arriving at `o`, since `s` depends only on the cosine between propagation
    /// directions.
    pub fn ln_upsilon(weighted: &ComplexVmf, mixture: &VmfMixture, w_out: DVec3) -> Complex64 {
        let terms: Vec<Complex64> = mixture
            .lobes_about(w_out)
            .iter()
            .map(|lobe| weighted.mul(lobe).ln_sphere_integral())
            .collect();
        ln_sum_exp_complex(&terms)
    }
}

/// `ln sum_j e^(z_j)` for complex `z_j`, without overflow (imaginary part modulo `2 pi`).
pub fn ln_sum_exp_complex(z: &[Complex64]) -> Complex64 {
    let m = z.iter().map(|v| v.re).fold(f64::NEG_INFINITY, f64::max);
    if !m.is_finite() {
        return Complex64::new(m, 0.0);
    }
    let s: Complex64 = z.iter().map(|v| (v - m).exp()).sum();
    s.ln() + m
}

/// A unit-integral Gaussian (von Mises) aperture in flatland: concentration `gamma` about the
/// unit axis `axis` in the plane, mask `C_2(gamma) e^(gamma axis . w)`.
///
/// ```
/// use glam::DVec2;
/// use speckle_vmf::CircleAperture;
/// let a = CircleAperture::new(16.0, DVec2::X).unwrap();
/// let at_focus = a.weighted(2.0 * std::f64::consts::PI, DVec2::ZERO, DVec2::ZERO, 0.0);
/// assert!((at_focus.circle_integral() - 1.0).norm() < 1e-14);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CircleAperture {
    gamma: f64,
    axis: DVec2,
    ln_scale: f64,
}

impl CircleAperture {
    /// An aperture of concentration `gamma` about `axis` (normalised; finite, non-zero).
    pub fn new(gamma: f64, axis: DVec2) -> Result<Self, VmfError> {
        let gamma = checked_gamma(gamma)?;
        let len = axis.length();
        if !(axis.is_finite() && len > 0.0 && len.is_finite()) {
            return Err(VmfError::InvalidOption {
                field: "axis",
                reason: format!("must be finite and non-zero (got {axis})"),
            });
        }
        Ok(Self {
            gamma,
            axis: axis / len,
            ln_scale: ln_circle_normaliser(gamma),
        })
    }

    /// The concentration `gamma`.
    pub fn gamma(&self) -> f64 {
        self.gamma
    }

    /// The unit optical axis.
    pub fn axis(&self) -> DVec2 {
        self.axis
    }

    /// The mask `m(w) = C_2(gamma) e^(gamma axis . w)`.
    pub fn mask(&self) -> CircleVmf {
        CircleVmf::real(self.ln_scale, self.gamma, self.axis)
    }

    /// The weighted aperture `m(w) e^(i k w . (o - focus)) e^(-tau)` (flatland Eqs. 26-27).
    pub fn weighted(&self, k: f64, focus: DVec2, o: DVec2, tau: f64) -> CircleVmf {
        let g = self.gamma * self.axis;
        let p = k * (o - focus);
        CircleVmf::new(
            Complex64::new(self.ln_scale - tau, 0.0),
            [Complex64::new(g.x, p.x), Complex64::new(g.y, p.y)],
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn validation_names_the_field() {
        let e = Aperture::new(f64::NAN, DVec3::Z).unwrap_err().to_string();
        assert!(e.starts_with("concentration:"), "{e}");
        let e = Aperture::new(1.0, DVec3::new(0.0, f64::INFINITY, 0.0))
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("axis:"), "{e}");
        let e = CircleAperture::new(2e7, DVec2::X).unwrap_err().to_string();
        assert!(e.starts_with("concentration:"), "{e}");
        let e = gamma_from_na(1e-4).unwrap_err().to_string();
        assert!(e.starts_with("numerical_aperture:"), "{e}");
    }

    #[test]
    fn ln_sum_exp_complex_matches_direct_sum() {
        let z = [
            Complex64::new(1.0, 0.3),
            Complex64::new(-2.0, 2.0),
            Complex64::new(0.5, -1.0),
        ];
        let direct: Complex64 = z.iter().map(|v| v.exp()).sum();
        assert!((ln_sum_exp_complex(&z).exp() - direct).norm() < 1e-14 * direct.norm());
        // Shifted by 1e5: no overflow, same phase.
        let big: Vec<Complex64> = z.iter().map(|v| v + 1e5).collect();
        let l = ln_sum_exp_complex(&big);
        assert!(((l - 1e5).exp() - direct).norm() < 1e-10 * direct.norm());
    }

    /// The vacuum beam tends to the unit plane wave as `gamma` grows: relative error ~ `k^2 r^2
    /// / gamma`-ish at fixed `x`; measured at `gamma = 1e5`, `|x - f| = 0.3` wavelengths.
    #[test]
    fn plane_wave_limit() {
        let k = 2.0 * PI;
        let a = Aperture::new(1e5, DVec3::new(0.0, 0.6, 0.8)).unwrap();
        let f = DVec3::new(0.1, -0.2, 0.3);
        let x = f + DVec3::new(0.1, 0.2, -0.1);
        let u = a.weighted(k, f, x, 0.0).sphere_integral();
        let plane = Complex64::from_polar(1.0, k * a.axis().dot(x - f));
        assert!((u - plane).norm() < 1e-4, "{u} vs {plane}");
        let c = CircleAperture::new(1e5, DVec2::new(0.6, 0.8)).unwrap();
        let (f2, x2) = (DVec2::new(0.1, -0.2), DVec2::new(0.2, 0.0));
        let u = c.weighted(k, f2, x2, 0.0).circle_integral();
        let plane = Complex64::from_polar(1.0, k * c.axis().dot(x2 - f2));
        assert!((u - plane).norm() < 1e-4, "{u} vs {plane}");
    }

    /// `gamma = 0`: the isotropic superposition `sin(kr)/(kr)` in 3D, `J_0(kr)` in flatland.
    #[test]
    fn isotropic_limit() {
        let k = 2.0 * PI;
        let a = Aperture::new(0.0, DVec3::Z).unwrap();
        for r in [1e-3, 0.37, 2.0, 15.3] {
            let x = r * DVec3::new(0.48, 0.6, 0.64);
            let u = a.weighted(k, DVec3::ZERO, x, 0.0).sphere_integral();
            let exact = (k * r).sin() / (k * r);
            assert!((u - exact).norm() < 1e-14, "r={r}: {u} vs {exact}");
        }
        let c = CircleAperture::new(0.0, DVec2::Y).unwrap();
        // J_0(2 pi) = 0.22027690853993446 (mpmath)
        let u = c
            .weighted(k, DVec2::ZERO, DVec2::new(0.6, 0.8), 0.0)
            .circle_integral();
        assert!((u - 0.220_276_908_539_934_46).norm() < 1e-14, "{u}");
    }
}
