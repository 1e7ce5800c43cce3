//! Seeing through a scattering slab (Katz et al. 2014; Bar et al. 2019, Sec. 6.3, Fig. 13), the
//! study of `speckle seeing-through`.
//!
//! An object made of incoherent point illuminators far behind a slab, at angular offsets
//! `theta_p` within a few multiples of `Delta` (`object_step_mdeg`), lights the slab with plane
//! waves `i_p = unit(tan theta_px, tan theta_py, 1)`; a camera at infinity images the
//! transmitted far field over `pixels x pixels` directions `pixel_mdeg` apart about +z. Within
//! the memory-effect range the speckle pattern of `i_p` is the pattern of `i_0` shifted by
//! `theta_p - theta_0` (`u_{i + theta}(v + theta) ~ u_i(v)`), so the incoherent image
//! `I(v) = sum_p |u_p(v)|^2` is the object convolved with one speckle pattern, and the image's
//! autocorrelation is the object's (convolved with the speckle grain's, on a flat background
//! removed with the image's mean). Phase retrieval ([`retrieval`], Fienup's HIO and error
//! reduction) recovers the object from it, up to a translation and a 180-degree rotation.
//!
//! Every realization of the image is one draw of the fields of all `(i_p, v)` pairs from the
//! same sampled paths (Alg. 2 of the paper, `speckle_estimators::render_fields`, forward paths,
//! the first vertex exponential in depth and its direction from the phase function, the mean
//! (ballistic) field left out), so the patterns of the illuminators are as correlated as the
//! medium makes them: the study also measures that correlation directly (the Pearson
//! correlation of `|u_0|^2` and `|u_p|^2` shifted back by the tilt difference, against the
//! separation), which says where the object leaves the memory-effect range.
//!
//! The slab and camera (`SlabCamera`: the scene, its checks and cost) and the sampled
//! patterns of one realization (`sampled_patterns`) are shared with the memory-effect images
//! of Fig. 1 ([`crate::memory::MemoryImagesStudy`]).
//!
//! The study file (TOML, unknown keys rejected; lengths in micrometres, angles in
//! millidegrees):
//!
//! ```toml
//! name = "fig13_seeing_through"   # output prefix (default: the file's stem)
//! wavelength_um = 0.5             # in the medium
//! thickness_um = 1000.0           # L
//! mean_free_path_um = 100.0       # 1 / sigma_s
//! albedo = 1.0                    # sigma_s / sigma_t, in (0, 1]
//! width_um = 11500.0              # lateral size of the slab: the speckle grain is lambda / W
//! g = [0.9, 0.85]                 # one case per HG mean cosine, each in (-1, 1)
//! object = ["#####.", "#.....", "####..", "#.....", "#.....", "#....."]   # '#' lit, rows down
//! object_step_mdeg = 2.5          # Delta, a whole number of pixels
//! pixels = 64                     # the image is pixels x pixels (even)
//! pixel_mdeg = 1.25               # the camera's angular pitch
//! realizations = 4                # images per case (their autocorrelations are averaged)
//! window = 32                     # the autocorrelation window (even), at least twice the object
//!
//! [render]
//! paths = 4000                    # sampled paths per realization
//! seed = 1
//!
//! [retrieval]                     # optional: Fienup's HIO, then error reduction
//! hio = 2000
//! er = 200
//! beta = 0.9
//! starts = 8
//! ```

mod render;
pub mod retrieval;

pub use render::{SeeingCase, SeeingThrough};
pub(crate) use render::{add, sampled_patterns};

use crate::memory::{StudyOutput, StudyOverrides};
use serde::{Deserialize, Serialize};
use speckle_scene::validate::{invalid as bad, positive};
use speckle_scene::{LoadError, SceneError};
use std::path::Path;

/// Most cases (`g` values) of a study.
pub const MAX_CASES: usize = 8;
/// Most lit object cells.
pub const MAX_POINTS: usize = 64;
/// Most image pixels along a side.
pub const MAX_PIXELS: usize = 256;
/// Most pairs (lit cells times pixels) of one realization's render.
pub const MAX_PAIRS: usize = 1 << 21;
/// Most realizations per case.
pub const MAX_REALIZATIONS: usize = 64;
/// Largest optical depth `L / l` (the cost per path grows with it).
pub const MAX_OPTICAL_DEPTH: f64 = 50.0;

/// `[render]` of a seeing-through study.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SeeingRender {
    /// Sampled paths per realization.
    pub paths: u64,
    /// Seed: realization `r` of case `c` renders from `derive_seed(seed, c R + r)`.
    pub seed: u64,
}

