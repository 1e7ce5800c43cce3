//! The renders of the images: the scenes of the cases, the check's covariance renders (their
//! blocks, jackknife and Isserlis moments) and the field render of the refocused amplitudes.

use super::plan::{ImageCase, ImagePlan};
use super::results::{PixelPrediction, PixelStats, RefocusImages};
use crate::StudyError;
use crate::memory::refocus::RefocusStudy;
use crate::memory::render::slab_tracer;
use speckle_endpoints::{Pair, Sensor, Source};
use speckle_estimators::{
    CovarianceOptions, EstimatorError, FieldOptions, Progress, Scene, render_covariance,
    render_fields,
};
use speckle_medium::{DVec3, HomogeneousBox};
use speckle_phase::{Complex64, Phase};
use speckle_stats::jackknife::jackknife;
use speckle_stats::rng::derive_seed;
use std::time::Instant;

/// Index of the field render's seed, `derive_seed(render.seed, FIELD_SEED_INDEX)`.
const FIELD_SEED_INDEX: u64 = 1 << 40;
/// Index of the first check group's seed: group `i` of case `c` renders with
/// `derive_seed(render.seed, CHECK_SEED_INDEX + c groups + i)`.
const CHECK_SEED_INDEX: u64 = 1 << 41;

/// Where a case's fields sit among the pairs of a scene.
#[derive(Debug, Clone, Copy)]
struct CaseLayout {
    /// The first pair of the case: `n_tau` pairs `(g, r_m)`, then `n_tau` per pixel `(x, s_m)`.
    first: usize,
}

impl RefocusStudy {
    /// The scene of the given cases with the given pixel offsets `(o_x, o_y)` per case (the
    /// same for all): per case, sources `g` then the pixels, sensors `r_m` then `s_m`, pairs
    /// `(g, r_m)` then `(x_p, s_m)` pixel after pixel.
    fn image_scene(
        &self,
        cases: &[ImageCase],
        pixels: &[(f64, f64)],
    ) -> Result<(Scene<HomogeneousBox, Phase>, Vec<CaseLayout>), EstimatorError> {
        let f = &self.file;
        let geo = &self.geometry;
        let l = f.thickness_um;
        let medium = geo.slab()?;
        let beam = |x: f64, y: f64, z: f64, tilt: f64| geo.beam(DVec3::new(x, y, z), tilt);
        let (mut sources, mut sensors, mut pairs, mut layout) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let nt = geo.tau.len();
        for c in cases {
            let da = geo.delta_a(c.delta_b, c.theta);
            layout.push(CaseLayout { first: pairs.len() });
            let g = sources.len();
            sources.push(Source::GaussianBeam(beam(
                -da / 2.0,
                0.0,
                -l / 2.0,
                -c.theta / 2.0,
            )?));
            let r0 = sensors.len();
            for s in [-1.0, 1.0] {
                for &t in &geo.tau {
                    sensors.push(Sensor::GaussianBeam(beam(
                        t + s * c.delta_b / 2.0,
                        0.0,
                        l / 2.0,
                        0.0,
                    )?));
                }
            }
            pairs.extend((0..nt).map(|m| Pair {
                source: g,
                sensor: r0 + m,
            }));
            for &(ox, oy) in pixels {
                let x = sources.len();
                sources.push(Source::GaussianBeam(beam(
                    da / 2.0 + ox,
                    oy,
                    -l / 2.0,
                    c.theta / 2.0,
                )?));
                pairs.extend((0..nt).map(|m| Pair {
                    source: x,
                    sensor: r0 + nt + m,
                }));
            }
        }
        let scene = Scene::new(
            medium,
            geo.phase()?,
            f.wavelength_um,
            sources,
            sensors,
            pairs,
        )?;
        Ok((scene, layout))
    }

    /// The phase ramp `a_m = exp(-i q tau_m)`, `q = 2 k sin(theta/2)`, of a case.
    fn ramp(&self, theta: f64) -> Vec<Complex64> {
        let q = self.geometry.k() * 2.0 * (theta / 2.0).sin();
        self.geometry
            .tau
            .iter()
            .map(|&t| Complex64::from_polar(1.0, -q * t))
            .collect()
    }

