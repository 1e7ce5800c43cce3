//! Sampling first vertices and directions around focused Gaussian beams (Bar et al. 2020,
//! Eqs. 33-36 and Sec. 6).

use glam::DVec3;
use speckle_medium::Medium;
use speckle_phase::{Dimension, PhaseFunction};

/// How the first vertex and direction of a sub-path follow the scene's focused Gaussian beams
/// (sources, and sensors in source form for the reversed order); `render.beams` in a scene file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BeamStrategy {
    /// No beam components: the configured strategies alone.
    Off,
    /// First vertices from the Gaussian-beam structure (Bar et al. 2020, Eqs. 33-36) mixed with
    /// the volume strategy; first directions from the configured strategy.
    Position,
    /// As [`BeamStrategy::Position`], and the first direction of a beam sample from the vMF pair
    /// mixture of `|Upsilon|^2` (Sec. 6, Eq. 41; 3D) mixed with the phase function about the
    /// beam's axis. The default: unbiased, and far fewer wasted samples where a beam lights a
    /// small part of the medium or the phase function is forward (notes Sec. 7.4).
    #[default]
    PositionAndDirection,
}

/// A focused Gaussian beam in source form as the tracer samples around it: the focal point, the
/// unit propagation axis through it, and the aperture's vMF concentration `gamma_a` (a sensor's
/// source form has its viewing axis reversed).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Beam {
    /// The focal point.
    pub focus: DVec3,
    /// The unit propagation axis (source form).
    pub axis: DVec3,
    /// The aperture's concentration `gamma_a >= 0`.
    pub concentration: f64,
}

/// Bins of the tabulated axial density of a beam component.
pub(crate) const BEAM_BINS: usize = 512;
/// Most amplitude lobes the direction mixture of a beam pairs (the heaviest ones).
pub(crate) const BEAM_LOBES: usize = 6;
/// The share of the phase function about the beam's axis in a beam's first direction.
pub(crate) const BEAM_PHASE_SHARE: f64 = 0.25;
/// Smallest aperture concentration used for the beam's width (an isotropic beam, `gamma_a = 0`,
/// is infinitely wide away from its focus).
const MIN_BEAM_GAMMA: f64 = 1e-3;

/// The sampler of one beam component: axial coordinate `z = (x - f) . a` from a piecewise
/// constant table of `e^(-OD(z)) / w(z)^2` over the box's extent along the axis (the z-marginal
/// of `int |e|^2 dxy`, notes Sec. 6.2, `OD` the optical depth from the medium's entry along the
/// axis line), and the transverse offset from a Gaussian of standard deviation `w(z)` per
/// transverse axis, `w(z)^2 = (gamma_a + gamma_s) / k^2 + z^2 / gamma_a` (Eq. 35). Its density is
/// exactly that of the sample (the table is the density, not an approximation of one).
#[derive(Debug, Clone)]
pub(crate) struct BeamSampler {
    focus: DVec3,
    axis: DVec3,
    /// Transverse unit axes (the second unused in flatland).
    e1: DVec3,
    e2: DVec3,
    dimension: Dimension,
    /// `(gamma_a + gamma_s) / k^2` and `1 / gamma_a`.
    waist2: f64,
    inv_gamma: f64,
    z0: f64,
    dz: f64,
    /// Cumulative bin masses (`cdf[BEAM_BINS] = 1`) and bin densities `mass / dz`.
    cdf: Vec<f64>,
    density: Vec<f64>,
    /// The direction mixture (3D with [`BeamStrategy::PositionAndDirection`]): the aperture at
    /// unit amplitude, the lobes `(gamma_m, l_m)` it pairs, and the wavenumber.
    directions: Option<BeamDirections>,
}

#[derive(Debug, Clone)]
struct BeamDirections {
    aperture: speckle_vmf::Aperture,
    lobes: Vec<(f64, f64)>,
    k: f64,
}

/// Most pairs of the direction mixture.
const MAX_PAIRS: usize = BEAM_LOBES * (BEAM_LOBES + 1) / 2;

