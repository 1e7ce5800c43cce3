//! Speckle images under tilted illumination and their shift (Bar et al. 2019, Fig. 1), the
//! study of `speckle memory-images`.
//!
//! A slab of Henyey-Greenstein scatterers (the paper's: `L` = 1 mm, mean free path 0.1 mm,
//! 500 nm) is lit by plane waves tilted about +y by `theta_n = n Delta` (`n` from `tilts`,
//! `Delta` = `delta_mdeg`, a whole number of pixels) and imaged in transmission by a camera at
//! infinity over `pixels x pixels` directions `pixel_mdeg` apart about +z, the geometry of the
//! seeing-through study ([`crate::seeing`]), whose renderer this study shares: every
//! realization draws the fields of all the tilts from the same sampled paths (Alg. 2, forward
//! paths, the mean field left out), one realization of the medium seen under every tilt.
//!
//! Within the memory-effect range the pattern under `theta_n` is the untilted one shifted by
//! `theta_n` (`u_{i + theta}(v + theta) ~ u_i(v)`), `n Delta / pixel_mdeg` columns to the right.
//! For each image the study computes its normalised cross-correlation with the untilted image of
//! the same `g` (the figure's black insets): at each lag `d`, the Pearson correlation `X_n(d)` of
//! `I_0(x)` and `I_n(x + d)` over the pixels both images cover
//! ([`crate::seeing::retrieval::normalised_cross_correlation`], by FFT), so `X_0(0) = 1`. It
//! peaks at the memory-effect shift, and its height there, the `peak`, is the intensity
//! correlation `|C_0n|^2 / (C_00 C_nn)` of the covariance render (`speckle memory-tilt`,
//! Gaussian speckle) on the same slab. Its mean and standard error are over the realizations.
//! (Normalising by the overlap's own means and variances, rather than the whole images', halves
//! the spread of the peaks over realizations: a realization's intensity scale cancels.)
//!
//! The study file (TOML, unknown keys rejected; lengths in micrometres, angles in
//! millidegrees):
//!
//! ```toml
//! name = "fig1_memory_images"     # output prefix (default: the file's stem)
//! wavelength_um = 0.5             # in the medium
//! thickness_um = 1000.0           # L
//! mean_free_path_um = 100.0       # 1 / sigma_s
//! albedo = 1.0                    # sigma_s / sigma_t, in (0, 1]
//! width_um = 11500.0              # lateral size of the slab: the speckle grain is lambda / W
//! g = [0.0, 0.9]                  # one row of images per HG mean cosine, each in (-1, 1)
//! delta_mdeg = 2.5                # Delta, a whole number of pixels
//! tilts = [0, 1, 3, 5]            # the columns, in Delta: strictly increasing from 0
//! pixels = 64                     # the images are pixels x pixels (even)
//! pixel_mdeg = 1.25               # the camera's angular pitch
//! realizations = 4                # images per g and tilt (at least 2: the standard errors)
//! window = 24                     # the insets' side (even): 2 (largest shift + 2) to pixels - 2
//!
//! [render]
//! paths = 4000                    # sampled paths per realization
//! seed = 1
//! ```

use super::study::{StudyOutput, StudyOverrides};
use super::{Array, slab_tracer_json};
use crate::StudyError;
use crate::seeing::retrieval::normalised_cross_correlation;
use crate::seeing::{MAX_PAIRS, SeeingRender, SlabCamera, add, sampled_patterns};
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use speckle_estimators::{Coherence, Progress};
use speckle_scene::validate::invalid as bad;
use speckle_scene::{LoadError, SceneError};
use speckle_stats::rng::derive_seed;
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

/// Most tilts (columns) of a study.
pub const MAX_IMAGE_TILTS: usize = 16;