    /// The rough cost of the images on `threads` threads: seconds and bytes.
    pub fn images_estimate(&self, threads: usize) -> (f64, f64) {
        use speckle_scene::cost::{covariance_seconds, expected_vertices, gaussian_legs};
        let Some(p) = &self.images else {
            return (0.0, 0.0);
        };
        let f = &self.file;
        let t = 1.0 / f.mean_free_path_um;
        let taus = [t * f.width_um, t * f.width_um, t * f.thickness_um];
        let v = expected_vertices(&taus, 1.0, f.g, speckle_medium::Dimension::Three, u32::MAX);
        let nt = self.geometry.tau.len() as f64;
        let cases = p.cases.len() as f64;
        let pixels = p.pixels() as f64;
        let pairs = cases * (pixels + 1.0) * nt;
        // Every endpoint is a Gaussian beam of the single vMF lobe.
        let legs = gaussian_legs(cases * (pixels + 1.0 + 2.0 * nt), 1);
        let paths = p.file.realizations as f64 * p.file.paths as f64;
        let per_pair =
            covariance_seconds(paths, v, 0.0, 1.0) - covariance_seconds(paths, v, 0.0, 0.0);
        let fields = covariance_seconds(paths, v, legs, 0.0) + pairs * per_pair;
        let check_pairs = (1.0 + p.check_pixels().len() as f64) * nt;
        let check = cases
            * covariance_seconds(
                f.render.paths as f64,
                v,
                gaussian_legs(2.0 * nt + 6.0, 1),
                check_pairs,
            );
        let bytes = 16.0 * pairs * (p.file.realizations as f64 + 1.0)
            + 16.0 * p.file.realizations as f64 * cases * pixels;
        ((fields + check) / threads.max(1) as f64, bytes)
    }

    /// Renders the images of `[images]` (`None` without it): the fields of every case in one
    /// field render of `images.realizations` realizations of `images.paths` sub-paths (seed
    /// `derive_seed(render.seed, 2^40)`, `render.coherence` and the study's tracer), then the
    /// check: per case `render.groups` covariance renders of `render.paths` paths in all (group
    /// `i` of case `c` seeded with `derive_seed(render.seed, 2^41 + c groups + i)`).
    pub fn render_images(
        &self,
        progress: &dyn Progress,
    ) -> Result<Option<RefocusImages>, StudyError> {
        let Some(plan) = &self.images else {
            return Ok(None);
        };
        self.render_images_with(plan, false, progress).map(Some)
    }

