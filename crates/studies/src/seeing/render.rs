//! The render of a seeing-through study and its reduction: speckle images, their
//! autocorrelation against the one a perfect memory effect would give, the phase-retrieved
//! object, and the correlation of the illuminators' patterns against their separation.

use super::retrieval::{Retrieval, autocorrelation, crop, retrieve, similarity};
use super::{SeeingStudy, SlabCamera};
use crate::StudyError;
use crate::memory::{Array, slab_tracer, slab_tracer_json};
use serde_json::{Value, json};
use speckle_endpoints::{Pair, Sensor, Source};
use speckle_estimators::{Coherence, EstimatorError, FieldOptions, Progress, Scene, render_fields};
use speckle_medium::{Aabb, DVec3, HomogeneousBox};
use speckle_phase::Phase;
use speckle_stats::rng::derive_seed;
use std::fmt::Write as _;
use std::time::Instant;

/// One case (one `g`) of a study.
#[derive(Debug, Clone, PartialEq)]
pub struct SeeingCase {
    /// The HG mean cosine.
    pub g: f64,
    /// The speckle images `I = sum_p |u_p|^2`, one `n x n` row-major image per realization.
    pub images: Vec<Vec<f64>>,
    /// The images' autocorrelation (mean removed, averaged over realizations), centred `w x w`,
    /// scaled to 1 at lag 0.
    pub autocorrelation: Vec<f64>,
    /// What a perfect memory effect would make it: the object's autocorrelation convolved with
    /// the autocorrelation of one illuminator's pattern (the first lit cell's), scaled alike.
    pub predicted: Vec<f64>,
    /// The Pearson correlation of [`SeeingCase::autocorrelation`] and
    /// [`SeeingCase::predicted`] over the window.
    pub autocorrelation_match: f64,
    /// The phase-retrieved object, `w x w`, largest value 1.
    pub reconstruction: Vec<f64>,
    /// Its Fourier-magnitude misfit (`retrieval::Retrieved::fourier_error`).
    pub fourier_error: f64,
    /// How well it matches the object ([`super::retrieval::similarity`]: 1 is exact).
    pub similarity: f64,
    /// The same for the object retrieved from [`SeeingCase::predicted`]: what the retrieval
    /// achieves with a perfect memory effect and the same speckle grain and noise.
    pub ideal_similarity: f64,
    /// Per lit cell `p`: the Pearson correlation of the first cell's pattern `|u_0|^2` and
    /// `|u_p|^2` shifted back by their tilt difference (over the overlap, averaged over
    /// realizations); 1 for the first cell.
    pub memory: Vec<f64>,
    /// Their standard errors (the spread over realizations over `sqrt(R)`; 0 with one).
    pub memory_stderr: Vec<f64>,
}

/// The result of a seeing-through study.
#[derive(Debug, Clone, PartialEq)]
pub struct SeeingThrough {
    /// The object in the `w x w` window (1 at lit cells).
    pub object: Vec<f64>,
    /// Its autocorrelation, centred `w x w`, scaled to 1 at lag 0.
    pub object_autocorrelation: Vec<f64>,
    /// Per lit cell: its angular separation from the first, millidegrees.
    pub separation_mdeg: Vec<f64>,
    /// The cases, in the order of `g`.
    pub cases: Vec<SeeingCase>,
    /// Wall time, seconds.
    pub wall: f64,
}

impl SeeingStudy {
    /// The medium, sources (one plane wave per lit cell) and sensors (the image's far-field
    /// directions, row-major) of case `g`; every pair, source-major.
    pub fn scene(&self, g: f64) -> Result<Scene<HomogeneousBox, Phase>, EstimatorError> {
        let f = &self.file;
        let rows = f.object.len() as f64;
        let cols = f.object[0].chars().count() as f64;
        let tilts: Vec<(f64, f64)> = self
            .points
            .iter()
            .map(|&(r, c)| {
                (
                    (c as f64 - 0.5 * (cols - 1.0)) * f.object_step_mdeg,
                    (r as f64 - 0.5 * (rows - 1.0)) * f.object_step_mdeg,
                )
            })
            .collect();
        self.file.camera().scene(g, &tilts)
    }

    /// Rough cost of the study on `threads` threads.
    pub fn estimate(&self, threads: usize) -> speckle_scene::cost::Estimate {
        let f = &self.file;
        f.camera().estimate(
            &f.g,
            self.points.len(),
            f.realizations,
            f.render.paths,
            f.g.len() * f.realizations,
            threads,
        )
    }