/// A memory-images study file (see the module docs).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MemoryImagesFile {
    /// Output prefix (default: the stem of the file name).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Wavelength in the medium, micrometres.
    pub wavelength_um: f64,
    /// Slab thickness, micrometres.
    pub thickness_um: f64,
    /// Mean free path `1 / sigma_s`, micrometres.
    pub mean_free_path_um: f64,
    /// Single-scattering albedo.
    #[serde(default = "one")]
    pub albedo: f64,
    /// Lateral size of the slab, micrometres.
    pub width_um: f64,
    /// HG mean cosines, one row of images each.
    pub g: Vec<f64>,
    /// The tilt step `Delta`, millidegrees.
    pub delta_mdeg: f64,
    /// The tilts, in multiples of `Delta`.
    pub tilts: Vec<u32>,
    /// Image side, pixels.
    pub pixels: usize,
    /// Angular pitch of the images, millidegrees.
    pub pixel_mdeg: f64,
    /// Images per `g` and tilt.
    pub realizations: usize,
    /// Side of the insets (the cross-correlations' lags), pixels.
    pub window: usize,
    /// `[render]`.
    #[serde(default)]
    pub render: SeeingRender,
    /// `[output]`.
    #[serde(default)]
    pub output: StudyOutput,
}

fn one() -> f64 {
    1.0
}

/// A validated memory-images study.
#[derive(Debug, Clone)]
pub struct MemoryImagesStudy {
    /// The document as parsed, with the command-line values filled in.
    pub file: MemoryImagesFile,
    /// Output prefix.
    pub name: String,
    /// Where the study came from.
    pub origin: String,
    /// Pixels per `Delta`.
    pub step: usize,
}

/// Loads and validates a memory-images study file.
pub fn load_memory_images_file(
    path: &Path,
    overrides: &StudyOverrides,
) -> Result<MemoryImagesStudy, LoadError> {
    super::study::load_study_file(path, overrides, load_memory_images_str)
}

/// Loads and validates a memory-images study from its text (`origin` names it in errors;
/// `default_name` is the output prefix when the study sets none).
pub fn load_memory_images_str(
    text: &str,
    origin: &str,
    default_name: &str,
    overrides: &StudyOverrides,
) -> Result<MemoryImagesStudy, LoadError> {
    super::study::load_study(
        text,
        origin,
        default_name,
        overrides,
        |f: &mut MemoryImagesFile| (&mut f.render.paths, &mut f.render.seed, &mut f.output),
        validate,
    )
}

impl MemoryImagesFile {
    fn camera(&self) -> SlabCamera {
        SlabCamera {
            wavelength_um: self.wavelength_um,
            thickness_um: self.thickness_um,
            mean_free_path_um: self.mean_free_path_um,
            albedo: self.albedo,
            width_um: self.width_um,
            pixels: self.pixels,
            pixel_mdeg: self.pixel_mdeg,
        }
    }
}

