//! Particle populations turned into bulk coefficients (Bar et al. 2019, Eq. 7 and App. A.1,
//! Eqs. 42-45), and the distribution of the particle type hit at a scattering point.

use crate::{Material, MediumError};
use speckle_phase::{Dimension, MieSphere};
use std::f64::consts::PI;
use std::ops::{Add, Mul};

/// The most particle types a [`TypeMix`] may declare (the scene holds one amplitude function per
/// type).
pub(crate) const MAX_TYPES: usize = 1 << 16;

/// Densest packing fraction of equal spheres, `pi / sqrt(18)` (Kepler).
const PACKING_3D: f64 = 0.740_480_489_693_061;
/// Densest packing fraction of equal disks, `pi / sqrt(12)` (hexagonal).
const PACKING_2D: f64 = 0.906_899_682_117_108_9;

fn nonnegative(field: impl FnOnce() -> String, value: f64) -> Result<f64, MediumError> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(MediumError::param(
            field(),
            format!("must be finite and >= 0 (got {value})"),
        ))
    }
}

/// The probabilities `beta_iota` of hitting a particle of type `iota = 0, 1, ..` at a scattering
/// point (Bar et al. 2019, Eq. 44):
///
/// `beta_iota = N_iota c_s,iota / sum_kappa N_kappa c_s,kappa`,
///
/// with a cumulative table for sampling. Type indices are global: they index the scene's list of
/// amplitude functions, so a material made only of type 2 is `[0, 0, 1]` ([`TypeMix::single`]).
/// The bulk outer product of amplitudes is `S(t1, t2) = sum_iota beta_iota s_iota(t1) s_iota(t2)*`
/// and the bulk phase function `rho(t) = sum_iota beta_iota |s_iota(t)|^2` (Eq. 44); see
/// [`TypeMix::weighted_sum`].
///
/// ```
/// use speckle_medium::TypeMix;
/// // Unnormalised weights are normalised: beta = [0.25, 0, 0.75].
/// let mix = TypeMix::new(vec![1.0, 0.0, 3.0]).unwrap();
/// assert_eq!(mix.beta(), &[0.25, 0.0, 0.75]);
/// assert_eq!(mix.sample(0.2), 0);
/// assert_eq!(mix.sample(0.3), 2);
/// // Bulk phase function from per-type values |s_iota|^2 (type 1 never scatters).
/// let rho = mix.weighted_sum(|iota| [0.1, 9.9, 0.3][iota]);
/// assert!((rho - 0.25).abs() < 1e-15);
/// assert!(TypeMix::new(vec![1.0, -1.0]).is_err());
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct TypeMix {
    beta: Vec<f64>,
    /// `cdf[i] = beta_0 + .. + beta_i`, exactly 1 from the last type with `beta > 0` on.
    cdf: Vec<f64>,
    /// Index of the last type with `beta > 0`.
    last: usize,
}

impl TypeMix {
    /// A mix from non-negative, finite weights (for instance `N_iota c_s,iota`), normalised to
    /// sum to one (Eq. 44). At least one weight must be positive; at most 65536 types.
    pub fn new(weights: Vec<f64>) -> Result<Self, MediumError> {
        if weights.is_empty() {
            return Err(MediumError::param("beta", "needs at least one type"));
        }
        if weights.len() > MAX_TYPES {
            return Err(MediumError::param(
                "beta",
                format!("{} types exceed the limit of {MAX_TYPES}", weights.len()),
            ));
        }
        for (i, &w) in weights.iter().enumerate() {
            nonnegative(|| format!("beta[{i}]"), w)?;
        }
        let total: f64 = weights.iter().sum();
        if !(total.is_finite() && total > 0.0) {
            return Err(MediumError::param(
                "beta",
                format!("the weights must have a finite sum > 0 (got {total})"),
            ));
        }
        // Eq. 44: beta_iota = w_iota / sum_kappa w_kappa.
        let mut beta = weights;
        for b in &mut beta {
            *b /= total;
        }
        Ok(Self::from_normalised(beta))
    }