impl Default for SeeingRender {
    fn default() -> Self {
        Self {
            paths: 4000,
            seed: 1,
        }
    }
}

/// `[retrieval]`: the options of [`retrieval::retrieve`].
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SeeingRetrieval {
    /// Hybrid input-output iterations per start.
    pub hio: usize,
    /// Error-reduction iterations after them.
    pub er: usize,
    /// HIO feedback.
    pub beta: f64,
    /// Random starts (the best fit is kept).
    pub starts: usize,
}

impl Default for SeeingRetrieval {
    fn default() -> Self {
        let d = retrieval::Retrieval::default();
        Self {
            hio: d.hio,
            er: d.er,
            beta: d.beta,
            starts: d.starts,
        }
    }
}

/// A seeing-through study file (see the module docs).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SeeingFile {
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
    /// HG mean cosines, one case each.
    pub g: Vec<f64>,
    /// The object: rows of `#` (lit) and `.` (dark), top to bottom.
    pub object: Vec<String>,
    /// Angular step between object cells, millidegrees.
    pub object_step_mdeg: f64,
    /// Image side, pixels.
    pub pixels: usize,
    /// Angular pitch of the image, millidegrees.
    pub pixel_mdeg: f64,
    /// Images per case.
    pub realizations: usize,
    /// Autocorrelation window, pixels.
    pub window: usize,
    /// `[render]`.
    #[serde(default)]
    pub render: SeeingRender,
    /// `[retrieval]`.
    #[serde(default)]
    pub retrieval: SeeingRetrieval,
    /// `[output]`.
    #[serde(default)]
    pub output: StudyOutput,
}

/// A slab imaged in transmission by a camera at infinity: the geometry the seeing-through study
/// shares with the memory-effect images ([`crate::memory::MemoryImagesStudy`]), in the units of their
/// study files (micrometres, millidegrees).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SlabCamera {
    /// Wavelength in the medium.
    pub wavelength_um: f64,
    /// Slab thickness `L`.
    pub thickness_um: f64,
    /// Mean free path `1 / sigma_s`.
    pub mean_free_path_um: f64,
    /// Single-scattering albedo.
    pub albedo: f64,
    /// Lateral size of the slab.
    pub width_um: f64,
    /// Image side, pixels.
    pub pixels: usize,
    /// Angular pitch of the image, millidegrees.
    pub pixel_mdeg: f64,
}

