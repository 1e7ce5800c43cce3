//! Electric-field Monte Carlo (EMC; Xu 2004, Sawicki et al. 2008), the baseline the 2019 paper
//! compares with (Bar et al. 2019, Sec. 6.1, Figs. 9 and 12), scalar (no polarization).
//!
//! EMC is volumetric light tracing that carries the path length as a phase. A photon enters the
//! medium from a plane wave `d` at a uniform point of the box's lit faces (weighted by their
//! projected areas, total `S`), flies exponential distances (`Medium::sample_flight`), scatters
//! with directions drawn from the phase function of its particle type, and has its weight
//! multiplied by the albedo at each collision (Russian roulette below 0.1). When it leaves the
//! box after `B >= 1` collisions along `w`, it is scored by every far-field sensor whose cone of
//! half-angle `cone` contains `w` (the detector bins; photons that leave unscattered are the
//! coherent beam, not speckle, and are not scored), with the phase of its path
//!
//! `phi = k (d . x_1 + sum_b |x_{b+1} - x_b| - w . x_B)`
//!
//! (`docs/conventions.md`: the incident phase at the first vertex, the path length, the far-field
//! phase of the last vertex). Each photon carries the power `S w / N`, so a sensor's intensity is
//! `|A(v)|^2 = dP / dOmega ~ S sum w / (N Omega)`, `Omega = 2 pi (1 - cos cone)` the bin's solid
//! angle: in the units of [`crate::render_intensity`], to which it converges as the cone
//! shrinks (the bin average of a smooth intensity).
//!
//! **Coherent backscattering** (Sawicki et al. 2008, here scalar): with
//! [`Coherence::ForwardAndReversed`], a photon of `B >= 2` collisions also scores the
//! interference of its path with the reversed one (the same scatterers in the opposite order,
//! entering at `x_B` and leaving from `x_1` along the same `w`):
//! `w r cos(k (d + w) . (x_B - x_1))`, `r = |a_rev| / |a|` the ratio of the reversed path's
//! amplitude to the traced one's: the end legs' attenuations (`exp(-(tau_rev - tau) / 2)`) and
//! the scattering amplitudes at the two end vertices (`s(d -> -w_in) s(-w_12 -> w)` over
//! `s(d -> w_12) s(w_in -> w)`); the reversed path itself is traced as another photon, which
//! scores its own `w`.
//!
//! **Fields.** A realization of `N` photons per source gives every sensor the field
//! `u = sum sqrt(S w / (N Omega)) e^{i phi}` over the photons in its bin (forward paths), whose
//! `E|u|^2` is the intensity. Each photon updates the sensors around its one exit direction, for
//! one source: the fields of different sources (and of sensors whose cones do not overlap) share
//! no photon and are uncorrelated, whatever the medium's memory effect. That is the difference
//! with the path-space estimators, which connect every path to every endpoint.
//!
//! Photon `n` of source `s` in realization `r` draws from stream `(r S + s) N + n` of the seed,
//! so results do not depend on the thread count. 3D scenes of plane-wave sources and far-field
//! sensors only.

use crate::{Coherence, EstimatorError, Progress, Scene};
use glam::DVec3;
use num_complex::Complex64;
use rayon::prelude::*;
use speckle_endpoints::{Sensor, Source};
use speckle_medium::{Dimension, Medium};
use speckle_phase::PhaseFunction;
use speckle_stats::CMatrix;
use speckle_stats::rng::PathRng;
use std::collections::HashMap;
use std::f64::consts::TAU;

/// Options of [`render_emc`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EmcOptions {
    /// Photons `N` per source and realization.
    pub photons: u64,
    /// Realizations `R` (at least 2: the intensity's standard error is their spread).
    pub realizations: usize,
    /// Seed.
    pub seed: u64,
    /// Half-angle of every sensor's bin, radians, in `(0, pi/2)`.
    pub cone: f64,
    /// With [`Coherence::ForwardAndReversed`] the intensity includes coherent backscattering.
    pub coherence: Coherence,
}