    /// The mix of one type `iota`: `beta = [0, .., 0, 1]` of length `iota + 1`. Errors when
    /// `iota` is 65536 or more.
    ///
    /// ```
    /// use speckle_medium::TypeMix;
    /// let m = TypeMix::single(2).unwrap();
    /// assert_eq!((m.type_count(), m.sample(0.9)), (3, 2));
    /// ```
    pub fn single(iota: usize) -> Result<Self, MediumError> {
        if iota >= MAX_TYPES {
            return Err(MediumError::param(
                "type",
                format!("type index {iota} exceeds the limit of {MAX_TYPES} types"),
            ));
        }
        let mut beta = vec![0.0; iota + 1];
        beta[iota] = 1.0;
        Ok(Self::from_normalised(beta))
    }

    /// The mix of type 0 alone, `beta = [1]`.
    pub fn one() -> Self {
        Self::from_normalised(vec![1.0])
    }

    fn from_normalised(beta: Vec<f64>) -> Self {
        // At least one beta is > 0: the largest weight is >= total / n.
        let last = beta.iter().rposition(|&b| b > 0.0).unwrap_or(0);
        let mut acc = 0.0;
        let cdf = beta
            .iter()
            .enumerate()
            .map(|(i, b)| {
                acc += b;
                if i >= last { 1.0 } else { acc.min(1.0) }
            })
            .collect();
        Self { beta, cdf, last }
    }

    /// Number of types the mix declares (the length of [`TypeMix::beta`], trailing zeros
    /// included).
    pub fn type_count(&self) -> usize {
        self.beta.len()
    }

    /// The probabilities `beta_iota` (Eq. 44); they sum to one.
    pub fn beta(&self) -> &[f64] {
        &self.beta
    }

    /// Samples a type from one uniform variate `u` in `[0, 1)`: type `iota` with probability
    /// `beta_iota`, by inversion of the cumulative table. A type with `beta = 0` is never
    /// returned.
    #[inline]
    pub fn sample(&self, u: f64) -> usize {
        if self.last == 0 {
            return 0;
        }
        // First type whose cumulative probability exceeds u.
        self.cdf.partition_point(|&c| c <= u).min(self.last)
    }

    /// Writes `beta` into `out` and zeros after it.
    ///
    /// # Panics
    /// If `out` is shorter than [`TypeMix::type_count`].
    pub fn probabilities(&self, out: &mut [f64]) {
        let n = self.beta.len();
        assert!(
            out.len() >= n,
            "type_probabilities: output has {} entries, the mix has {n} types",
            out.len()
        );
        out[..n].copy_from_slice(&self.beta);
        out[n..].fill(0.0);
    }

    /// `sum_iota beta_iota f(iota)` over the types with `beta_iota > 0`: with
    /// `f(iota) = |s_iota(theta)|^2` the bulk phase function `rho(theta)`, with
    /// `f(iota) = s_iota(t1) s_iota(t2)*` the bulk outer product `S(t1, t2)` (Eq. 44).
    pub fn weighted_sum<T>(&self, mut f: impl FnMut(usize) -> T) -> T
    where
        T: Default + Add<Output = T> + Mul<f64, Output = T>,
    {
        self.beta
            .iter()
            .enumerate()
            .filter(|(_, b)| **b > 0.0)
            .fold(T::default(), |acc, (i, &b)| acc + f(i) * b)
    }
}

/// How much of one particle type the medium holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Concentration {
    /// Mean number of particles per unit volume `N` (Eq. 42's `N_iota`); in flatland, per unit
    /// area.
    NumberDensity(f64),
    /// Fraction `varsigma` of the volume the particles occupy, in `[0, 1]`; converted by Eq. 42,
    /// `N = varsigma / (4/3 pi r^3)`. In flatland it is the area fraction of the disks (cross
    /// sections of infinite cylinders), `N = varsigma / (pi r^2)`.
    VolumeFraction(f64),
}

/// One particle type: its radius, its scattering and absorption cross sections, and its
/// concentration (Bar et al. 2019, Sec. 3 and App. A.1).
///
/// A plain description: [`ParticleMix::new`] validates it and names the offending field
/// (`particles[1].radius`). Cross sections are areas in 3D (e.g. [`MieSphere::c_sca`]); in
/// flatland they are lengths (per unit length of an infinite cylinder), matching a number
/// density per unit area so that `N c_s` is an inverse length in both.
///
/// ```
/// use speckle_medium::{Concentration, ParticleType};
/// let p = ParticleType::new(0.5, 1.2, 0.0, Concentration::VolumeFraction(0.01));
/// assert_eq!(p.radius, 0.5);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParticleType {
    /// Radius `r_iota > 0` (length unit of the scene).
    pub radius: f64,
    /// Scattering cross section `c_s,iota >= 0`.
    pub c_sca: f64,
    /// Absorption cross section `c_a,iota >= 0`.
    pub c_abs: f64,
    /// Number density or volume fraction.
    pub concentration: Concentration,
}