    /// Renders every realization of every case (realization `r` of case `c` from
    /// `derive_seed(render.seed, c realizations + r)`) and reduces them.
    pub fn render(&self, progress: &dyn Progress) -> Result<SeeingThrough, StudyError> {
        let start = Instant::now();
        let f = &self.file;
        let (n, w) = (f.pixels, f.window);
        let np = self.points.len();
        let object = self.object_in_window();
        let object_ac = normalised(crop(&autocorrelation(&object, w, false), 2 * w, w));
        let separation_mdeg = self
            .points
            .iter()
            .map(|&(r, c)| {
                let (r0, c0) = self.points[0];
                let d = (r as f64 - r0 as f64).hypot(c as f64 - c0 as f64);
                d * f.object_step_mdeg
            })
            .collect();
        let retrieval = Retrieval {
            hio: f.retrieval.hio,
            er: f.retrieval.er,
            beta: f.retrieval.beta,
            starts: f.retrieval.starts,
            seed: f.render.seed,
        };
        let mut cases = Vec::with_capacity(f.g.len());
        for (ci, &g) in f.g.iter().enumerate() {
            let scene = self.scene(g)?;
            let mut images = Vec::with_capacity(f.realizations);
            let mut ac = vec![0.0; w * w];
            let mut single_ac = vec![0.0; w * w];
            let mut memory = vec![0.0; np];
            let mut memory_sq = vec![0.0; np];
            for r in 0..f.realizations {
                let seed = derive_seed(f.render.seed, (ci * f.realizations + r) as u64);
                let patterns = sampled_patterns(&scene, f.render.paths, seed, progress)?;
                let image: Vec<f64> = (0..n * n)
                    .map(|q| patterns.iter().map(|s| s[q]).sum())
                    .collect();
                add(&mut ac, &crop(&autocorrelation(&image, n, true), 2 * n, w));
                add(
                    &mut single_ac,
                    &crop(&autocorrelation(&patterns[0], n, true), 2 * n, w),
                );
                for p in 0..np {
                    let c = self.pattern_correlation(&patterns[0], &patterns[p], p);
                    memory[p] += c;
                    memory_sq[p] += c * c;
                }
                images.push(image);
            }
            let rn = f.realizations as f64;
            let memory_stderr = memory
                .iter()
                .zip(&memory_sq)
                .map(|(m, q)| {
                    let var = (q - m * m / rn) / (rn - 1.0).max(1.0);
                    if f.realizations > 1 {
                        (var.max(0.0) / rn).sqrt()
                    } else {
                        0.0
                    }
                })
                .collect();
            memory.iter_mut().for_each(|m| *m /= rn);
            let autocorrelation = normalised(ac);
            let predicted = normalised(self.predicted(&object, &single_ac));
            let retrieved = retrieve(&autocorrelation, w, &retrieval);
            let ideal = retrieve(&predicted, w, &retrieval);
            cases.push(SeeingCase {
                g,
                images,
                autocorrelation_match: pearson(&autocorrelation, &predicted),
                similarity: similarity(&retrieved.object, &object, w),
                ideal_similarity: similarity(&ideal.object, &object, w),
                autocorrelation,
                predicted,
                reconstruction: retrieved.object,
                fourier_error: retrieved.fourier_error,
                memory,
                memory_stderr,
            });
        }
        Ok(SeeingThrough {
            object,
            object_autocorrelation: object_ac,
            separation_mdeg,
            cases,
            wall: start.elapsed().as_secs_f64(),
        })
    }

    /// The object in the `w x w` window, centred.
    pub fn object_in_window(&self) -> Vec<f64> {
        let w = self.file.window;
        let (rows, cols) = (self.file.object.len(), self.file.object[0].chars().count());
        let (h, v) = ((cols - 1) * self.step + 1, (rows - 1) * self.step + 1);
        let (oy, ox) = ((w - v) / 2, (w - h) / 2);
        let mut o = vec![0.0; w * w];
        for &(r, c) in &self.points {
            o[(oy + r * self.step) * w + ox + c * self.step] = 1.0;
        }
        o
    }

