//! The sphere integrals of a vertex's Gaussian connections, many at once (issue 30, item 2).
//!
//! Every connection of a Gaussian beam is a sum over the amplitude's vMF lobes of sphere
//! integrals of complex vMFs, `int e^(l + mu . w) dw = 4 pi e^l sinh(b) / b`, `b = sqrt(mu . mu)`
//! (Eq. 29). [`ComplexVmf::ln_sphere_integral`] evaluates one in log form with the standard
//! library's complex square root, logarithms and exponential (about a dozen `hypot`, `atan2`,
//! `sin_cos`, `exp_m1` and `log` calls); here a [`Batch`] collects the integrals of a vertex's
//! connections (every beam and lobe) and evaluates them in chunks of [`LANES`] with only
//! arithmetic, square roots and the branch-free [`crate::fastmath`] kernels, a loop that the
//! compiler vectorises, compiled for the CPU's widest vector instructions and chosen at run time
//! (`pulp`). No fused multiply-adds are formed, so every instruction set gives the same bits.
//!
//! **Method.** With `s = mu . mu` (complex) and `r = |s| = |b|^2`:
//!
//! - `r < 1/4` (`|b| < 1/2`): `4 pi e^l (1 + s/3! + s^2/5! + ... + s^7/15!)`, the Taylor series
//!   of `sinh(b) / b` in `s` (no root needed; the next term is below `4e-20`).
//! - otherwise: the principal root `b` (`Re b >= 0`) from `t = sqrt((r + |Re s|) / 2)` without
//!   cancellation, and `4 pi e^(l + b) (1 - e^(-2 b)) / (2 b)`, where
//!   `1 - e^(-2 b) = (1 - E) + 2 E sin^2(y) + 2 i E sin(y) cos(y)`, `E = e^(-2 Re b)`,
//!   `y = Im b`, with `1 - E` from its Taylor series where `2 Re b < 1/2` (no cancellation next to
//!   the zeros of `sinh`), and the division by `2 b` as the product with `conj(b) / (2 r)`.
//!
//! The magnitude `e^(Re l + Re b)` and the phase `Im l + Im b` are exponentiated once, as the
//! log form does, so nothing overflows that the value itself would not. Lanes whose phases are
//! beyond [`crate::fastmath::SIN_COS_MAX`], or whose `|s|` is not finite, are recomputed by the
//! log form. Agreement with [`ComplexVmf::ln_sphere_integral`]: this module's tests (within two
//! roundings of the phase, in units of the integral's scale `|e^(l + b)| / |b|`). Flatland
//! (`2 pi I_0(b)`) takes the log form lane by lane.

use crate::fastmath::{exp, in_sin_cos_range, sin_cos_reduced};
use num_complex::Complex64;
use speckle_vmf::ComplexVmf;

/// Integrals per chunk: two 512-bit vectors of `f64` per array.
pub(crate) const LANES: usize = 16;

/// The lanes the kernel evaluates together (one 512-bit vector of `f64`; a partly filled
/// chunk costs whole groups only).
const GROUP: usize = 8;

/// Chunks of at most this many lanes are evaluated lane by lane.
const SCALAR: usize = 2;

/// `ln(4 pi)`.
const LN_4PI: f64 = 2.531_024_246_969_290_7;

/// The integrals waiting to be evaluated, structure of arrays, each with the index of what it
/// adds to (its owner) and a complex factor, or a value known already (so that every owner
/// receives its terms in the order they were pushed, whatever the chunk boundaries).
#[derive(Debug, Clone)]
pub(crate) struct Batch {
    three: bool,
    n: usize,
    ls_re: [f64; LANES],
    ls_im: [f64; LANES],
    mu_re: [[f64; LANES]; 3],
    mu_im: [[f64; LANES]; 3],
    /// Per lane, the factor of its integral, or its value where `known` has its bit.
    extra: [Complex64; LANES],
    known: u32,
    owner: [usize; LANES],
}

impl Batch {
    /// An empty batch for a 3D medium (`three`) or flatland.
    pub(crate) fn new(three: bool) -> Self {
        Self {
            three,
            n: 0,
            ls_re: [0.0; LANES],
            ls_im: [0.0; LANES],
            mu_re: [[0.0; LANES]; 3],
            mu_im: [[0.0; LANES]; 3],
            extra: [Complex64::new(1.0, 0.0); LANES],
            known: 0,
            owner: [0; LANES],
        }
    }