impl ParticleType {
    /// A particle type from its fields (validated by [`ParticleMix::new`]).
    pub const fn new(radius: f64, c_sca: f64, c_abs: f64, concentration: Concentration) -> Self {
        Self {
            radius,
            c_sca,
            c_abs,
            concentration,
        }
    }

    /// A Mie sphere's radius and cross sections ([`MieSphere::c_sca`], [`MieSphere::c_abs`]), in
    /// the length unit of the sphere (units of `1 / k` for [`MieSphere::from_size_parameter`]).
    /// Mie spheres are 3D particles: do not use them in a flatland mix.
    ///
    /// ```
    /// use speckle_medium::{Concentration, ParticleMix, ParticleType};
    /// use speckle_phase::{Complex64, MieSphere};
    /// let mie = MieSphere::new(0.5, Complex64::new(1.2, 0.0), 1.33, 0.532).unwrap();
    /// let p = ParticleType::from_mie(&mie, Concentration::VolumeFraction(0.001));
    /// let mix = ParticleMix::new(vec![p], 0.0).unwrap();
    /// let n = 0.001 / (4.0 / 3.0 * std::f64::consts::PI * 0.125);
    /// assert!((mix.sigma_s() - n * mie.c_sca()).abs() < 1e-12 * mix.sigma_s());
    /// ```
    pub fn from_mie(mie: &MieSphere, concentration: Concentration) -> Self {
        Self::new(mie.radius(), mie.c_sca(), mie.c_abs(), concentration)
    }

    /// Volume of one particle, `4/3 pi r^3`; in flatland the disk area `pi r^2`.
    pub fn particle_measure(&self, dimension: Dimension) -> f64 {
        match dimension {
            Dimension::Three => 4.0 / 3.0 * PI * self.radius.powi(3),
            Dimension::Two => PI * self.radius * self.radius,
        }
    }
}

/// A mixture of particle types in a host medium, and the bulk coefficients it makes
/// (Bar et al. 2019, Eq. 7 for one type, App. A.1 Eqs. 42-44 for several):
///
/// - `N_iota = varsigma_iota / (4/3 pi r_iota^3)` when a volume fraction is given (Eq. 42),
/// - `sigma_s = sum_iota N_iota c_s,iota`,
///   `sigma_a = sum_iota N_iota c_a,iota + sigma_a^med` (Eq. 43),
/// - `beta_iota = N_iota c_s,iota / sigma_s` (Eq. 44), the probability that a scattering event
///   hits type `iota`; the bulk phase function is `rho = sum_iota beta_iota |s_iota|^2`.
///
/// Validation: every radius finite and > 0, cross sections and concentrations finite and >= 0,
/// at least one type that scatters (`N c_s > 0`), each type's volume fraction (given, or
/// `N` times the particle volume) at most the densest packing of equal spheres `pi / sqrt(18)`
/// (disks in flatland: `pi / sqrt(12)`), and the fractions summing to at most 1. The paper's
/// model further assumes sparse particles (independent scattering); that is not checked.
///
/// ```
/// use speckle_medium::{Concentration, ParticleMix, ParticleType};
/// let mix = ParticleMix::new(
///     vec![
///         ParticleType::new(1.0, 2.0, 0.5, Concentration::NumberDensity(0.01)),
///         ParticleType::new(0.5, 1.0, 0.0, Concentration::NumberDensity(0.03)),
///     ],
///     0.001,
/// )
/// .unwrap();
/// assert!((mix.sigma_s() - 0.05).abs() < 1e-15); // 0.01 * 2 + 0.03 * 1
/// assert!((mix.sigma_a() - 0.006).abs() < 1e-15); // 0.01 * 0.5 + 0.001
/// assert!((mix.beta()[0] - 0.4).abs() < 1e-15);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct ParticleMix {
    dimension: Dimension,
    types: Vec<ParticleType>,
    number_densities: Vec<f64>,
    volume_fractions: Vec<f64>,
    host_sigma_a: f64,
    sigma_s: f64,
    particle_sigma_a: f64,
    beta: TypeMix,
}