impl SeeingFile {
    /// The slab and camera of the study.
    pub(crate) fn camera(&self) -> SlabCamera {
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

impl SlabCamera {
    /// Checks the slab, the camera, the mean cosines `g`, the angular step (`step.0` names it,
    /// `step.1` in millidegrees: a whole number of pixels, returned), the realizations and
    /// `render.paths`; errors name the study file's field.
    pub(crate) fn validate(
        &self,
        g: &[f64],
        step: (&str, f64),
        realizations: usize,
        paths: u64,
    ) -> Result<usize, SceneError> {
        let (step_field, step_mdeg) = step;
        for (field, v) in [
            ("wavelength_um", self.wavelength_um),
            ("thickness_um", self.thickness_um),
            ("mean_free_path_um", self.mean_free_path_um),
            ("width_um", self.width_um),
            (step_field, step_mdeg),
            ("pixel_mdeg", self.pixel_mdeg),
        ] {
            positive(field, v)?;
        }
        if !(self.albedo > 0.0 && self.albedo <= 1.0) {
            return Err(bad(
                "albedo",
                format!("must be in (0, 1] (got {})", self.albedo),
            ));
        }
        let depth = self.thickness_um / self.mean_free_path_um * (1.0 / self.albedo);
        if depth > MAX_OPTICAL_DEPTH {
            return Err(bad(
                "thickness_um",
                format!(
                    "gives an optical depth of {depth:.4e}, above {MAX_OPTICAL_DEPTH} (the cost \
                     per path grows with it)"
                ),
            ));
        }
        if self.width_um > 1e6 * self.thickness_um {
            return Err(bad(
                "width_um",
                format!(
                    "must be at most 1e6 times the thickness ({} um; got {:.4e})",
                    self.thickness_um, self.width_um
                ),
            ));
        }
        if self.width_um < self.thickness_um {
            return Err(bad(
                "width_um",
                format!(
                    "must be at least the thickness ({} um; got {}): light leaves a narrower \
                     slab through its sides",
                    self.thickness_um, self.width_um
                ),
            ));
        }
        if g.is_empty() || g.len() > MAX_CASES {
            return Err(bad(
                "g",
                format!("must list 1 to {MAX_CASES} values (got {})", g.len()),
            ));
        }
        for (i, &g) in g.iter().enumerate() {
            if !(g.is_finite() && g.abs() < 1.0) {
                return Err(bad(
                    format!("g[{i}]"),
                    format!("must be in (-1, 1) (got {g})"),
                ));
            }
        }
        let ratio = step_mdeg / self.pixel_mdeg;
        let whole = ratio.round();
        if !(whole >= 1.0 && (ratio - whole).abs() <= 1e-9 * ratio) {
            return Err(bad(
                step_field,
                format!(
                    "must be a whole number of pixels (pixel_mdeg = {}; got {step_mdeg} = \
                     {ratio:.6} pixels)",
                    self.pixel_mdeg
                ),
            ));
        }
        if !(8..=MAX_PIXELS).contains(&self.pixels) || !self.pixels.is_multiple_of(2) {
            return Err(bad(
                "pixels",
                format!("must be even and in 8..={MAX_PIXELS} (got {})", self.pixels),
            ));
        }
        let half = 0.5 * self.pixels as f64 * self.pixel_mdeg.max(step_mdeg) * 1e-3;
        if half >= 30.0 {
            return Err(bad(
                "pixel_mdeg",
                format!(
                    "gives an image {:.4e} degrees wide; keep it within 60",
                    2.0 * half
                ),
            ));
        }
        if !(1..=MAX_REALIZATIONS).contains(&realizations) {
            return Err(bad(
                "realizations",
                format!("must be in 1..={MAX_REALIZATIONS} (got {realizations})"),
            ));
        }
        if paths == 0 || paths > 1 << 32 {
            return Err(bad(
                "render.paths",
                format!("must be in 1..=2^32 (got {paths})"),
            ));
        }
        Ok(whole as usize)
    }
}

fn one() -> f64 {
    1.0
}

/// A validated seeing-through study.
#[derive(Debug, Clone)]
pub struct SeeingStudy {
    /// The document as parsed, with the command-line values filled in.
    pub file: SeeingFile,
    /// Output prefix.
    pub name: String,
    /// Where the study came from.
    pub origin: String,
    /// The lit cells `(row, column)` of the object, in reading order.
    pub points: Vec<(usize, usize)>,
    /// Pixels per object step.
    pub step: usize,
}

/// Loads and validates a study file.
pub fn load_seeing_file(path: &Path, overrides: &StudyOverrides) -> Result<SeeingStudy, LoadError> {
    crate::memory::study::load_study_file(path, overrides, load_seeing_str)
}

/// Loads and validates a study from its text (`origin` names it in errors; `default_name` is
/// the output prefix when the study sets none).
pub fn load_seeing_str(
    text: &str,
    origin: &str,
    default_name: &str,
    overrides: &StudyOverrides,
) -> Result<SeeingStudy, LoadError> {
    crate::memory::study::load_study(
        text,
        origin,
        default_name,
        overrides,
        |f: &mut SeeingFile| (&mut f.render.paths, &mut f.render.seed, &mut f.output),
        validate,
    )
}

fn validate(file: SeeingFile, origin: &str, default_name: &str) -> Result<SeeingStudy, SceneError> {
    let name = file
        .name
        .clone()
        .unwrap_or_else(|| default_name.to_string());
    speckle_scene::validate::name(&name)?;
    let step = file.camera().validate(
        &file.g,
        ("object_step_mdeg", file.object_step_mdeg),
        file.realizations,
        file.render.paths,
    )?;
    let points = object_points(&file.object)?;
    let extent = |n: usize| (n - 1) * step + 1;
    let rows = file.object.len();
    let cols = file.object[0].chars().count();
    let size = extent(rows).max(extent(cols));
    if 2 * size > file.pixels {
        return Err(bad(
            "object",
            format!(
                "spans {size} pixels ({rows} x {cols} cells {step} pixels apart); the image \
                 (pixels = {}) must be at least twice that",
                file.pixels
            ),
        ));
    }
    if !file.window.is_multiple_of(2) || file.window < 2 * size + 2 || file.window > 2 * file.pixels
    {
        return Err(bad(
            "window",
            format!(
                "must be even, at least twice the object's extent plus 2 ({}) and at most twice \
                 pixels ({}) (got {})",
                2 * size + 2,
                2 * file.pixels,
                file.window
            ),
        ));
    }
    let pairs = points.len().saturating_mul(file.pixels * file.pixels);
    if pairs > MAX_PAIRS {
        return Err(bad(
            "pixels",
            format!(
                "gives {pairs} pairs per render ({} lit cells x {}^2 pixels), above {MAX_PAIRS}",
                points.len(),
                file.pixels
            ),
        ));
    }
    let r = &file.retrieval;
    if !(r.beta.is_finite() && r.beta > 0.0 && r.beta <= 2.0) {
        return Err(bad(
            "retrieval.beta",
            format!("must be in (0, 2] (got {})", r.beta),
        ));
    }
    if r.hio + r.er == 0 || r.hio + r.er > 100_000 {
        return Err(bad(
            "retrieval.hio",
            format!("hio + er must be in 1..=100000 (got {} + {})", r.hio, r.er),
        ));
    }
    if !(1..=256).contains(&r.starts) {
        return Err(bad(
            "retrieval.starts",
            format!("must be in 1..=256 (got {})", r.starts),
        ));
    }
    Ok(SeeingStudy {
        file,
        name,
        origin: origin.to_string(),
        points,
        step,
    })
}

/// The lit cells of the object's rows (`#` lit, `.` dark, equal lengths).
fn object_points(rows: &[String]) -> Result<Vec<(usize, usize)>, SceneError> {
    if rows.is_empty() || rows.len() > 32 {
        return Err(bad(
            "object",
            format!("must have 1 to 32 rows (got {})", rows.len()),
        ));
    }
    let cols = rows[0].chars().count();
    let mut points = vec![];
    for (r, row) in rows.iter().enumerate() {
        if row.chars().count() != cols || cols == 0 || cols > 32 {
            return Err(bad(
                format!("object[{r}]"),
                format!(
                    "must have as many cells as the first row, 1 to 32 ({cols}; got {})",
                    row.chars().count()
                ),
            ));
        }
        for (c, ch) in row.chars().enumerate() {
            match ch {
                '#' => points.push((r, c)),
                '.' => {}
                other => {
                    return Err(bad(
                        format!("object[{r}]"),
                        format!("may hold only '#' (lit) and '.' (dark); found {other:?}"),
                    ));
                }
            }
        }
    }
    if points.is_empty() || points.len() > MAX_POINTS {
        return Err(bad(
            "object",
            format!("must light 1 to {MAX_POINTS} cells (got {})", points.len()),
        ));
    }
    Ok(points)
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r######"
wavelength_um = 0.5
thickness_um = 1000.0
mean_free_path_um = 100.0
width_um = 23000.0
g = [0.9]
object = ["##.", ".#."]
object_step_mdeg = 2.5
pixels = 16
pixel_mdeg = 1.25
realizations = 2
window = 12
"######;

    fn load(text: &str) -> Result<SeeingStudy, LoadError> {
        load_seeing_str(text, "s.toml", "s", &StudyOverrides::default())
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
        assert_eq!(s.points, vec![(0, 0), (0, 1), (1, 1)]);
        assert_eq!(s.step, 2);
        assert_eq!(s.name, "s");
    }

    #[test]
    fn bad_studies_name_their_field() {
        refused("g = [0.9]", "g = [1.0]", "g[0]");
        refused("g = [0.9]", "g = []", "g");
        refused("\"##.\", \".#.\"", "\"##.\", \".x.\"", "object[1]");
        refused("\"##.\", \".#.\"", "\"##.\", \".#\"", "object[1]");
        refused("\"##.\", \".#.\"", "\"...\"", "object");
        refused(
            "object_step_mdeg = 2.5",
            "object_step_mdeg = 2.0",
            "object_step_mdeg",
        );
        refused(
            "object_step_mdeg = 2.5",
            "object_step_mdeg = nan",
            "object_step_mdeg",
        );
        refused("pixels = 16", "pixels = 15", "pixels");
        refused("pixels = 16", "pixels = 8", "object");
        refused("window = 12", "window = 8", "window");
        refused("realizations = 2", "realizations = 0", "realizations");
        refused(
            "thickness_um = 1000.0",
            "thickness_um = -1.0",
            "thickness_um",
        );
        refused(
            "thickness_um = 1000.0",
            "thickness_um = 1e9",
            "thickness_um",
        );
        refused("width_um = 23000.0", "width_um = 10.0", "width_um");
        refused("width_um = 23000.0", "width_um = 1e300", "width_um");
        refused("window = 12", "window = 12\nwindw = 3", "windw");
        refused("pixels = 16", "pixels = 258", "pixels");
    }
}