    /// [`Self::render_images`] of `plan`; with `unconjugated` the pattern is `u_g(r_m) exp(-i q
    /// tau_m)` without the complex conjugate (a check that the conjugation is what focuses).
    pub fn render_images_with(
        &self,
        plan: &ImagePlan,
        unconjugated: bool,
        progress: &dyn Progress,
    ) -> Result<RefocusImages, StudyError> {
        let r = &self.file.render;
        let coherence = r.coherence.coherence();
        let nt = self.geometry.tau.len();
        let n = plan.offsets.len();
        let np = plan.pixels();
        let nc = plan.cases.len();
        // The check first: its |E A(0)| normalises everything.
        let start = Instant::now();
        let cp = plan.check_pixels();
        let check_offsets: Vec<(f64, f64)> = cp
            .iter()
            .map(|&(ix, iy)| (plan.offsets[ix], plan.rows[iy]))
            .collect();
        let nk = cp.len();
        let g = r.groups as u64;
        // blocks[c][i]: group i's covariance blocks of case c.
        let mut blocks: Vec<Vec<Blocks>> = Vec::with_capacity(nc);
        let mut weights = vec![0.0; r.groups];
        for (c, case) in plan.cases.iter().enumerate() {
            let (scene, _) = self.image_scene(std::slice::from_ref(case), &check_offsets)?;
            let mut per_group = Vec::with_capacity(r.groups);
            for i in 0..g {
                let paths = r.paths / g + u64::from(i < r.paths % g);
                let opts = CovarianceOptions {
                    paths,
                    seed: derive_seed(r.seed, CHECK_SEED_INDEX + c as u64 * g + i),
                    coherence,
                    sampling: slab_tracer(coherence),
                };
                let est = render_covariance(&scene, &opts, progress)?;
                let v = &est.total.value;
                per_group.push(Blocks::from_fn(nt, nk, |a, b| v.get(a, b)));
                weights[i as usize] = paths as f64;
            }
            blocks.push(per_group);
        }
        let ramps: Vec<Vec<Complex64>> = plan.cases.iter().map(|c| self.ramp(c.theta)).collect();
        // The statistic: |E A(0)|^2 (target of case 0), then per case and check pixel: Re E A,
        // Im E A (by |E A(0)|), |E A|^2 + Var A, Var A and |E A|^2 (by |E A(0)|^2), from the covariances
        // pooled over the groups kept.
        let stat = |skip: Option<usize>| -> Vec<f64> {
            let kept: Vec<usize> = (0..r.groups).filter(|&i| Some(i) != skip).collect();
            let w: f64 = kept.iter().map(|&i| weights[i]).sum();
            let pooled: Vec<Blocks> = blocks
                .iter()
                .map(|b| Blocks::pool(kept.iter().map(|&i| (&b[i], weights[i] / w))))
                .collect();
            let moments: Vec<Vec<(Complex64, f64)>> = pooled
                .iter()
                .zip(&ramps)
                .map(|(b, a)| (0..nk).map(|k| b.moments(k, a)).collect())
                .collect();
            let norm = moments[0][0].0.norm_sqr();
            let mut out = vec![norm];
            for m in &moments {
                for &(mean, var) in m {
                    out.extend([
                        mean.re / norm.sqrt(),
                        mean.im / norm.sqrt(),
                        (mean.norm_sqr() + var) / norm,
                        var / norm,
                        mean.norm_sqr() / norm,
                    ]);
                }
            }
            out
        };
        // Jackknife standard errors, and the jackknife's bias correction `G v - (G - 1) mean(v_i)`
        // of the values: `|E A|^2` and the products of covariances in `Var A` carry an upward
        // bias of the order of the squared standard errors of their entries (many near zero).
        let (raw, se) = jackknife(r.groups, stat);
        let gf = r.groups as f64;
        let loo: Vec<Vec<f64>> = (0..r.groups).map(|i| stat(Some(i))).collect();
        let value: Vec<f64> = (0..raw.len())
            .map(|j| gf * raw[j] - (gf - 1.0) * loo.iter().map(|l| l[j]).sum::<f64>() / gf)
            .collect();
        let norm = value[0];
        let predicted = (0..nc)
            .map(|c| {
                (0..nk)
                    .map(|k| {
                        let j = 1 + 5 * (nk * c + k);
                        PixelPrediction {
                            mean_re: (value[j], se[j]),
                            mean_im: (value[j + 1], se[j + 1]),
                            power: (value[j + 2], se[j + 2]),
                            var: (value[j + 3], se[j + 3]),
                            focus: (value[j + 4], se[j + 4]),
                        }
                    })
                    .collect()
            })
            .collect();
        let check_wall = start.elapsed().as_secs_f64();

        // The fields: every case in one scene, one realization one medium.
        let start = Instant::now();
        let pixels: Vec<(f64, f64)> = (0..np)
            .map(|p| (plan.offsets[p % n], plan.rows[p / n]))
            .collect();
        let (scene, layout) = self.image_scene(&plan.cases, &pixels)?;
        let opts = FieldOptions {
            realizations: plan.file.realizations,
            paths_per_realization: plan.file.paths,
            seed: derive_seed(r.seed, FIELD_SEED_INDEX),
            coherence,
            add_mean: false,
            sampling: slab_tracer(coherence),
        };
        let est = render_fields(&scene, &opts, progress)?;
        let rr = plan.file.realizations;
        let scale = 1.0 / norm.sqrt();
        let mut amplitude = vec![Complex64::new(0.0, 0.0); rr * nc * np];
        for q in 0..rr {
            let u = |j: usize| est.fields.get(q, j);
            for (c, lay) in layout.iter().enumerate() {
                let pattern: Vec<Complex64> = (0..nt)
                    .map(|m| {
                        let ug = u(lay.first + m);
                        (if unconjugated { ug } else { ug.conj() }) * ramps[c][m]
                    })
                    .collect();
                for p in 0..np {
                    let x0 = lay.first + nt * (1 + p);
                    let a: Complex64 = (0..nt).map(|m| u(x0 + m) * pattern[m]).sum();
                    amplitude[(q * nc + c) * np + p] = a * scale;
                }
            }
        }
        let measured = (0..nc)
            .map(|c| {
                cp.iter()
                    .map(|&(ix, iy)| {
                        let p = iy * n + ix;
                        let a: Vec<Complex64> =
                            (0..rr).map(|q| amplitude[(q * nc + c) * np + p]).collect();
                        pixel_stats(&a)
                    })
                    .collect()
            })
            .collect();
        Ok(RefocusImages {
            amplitude,
            norm,
            measured,
            predicted,
            fields_wall: start.elapsed().as_secs_f64(),
            check_wall,
        })
    }
}