    /// Queues `factor * int e^(log_scale + mu . w) dw` for `owner`; evaluates the chunk into
    /// `sink(owner, value)` when it is full.
    #[inline]
    pub(crate) fn push(
        &mut self,
        owner: usize,
        factor: Complex64,
        log_scale: Complex64,
        mu: [Complex64; 3],
        sink: &mut impl FnMut(usize, Complex64),
    ) {
        let l = self.n;
        self.ls_re[l] = log_scale.re;
        self.ls_im[l] = log_scale.im;
        for (a, m) in mu.iter().enumerate() {
            self.mu_re[a][l] = m.re;
            self.mu_im[a][l] = m.im;
        }
        self.extra[l] = factor;
        self.known &= !(1 << l);
        self.owner[l] = owner;
        self.n += 1;
        if self.n == LANES {
            self.flush(sink);
        }
    }

    /// Queues the value `value` for `owner` (passed on in order with the integrals).
    #[inline]
    pub(crate) fn push_value(
        &mut self,
        owner: usize,
        value: Complex64,
        sink: &mut impl FnMut(usize, Complex64),
    ) {
        let l = self.n;
        // A harmless integrand (mu = 0) keeps the lane's arithmetic finite.
        self.ls_re[l] = 0.0;
        self.ls_im[l] = 0.0;
        for a in 0..3 {
            self.mu_re[a][l] = 0.0;
            self.mu_im[a][l] = 0.0;
        }
        self.extra[l] = value;
        self.known |= 1 << l;
        self.owner[l] = owner;
        self.n += 1;
        if self.n == LANES {
            self.flush(sink);
        }
    }

    /// Evaluates the queued lanes into `sink(owner, value)`, in the order they were pushed.
    pub(crate) fn flush(&mut self, sink: &mut impl FnMut(usize, Complex64)) {
        let n = self.n;
        if n == 0 {
            return;
        }
        self.n = 0;
        let (mut re, mut im) = ([0.0; LANES], [0.0; LANES]);
        let fine = if !self.three {
            0
        } else if n <= SCALAR {
            // A vector group would compute mostly empty lanes: the same arithmetic lane by lane
            // (bitwise the same).
            let mut fine = 0;
            for l in 0..n {
                let (mu_re, mu_im) = (self.mu_re.map(|m| m[l]), self.mu_im.map(|m| m[l]));
                let (v, ok) = sphere_integral(self.ls_re[l], self.ls_im[l], mu_re, mu_im);
                (re[l], im[l]) = (v.re, v.im);
                fine |= (ok as u32) << l;
            }
            fine
        } else {
            pulp::Arch::new().dispatch(Kernel {
                b: self,
                n,
                re: &mut re,
                im: &mut im,
            })
        };
        for l in 0..n {
            let v = if self.known & (1 << l) != 0 {
                self.extra[l]
            } else if fine & (1 << l) != 0 {
                Complex64::new(re[l], im[l]) * self.extra[l]
            } else {
                self.log_form(l) * self.extra[l]
            };
            sink(self.owner[l], v);
        }
    }

    /// Lane `l`'s integral by the log form of `speckle-vmf` (flatland, and the lanes the
    /// kernel leaves).
    #[cold]
    fn log_form(&self, l: usize) -> Complex64 {
        let ls = Complex64::new(self.ls_re[l], self.ls_im[l]);
        let mu = std::array::from_fn(|a| Complex64::new(self.mu_re[a][l], self.mu_im[a][l]));
        super::near::ln_integral(&ComplexVmf::new(ls, mu), self.three).exp()
    }
}

/// The vectorised evaluation of a full chunk; returns the mask of lanes it computed exactly.
struct Kernel<'a> {
    b: &'a Batch,
    /// The lanes in use (the kernel runs whole groups of [`GROUP`]).
    n: usize,
    re: &'a mut [f64; LANES],
    im: &'a mut [f64; LANES],
}