/// An EMC render: intensities of every pair and field realizations.
#[derive(Debug, Clone, PartialEq)]
pub struct EmcEstimate {
    /// `E|u_j|^2` of every pair of the scene (forward paths, and the backscattering
    /// interference with [`Coherence::ForwardAndReversed`]).
    pub intensity: Vec<f64>,
    /// Its standard errors (the spread of the realizations' estimates over `sqrt(R)`).
    pub intensity_stderr: Vec<f64>,
    /// Field realizations, `R x J` (forward paths).
    pub fields: CMatrix,
    /// The bins' solid angle `Omega`.
    pub solid_angle: f64,
    /// Photons per source and realization.
    pub photons: u64,
}

/// The lit faces of a box for a plane wave along `d`: per face, its axis, the coordinate of its
/// plane and its projected area (cumulative).
struct Entry {
    faces: Vec<(usize, f64, f64)>,
    area: f64,
    min: DVec3,
    max: DVec3,
}

impl Entry {
    fn new(min: DVec3, max: DVec3, d: DVec3) -> Self {
        let size = max - min;
        let mut faces = vec![];
        let mut area = 0.0;
        for a in 0..3 {
            if d[a] == 0.0 {
                continue;
            }
            let (b, c) = ((a + 1) % 3, (a + 2) % 3);
            area += d[a].abs() * size[b] * size[c];
            let plane = if d[a] > 0.0 { min[a] } else { max[a] };
            faces.push((a, plane, area));
        }
        Self {
            faces,
            area,
            min,
            max,
        }
    }

    /// A uniform point of the projected lit faces.
    fn sample(&self, rng: &mut PathRng) -> DVec3 {
        let u = rng.next_f64() * self.area;
        let &(a, plane, _) = self
            .faces
            .iter()
            .find(|f| u < f.2)
            .unwrap_or_else(|| self.faces.last().expect("a lit face"));
        let mut x = DVec3::ZERO;
        for k in 0..3 {
            x[k] = if k == a {
                plane
            } else {
                self.min[k] + rng.next_f64() * (self.max[k] - self.min[k])
            };
        }
        x
    }
}

/// Far-field sensor directions hashed into cells of the cone's size, to find the bins a
/// direction falls in.
struct Bins {
    dirs: Vec<DVec3>,
    cos_cone: f64,
    cell: f64,
    grid: HashMap<[i64; 3], Vec<usize>>,
}

impl Bins {
    fn new(dirs: Vec<DVec3>, cone: f64) -> Self {
        let cell = 2.0 * (0.5 * cone).sin() * 1.0001;
        let mut grid: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
        for (i, d) in dirs.iter().enumerate() {
            grid.entry(Self::key(*d, cell)).or_default().push(i);
        }
        Self {
            dirs,
            cos_cone: cone.cos(),
            cell,
            grid,
        }
    }

    fn key(d: DVec3, cell: f64) -> [i64; 3] {
        [0, 1, 2].map(|a| (d[a] / cell).floor() as i64)
    }

    /// Calls `f` with every sensor whose cone contains `w`.
    fn each(&self, w: DVec3, mut f: impl FnMut(usize)) {
        // A direction within the cone is closer than the chord 2 sin(cone / 2) = cell.
        let k = Self::key(w, self.cell);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    if let Some(list) = self.grid.get(&[k[0] + dx, k[1] + dy, k[2] + dz]) {
                        for &i in list {
                            if self.dirs[i].dot(w) >= self.cos_cone {
                                f(i);
                            }
                        }
                    }
                }
            }
        }
    }
}

/// Russian roulette below this weight.
const ROULETTE: f64 = 0.1;

/// Most collisions of a photon (a guard; the roulette ends paths long before).
const MAX_COLLISIONS: u32 = 1_000_000;