fn validate(
    file: MemoryImagesFile,
    origin: &str,
    default_name: &str,
) -> Result<MemoryImagesStudy, SceneError> {
    let name = file
        .name
        .clone()
        .unwrap_or_else(|| default_name.to_string());
    speckle_scene::validate::name(&name)?;
    let step = file.camera().validate(
        &file.g,
        ("delta_mdeg", file.delta_mdeg),
        file.realizations,
        file.render.paths,
    )?;
    if file.realizations < 2 {
        return Err(bad(
            "realizations",
            format!(
                "must be at least 2: the standard errors are the spread over realizations (got \
                 {})",
                file.realizations
            ),
        ));
    }
    let t = &file.tilts;
    if t.is_empty() || t.len() > MAX_IMAGE_TILTS {
        return Err(bad(
            "tilts",
            format!("must list 1 to {MAX_IMAGE_TILTS} values (got {})", t.len()),
        ));
    }
    if t[0] != 0 {
        return Err(bad(
            "tilts[0]",
            format!(
                "must be 0: the untilted image is the reference (got {})",
                t[0]
            ),
        ));
    }
    for i in 1..t.len() {
        if t[i] <= t[i - 1] {
            return Err(bad(
                format!("tilts[{i}]"),
                format!(
                    "must be above tilts[{}] = {} (got {})",
                    i - 1,
                    t[i - 1],
                    t[i]
                ),
            ));
        }
    }
    let shift = (*t.last().unwrap_or(&0) as usize).saturating_mul(step);
    let w = file.window;
    if !w.is_multiple_of(2) || w < 2 * shift.saturating_add(2) || w + 2 > file.pixels {
        return Err(bad(
            "window",
            format!(
                "must be even, at least twice the largest shift plus 2, so that the peak and a \
                 lag beyond it are inside ({}: tilts up to {} Delta of {step} pixels), and at \
                 most pixels - 2 ({}: the inset and its frame fit in the image) (got {w})",
                2 * shift.saturating_add(2),
                t.last().unwrap_or(&0),
                file.pixels - 2
            ),
        ));
    }
    let pairs = t.len().saturating_mul(file.pixels * file.pixels);
    if pairs > MAX_PAIRS {
        return Err(bad(
            "pixels",
            format!(
                "gives {pairs} pairs per render ({} tilts x {}^2 pixels), above {MAX_PAIRS}",
                t.len(),
                file.pixels
            ),
        ));
    }
    Ok(MemoryImagesStudy {
        file,
        name,
        origin: origin.to_string(),
        step,
    })
}

/// One `g` (a row of the figure) of [`MemoryImages`].
#[derive(Debug, Clone, PartialEq)]
pub struct MemoryImagesRow {
    /// The HG mean cosine.
    pub g: f64,
    /// The speckle images `|u(v)|^2`, `[realization][tilt]`, row-major `n x n` (rows along +y).
    pub images: Vec<Vec<Vec<f64>>>,
    /// Per tilt: the cross-correlation `X_n` with the untilted image (module docs), centred
    /// `w x w` (lag 0 at `(w/2, w/2)`), averaged over the realizations.
    pub correlation: Vec<Vec<f64>>,
    /// Per tilt: `X_n` at the memory-effect shift, averaged over the realizations.
    pub peak: Vec<f64>,
    /// Its standard error (the spread over realizations over `sqrt(R)`).
    pub peak_stderr: Vec<f64>,
    /// `X_n` at the shift per realization, `[realization][tilt]`.
    pub peak_realizations: Vec<Vec<f64>>,
    /// Per tilt: the lag `(rows, columns)` of the averaged cross-correlation's maximum.
    pub peak_lag: Vec<(i64, i64)>,
}

/// The result of a memory-images study.
#[derive(Debug, Clone, PartialEq)]
pub struct MemoryImages {
    /// The tilts, millidegrees.
    pub tilts_mdeg: Vec<f64>,
    /// The memory-effect shift of each tilt, columns.
    pub shifts: Vec<usize>,
    /// The rows, in the order of `g`.
    pub rows: Vec<MemoryImagesRow>,
    /// Wall time, seconds.
    pub wall: f64,
}

impl MemoryImagesStudy {
    /// The plane waves' tilts `(theta_x, theta_y)`, millidegrees.
    pub fn tilts_mdeg(&self) -> Vec<(f64, f64)> {
        let d = self.file.delta_mdeg;
        self.file
            .tilts
            .iter()
            .map(|&n| (n as f64 * d, 0.0))
            .collect()
    }

    /// The library scene of row `g` (errors name `g`): the slab, a plane wave per tilt and the
    /// image's far-field directions; every pair, source-major.
    pub fn scene(
        &self,
        g: f64,
    ) -> Result<
        speckle_estimators::Scene<speckle_medium::HomogeneousBox, speckle_phase::Phase>,
        speckle_estimators::EstimatorError,
    > {
        self.file.camera().scene(g, &self.tilts_mdeg())
    }

    /// Rough cost of the study on `threads` threads.
    pub fn estimate(&self, threads: usize) -> speckle_scene::cost::Estimate {
        let f = &self.file;
        f.camera().estimate(
            &f.g,
            f.tilts.len(),
            f.realizations,
            f.render.paths,
            f.g.len() * f.realizations * f.tilts.len(),
            threads,
        )
    }