/// The covariance blocks of a check scene (pairs `(g, r_m)`, then `(x_k, s_m)` for the check
/// pixels): `C[(x_k, s_m), (g, r_m)]`, `C[(x_k, s_m), (x_k, s_m')]` and `C[(g, r_m'), (g,
/// r_m)]`.
#[derive(Debug, Clone)]
struct Blocks {
    nt: usize,
    /// `cross[k nt + m]`.
    cross: Vec<Complex64>,
    /// `xx[(k nt + m) nt + m']`.
    xx: Vec<Complex64>,
    /// `gg[m' nt + m] = C[(g, r_m'), (g, r_m)]`.
    gg: Vec<Complex64>,
}

impl Blocks {
    fn from_fn(nt: usize, nk: usize, c: impl Fn(usize, usize) -> Complex64) -> Self {
        let x = |k: usize| nt * (1 + k);
        Self {
            nt,
            cross: (0..nk * nt)
                .map(|j| c(x(j / nt) + j % nt, j % nt))
                .collect(),
            xx: (0..nk * nt * nt)
                .map(|j| {
                    let (k, m, mp) = (j / (nt * nt), (j / nt) % nt, j % nt);
                    c(x(k) + m, x(k) + mp)
                })
                .collect(),
            gg: (0..nt * nt).map(|j| c(j / nt, j % nt)).collect(),
        }
    }

    /// The weighted sum of blocks.
    fn pool<'a>(parts: impl Iterator<Item = (&'a Blocks, f64)>) -> Self {
        let mut out: Option<Blocks> = None;
        for (b, w) in parts {
            let o = out.get_or_insert_with(|| Blocks {
                nt: b.nt,
                cross: vec![Complex64::new(0.0, 0.0); b.cross.len()],
                xx: vec![Complex64::new(0.0, 0.0); b.xx.len()],
                gg: vec![Complex64::new(0.0, 0.0); b.gg.len()],
            });
            for (d, s) in [
                (&mut o.cross, &b.cross),
                (&mut o.xx, &b.xx),
                (&mut o.gg, &b.gg),
            ] {
                for (x, y) in d.iter_mut().zip(s) {
                    *x += y * w;
                }
            }
        }
        out.expect("at least one group")
    }

    /// `E A` and the Isserlis `Var A` of check pixel `k` with the ramp `a`.
    fn moments(&self, k: usize, a: &[Complex64]) -> (Complex64, f64) {
        let nt = self.nt;
        let mean = (0..nt).map(|m| self.cross[k * nt + m] * a[m]).sum();
        let mut var = Complex64::new(0.0, 0.0);
        for m in 0..nt {
            for mp in 0..nt {
                var += a[m] * a[mp].conj() * self.xx[(k * nt + m) * nt + mp] * self.gg[mp * nt + m];
            }
        }
        (mean, var.re)
    }
}

/// Mean, power and variance of samples of `A`, with their standard errors.
fn pixel_stats(a: &[Complex64]) -> PixelStats {
    let r = a.len() as f64;
    let mean: Complex64 = a.iter().sum::<Complex64>() / r;
    let p: Vec<f64> = a.iter().map(|z| z.norm_sqr()).collect();
    let d: Vec<f64> = a.iter().map(|z| (z - mean).norm_sqr()).collect();
    let mean_sd = |x: &[f64]| {
        let m = x.iter().sum::<f64>() / r;
        let v = x.iter().map(|y| (y - m).powi(2)).sum::<f64>() / (r - 1.0);
        (m, (v / r).sqrt())
    };
    let (power, power_se) = mean_sd(&p);
    let (var_biased, var_se) = mean_sd(&d);
    let var = var_biased * r / (r - 1.0);
    PixelStats {
        mean_re: mean.re,
        mean_im: mean.im,
        mean_se: mean_sd(&a.iter().map(|z| z.re).collect::<Vec<_>>()).1,
        mean_im_se: mean_sd(&a.iter().map(|z| z.im).collect::<Vec<_>>()).1,
        power,
        power_se,
        var,
        var_se,
    }
}