/// The vMF pair mixture of one beam at one point: `ln` weights (normalised) and parameters.
struct Pairs {
    n: usize,
    ln_weight: [f64; MAX_PAIRS],
    r: [DVec3; MAX_PAIRS],
}

impl BeamSampler {
    /// The sampler of `beam` in `m` for wavenumber `k` and a scattering amplitude with vMF lobes
    /// `lobes` (`None`: no lobes, isotropic width and no direction mixture).
    pub(crate) fn new<M: Medium>(
        beam: &Beam,
        m: &M,
        k: f64,
        lobes: Option<&[(f64, f64)]>,
        directions: bool,
    ) -> Self {
        let dimension = m.dimension();
        let axis = beam.axis.normalize();
        let (e1, e2) = match dimension {
            Dimension::Three => axis.any_orthonormal_pair(),
            Dimension::Two => (DVec3::new(-axis.y, axis.x, 0.0), DVec3::ZERO),
        };
        let gamma_a = beam.concentration.max(MIN_BEAM_GAMMA);
        // The amplitude's mass per lobe, ln(e^l int e^(gamma mu) dw), for the waist's gamma_s
        // (the mass-weighted mean of the forward lobes) and the heaviest lobes to pair.
        let mut lobes: Vec<(f64, f64, f64)> = lobes
            .unwrap_or(&[])
            .iter()
            .map(|&(g, l)| (g, l, l + speckle_vmf::ln_sinhc(g)))
            .filter(|t| t.2.is_finite())
            .collect();
        let top = lobes.iter().map(|t| t.2).fold(f64::NEG_INFINITY, f64::max);
        let (num, den) = lobes.iter().fold((0.0, 0.0), |(a, b), t| {
            let w = (t.2 - top).exp();
            (a + w * t.0.max(0.0), b + w)
        });
        let gamma_s = if den > 0.0 { num / den } else { 0.0 };
        lobes.sort_by(|a, b| b.2.total_cmp(&a.2));
        lobes.truncate(BEAM_LOBES);
        // The box's extent along the axis.
        let b = m.bounds();
        let (lo, hi) = (b.min(), b.max());
        let (mut z_lo, mut z_hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for i in 0..8 {
            let c = DVec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            );
            let z = (c - beam.focus).dot(axis);
            z_lo = z_lo.min(z);
            z_hi = z_hi.max(z);
        }
        let dz = ((z_hi - z_lo) / BEAM_BINS as f64).max(f64::MIN_POSITIVE);
        let waist2 = (gamma_a + gamma_s) / (k * k);
        let inv_gamma = 1.0 / gamma_a;
        // ln of the unnormalised bin densities, then masses.
        let ln_f: Vec<f64> = (0..BEAM_BINS)
            .map(|i| {
                let z = z_lo + (i as f64 + 0.5) * dz;
                let od = m.optical_depth_to_infinity(beam.focus + z * axis, -axis);
                let od = if od.is_finite() { od } else { f64::INFINITY };
                -od - (waist2 + z * z * inv_gamma).ln()
            })
            .collect();
        let top = ln_f.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let mass: Vec<f64> = if top.is_finite() {
            ln_f.iter().map(|l| (l - top).exp()).collect()
        } else {
            vec![1.0; BEAM_BINS]
        };
        let total: f64 = mass.iter().sum();
        let mut cdf = Vec::with_capacity(BEAM_BINS + 1);
        let mut acc = 0.0;
        cdf.push(0.0);
        for w in &mass {
            acc += w / total;
            cdf.push(acc);
        }
        cdf[BEAM_BINS] = 1.0;
        let density = mass.iter().map(|w| w / total / dz).collect();
        let directions = (directions && dimension == Dimension::Three && !lobes.is_empty())
            .then(|| {
                speckle_vmf::Aperture::new(beam.concentration, axis)
                    .ok()
                    .map(|aperture| BeamDirections {
                        aperture,
                        lobes: lobes.iter().map(|t| (t.0, t.1)).collect(),
                        k,
                    })
            })
            .flatten();
        Self {
            focus: beam.focus,
            axis,
            e1,
            e2,
            dimension,
            waist2,
            inv_gamma,
            z0: z_lo,
            dz,
            cdf,
            density,
            directions,
        }
    }