    /// `sum_e (O * O)(e) S(d - e)`: the object's autocorrelation (lags of its lit cells)
    /// convolved with one pattern's autocorrelation `s` (centred `w x w`).
    fn predicted(&self, object: &[f64], s: &[f64]) -> Vec<f64> {
        let w = self.file.window as i64;
        let lit: Vec<(i64, i64)> = (0..object.len() as i64)
            .filter(|&i| object[i as usize] > 0.0)
            .map(|i| (i / w, i % w))
            .collect();
        let mut out = vec![0.0; (w * w) as usize];
        for &(ra, ca) in &lit {
            for &(rb, cb) in &lit {
                let (ey, ex) = (rb - ra, cb - ca);
                for y in 0..w {
                    let sy = y - ey;
                    if !(0..w).contains(&sy) {
                        continue;
                    }
                    for x in 0..w {
                        let sx = x - ex;
                        if (0..w).contains(&sx) {
                            out[(y * w + x) as usize] += s[(sy * w + sx) as usize];
                        }
                    }
                }
            }
        }
        out
    }

    /// The Pearson correlation of `a` (the first cell's pattern) and `b` (cell `p`'s) shifted
    /// back by their tilt difference, over the pixels both cover.
    fn pattern_correlation(&self, a: &[f64], b: &[f64], p: usize) -> f64 {
        let n = self.file.pixels as i64;
        let (r0, c0) = self.points[0];
        let (r, c) = self.points[p];
        let s = self.step as i64;
        let (dy, dx) = ((r as i64 - r0 as i64) * s, (c as i64 - c0 as i64) * s);
        let mut xs = vec![];
        let mut ys = vec![];
        for y in 0..n {
            for x in 0..n {
                let (y2, x2) = (y + dy, x + dx);
                if (0..n).contains(&y2) && (0..n).contains(&x2) {
                    xs.push(a[(y * n + x) as usize]);
                    ys.push(b[(y2 * n + x2) as usize]);
                }
            }
        }
        pearson(&xs, &ys)
    }
}

