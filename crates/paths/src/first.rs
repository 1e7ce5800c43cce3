//! Strategies for the first vertex and the first direction of a sub-path.

use crate::{PathError, direction_in};
use glam::DVec3;
use speckle_medium::Medium;
use speckle_phase::{Dimension, PhaseFunction};

/// How the first vertex `x1` of a sub-path is sampled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FirstVertex {
    /// Density `q_o(x) = sigma_s(x) / V` (Eq. 35): uniform in a homogeneous medium.
    Uniform,
    /// Exponential in depth along the box axis closest to `direction` (the illumination axis),
    /// entering through the face that light from `direction` meets first, at the medium's
    /// extinction rate and truncated to the box; uniform across the other two axes. Concentrates
    /// samples where a plane wave arrives in an optically thick medium.
    ///
    /// Variance warning: with reversed paths the reversed term connects the source to the *last*
    /// vertex, so a rare deep first vertex carries a weight up to `e^{OD}`. In thick slabs seen in
    /// transmission with forward and reversed paths, prefer [`FirstVertex::Uniform`] (at optical
    /// depth 10 the standard error was about 20 times larger than forward-only).
    ExponentialDepth {
        /// The illumination's propagation direction.
        direction: DVec3,
    },
}

/// How the first direction `w1` is sampled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FirstDirection {
    /// Uniform on the sphere, density `1 / (4 pi)` (on the circle in flatland, `1 / (2 pi)`).
    Uniform,
    /// From the medium's phase function around `axis`, density `rho(axis . w1)`.
    Phase {
        /// The axis the phase function is centred on (for example the illumination direction).
        axis: DVec3,
    },
}

/// A first-vertex strategy resolved against a medium.
#[derive(Debug, Clone, Copy)]
pub(crate) enum FirstVertexSampler {
    Uniform {
        inv_v: f64,
    },
    Exponential {
        axis: usize,
        sign: f64,
        rate: f64,
        depth: f64,
        norm: f64,
        inv_area: f64,
    },
}

impl FirstVertexSampler {
    pub(crate) fn new<M: Medium>(s: FirstVertex, m: &M) -> Result<Self, PathError> {
        match s {
            FirstVertex::Uniform => Ok(Self::Uniform {
                inv_v: 1.0 / m.scattering_volume(),
            }),
            FirstVertex::ExponentialDepth { direction } => {
                let d = direction_in("first_vertex.direction", direction, m.dimension())?;
                let rate = m
                    .uniform_sigma_t()
                    .ok_or(PathError::NeedsHomogeneous("exponential-depth"))?;
                let axis = d.abs().max_position();
                let size = m.bounds().size();
                let depth = size[axis];
                // The transverse area (a length in flatland).
                let area = m.bounds().measure() / depth;
                Ok(Self::Exponential {
                    axis,
                    sign: d[axis].signum(),
                    rate,
                    depth,
                    // 1 - exp(-rate * depth), the truncation of the exponential.
                    norm: -(-rate * depth).exp_m1(),
                    inv_area: 1.0 / area,
                })
            }
        }
    }

    /// The density of `x` (inside the medium's box).
    pub(crate) fn pdf<M: Medium>(&self, m: &M, x: DVec3) -> f64 {
        match *self {
            Self::Uniform { inv_v } => m.sigma_s(x) * inv_v,
            Self::Exponential {
                axis,
                sign,
                rate,
                norm,
                inv_area,
                ..
            } => {
                let b = m.bounds();
                let t = if sign >= 0.0 {
                    x[axis] - b.min()[axis]
                } else {
                    b.max()[axis] - x[axis]
                };
                rate * (-rate * t).exp() / norm * inv_area
            }
        }
    }

    /// A point and its density.
    #[inline]
    pub(crate) fn sample<M: Medium>(&self, m: &M, u: [f64; 3]) -> (DVec3, f64) {
        match *self {
            Self::Uniform { inv_v } => {
                let x = m.sample_scatterer(u);
                (x, m.sigma_s(x) * inv_v)
            }
            Self::Exponential {
                axis,
                sign,
                rate,
                depth,
                norm,
                inv_area,
            } => {
                // Depth t in [0, depth) with density rate exp(-rate t) / norm.
                let t = (-(-u[0] * norm).ln_1p() / rate).min(depth);
                let c = match axis {
                    0 => [0.0, u[1], u[2]],
                    1 => [u[1], 0.0, u[2]],
                    _ => [u[1], u[2], 0.0],
                };
                let b = m.bounds();
                let mut x = b.lerp(c);
                x[axis] = if sign >= 0.0 {
                    b.min()[axis] + t
                } else {
                    b.max()[axis] - t
                };
                (x, rate * (-rate * t).exp() / norm * inv_area)
            }
        }
    }
}