impl ParticleMix {
    /// A 3D mixture of `types` (type `iota` is `types[iota]`) in a host of absorption
    /// coefficient `host_sigma_a >= 0` (Eq. 43's `sigma_a^med`).
    pub fn new(types: Vec<ParticleType>, host_sigma_a: f64) -> Result<Self, MediumError> {
        Self::new_in(Dimension::Three, types, host_sigma_a)
    }

    /// A mixture in 3D or in flatland. In flatland number densities are per unit area, volume
    /// fractions are area fractions (`N = varsigma / (pi r^2)`) and cross sections are lengths.
    ///
    /// ```
    /// use speckle_medium::{Concentration, Dimension, ParticleMix, ParticleType};
    /// let disk = ParticleType::new(2.0, 3.0, 0.0, Concentration::VolumeFraction(0.1));
    /// let mix = ParticleMix::new_in(Dimension::Two, vec![disk], 0.0).unwrap();
    /// let n = 0.1 / (std::f64::consts::PI * 4.0);
    /// assert!((mix.number_densities()[0] - n).abs() < 1e-15);
    /// ```
    pub fn new_in(
        dimension: Dimension,
        types: Vec<ParticleType>,
        host_sigma_a: f64,
    ) -> Result<Self, MediumError> {
        if types.is_empty() {
            return Err(MediumError::param(
                "particles",
                "needs at least one particle type",
            ));
        }
        if types.len() > MAX_TYPES {
            return Err(MediumError::param(
                "particles",
                format!("{} types exceed the limit of {MAX_TYPES}", types.len()),
            ));
        }
        if !(host_sigma_a.is_finite() && host_sigma_a >= 0.0) {
            return Err(MediumError::InvalidCoefficient {
                field: "host_sigma_a",
                value: host_sigma_a,
            });
        }
        let packing = match dimension {
            Dimension::Three => PACKING_3D,
            Dimension::Two => PACKING_2D,
        };
        let mut number_densities = Vec::with_capacity(types.len());
        let mut volume_fractions = Vec::with_capacity(types.len());
        for (i, p) in types.iter().enumerate() {
            let r = p.radius;
            if !(r.is_finite() && r > 0.0) {
                return Err(MediumError::param(
                    format!("particles[{i}].radius"),
                    format!("must be finite and > 0 (got {r})"),
                ));
            }
            nonnegative(|| format!("particles[{i}].c_sca"), p.c_sca)?;
            nonnegative(|| format!("particles[{i}].c_abs"), p.c_abs)?;
            let measure = p.particle_measure(dimension);
            let (n, fraction) = match p.concentration {
                Concentration::NumberDensity(n) => {
                    let n = nonnegative(|| format!("particles[{i}].concentration"), n)?;
                    (n, n * measure)
                }
                Concentration::VolumeFraction(f) => {
                    let f = nonnegative(|| format!("particles[{i}].concentration"), f)?;
                    // Eq. 42: N = varsigma / (4/3 pi r^3) (pi r^2 in flatland).
                    (f / measure, f)
                }
            };
            if !(n.is_finite() && fraction.is_finite()) {
                return Err(MediumError::param(
                    format!("particles[{i}].concentration"),
                    format!(
                        "number density {n} and volume fraction {fraction} must be finite \
                         (radius {r})"
                    ),
                ));
            }
            if fraction > packing {
                return Err(MediumError::param(
                    format!("particles[{i}].concentration"),
                    format!(
                        "volume fraction {fraction} exceeds the densest packing of equal \
                         particles ({packing:.4}): impossible"
                    ),
                ));
            }
            number_densities.push(n);
            volume_fractions.push(fraction);
        }
        let total_fraction: f64 = volume_fractions.iter().sum();
        if total_fraction > 1.0 {
            return Err(MediumError::param(
                "particles",
                format!(
                    "the volume fractions sum to {total_fraction} > 1: the particles do not fit"
                ),
            ));
        }
        // Eq. 43.
        let weights: Vec<f64> = types
            .iter()
            .zip(&number_densities)
            .map(|(p, n)| n * p.c_sca)
            .collect();
        let sigma_s: f64 = weights.iter().sum();
        let particle_sigma_a: f64 = types
            .iter()
            .zip(&number_densities)
            .map(|(p, n)| n * p.c_abs)
            .sum();
        if !(sigma_s.is_finite() && (particle_sigma_a + host_sigma_a).is_finite()) {
            return Err(MediumError::param(
                "particles",
                format!(
                    "the bulk coefficients overflow (sigma_s {sigma_s}, sigma_a \
                     {particle_sigma_a} + {host_sigma_a})"
                ),
            ));
        }
        if sigma_s <= 0.0 {
            return Err(MediumError::param(
                "particles",
                "no type scatters (every N c_sca is 0): a medium that does not scatter \
                 produces no speckle",
            ));
        }
        // Eq. 44: beta_iota = N_iota c_s,iota / sigma_s.
        let beta = TypeMix::new(weights)?;
        Ok(Self {
            dimension,
            types,
            number_densities,
            volume_fractions,
            host_sigma_a,
            sigma_s,
            particle_sigma_a,
            beta,
        })
    }