impl SlabCamera {
    /// The slab (HG mean cosine `g`), plane-wave sources tilted by `(theta_x, theta_y)`
    /// millidegrees each (`unit(tan theta_x, tan theta_y, 1)`) and far-field sensors on the
    /// `pixels x pixels` grid `pixel_mdeg` apart about +z (row-major, rows along +y); every
    /// pair, source-major. Errors name `g` for a bad mean cosine.
    pub(crate) fn scene(
        &self,
        g: f64,
        tilts_mdeg: &[(f64, f64)],
    ) -> Result<Scene<HomogeneousBox, Phase>, EstimatorError> {
        let slab = Aabb::centered(
            DVec3::ZERO,
            DVec3::new(self.width_um, self.width_um, self.thickness_um),
        )
        .map_err(|e| EstimatorError::InvalidInput {
            field: "width_um".into(),
            reason: e.to_string(),
        })?;
        let sigma_s = 1.0 / self.mean_free_path_um;
        let sigma_a = sigma_s * (1.0 / self.albedo - 1.0);
        let medium = HomogeneousBox::new(slab, sigma_s, sigma_a).map_err(|e| {
            EstimatorError::InvalidInput {
                field: "mean_free_path_um".into(),
                reason: e.to_string(),
            }
        })?;
        let phase = Phase::hg(g).map_err(|e| EstimatorError::InvalidInput {
            field: "g".into(),
            reason: e.to_string(),
        })?;
        let mdeg = |a: f64| (a * 1e-3).to_radians().tan();
        let sources = tilts_mdeg
            .iter()
            .map(|&(x, y)| Source::plane_wave(DVec3::new(mdeg(x), mdeg(y), 1.0)))
            .collect::<Result<Vec<_>, _>>()?;
        let n = self.pixels;
        let mid = 0.5 * (n as f64 - 1.0);
        let sensors = (0..n * n)
            .map(|q| {
                let tx = mdeg(((q % n) as f64 - mid) * self.pixel_mdeg);
                let ty = mdeg(((q / n) as f64 - mid) * self.pixel_mdeg);
                Sensor::far_field(DVec3::new(tx, ty, 1.0))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let pairs = Pair::all(sources.len(), sensors.len());
        Ok(Scene::new(
            medium,
            phase,
            self.wavelength_um,
            sources,
            sensors,
            pairs,
        )?)
    }

    /// Rough cost of `realizations` renders of `paths` paths for each of `gs`, with `sources`
    /// plane waves, keeping `images` images, on `threads` threads.
    pub(crate) fn estimate(
        &self,
        gs: &[f64],
        sources: usize,
        realizations: usize,
        paths: u64,
        images: usize,
        threads: usize,
    ) -> speckle_scene::cost::Estimate {
        use speckle_scene::cost::{expected_vertices, field_seconds};
        let t = 1.0 / (self.mean_free_path_um * self.albedo);
        let taus = [t * self.width_um, t * self.width_um, t * self.thickness_um];
        let pixels = (self.pixels * self.pixels) as f64;
        let legs = sources as f64 + pixels;
        let pairs = sources as f64 * pixels;
        let seconds: f64 = gs
            .iter()
            .map(|&g| {
                let v = expected_vertices(
                    &taus,
                    self.albedo,
                    g,
                    speckle_medium::Dimension::Three,
                    u32::MAX,
                );
                realizations as f64 * field_seconds(paths as f64, v, legs, pairs)
            })
            .sum();
        speckle_scene::cost::Estimate {
            bytes: 16.0 * pairs * (3.0 + threads as f64) + 8.0 * images as f64 * pixels + 1e6,
            memory_field: "pixels".into(),
            seconds: seconds / threads.max(1) as f64,
            time_field: "render.paths".into(),
            vertices_per_path: 0.0,
        }
    }
}

/// One realization of the fields of every pair of `scene` (a [`SlabCamera::scene`]) from
/// `paths` sampled paths (Alg. 2, `render_fields`: forward paths, the first vertex exponential
/// in depth and its direction from the phase function, the mean (ballistic) field left out):
/// per source, its intensity pattern `|u(v)|^2` over the sensors.
pub(crate) fn sampled_patterns(
    scene: &Scene<HomogeneousBox, Phase>,
    paths: u64,
    seed: u64,
    progress: &dyn Progress,
) -> Result<Vec<Vec<f64>>, EstimatorError> {
    let o = FieldOptions {
        realizations: 1,
        paths_per_realization: paths,
        seed,
        coherence: Coherence::ForwardOnly,
        add_mean: false,
        sampling: slab_tracer(Coherence::ForwardOnly),
    };
    let est = render_fields(scene, &o, progress)?;
    let m = scene.sensors().len();
    Ok((0..scene.sources().len())
        .map(|p| {
            (0..m)
                .map(|q| est.fields.get(0, p * m + q).norm_sqr())
                .collect()
        })
        .collect())
}

pub(crate) fn add(acc: &mut [f64], x: &[f64]) {
    acc.iter_mut().zip(x).for_each(|(a, b)| *a += b);
}

/// `a` divided by its value at lag 0 (the centre of a centred `w x w` array).
fn normalised(mut a: Vec<f64>) -> Vec<f64> {
    let w = (a.len() as f64).sqrt() as usize;
    let c = a[(w / 2) * w + w / 2];
    if c != 0.0 {
        a.iter_mut().for_each(|v| *v /= c);
    }
    a
}

/// The Pearson correlation of two equally long samples (0 when either is constant).
pub(crate) fn pearson(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        let (dx, dy) = (x - ma, y - mb);
        sab += dx * dy;
        saa += dx * dx;
        sbb += dy * dy;
    }
    if saa > 0.0 && sbb > 0.0 {
        sab / (saa * sbb).sqrt()
    } else {
        0.0
    }
}

impl SeeingThrough {
    /// The arrays to write (`<name>.<key>.npy`).
    pub fn arrays(&self, s: &SeeingStudy) -> Vec<Array> {
        let (n, w) = (s.file.pixels, s.file.window);
        let nc = self.cases.len();
        let r = s.file.realizations;
        let per_case = |f: &dyn Fn(&SeeingCase) -> &Vec<f64>| -> Vec<f64> {
            self.cases
                .iter()
                .flat_map(|c| f(c).iter().copied())
                .collect()
        };
        vec![
            Array {
                key: "object",
                shape: vec![w, w],
                data: self.object.clone(),
                content: "the object in the autocorrelation window: 1 at lit cells",
            },
            Array {
                key: "object_autocorrelation",
                shape: vec![w, w],
                data: self.object_autocorrelation.clone(),
                content: "its autocorrelation, lag 0 at [w/2, w/2], scaled to 1 there",
            },
            Array {
                key: "images",
                shape: vec![nc, r, n, n],
                data: self
                    .cases
                    .iter()
                    .flat_map(|c| c.images.iter().flatten().copied())
                    .collect(),
                content: "speckle images sum_p |u_p|^2 [case, realization, row (+y), column \
                          (+x)], absolute units of docs/conventions.md",
            },
            Array {
                key: "autocorrelation",
                shape: vec![nc, w, w],
                data: per_case(&|c| &c.autocorrelation),
                content: "the images' autocorrelation (mean removed, averaged over \
                          realizations), lag 0 at [w/2, w/2], scaled to 1 there",
            },
            Array {
                key: "predicted_autocorrelation",
                shape: vec![nc, w, w],
                data: per_case(&|c| &c.predicted),
                content: "with a perfect memory effect: the object's autocorrelation convolved \
                          with one illuminator's pattern's, scaled alike",
            },
            Array {
                key: "reconstruction",
                shape: vec![nc, w, w],
                data: per_case(&|c| &c.reconstruction),
                content: "the phase-retrieved object (HIO, then error reduction), largest \
                          value 1; up to a translation and a 180-degree rotation",
            },
            Array {
                key: "memory_correlation",
                shape: vec![nc, self.separation_mdeg.len()],
                data: per_case(&|c| &c.memory),
                content: "per lit cell: Pearson correlation of the first cell's pattern and \
                          its own shifted back by the tilt difference",
            },
            Array {
                key: "memory_correlation_stderr",
                shape: vec![nc, self.separation_mdeg.len()],
                data: per_case(&|c| &c.memory_stderr),
                content: "their standard errors (spread over realizations / sqrt(R))",
            },
            Array {
                key: "separation_mdeg",
                shape: vec![self.separation_mdeg.len()],
                data: self.separation_mdeg.clone(),
                content: "per lit cell: angular separation from the first, millidegrees",
            },
        ]
    }