/// A first-direction strategy with its axis validated.
#[derive(Debug, Clone, Copy)]
pub(crate) enum FirstDirectionSampler {
    Uniform(Dimension),
    Phase(DVec3),
}

impl FirstDirectionSampler {
    pub(crate) fn new(s: FirstDirection, dimension: Dimension) -> Result<Self, PathError> {
        Ok(match s {
            FirstDirection::Uniform => Self::Uniform(dimension),
            FirstDirection::Phase { axis } => {
                Self::Phase(direction_in("first_direction.axis", axis, dimension)?)
            }
        })
    }

    /// A direction and its solid-angle density (angle density in flatland).
    #[inline]
    pub(crate) fn sample<P: PhaseFunction>(&self, p: &P, u: [f64; 2]) -> (DVec3, f64) {
        match *self {
            Self::Uniform(d) => (d.sample_uniform_direction(u), d.uniform_direction_pdf()),
            Self::Phase(axis) => {
                let w = p.sample_direction(axis, u);
                (w, p.pdf_direction(axis, w))
            }
        }
    }

    /// The density of `w` as a first direction from a vertex where `p` scatters.
    #[inline]
    pub(crate) fn pdf<P: PhaseFunction>(&self, p: &P, w: DVec3) -> f64 {
        match *self {
            Self::Uniform(d) => d.uniform_direction_pdf(),
            Self::Phase(axis) => p.pdf_direction(axis, w),
        }
    }
}

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
        sample_vmf(pairs.r[k], u)
    }
}

/// A direction from the real vMF `C_3(|r|) e^(r . w)` (uniform for `r ~ 0`).
fn sample_vmf(r: DVec3, u: [f64; 2]) -> DVec3 {
    let kappa = r.length();
    let cos = if kappa > 1e-8 {
        // Inverse CDF of e^(kappa t) on [-1, 1], stable for large kappa.
        (1.0 + ((1.0 - u[0]) * (-2.0 * kappa).exp_m1()).ln_1p() / kappa).clamp(-1.0, 1.0)
    } else {
        return Dimension::Three.sample_uniform_direction(u);
    };
    let mean = r / kappa;
    let (a, b) = mean.any_orthonormal_pair();
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    let (s, c) = (std::f64::consts::TAU * u[1]).sin_cos();
    cos * mean + sin * (c * a + s * b)
}

/// The first-vertex mixture of a medium with endpoints to sample around: point endpoints inside
/// the medium or next to it, and focused Gaussian beams. With probability `volume` the volume
/// strategy ([`FirstVertexSampler`]), otherwise one of the components, by groups (`groups`:
/// each group has a probability, split equally among its components; usually one group of
/// all): a point `x1 = p + r w` around one of the `points`, `w` uniform on the sphere
/// (circle) and `r` exponential at `rate`, density `rate exp(-rate r) / (4 pi r^2)` (flatland
/// `/ (2 pi r)`) over all space, or a point from one of the `beams` ([`BeamSampler`]). Points
/// that land outside the medium's box start no path (their contribution, zero, is counted).
/// The `1/r^2` of the point density cancels the `1/r^2` of a point endpoint's connection, which
/// near the endpoint would otherwise give the estimator infinite variance
/// (`shared/notes/spatiotemporal-2023.md`, Build 3 of issue 12).
#[derive(Debug, Clone)]
pub(crate) struct EndpointMixture {
    pub(crate) points: Vec<DVec3>,
    pub(crate) rates: Vec<f64>,
    pub(crate) beams: Vec<BeamSampler>,
    /// Probability of the volume strategy (0: the components alone).
    pub(crate) volume: f64,
    /// Groups of components, points first and then beams in order: `(end, probability)`, the
    /// components from the previous group's end to `end` sharing `probability` equally. The
    /// probabilities sum to `1 - volume`.
    pub(crate) groups: Vec<(usize, f64)>,
    pub(crate) dimension: Dimension,
}