    /// Renders every realization of every row (realization `r` of row `c` from
    /// `derive_seed(render.seed, c realizations + r)`) and their cross-correlations.
    pub fn render(&self, progress: &dyn Progress) -> Result<MemoryImages, StudyError> {
        let start = Instant::now();
        let f = &self.file;
        let (n, w, nt, nr) = (f.pixels, f.window, f.tilts.len(), f.realizations);
        let shifts: Vec<usize> = f.tilts.iter().map(|&t| t as usize * self.step).collect();
        let mut rows = Vec::with_capacity(f.g.len());
        for (ci, &g) in f.g.iter().enumerate() {
            let scene = self.scene(g)?;
            let mut images = Vec::with_capacity(nr);
            let mut correlation = vec![vec![0.0; w * w]; nt];
            let mut peak_realizations = Vec::with_capacity(nr);
            for r in 0..nr {
                let seed = derive_seed(f.render.seed, (ci * nr + r) as u64);
                let patterns = sampled_patterns(&scene, f.render.paths, seed, progress)?;
                let mut peaks = Vec::with_capacity(nt);
                for (t, acc) in correlation.iter_mut().enumerate() {
                    let x = normalised_cross_correlation(&patterns[0], &patterns[t], n, w);
                    peaks.push(x[(w / 2) * w + w / 2 + shifts[t]]);
                    add(acc, &x);
                }
                peak_realizations.push(peaks);
                images.push(patterns);
            }
            let rn = nr as f64;
            correlation
                .iter_mut()
                .for_each(|c| c.iter_mut().for_each(|v| *v /= rn));
            let (mut peak, mut peak_stderr) = (vec![], vec![]);
            for t in 0..nt {
                let (m, se) = mean_stderr(peak_realizations.iter().map(|p: &Vec<f64>| p[t]));
                peak.push(m);
                peak_stderr.push(se);
            }
            let peak_lag = correlation.iter().map(|c| argmax_lag(c, w)).collect();
            rows.push(MemoryImagesRow {
                g,
                images,
                correlation,
                peak,
                peak_stderr,
                peak_realizations,
                peak_lag,
            });
        }
        Ok(MemoryImages {
            tilts_mdeg: self.tilts_mdeg().iter().map(|t| t.0).collect(),
            shifts,
            rows,
            wall: start.elapsed().as_secs_f64(),
        })
    }
}

/// The mean of `values` and its standard error (0 for fewer than two).
fn mean_stderr(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let v: Vec<f64> = values.collect();
    let k = v.len() as f64;
    let m = v.iter().sum::<f64>() / k;
    if v.len() < 2 {
        return (m, 0.0);
    }
    let var = v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (k - 1.0);
    (m, (var / k).sqrt())
}

/// The lag `(rows, columns)` of the largest value of a centred `w x w` array.
fn argmax_lag(c: &[f64], w: usize) -> (i64, i64) {
    let i = (0..c.len()).fold(0, |b, i| if c[i] > c[b] { i } else { b });
    let half = (w / 2) as i64;
    ((i / w) as i64 - half, (i % w) as i64 - half)
}