impl pulp::WithSimd for Kernel<'_> {
    type Output = u32;
    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) -> u32 {
        let b = self.b;
        let mut mask = 0u32;
        for g in 0..self.n.div_ceil(GROUP) {
            let r = g * GROUP..(g + 1) * GROUP;
            let group = |a: &[f64; LANES]| -> [f64; GROUP] {
                a[r.clone()].try_into().expect("a whole group")
            };
            let (ls_re, ls_im) = (group(&b.ls_re), group(&b.ls_im));
            let mu_re = b.mu_re.each_ref().map(group);
            let mu_im = b.mu_im.each_ref().map(group);
            let (mut re, mut im, mut fine) = ([0.0; GROUP], [0.0; GROUP], [false; GROUP]);
            for j in 0..GROUP {
                let m_re = [mu_re[0][j], mu_re[1][j], mu_re[2][j]];
                let m_im = [mu_im[0][j], mu_im[1][j], mu_im[2][j]];
                let (v, ok) = sphere_integral(ls_re[j], ls_im[j], m_re, m_im);
                re[j] = v.re;
                im[j] = v.im;
                fine[j] = ok;
            }
            self.re[r.clone()].copy_from_slice(&re);
            self.im[r.clone()].copy_from_slice(&im);
            for (j, ok) in fine.iter().enumerate() {
                mask |= (*ok as u32) << (r.start + j);
            }
        }
        mask
    }
}

/// `1 - e^u` for `-1/2 < u <= 0` by its Taylor series to `u^15` (relative error below `1e-17`).
#[inline(always)]
fn one_minus_exp_small(u: f64) -> f64 {
    // -(u + u^2/2! + ... + u^15/15!) = -u (1 + u/2! + ... + u^14/15!), Estrin's scheme.
    let u2 = u * u;
    let u4 = u2 * u2;
    let u8 = u4 * u4;
    let a0 = 1.0 + u * (1.0 / 2.0);
    let a1 = 1.0 / 6.0 + u * (1.0 / 24.0);
    let a2 = 1.0 / 120.0 + u * (1.0 / 720.0);
    let a3 = 1.0 / 5_040.0 + u * (1.0 / 40_320.0);
    let a4 = 1.0 / 362_880.0 + u * (1.0 / 3_628_800.0);
    let a5 = 1.0 / 39_916_800.0 + u * (1.0 / 479_001_600.0);
    let a6 = 1.0 / 6_227_020_800.0 + u * (1.0 / 87_178_291_200.0);
    let a7 = 1.0 / 1_307_674_368_000.0;
    let b0 = a0 + a1 * u2;
    let b1 = a2 + a3 * u2;
    let b2 = a4 + a5 * u2;
    let b3 = a6 + a7 * u2;
    let q = (b0 + b1 * u4) + (b2 + b3 * u4) * u8;
    -(u * q)
}