    /// A report, a line per case.
    pub fn text(&self, s: &SeeingStudy) -> String {
        let mut t = String::new();
        let far = self
            .separation_mdeg
            .iter()
            .enumerate()
            .fold((0, 0.0), |b, (i, &d)| if d > b.1 { (i, d) } else { b });
        let _ = writeln!(
            t,
            "{}: {} lit cells up to {:.4} mdeg apart, {} x {} images of {} mdeg pixels",
            s.name,
            self.separation_mdeg.len(),
            far.1,
            s.file.pixels,
            s.file.pixels,
            s.file.pixel_mdeg
        );
        for c in &self.cases {
            let _ = writeln!(
                t,
                "  g = {}: reconstruction similarity {:.3} (Fourier error {:.3}; {:.3} with a \
                 perfect memory effect); autocorrelation vs perfect memory effect {:.3}; \
                 pattern correlation at {:.4} mdeg {:.3}",
                c.g,
                c.similarity,
                c.fourier_error,
                c.ideal_similarity,
                c.autocorrelation_match,
                far.1,
                c.memory[far.0]
            );
        }
        t
    }

    /// The sidecar, with `files` (what the caller wrote, by key).
    pub fn describe(&self, s: &SeeingStudy, files: Value, threads: usize) -> Value {
        json!({
            "command": "seeing-through",
            "study_file": s.origin,
            "study": serde_json::to_value(&s.file).unwrap_or(Value::Null),
            "geometry": {
                "slab_um": [s.file.width_um, s.file.width_um, s.file.thickness_um],
                "sources": "a plane wave unit(tan theta_x, tan theta_y, 1) per lit cell, \
                            theta = (cell - centre) object_step",
                "sensors": "far-field directions unit(tan t_x, tan t_y, 1), t = (pixel - \
                            centre) pixel_mdeg, row-major (rows along +y)",
                "pixels_per_object_step": s.step,
            },
            "render": {
                "paths_per_realization": s.file.render.paths,
                "realizations": s.file.realizations,
                "seed": s.file.render.seed,
                "realization_seeds": "realization r of case c renders with \
                                      derive_seed(render.seed, c realizations + r)",
                "estimator": "render_fields (Alg. 2), forward paths, the mean (ballistic) \
                              field left out",
                "tracer": slab_tracer_json(Coherence::ForwardOnly),
                "threads": threads,
                "wall_time_s": self.wall,
            },
            "cases": self.cases.iter().map(|c| json!({
                "g": c.g,
                "similarity": c.similarity,
                "ideal_similarity": c.ideal_similarity,
                "fourier_error": c.fourier_error,
                "autocorrelation_match": c.autocorrelation_match,
                "memory_correlation": c.memory,
                "memory_correlation_stderr": c.memory_stderr,
            })).collect::<Vec<_>>(),
            "separation_mdeg": self.separation_mdeg,
            "files": files,
        })
    }
}