    /// Whether first directions sampled around this beam follow its direction mixture.
    #[inline]
    pub(crate) fn samples_directions(&self) -> bool {
        self.directions.is_some()
    }

    /// The density of the point `x`.
    #[inline]
    pub(crate) fn pdf(&self, x: DVec3) -> f64 {
        let d = x - self.focus;
        let z = d.dot(self.axis);
        let t = (z - self.z0) / self.dz;
        if !(t >= 0.0 && t < BEAM_BINS as f64) {
            return 0.0;
        }
        let pz = self.density[t as usize];
        let w2 = self.waist2 + z * z * self.inv_gamma;
        let r = d - z * self.axis;
        let r2 = r.length_squared();
        let gauss = match self.dimension {
            Dimension::Three => (-0.5 * r2 / w2).exp() / (std::f64::consts::TAU * w2),
            Dimension::Two => (-0.5 * r2 / w2).exp() / (std::f64::consts::TAU * w2).sqrt(),
        };
        pz * gauss
    }

    /// A point sampled from the beam with three variates.
    #[inline]
    pub(crate) fn sample(&self, u: [f64; 3]) -> DVec3 {
        // The bin by its cumulative mass, then uniform within it.
        let i = self.cdf.partition_point(|&c| c <= u[0]).clamp(1, BEAM_BINS) - 1;
        let span = self.cdf[i + 1] - self.cdf[i];
        let f = if span > 0.0 {
            ((u[0] - self.cdf[i]) / span).clamp(0.0, 1.0)
        } else {
            0.5
        };
        let z = self.z0 + (i as f64 + f) * self.dz;
        let w = (self.waist2 + z * z * self.inv_gamma).sqrt();
        // Box-Muller: a 2D (3D) or 1D (flatland) standard normal offset.
        let rho = (-2.0 * (-u[1]).ln_1p()).sqrt() * w;
        let (s, c) = (std::f64::consts::TAU * u[2]).sin_cos();
        let off = match self.dimension {
            Dimension::Three => rho * (c * self.e1 + s * self.e2),
            Dimension::Two => rho * c * self.e1,
        };
        self.focus + z * self.axis + off
    }