/// `int e^(l + mu . w) dw` over the unit sphere for `l = ls_re + i ls_im`,
/// `mu = mu_re + i mu_im`, branch-free (module docs), and whether the kernels were in range.
#[inline(always)]
pub(crate) fn sphere_integral(
    ls_re: f64,
    ls_im: f64,
    mu_re: [f64; 3],
    mu_im: [f64; 3],
) -> (Complex64, bool) {
    // s = mu . mu (bilinear).
    let s_re = (mu_re[0] * mu_re[0] - mu_im[0] * mu_im[0])
        + (mu_re[1] * mu_re[1] - mu_im[1] * mu_im[1])
        + (mu_re[2] * mu_re[2] - mu_im[2] * mu_im[2]);
    let s_im = 2.0 * ((mu_re[0] * mu_im[0] + mu_re[1] * mu_im[1]) + mu_re[2] * mu_im[2]);
    let r = (s_re * s_re + s_im * s_im).sqrt();
    // The principal root b of s, Re b >= 0, without cancellation.
    let t = (0.5 * (r + s_re.abs())).sqrt();
    // One division for both quotients: 1 / (t r).
    let d = 1.0 / (t * r);
    let u = 0.5 * s_im.abs() * (r * d);
    let positive = s_re >= 0.0;
    let b_re = if positive { t } else { u };
    let b_im = (if positive { u } else { t }).copysign(s_im);
    // (1 - e^(-2 b)) / (2 b) = (1 - e^(-2 b)) conj(b) / (2 r).
    let big_e = exp(-2.0 * b_re);
    let (sy, cy) = sin_cos_reduced(b_im);
    let small = -2.0 * b_re > -0.5;
    let one_minus_e = if small {
        one_minus_exp_small(-2.0 * b_re)
    } else {
        1.0 - big_e
    };
    let a_re = one_minus_e + 2.0 * big_e * (sy * sy);
    let a_im = 2.0 * big_e * (sy * cy);
    let inv = 0.5 * (t * d);
    let f_re = (a_re * b_re + a_im * b_im) * inv;
    let f_im = (a_im * b_re - a_re * b_im) * inv;
    // 1 + s/3! + ... + s^7/15! by Horner's scheme in complex arithmetic.
    let coeff = [
        1.0 / 1_307_674_368_000.0,
        1.0 / 6_227_020_800.0,
        1.0 / 39_916_800.0,
        1.0 / 362_880.0,
        1.0 / 5040.0,
        1.0 / 120.0,
        1.0 / 6.0,
        1.0,
    ];
    let (mut p_re, mut p_im) = (coeff[0], 0.0);
    for c in &coeff[1..] {
        let re = (s_re * p_re - s_im * p_im) + c;
        p_im = s_re * p_im + s_im * p_re;
        p_re = re;
    }
    let series = r < 0.25;
    let (m_re, m_im) = if series { (p_re, p_im) } else { (f_re, f_im) };
    let x = ls_re + LN_4PI + if series { 0.0 } else { b_re };
    let phi = ls_im + if series { 0.0 } else { b_im };
    let mag = exp(x);
    let (sp, cp) = sin_cos_reduced(phi);
    let v_re = mag * (cp * m_re - sp * m_im);
    let v_im = mag * (cp * m_im + sp * m_re);
    let fine = in_sin_cos_range(phi) && (series || in_sin_cos_range(b_im)) && r < 1e300;
    (Complex64::new(v_re, v_im), fine)
}