impl MemoryImages {
    /// The arrays to write (`<name>.<key>.npy`).
    pub fn arrays(&self, s: &MemoryImagesStudy) -> Vec<Array> {
        let (n, w) = (s.file.pixels, s.file.window);
        let (ng, nt, nr) = (self.rows.len(), self.shifts.len(), s.file.realizations);
        let per_row = |f: &dyn Fn(&MemoryImagesRow) -> Vec<f64>| -> Vec<f64> {
            self.rows.iter().flat_map(f).collect()
        };
        vec![
            Array {
                key: "images",
                shape: vec![ng, nr, nt, n, n],
                data: per_row(&|r| r.images.iter().flatten().flatten().copied().collect()),
                content: "speckle images |u|^2 [g, realization, tilt, row (+y), column (+x)], \
                          absolute units of docs/conventions.md",
            },
            Array {
                key: "correlation",
                shape: vec![ng, nt, w, w],
                data: per_row(&|r| r.correlation.iter().flatten().copied().collect()),
                content: "the insets: per lag d, the Pearson correlation of the untilted image \
                          I_0(x) and the tilted one I_n(x + d) over the pixels both cover (1 at \
                          lag 0 of the untilted image), averaged over realizations; [g, tilt, lag \
                          row, lag column], lag 0 at [w/2, w/2]",
            },
            Array {
                key: "peak",
                shape: vec![ng, nt],
                data: per_row(&|r| r.peak.clone()),
                content: "the cross-correlation at the memory-effect shift (0, tilt / \
                          pixel_mdeg), mean over realizations",
            },
            Array {
                key: "peak_stderr",
                shape: vec![ng, nt],
                data: per_row(&|r| r.peak_stderr.clone()),
                content: "its standard error (spread over realizations / sqrt(R))",
            },
            Array {
                key: "peak_realizations",
                shape: vec![ng, nr, nt],
                data: per_row(&|r| r.peak_realizations.iter().flatten().copied().collect()),
                content: "the cross-correlation at the shift per realization",
            },
            Array {
                key: "peak_lag",
                shape: vec![ng, nt, 2],
                data: per_row(&|r| {
                    r.peak_lag
                        .iter()
                        .flat_map(|&(y, x)| [y as f64, x as f64])
                        .collect()
                }),
                content: "the lag (rows, columns) of the averaged cross-correlation's maximum",
            },
            Array {
                key: "tilts_mdeg",
                shape: vec![nt],
                data: self.tilts_mdeg.clone(),
                content: "the illumination tilts about +y, millidegrees",
            },
        ]
    }

    /// A report: the peak heights per row.
    pub fn text(&self, s: &MemoryImagesStudy) -> String {
        let f = &s.file;
        let mut t = String::new();
        let _ = writeln!(
            t,
            "{}: {} x {} images of {} mdeg pixels, tilts {:?} x Delta = {} mdeg ({} pixels); \
             correlation with the untilted image at the memory-effect shift (mean +- SE over {} \
             realizations):",
            s.name, f.pixels, f.pixels, f.pixel_mdeg, f.tilts, f.delta_mdeg, s.step, f.realizations
        );
        for r in &self.rows {
            let cells: Vec<String> = (0..self.shifts.len())
                .map(|i| {
                    let (y, x) = r.peak_lag[i];
                    let at = if (y, x) == (0, self.shifts[i] as i64) {
                        String::new()
                    } else {
                        format!(" (maximum at ({y}, {x}))")
                    };
                    format!(
                        "{} Delta {:.3} +- {:.3}{at}",
                        f.tilts[i], r.peak[i], r.peak_stderr[i]
                    )
                })
                .collect();
            let _ = writeln!(t, "  g = {}: {}", r.g, cells.join(", "));
        }
        t
    }