/// Which strategy sampled a first vertex.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Component {
    Volume,
    Point,
    Beam(usize),
}

impl EndpointMixture {
    /// One group of all components (`points` then `beams`) beside the volume's share.
    pub(crate) fn one_group(n: usize, volume: f64) -> Vec<(usize, f64)> {
        vec![(n, 1.0 - volume)]
    }

    /// The groups with their component ranges and per-component probabilities.
    fn ranges(&self) -> impl Iterator<Item = (std::ops::Range<usize>, f64)> + '_ {
        let mut start = 0;
        self.groups.iter().map(move |&(end, p)| {
            let r = start..end;
            start = end;
            let each = p / r.len() as f64;
            (r, each)
        })
    }

    /// Whether some beam samples first directions from its own strategy.
    #[inline]
    pub(crate) fn samples_directions(&self) -> bool {
        self.beams.iter().any(BeamSampler::samples_directions)
    }

    /// The density of the component around point `k` at `x`.
    #[inline]
    fn point_pdf(&self, k: usize, x: DVec3) -> f64 {
        let r = (x - self.points[k]).length();
        let rate = self.rates[k];
        let radial = rate * (-rate * r).exp();
        match self.dimension {
            Dimension::Three => radial / (4.0 * std::f64::consts::PI * r * r),
            Dimension::Two => radial / (std::f64::consts::TAU * r),
        }
    }

    /// The sums over the components in `r` of the points' densities and of `beam` over the
    /// beams, as two sums (points, then beams).
    #[inline]
    fn sums(
        &self,
        r: std::ops::Range<usize>,
        x: DVec3,
        beam: impl Fn(&BeamSampler) -> f64,
    ) -> (f64, f64) {
        let np = self.points.len();
        let points: f64 = (r.start.min(np)..r.end.min(np))
            .map(|k| self.point_pdf(k, x))
            .sum();
        let (b0, b1) = (r.start.max(np) - np, r.end.max(np) - np);
        let beams = if b0 == b1 {
            0.0
        } else {
            self.beams[b0..b1].iter().map(beam).sum::<f64>()
        };
        (points, beams)
    }

    /// The mixture density at `x` (inside the box), given the volume strategy's density there.
    #[inline]
    pub(crate) fn pdf(&self, volume_pdf: f64, x: DVec3) -> f64 {
        let mut total = self.volume * volume_pdf;
        for (r, each) in self.ranges() {
            let (points, beams) = self.sums(r, x, |b| b.pdf(x));
            let all = if beams == 0.0 { points } else { points + beams };
            total += each * all;
        }
        total
    }

    /// The joint density of the first vertex `x` and first direction `w` when beams sample
    /// directions: `volume q_o(x) p(w) + sum over groups of each component's probability times
    /// (sum_points q_k(x) p(w) + sum_beams q_j(x) p_j(w | x))`, with `p` the configured direction
    /// density `base`.
    #[inline]
    pub(crate) fn joint_pdf<P: PhaseFunction>(
        &self,
        volume_pdf: f64,
        base: f64,
        phase: &P,
        x: DVec3,
        w: DVec3,
    ) -> f64 {
        let mut total = self.volume * volume_pdf * base;
        for (r, each) in self.ranges() {
            let (points, beams) = self.sums(r, x, |b| {
                let q = b.pdf(x);
                if q == 0.0 {
                    0.0
                } else if b.samples_directions() {
                    q * b.direction_pdf(phase, x, w)
                } else {
                    q * base
                }
            });
            total += each * (points * base + beams);
        }
        total
    }

    /// A point sampled from one of the components, chosen by `c` in `[volume, 1)` (a group by
    /// its probability, then a component of it), with three variates, and which component it
    /// came from.
    #[inline]
    pub(crate) fn sample_component(&self, c: f64, u: [f64; 3]) -> (DVec3, Component) {
        let mut start = 0;
        let mut below = self.volume;
        let mut k = 0;
        for (g, &(end, p)) in self.groups.iter().enumerate() {
            if c < below + p || g + 1 == self.groups.len() {
                let n = end - start;
                k = start + (((c - below) / p * n as f64) as usize).min(n - 1);
                break;
            }
            below += p;
            start = end;
        }
        if k >= self.points.len() {
            let j = k - self.points.len();
            return (self.beams[j].sample(u), Component::Beam(j));
        }
        let w = self.dimension.sample_uniform_direction([u[0], u[1]]);
        let r = -(-u[2]).ln_1p() / self.rates[k];
        (self.points[k] + r * w, Component::Point)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use speckle_medium::{Aabb, HomogeneousBox};

    #[test]
    fn point_mixture_densities_integrate_to_their_mass_in_the_box() {
        // E[1 / q(x); x in box] over mixture samples is the box's measure: `pdf` is the density
        // `sample_point` draws from, in 3D and flatland (one point inside the box, one on a
        // face, so that some samples leave it).
        let cases = [
            (
                Aabb::new(DVec3::new(-1.0, -1.0, 0.0), DVec3::new(1.0, 1.0, 2.0)).unwrap(),
                [DVec3::new(0.3, 0.0, 0.0), DVec3::new(-0.2, 0.5, 1.0)],
                Dimension::Three,
            ),
            (
                Aabb::flat(glam::DVec2::new(-1.0, 0.0), glam::DVec2::new(1.0, 2.0)).unwrap(),
                [DVec3::new(0.3, 0.0, 0.0), DVec3::new(-0.2, 1.0, 0.0)],
                Dimension::Two,
            ),
        ];
        for (b, points, dimension) in cases {
            let m = HomogeneousBox::new(b, 1.5, 0.0).unwrap();
            let vol = FirstVertexSampler::new(FirstVertex::Uniform, &m).unwrap();
            let mix = EndpointMixture {
                points: points.to_vec(),
                rates: vec![1.5, 0.7],
                beams: vec![],
                volume: 1.0 / 3.0,
                groups: EndpointMixture::one_group(2, 1.0 / 3.0),
                dimension,
            };
            let n = 400_000;
            let (mut acc, mut acc2) = (0.0, 0.0);
            let mut rng = crate::PathRng::new(9, 0);
            for _ in 0..n {
                let c = rng.next_f64();
                let x = if c < mix.volume {
                    vol.sample(&m, rng.next_3()).0
                } else {
                    mix.sample_component(c, rng.next_3()).0
                };
                if b.contains(x) {
                    let y = 1.0 / mix.pdf(vol.pdf(&m, x), x);
                    acc += y;
                    acc2 += y * y;
                }
            }
            let measure = b.measure();
            let mean = acc / n as f64;
            let se = ((acc2 / n as f64 - mean * mean) / n as f64).sqrt();
            assert!(
                (mean - measure).abs() < 4.0 * se,
                "{dimension}: {mean} +- {se} vs {measure}"
            );
            assert!(se < 0.01 * measure, "{se}");
        }
    }

    #[test]
    fn exponential_depth_density_integrates_to_one() {
        let b = Aabb::new(DVec3::new(-1.0, -2.0, 0.0), DVec3::new(1.0, 2.0, 3.0)).unwrap();
        let m = HomogeneousBox::new(b, 1.0, 0.5).unwrap();
        for dir in [DVec3::Z, -DVec3::Z, DVec3::new(0.9, 0.1, 0.2)] {
            let s = FirstVertexSampler::new(FirstVertex::ExponentialDepth { direction: dir }, &m)
                .unwrap();
            // E[1/q(x)] over samples equals the box volume.
            let n = 20_000;
            let mut acc = 0.0;
            for i in 0..n {
                let u = [
                    (i as f64 + 0.5) / n as f64,
                    (i as f64 * 0.7548).fract(),
                    (i as f64 * 0.5698).fract(),
                ];
                let (x, q) = s.sample(&m, u);
                assert!(b.contains(x), "{x}");
                assert!((s.pdf(&m, x) - q).abs() <= 1e-12 * q);
                acc += 1.0 / q;
            }
            let vol = b.volume();
            assert!(
                (acc / n as f64 - vol).abs() < 1e-3 * vol,
                "{dir}: {} vs {vol}",
                acc / n as f64
            );
        }
    }

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