/// `int h(w) dw` over the sphere (3D) or the circle (flatland) as a value: the branch-free
/// kernel of [`sphere_integral`] in 3D, the log form where it is out of range and in flatland.
pub(crate) fn integral(h: &ComplexVmf, three: bool) -> Complex64 {
    if three {
        let (re, im) = (h.mu.map(|m| m.re), h.mu.map(|m| m.im));
        let (v, fine) = sphere_integral(h.log_scale.re, h.log_scale.im, re, im);
        if fine {
            return v;
        }
    }
    super::near::ln_integral(h, three).exp()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn uniform(seed: u64) -> impl FnMut() -> f64 {
        let mut rng = speckle_stats::PathRng::new(seed, 0);
        move || rng.next_f64()
    }

    /// Random complex vMFs over the scales the connections meet: `|mu|` from `1e-3` to `3e3`
    /// (series and full forms), any phase, real parts of either sign.
    fn random_vmf(next: &mut impl FnMut() -> f64) -> ComplexVmf {
        let mut part = || {
            let size = 10f64.powf(-3.0 + 6.5 * next());
            let d = DVec3::new(next() - 0.5, next() - 0.5, next() - 0.5).normalize();
            size * d
        };
        let (re, im) = (part(), part());
        let ls = Complex64::new(-re.length() + 3.0 * (next() - 0.5), 200.0 * (next() - 0.5));
        ComplexVmf::new(ls, std::array::from_fn(|a| Complex64::new(re[a], im[a])))
    }

    use glam::DVec3;

    /// The error of an integral against the log form, in units of the rounding it is computed
    /// with: the scale `|e^(l + b)| / |b|` (the magnitude of the terms of `sinh(b) / b`, or
    /// the value's own magnitude where larger) times the rounding of its phase, `2^-52` of
    /// `1 + |Im l| + |b|` (both forms exponentiate the phase `Im l + Im b`).
    fn error(h: &ComplexVmf, got: Complex64) -> f64 {
        let want = h.ln_sphere_integral().exp();
        let b = h.beta();
        let scale = (h.log_scale.re + LN_4PI + b.re.abs()).exp() / b.norm().max(0.5);
        let rounding = f64::EPSILON * (1.0 + h.log_scale.im.abs() + b.norm());
        (got - want).norm() / (scale.max(want.norm()) * rounding)
    }

    #[test]
    fn batch_integrals_match_the_log_form() {
        let mut next = uniform(5);
        let (mut worst, mut count) = (0.0f64, 0);
        let mut batch = Batch::new(true);
        let vmfs: Vec<ComplexVmf> = (0..20_000).map(|_| random_vmf(&mut next)).collect();
        let mut got = vec![Complex64::new(0.0, 0.0); vmfs.len()];
        let factor = Complex64::new(1.0, 0.0);
        {
            let sink = &mut |i: usize, v: Complex64| got[i] += v;
            for (i, h) in vmfs.iter().enumerate() {
                batch.push(i, factor, h.log_scale, h.mu, sink);
            }
            batch.flush(sink);
        }
        for (h, g) in vmfs.iter().zip(&got) {
            let e = error(h, *g);
            worst = worst.max(e);
            count += (h.mu_squared().norm() < 0.25) as usize;
        }
        eprintln!("20 000 integrals ({count} by the series): worst error {worst:.2} roundings");
        assert!(count > 1000, "the series form was exercised {count} times");
        assert!(worst < 16.0, "worst error {worst} roundings");
    }

    /// Next to the zeros of `sinh` (`b = i pi n`, Re b small) and across the series radius.
    #[test]
    fn integrals_near_the_zeros_of_sinh_and_the_series_edge() {
        let mut worst = 0.0f64;
        for n in 1..40 {
            for eps in [1e-12, 1e-8, 1e-4, 0.01, 0.2, 0.24] {
                for b in [
                    Complex64::new(eps, std::f64::consts::PI * n as f64),
                    Complex64::new(eps, std::f64::consts::PI * n as f64 + eps),
                    Complex64::new(0.5 - eps, 0.1 * n as f64),
                    Complex64::new(0.0, 0.5 + eps * (n as f64 - 20.0) / 20.0),
                ] {
                    // mu = (b, 0, 0) has mu . mu = b^2.
                    let z = Complex64::new(0.0, 0.0);
                    let h = ComplexVmf::new(Complex64::new(-1.0, 3.0), [b, z, z]);
                    let e = error(&h, integral(&h, true));
                    worst = worst.max(e);
                }
            }
        }
        eprintln!("near the zeros of sinh: worst error {worst:.2} roundings");
        assert!(worst < 16.0, "worst error {worst} roundings");
    }

    /// The dispatched kernel gives the bits of the scalar function compiled for the baseline,
    /// and lanes out of the kernels' range (huge phases, non-finite parameters) take the log
    /// form.
    #[test]
    fn dispatched_batch_is_bitwise_the_scalar_kernel() {
        let mut next = uniform(9);
        let mut vmfs: Vec<ComplexVmf> = (0..999).map(|_| random_vmf(&mut next)).collect();
        vmfs[7].log_scale.im = 1e8;
        vmfs[300].mu[1].im = 2e7;
        let mut got = vec![Complex64::new(0.0, 0.0); vmfs.len()];
        {
            let sink = &mut |i: usize, v: Complex64| got[i] = v;
            let mut batch = Batch::new(true);
            for (i, h) in vmfs.iter().enumerate() {
                batch.push(i, Complex64::new(1.0, 0.0), h.log_scale, h.mu, sink);
            }
            batch.flush(sink);
        }
        for (i, (h, g)) in vmfs.iter().zip(&got).enumerate() {
            let (re, im) = (h.mu.map(|m| m.re), h.mu.map(|m| m.im));
            let (v, fine) = sphere_integral(h.log_scale.re, h.log_scale.im, re, im);
            if fine {
                // The batch applies each lane's factor (here 1) after the kernel.
                let v = v * Complex64::new(1.0, 0.0);
                assert_eq!(
                    (v.re.to_bits(), v.im.to_bits()),
                    (g.re.to_bits(), g.im.to_bits())
                );
            } else {
                assert!(i == 7 || i == 300, "lane {i} left the kernel");
                let want = h.ln_sphere_integral().exp();
                assert!(*g == want, "lane {i}: {g} against {want}");
            }
        }
    }
}