    /// 3D or flatland.
    pub fn dimension(&self) -> Dimension {
        self.dimension
    }

    /// The particle types, as given.
    pub fn types(&self) -> &[ParticleType] {
        &self.types
    }

    /// Number densities `N_iota` (Eq. 42).
    pub fn number_densities(&self) -> &[f64] {
        &self.number_densities
    }

    /// Volume fractions `varsigma_iota = N_iota 4/3 pi r_iota^3` (area fractions in flatland).
    pub fn volume_fractions(&self) -> &[f64] {
        &self.volume_fractions
    }

    /// The host's absorption coefficient `sigma_a^med`.
    pub fn host_sigma_a(&self) -> f64 {
        self.host_sigma_a
    }

    /// Scattering coefficient `sigma_s = sum N_iota c_s,iota` (Eq. 43).
    pub fn sigma_s(&self) -> f64 {
        self.sigma_s
    }

    /// Absorption by the particles alone, `sum N_iota c_a,iota`.
    pub fn particle_sigma_a(&self) -> f64 {
        self.particle_sigma_a
    }

    /// Absorption coefficient `sigma_a = sum N_iota c_a,iota + sigma_a^med` (Eq. 43).
    pub fn sigma_a(&self) -> f64 {
        self.particle_sigma_a + self.host_sigma_a
    }

    /// Extinction coefficient `sigma_t = sigma_s + sigma_a`.
    pub fn sigma_t(&self) -> f64 {
        self.sigma_s + self.sigma_a()
    }

    /// The type probabilities `beta_iota = N_iota c_s,iota / sigma_s` (Eq. 44).
    pub fn beta(&self) -> &[f64] {
        self.beta.beta()
    }

    /// The type probabilities as a sampler.
    pub fn type_mix(&self) -> &TypeMix {
        &self.beta
    }

    /// The bulk material `(sigma_s, sigma_a, beta)`, host absorption included.
    pub fn material(&self) -> Material {
        Material::new(self.sigma_s, self.sigma_a(), self.beta.clone())
    }