/// Renders the scene's pairs by electric-field Monte Carlo (see the module docs).
pub fn render_emc<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    options: &EmcOptions,
    progress: &dyn Progress,
) -> Result<EmcEstimate, EstimatorError> {
    let bad = |field: &str, reason: String| EstimatorError::InvalidInput {
        field: field.into(),
        reason,
    };
    let m = scene.medium();
    if scene.has_detectors() {
        return Err(bad(
            "sensors",
            "EMC takes plane-wave sources and far-field sensors, not detectors".into(),
        ));
    }
    if m.dimension() != Dimension::Three {
        return Err(bad("dimension", "EMC renders 3D scenes only".into()));
    }
    let dirs_in: Vec<DVec3> = scene
        .sources()
        .iter()
        .enumerate()
        .map(|(i, s)| match s {
            Source::PlaneWave { direction } => Ok(*direction),
            _ => Err(bad(
                &format!("sources[{i}]"),
                "EMC takes plane-wave sources only".into(),
            )),
        })
        .collect::<Result<_, _>>()?;
    let dirs_out: Vec<DVec3> = scene
        .sensors()
        .iter()
        .enumerate()
        .map(|(i, s)| match s {
            Sensor::FarField { direction } => Ok(*direction),
            _ => Err(bad(
                &format!("sensors[{i}]"),
                "EMC takes far-field sensors only".into(),
            )),
        })
        .collect::<Result<_, _>>()?;
    if !(options.cone > 0.0 && options.cone < 0.5 * std::f64::consts::PI) {
        return Err(bad(
            "cone",
            format!("must be in (0, 90) degrees (got {} rad)", options.cone),
        ));
    }
    if options.realizations < 2 {
        return Err(bad(
            "realizations",
            format!("must be at least 2 (got {})", options.realizations),
        ));
    }
    if options.photons == 0 {
        return Err(bad("photons", "must be at least 1".into()));
    }
    let (ns, nv) = (dirs_in.len(), dirs_out.len());
    // pair[s * nv + v]: the pair index of (s, v), if listed.
    let mut pair = vec![None; ns * nv];
    for (j, p) in scene.pairs().iter().enumerate() {
        pair[p.source * nv + p.sensor] = Some(j);
    }
    let j = scene.pairs().len();
    let bins = Bins::new(dirs_out, options.cone);
    let omega = TAU * (1.0 - options.cone.cos());
    let b = m.bounds();
    let entries: Vec<Entry> = dirs_in
        .iter()
        .map(|&d| Entry::new(b.min(), b.max(), d))
        .collect();
    let n = options.photons;
    let units: Vec<(usize, usize)> = (0..options.realizations)
        .flat_map(|r| (0..ns).map(move |s| (r, s)))
        .collect();
    // Per unit (realization, source): per sensor, the intensity sum and the field.
    let results: Vec<Option<(Vec<f64>, Vec<Complex64>)>> = units
        .par_iter()
        .map(|&(r, s)| {
            if progress.cancelled() {
                return None;
            }
            let mut sums = vec![0.0; nv];
            let mut field = vec![Complex64::new(0.0, 0.0); nv];
            let scale = entries[s].area / (n as f64 * omega);
            for p in 0..n {
                let stream = ((r * ns + s) as u64) * n + p;
                let mut rng = PathRng::new(options.seed, stream);
                trace(
                    scene,
                    &entries[s],
                    dirs_in[s],
                    &bins,
                    options.coherence,
                    &mut rng,
                    |v, w, phi, cbs| {
                        sums[v] += w * (1.0 + cbs);
                        field[v] += Complex64::from_polar((scale * w).sqrt(), phi);
                    },
                );
            }
            progress.advance(n);
            sums.iter_mut().for_each(|x| *x *= scale);
            Some((sums, field))
        })
        .collect();
    if results.iter().any(Option::is_none) || progress.cancelled() {
        return Err(EstimatorError::Cancelled);
    }
    let rn = options.realizations;
    let mut per_real = vec![vec![0.0; j]; rn];
    let mut fields = CMatrix::zeros(rn, j);
    for ((r, s), res) in units.iter().zip(results) {
        let (sums, field) = res.expect("not cancelled");
        for v in 0..nv {
            if let Some(jj) = pair[s * nv + v] {
                per_real[*r][jj] = sums[v];
                fields.as_mut_slice()[*r * j + jj] = field[v];
            }
        }
    }
    let mut intensity = vec![0.0; j];
    let mut intensity_stderr = vec![0.0; j];
    for jj in 0..j {
        let mean = per_real.iter().map(|x| x[jj]).sum::<f64>() / rn as f64;
        let var = per_real.iter().map(|x| (x[jj] - mean).powi(2)).sum::<f64>() / (rn - 1) as f64;
        intensity[jj] = mean;
        intensity_stderr[jj] = (var / rn as f64).sqrt();
    }
    Ok(EmcEstimate {
        intensity,
        intensity_stderr,
        fields,
        solid_angle: omega,
        photons: n,
    })
}