    /// The vMF pair mixture of `|Upsilon(w; x)|^2` (notes Sec. 6.3): the aperture at `x`, each
    /// lobe's convolution linearised about the beam's axis (Eqs. 31-32, refused past the bound
    /// the exact convolution obeys), phases dropped, and every unordered pair of lobes a real vMF
    /// `e^(a_1 + a_2 + (r_1 + r_2) . w)` weighted by its integral (cross terms counted twice).
    fn pairs(&self, d: &BeamDirections, x: DVec3) -> Pairs {
        let a = d.aperture.weighted(d.k, self.focus, x, 0.0);
        let re_norm =
            |v: &speckle_vmf::ComplexVmf| DVec3::new(v.mu[0].re, v.mu[1].re, v.mu[2].re).length();
        let ln4pi = (4.0 * std::f64::consts::PI).ln();
        let mut lobe = [(0.0, DVec3::ZERO); BEAM_LOBES];
        let mut n = 0;
        for &(gamma, l) in &d.lobes {
            let Some(c) = a.convolve_approx(gamma, self.axis) else {
                continue;
            };
            let bound = a.log_scale.re + ln4pi + re_norm(&a) + gamma.abs();
            let r = DVec3::new(c.mu[0].re, c.mu[1].re, c.mu[2].re);
            let s = c.log_scale.re + l;
            if c.log_scale.re + r.length() <= bound && s.is_finite() && r.is_finite() {
                lobe[n] = (s, r);
                n += 1;
            }
        }
        let mut p = Pairs {
            n: 0,
            ln_weight: [0.0; MAX_PAIRS],
            r: [DVec3::ZERO; MAX_PAIRS],
        };
        for i in 0..n {
            for j in i..n {
                let r = lobe[i].1 + lobe[j].1;
                let twice = if i == j { 0.0 } else { std::f64::consts::LN_2 };
                p.ln_weight[p.n] =
                    lobe[i].0 + lobe[j].0 + twice + speckle_vmf::ln_sinhc(r.length());
                p.r[p.n] = r;
                p.n += 1;
            }
        }
        let top = p.ln_weight[..p.n]
            .iter()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max);
        let sum: f64 = p.ln_weight[..p.n].iter().map(|w| (w - top).exp()).sum();
        let ln_total = top + sum.ln();
        if !ln_total.is_finite() {
            p.n = 0;
        }
        for w in &mut p.ln_weight[..p.n] {
            *w -= ln_total;
        }
        p
    }

    /// The density of the first direction `w` at `x` under this beam's direction strategy: the
    /// share [`BEAM_PHASE_SHARE`] of the phase function `phase` about the axis and the rest of
    /// the vMF pair mixture (all of the phase function where no lobe pairs).
    #[inline]
    pub(crate) fn direction_pdf<P: PhaseFunction>(&self, phase: &P, x: DVec3, w: DVec3) -> f64 {
        let along = phase.pdf_direction(self.axis, w);
        let Some(d) = &self.directions else {
            return along;
        };
        let p = self.pairs(d, x);
        if p.n == 0 {
            return along;
        }
        let pairs: f64 = (0..p.n)
            .map(|i| {
                let kappa = p.r[i].length();
                (p.ln_weight[i] + speckle_vmf::ln_vmf_normaliser(kappa) + p.r[i].dot(w)).exp()
            })
            .sum();
        BEAM_PHASE_SHARE * along + (1.0 - BEAM_PHASE_SHARE) * pairs
    }

    /// A first direction at `x` from this beam's direction strategy, with the variate `c` in
    /// `[0, 1)` choosing the phase function or a pair and two for the direction.
    #[inline]
    pub(crate) fn sample_direction<P: PhaseFunction>(
        &self,
        phase: &P,
        x: DVec3,
        c: f64,
        u: [f64; 2],
    ) -> DVec3 {
        let pairs = match &self.directions {
            Some(d) if c >= BEAM_PHASE_SHARE => self.pairs(d, x),
            _ => return phase.sample_direction(self.axis, u),
        };
        if pairs.n == 0 {
            return phase.sample_direction(self.axis, u);
        }
        let mut t = (c - BEAM_PHASE_SHARE) / (1.0 - BEAM_PHASE_SHARE);
        let mut k = pairs.n - 1;
        for i in 0..pairs.n {
            let w = pairs.ln_weight[i].exp();
            if t < w {
                k = i;
                break;
            }
            t -= w;
        }
        speckle_vmf::sample_sphere_vmf(pairs.r[k], u)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use speckle_medium::{Aabb, HomogeneousBox};

    /// Mean and standard error of `f` over `n` draws.
    fn mean_se(n: usize, mut f: impl FnMut() -> f64) -> (f64, f64) {
        let (mut a, mut a2) = (0.0, 0.0);
        for _ in 0..n {
            let y = f();
            a += y;
            a2 += y * y;
        }
        let m = a / n as f64;
        (m, ((a2 / n as f64 - m * m) / n as f64).sqrt())
    }

    /// A beam component in 3D (axis tilted, focus inside the box) and in flatland.
    fn beam_cases() -> Vec<(HomogeneousBox, BeamSampler)> {
        let lobes = [(0.0, -1.2), (8.0, -2.0), (30.0, -9.0)];
        let b3 = Aabb::new(DVec3::new(-3.0, -3.0, 0.0), DVec3::new(3.0, 3.0, 4.0)).unwrap();
        let m3 = HomogeneousBox::new(b3, 0.6, 0.1).unwrap();
        let beam3 = Beam {
            focus: DVec3::new(0.5, -0.3, 1.5),
            axis: DVec3::new(0.2, 0.1, 1.0).normalize(),
            concentration: 16.0,
        };
        let s3 = BeamSampler::new(&beam3, &m3, std::f64::consts::TAU, Some(&lobes), true);
        let b2 = Aabb::flat(glam::DVec2::new(-3.0, 0.0), glam::DVec2::new(3.0, 4.0)).unwrap();
        let m2 = HomogeneousBox::new(b2, 0.6, 0.1).unwrap();
        let beam2 = Beam {
            focus: DVec3::new(0.5, 1.0, 0.0),
            axis: DVec3::new(-0.3, -1.0, 0.0).normalize(),
            concentration: 4.0,
        };
        let s2 = BeamSampler::new(&beam2, &m2, std::f64::consts::TAU, Some(&lobes), true);
        vec![(m3, s3), (m2, s2)]
    }

    /// The beam component's `pdf` is the density `sample` draws from: `E[1/q(x); x in box]` is
    /// the box's measure (3D and flatland), and a density 10% off is caught at more than 6
    /// standard errors; a histogram of the axial coordinate matches the tabulated marginal.
    #[test]
    fn beam_density_is_the_density_sampled() {
        for (m, s) in beam_cases() {
            let b = *m.bounds();
            let mut rng = crate::PathRng::new(21, 0);
            let n = 400_000;
            let mut inside = vec![];
            let (mean, se) = mean_se(n, || {
                let x = s.sample(rng.next_3());
                if b.contains(x) {
                    inside.push(x);
                    1.0 / s.pdf(x)
                } else {
                    0.0
                }
            });
            let measure = b.measure();
            let z = (mean - measure) / se;
            assert!(z.abs() < 4.0, "{mean} +- {se} vs {measure}");
            assert!(se < 0.05 * measure, "{se}");
            let wrong = (mean / 1.1 - measure) / (se / 1.1);
            assert!(wrong.abs() > 6.0, "a 10% pdf error gives z = {wrong}");
            // Histogram of z over 16 coarse bins against the table's mass (all samples).
            let mut rng = crate::PathRng::new(22, 0);
            let mut counts = [0u64; 16];
            let m_total = 200_000;
            for _ in 0..m_total {
                let x = s.sample(rng.next_3());
                let t = ((x - s.focus).dot(s.axis) - s.z0) / s.dz;
                counts[((t as usize) * 16 / BEAM_BINS).min(15)] += 1;
            }
            let step = BEAM_BINS / 16;
            let expect: Vec<f64> = (0..16)
                .map(|i| s.cdf[(i + 1) * step] - s.cdf[i * step])
                .collect();
            // Pearson's statistic against the 0.999 quantile for 15 degrees of freedom (37.7).
            let chi2: f64 = counts
                .iter()
                .zip(&expect)
                .map(|(&c, &q)| {
                    let e = q * m_total as f64;
                    (c as f64 - e).powi(2) / e
                })
                .sum();
            assert!(chi2 < 37.7, "chi2 {chi2}");
        }
    }

    /// The beam's direction density integrates to one over the sphere (circle): `E[1/p(w)]` over
    /// its own samples is `4 pi` (`2 pi`) at points on and off the axis, and a 10% error in
    /// the density is caught.
    #[test]
    fn beam_direction_density_is_the_density_sampled() {
        use speckle_phase::Phase;
        for (m, s) in beam_cases() {
            let (phase, full) = match m.dimension() {
                Dimension::Three => (Phase::hg(0.7).unwrap(), 4.0 * std::f64::consts::PI),
                Dimension::Two => (Phase::flat_hg(0.7).unwrap(), std::f64::consts::TAU),
            };
            assert_eq!(s.samples_directions(), m.dimension() == Dimension::Three);
            let off = match m.dimension() {
                Dimension::Three => s.e1 * 0.8,
                Dimension::Two => s.e1 * 0.5,
            };
            for x in [s.focus, s.focus + 1.0 * s.axis + off, s.focus - s.axis] {
                let mut rng = crate::PathRng::new(23, 0);
                let n = 200_000;
                let (mean, se) = mean_se(n, || {
                    let c = rng.next_f64();
                    let w = s.sample_direction(&phase, x, c, rng.next_2());
                    assert!((w.length() - 1.0).abs() < 1e-9, "{w}");
                    1.0 / s.direction_pdf(&phase, x, w)
                });
                assert!(
                    (mean - full).abs() < 4.0 * se,
                    "{x}: {mean} +- {se} vs {full}"
                );
                assert!(se < 0.05 * full, "{se}");
                assert!((mean / 1.1 - full).abs() > 10.0 * se / 1.1);
            }
        }
    }
}