    /// The material of the particles alone (host absorption left out): the base material for
    /// [`crate::VoxelGrid::from_densities`], where a density scales the particle numbers and
    /// the host absorption is passed separately.
    pub fn particle_material(&self) -> Material {
        Material::new(self.sigma_s, self.particle_sigma_a, self.beta.clone())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{chi_square_bound, chi_square_stat, uniform_stream};

    fn field_of(e: MediumError) -> String {
        match e {
            MediumError::InvalidParameter { field, .. } => field,
            MediumError::InvalidCoefficient { field, .. } => field.to_string(),
            other => panic!("unexpected error {other:?}"),
        }
    }

    #[test]
    fn type_mix_sampling_matches_beta() {
        // Zero weights at the start, the middle and the end must never be sampled.
        let w = vec![0.0, 1.0, 0.0, 2.0, 0.5, 0.0];
        let mix = TypeMix::new(w).unwrap();
        let n = 200_000;
        let mut counts = vec![0u64; mix.type_count()];
        let mut next = uniform_stream(42);
        for _ in 0..n {
            counts[mix.sample(next())] += 1;
        }
        for (i, &c) in counts.iter().enumerate() {
            assert!(
                mix.beta()[i] > 0.0 || c == 0,
                "type {i} sampled with beta 0"
            );
        }
        let (stat, dof) = chi_square_stat(&counts, mix.beta());
        assert_eq!(dof, 2);
        assert!(stat < chi_square_bound(dof), "chi2 {stat} dof {dof}");
        // The edges of [0, 1).
        assert_eq!(mix.sample(0.0), 1);
        assert_eq!(mix.sample(1.0 - f64::EPSILON / 2.0), 4);
        assert_eq!(mix.sample(1.0), 4);
        // Exactly at a cumulative boundary the next type is chosen: cdf = [0, 2/7, ..].
        assert_eq!(mix.sample(1.0 / 3.5), 3);
    }

    #[test]
    fn type_mix_probabilities_and_single() {
        let mix = TypeMix::single(2).unwrap();
        let mut out = [9.0; 4];
        mix.probabilities(&mut out);
        assert_eq!(out, [0.0, 0.0, 1.0, 0.0]);
        assert!((0..100).all(|i| mix.sample(i as f64 / 100.0) == 2));
        assert_eq!(TypeMix::one(), TypeMix::new(vec![3.0]).unwrap());
        assert_eq!(TypeMix::one().sample(0.7), 0);
    }

    #[test]
    fn type_mix_rejects_bad_weights() {
        let cases: [(Vec<f64>, &str); 6] = [
            (vec![], "beta"),
            (vec![1.0, f64::NAN], "beta[1]"),
            (vec![-1.0, 2.0], "beta[0]"),
            (vec![1.0, f64::INFINITY], "beta[1]"),
            (vec![0.0, 0.0], "beta"),
            (vec![f64::MAX, f64::MAX], "beta"),
        ];
        for (w, field) in cases {
            assert_eq!(
                field_of(TypeMix::new(w.clone()).unwrap_err()),
                field,
                "{w:?}"
            );
        }
        assert!(TypeMix::new(vec![1.0; MAX_TYPES + 1]).is_err());
        assert!(TypeMix::single(MAX_TYPES).is_err());
    }

    #[test]
    fn bulk_coefficients_follow_eqs_42_to_44() {
        let (r0, r1) = (0.3, 0.8);
        let (f0, n1) = (0.02, 1e-3);
        let mix = ParticleMix::new(
            vec![
                ParticleType::new(r0, 0.4, 0.1, Concentration::VolumeFraction(f0)),
                ParticleType::new(r1, 3.0, 0.0, Concentration::NumberDensity(n1)),
            ],
            0.05,
        )
        .unwrap();
        let n0 = f0 / (4.0 / 3.0 * PI * r0.powi(3));
        assert!((mix.number_densities()[0] - n0).abs() < 1e-15 * n0);
        let f1 = n1 * 4.0 / 3.0 * PI * r1.powi(3);
        assert!((mix.volume_fractions()[1] - f1).abs() < 1e-15 * f1);
        let ss = n0 * 0.4 + n1 * 3.0;
        assert!((mix.sigma_s() - ss).abs() < 1e-14 * ss);
        assert!((mix.sigma_a() - (n0 * 0.1 + 0.05)).abs() < 1e-14);
        assert!((mix.sigma_t() - (ss + n0 * 0.1 + 0.05)).abs() < 1e-14);
        assert!((mix.beta()[0] - n0 * 0.4 / ss).abs() < 1e-15);
        assert!((mix.beta().iter().sum::<f64>() - 1.0).abs() < 1e-15);
        let m = mix.material();
        assert_eq!((m.sigma_s, m.sigma_a), (mix.sigma_s(), mix.sigma_a()));
        assert_eq!(mix.particle_material().sigma_a, mix.particle_sigma_a());
        // An absorbing-only type gets beta = 0.
        let mix = ParticleMix::new(
            vec![
                ParticleType::new(1.0, 0.0, 1.0, Concentration::NumberDensity(0.01)),
                ParticleType::new(1.0, 1.0, 0.0, Concentration::NumberDensity(0.01)),
            ],
            0.0,
        )
        .unwrap();
        assert_eq!(mix.beta(), &[0.0, 1.0]);
        assert_eq!(mix.type_mix().sample(0.0), 1);
    }

    #[test]
    fn flatland_fractions_are_area_fractions() {
        let p = ParticleType::new(1.5, 2.0, 0.0, Concentration::VolumeFraction(0.2));
        let mix = ParticleMix::new_in(Dimension::Two, vec![p], 0.0).unwrap();
        let n = 0.2 / (PI * 2.25);
        assert!((mix.number_densities()[0] - n).abs() < 1e-16);
        assert!((mix.sigma_s() - 2.0 * n).abs() < 1e-15);
        // 0.85 fits disks (packing 0.9069) but not spheres (0.7405).
        let p = ParticleType::new(1.0, 1.0, 0.0, Concentration::VolumeFraction(0.85));
        assert!(ParticleMix::new_in(Dimension::Two, vec![p], 0.0).is_ok());
        assert!(ParticleMix::new(vec![p], 0.0).is_err());
    }

    #[test]
    fn particle_mix_rejects_bad_input() {
        let ok = ParticleType::new(1.0, 1.0, 0.0, Concentration::NumberDensity(0.01));
        let with = |f: &dyn Fn(&mut ParticleType)| {
            let mut p = ok;
            f(&mut p);
            ParticleMix::new(vec![ok, p], 0.0).map(|_| ())
        };
        type Edit<'a> = &'a dyn Fn(&mut ParticleType);
        let cases: [(Edit, &str); 10] = [
            (&|p| p.radius = 0.0, "particles[1].radius"),
            (&|p| p.radius = f64::NAN, "particles[1].radius"),
            (&|p| p.c_sca = -1.0, "particles[1].c_sca"),
            (&|p| p.c_abs = f64::INFINITY, "particles[1].c_abs"),
            (
                &|p| p.concentration = Concentration::NumberDensity(f64::NAN),
                "particles[1].concentration",
            ),
            (
                &|p| p.concentration = Concentration::VolumeFraction(-0.1),
                "particles[1].concentration",
            ),
            // A single fraction beyond the densest packing of spheres.
            (
                &|p| p.concentration = Concentration::VolumeFraction(0.75),
                "particles[1].concentration",
            ),
            // As a number density: 0.2 per unit volume of unit spheres is a fraction 0.84.
            (
                &|p| p.concentration = Concentration::NumberDensity(0.2),
                "particles[1].concentration",
            ),
            // A tiny radius makes N overflow.
            (
                &|p| {
                    p.radius = 1e-120;
                    p.concentration = Concentration::VolumeFraction(0.1);
                },
                "particles[1].concentration",
            ),
            // N c_sca overflows.
            (
                &|p| {
                    p.radius = 0.01;
                    p.concentration = Concentration::NumberDensity(100.0);
                    p.c_sca = 1e308;
                },
                "particles",
            ),
        ];
        for (f, field) in cases {
            assert_eq!(field_of(with(f).unwrap_err()), field);
        }
        // Fractions that each fit but sum to more than one.
        let big = ParticleType::new(1.0, 1.0, 0.0, Concentration::VolumeFraction(0.7));
        let small = ParticleType::new(0.1, 1.0, 0.0, Concentration::VolumeFraction(0.35));
        assert_eq!(
            field_of(ParticleMix::new(vec![big, small], 0.0).unwrap_err()),
            "particles"
        );
        // No scattering at all.
        let none = ParticleType::new(1.0, 1.0, 1.0, Concentration::NumberDensity(0.0));
        let dark = ParticleType::new(1.0, 0.0, 1.0, Concentration::NumberDensity(0.1));
        assert_eq!(
            field_of(ParticleMix::new(vec![none, dark], 0.0).unwrap_err()),
            "particles"
        );
        assert_eq!(
            field_of(ParticleMix::new(vec![], 0.0).unwrap_err()),
            "particles"
        );
        for h in [f64::NAN, -1.0, f64::INFINITY] {
            assert_eq!(
                field_of(ParticleMix::new(vec![ok], h).unwrap_err()),
                "host_sigma_a"
            );
        }
    }

    #[test]
    fn from_mie_copies_cross_sections() {
        use speckle_phase::Complex64;
        let mie = MieSphere::from_size_parameter(3.0, Complex64::new(1.5, 0.01)).unwrap();
        let p = ParticleType::from_mie(&mie, Concentration::NumberDensity(1e-3));
        assert_eq!(
            (p.radius, p.c_sca, p.c_abs),
            (3.0, mie.c_sca(), mie.c_abs())
        );
        assert!(p.c_abs > 0.0);
    }
}