/// Traces one photon of the plane wave `d` and calls `score(sensor, weight, phase, cbs)` for
/// every sensor whose bin it leaves in (`cbs`: the backscattering interference relative to the
/// weight, 0 without reversed paths or for single scattering).
fn trace<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    entry: &Entry,
    d: DVec3,
    bins: &Bins,
    coherence: Coherence,
    rng: &mut PathRng,
    mut score: impl FnMut(usize, f64, f64, f64),
) {
    let m = scene.medium();
    let phases = scene.phases();
    let k = scene.wavenumber();
    let mut x = entry.sample(rng);
    let mut w = d;
    let mut weight = 1.0;
    let mut phase = 0.0;
    // First vertex, its type and outgoing direction; last vertex's type and arrival.
    let (mut x1, mut ty1, mut w12) = (DVec3::ZERO, 0, DVec3::ZERO);
    let mut collisions = 0u32;
    let mut ty = 0;
    let mut w_in = d;
    loop {
        let t = {
            let mut u = || rng.next_f64();
            m.sample_flight(x, w, &mut u)
        };
        let Some(t) = t else { break };
        x += t * w;
        collisions += 1;
        if collisions == 1 {
            x1 = x;
            phase = k * d.dot(x);
        } else {
            phase += k * t;
        }
        weight *= m.albedo(x);
        ty = m.sample_type(x, rng.next_f64());
        w_in = w;
        w = phases[ty].sample_direction(w, [rng.next_f64(), rng.next_f64()]);
        if collisions == 1 {
            ty1 = ty;
            w12 = w;
        }
        if weight < ROULETTE {
            if rng.next_f64() * ROULETTE >= weight {
                return;
            }
            weight = ROULETTE;
        }
        if collisions >= MAX_COLLISIONS {
            return;
        }
    }
    if collisions == 0 {
        return;
    }
    let phi = phase - k * w.dot(x);
    let cbs = if coherence == Coherence::ForwardAndReversed && collisions >= 2 {
        let tau = m.optical_depth_to_infinity(x1, -d) + m.optical_depth_to_infinity(x, w);
        let tau_rev = m.optical_depth_to_infinity(x, -d) + m.optical_depth_to_infinity(x1, w);
        let (p1, pb) = (&phases[ty1], &phases[ty]);
        let fwd = (p1.amplitude_between(d, w12) * pb.amplitude_between(w_in, w)).norm();
        let rev = (pb.amplitude_between(d, -w_in) * p1.amplitude_between(-w12, w)).norm();
        if fwd > 0.0 {
            let r = (-0.5 * (tau_rev - tau)).exp() * rev / fwd;
            r * (k * (d + w).dot(x - x1)).cos()
        } else {
            0.0
        }
    } else {
        0.0
    };
    bins.each(w, |v| score(v, weight, phi, cbs));
}