    /// The sidecar, with `files` (what the caller wrote, by key).
    pub fn describe(&self, s: &MemoryImagesStudy, files: Value, threads: usize) -> Value {
        let f = &s.file;
        json!({
            "command": "memory-images",
            "study_file": s.origin,
            "study": serde_json::to_value(f).unwrap_or(Value::Null),
            "geometry": {
                "slab_um": [f.width_um, f.width_um, f.thickness_um],
                "sources": "a plane wave unit(tan theta, 0, 1) per tilt theta = n delta_mdeg \
                            (about +y)",
                "sensors": "far-field directions unit(tan t_x, tan t_y, 1), t = (pixel - \
                            centre) pixel_mdeg, row-major (rows along +y)",
                "pixels_per_delta": s.step,
                "shift_pixels": self.shifts,
            },
            "correlation": "X_n(d): the Pearson correlation of I_0(x) and I_n(x + d) over the \
                            pixels both images cover (normalised_cross_correlation, by FFT); \
                            the peak is X_n at d = (0, shift); mean and standard error over \
                            the realizations",
            "render": {
                "paths_per_realization": f.render.paths,
                "realizations": f.realizations,
                "seed": f.render.seed,
                "realization_seeds": "realization r of row c renders with \
                                      derive_seed(render.seed, c realizations + r)",
                "estimator": "render_fields (Alg. 2), forward paths, the mean (ballistic) \
                              field left out; every tilt from the same paths",
                "tracer": slab_tracer_json(Coherence::ForwardOnly),
                "threads": threads,
                "wall_time_s": self.wall,
            },
            "rows": self.rows.iter().map(|r| json!({
                "g": r.g,
                "peak": r.peak,
                "peak_stderr": r.peak_stderr,
                "peak_lag": r.peak_lag.iter().map(|&(y, x)| [y, x]).collect::<Vec<_>>(),
            })).collect::<Vec<_>>(),
            "tilts_mdeg": self.tilts_mdeg,
            "files": files,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r######"
wavelength_um = 0.5
thickness_um = 1000.0
mean_free_path_um = 100.0
width_um = 11500.0
g = [0.0, 0.9]
delta_mdeg = 2.5
tilts = [0, 1, 3]
pixels = 20
pixel_mdeg = 1.25
realizations = 2
window = 16
"######;

    fn load(text: &str) -> Result<MemoryImagesStudy, LoadError> {
        load_memory_images_str(text, "s.toml", "s", &StudyOverrides::default())
    }

    /// The error of `GOOD` with `from` replaced by `to`, which must name `field`.
    fn refused(from: &str, to: &str, field: &str) {
        assert!(GOOD.contains(from), "{from}");
        let e = load(&GOOD.replace(from, to)).unwrap_err().to_string();
        assert!(e.contains(field), "{field}: {e}");
    }

    #[test]
    fn a_valid_study_loads() {
        let s = load(GOOD).unwrap();
        assert_eq!(s.step, 2);
        assert_eq!(s.name, "s");
        assert_eq!(s.tilts_mdeg(), vec![(0.0, 0.0), (2.5, 0.0), (7.5, 0.0)]);
    }

    #[test]
    fn bad_studies_name_their_field() {
        refused("g = [0.0, 0.9]", "g = [0.0, 1.0]", "g[1]");
        refused("g = [0.0, 0.9]", "g = []", "g");
        refused("tilts = [0, 1, 3]", "tilts = [1, 3]", "tilts[0]");
        refused("tilts = [0, 1, 3]", "tilts = [0, 3, 3]", "tilts[2]");
        refused("tilts = [0, 1, 3]", "tilts = []", "tilts");
        refused("tilts = [0, 1, 3]", "tilts = [0, -1]", "tilts");
        refused("delta_mdeg = 2.5", "delta_mdeg = 2.0", "delta_mdeg");
        refused("delta_mdeg = 2.5", "delta_mdeg = nan", "delta_mdeg");
        refused("window = 16", "window = 14", "window");
        refused("window = 16", "window = 20", "window");
        refused("pixels = 20", "pixels = 19", "pixels");
        refused("realizations = 2", "realizations = 1", "realizations");
        refused("realizations = 2", "realizations = 65", "realizations");
        refused("width_um = 11500.0", "width_um = 10.0", "width_um");
        refused(
            "thickness_um = 1000.0",
            "thickness_um = 1e9",
            "thickness_um",
        );
        refused("window = 16", "window = 16\nwindw = 3", "windw");
    }

    #[test]
    fn the_largest_lag_is_found() {
        let mut c = vec![0.0; 36];
        c[2 * 6 + 5] = 0.7;
        c[3 * 6 + 3] = 0.5;
        assert_eq!(argmax_lag(&c, 6), (-1, 2));
    }
}
