//! The phase of path permutations (Bar et al. 2019, Appendix A.3, Figs. 15-16), the study of
//! `speckle permutations`.
//!
//! Claim 1 of the paper (Sec. 4.2) keeps only pairs of paths through the same vertices; "Vertex
//! permutations" and Appendix A.3 argue that of the orders in which the second path may visit
//! them, only the same order (forward) and the reversed one survive the integration over the
//! vertices' positions, because the phase of the pairwise throughput `mu(x_1) mu(x_2,P)^*` is
//! constant over the vertices only for those two (the reversed one only at backscattering,
//! Eq. 28). This study measures it on the paper's smallest case, three vertices between a plane
//! wave `i` and a far-field sensor `v` (`i_1 = i_2`, `v_1 = v_2`):
//!
//! - Fig. 15: with `x_1`, `x_2` fixed, the phase of `mu(x_1) mu(x_2,P)^*` over `x_3` on a grid
//!   of `pixels x pixels` cell centres of the square `[0, side]^2`, for the six orders `P` and
//!   every viewing direction (one at `v = -i`, others off it);
//! - Fig. 16: Eq. 58, `I_P = iint mu(x_1) mu(x_2,P)^* dx_2 dx_3` over the same square with
//!   `x_1` fixed, by Monte Carlo with jackknife standard errors, normalised by the forward
//!   order's `I_id`.
//!
//! **Flatland.** The vertices move in a plane, as in the paper's figures, so the study is
//! flatland (`docs/conventions.md`): lengths in wavelengths (`k = 2 pi`), the plane wave
//! `e^{ik i.x}`, a segment `e^{ikr} / sqrt(r)` (the far zone of the flatland point source), the
//! far-field sensor `e^{-ik v.x}`, isotropic scatterers (`s = 1 / sqrt(2 pi)` at each vertex)
//! and no attenuation: the bare geometry of the appendix. The `1 / sqrt(r)` of flatland keeps
//! Eq. 58 finite (in 3D the `1 / r^2` of two shared segments integrated over a plane diverges
//! logarithmically). The magnitudes are positive, so the phase of a product is
//! `k (L(x) - L(x_P))`, `L` the path's optical length `i.x_a + |x_b - x_a| + |x_c - x_b| -
//! v.x_c`.
//!
//! The study file (TOML, unknown keys rejected; lengths in wavelengths, angles in degrees):
//!
//! ```toml
//! name = "fig15_permutations"   # output prefix (default: the file's stem)
//! side = 20.0                   # the square [0, side]^2 over which x_3 (and x_2) vary
//! pixels = 200                  # the Fig. 15 maps: pixels x pixels positions of x_3
//! x1 = [10.0, 10.0]             # the fixed first vertex (Figs. 15 and 16)
//! x2 = [14.0, 12.5]             # the second vertex of the Fig. 15 maps
//! illumination_deg = 90.0       # i = (cos a, sin a)
//! view_offsets_deg = [0.0, 20.0]   # v = -i turned by each angle: 0 is backscattering
//!
//! [render]
//! samples = 16000000            # Monte Carlo samples of (x_2, x_3) for Eq. 58
//! seed = 1
//! groups = 32                   # jackknife groups
//! ```

mod plot;
mod study;

pub use plot::svg;
pub use study::{
    MapStats, NAMES, PERMUTATIONS, Permutations, ViewResult, optical_length, throughput,
};

use crate::memory::{StudyOutput, StudyOverrides};
use serde::{Deserialize, Serialize};
use speckle_scene::validate::{invalid as bad, positive};
use speckle_scene::{LoadError, SceneError};
use std::path::Path;

/// Most viewing directions.
pub const MAX_VIEWS: usize = 8;
/// Most pixels along a side of a Fig. 15 map.
pub const MAX_PIXELS: usize = 1024;
/// Largest side of the square, wavelengths.
pub const MAX_SIDE: f64 = 1000.0;

/// `[render]` of a permutations study.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PermutationsRender {
    /// Monte Carlo samples of `(x_2, x_3)` for Eq. 58.
    pub samples: u64,
    /// Seed: sample `n` draws from `PathRng::new(seed, n)`.
    pub seed: u64,
    /// Jackknife groups (consecutive ranges of samples).
    pub groups: usize,
}

impl Default for PermutationsRender {
    fn default() -> Self {
        Self {
            samples: 4_000_000,
            seed: 1,
            groups: 32,
        }
    }
}

/// A permutations study file (see the module docs).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PermutationsFile {
    /// Output prefix (default: the stem of the file name).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Side of the square `[0, side]^2`, wavelengths.
    pub side: f64,
    /// Pixels along a side of the Fig. 15 maps.
    pub pixels: usize,
    /// The fixed vertex `x_1`, wavelengths.
    pub x1: [f64; 2],
    /// The vertex `x_2` of the Fig. 15 maps, wavelengths.
    pub x2: [f64; 2],
    /// Direction of the plane wave, `i = (cos a, sin a)`, degrees.
    pub illumination_deg: f64,
    /// Viewing directions: `-i` turned by each angle (degrees), 0 being backscattering.
    pub view_offsets_deg: Vec<f64>,
    /// `[render]`.
    #[serde(default)]
    pub render: PermutationsRender,
    /// `[output]`.
    #[serde(default)]
    pub output: StudyOutput,
}

/// A validated permutations study.
#[derive(Debug, Clone)]
pub struct PermutationsStudy {
    /// The document as parsed, with the command-line values filled in.
    pub file: PermutationsFile,
    /// Output prefix.
    pub name: String,
    /// Where the study came from.
    pub origin: String,
}

/// Loads and validates a study file.
pub fn load_permutations_file(
    path: &Path,
    overrides: &StudyOverrides,
) -> Result<PermutationsStudy, LoadError> {
    crate::memory::study::load_study_file(path, overrides, load_permutations_str)
}

/// Loads and validates a study from its text (`origin` names it in errors; `default_name` is
/// the output prefix when the study sets none). `--paths` replaces `render.samples`.
pub fn load_permutations_str(
    text: &str,
    origin: &str,
    default_name: &str,
    overrides: &StudyOverrides,
) -> Result<PermutationsStudy, LoadError> {
    crate::memory::study::load_study(
        text,
        origin,
        default_name,
        overrides,
        |f: &mut PermutationsFile| (&mut f.render.samples, &mut f.render.seed, &mut f.output),
        validate,
    )
}

fn validate(
    file: PermutationsFile,
    origin: &str,
    default_name: &str,
) -> Result<PermutationsStudy, SceneError> {
    let name = file
        .name
        .clone()
        .unwrap_or_else(|| default_name.to_string());
    speckle_scene::validate::name(&name)?;
    positive("side", file.side)?;
    if file.side > MAX_SIDE {
        return Err(bad(
            "side",
            format!("must be at most {MAX_SIDE} wavelengths (got {})", file.side),
        ));
    }
    if !(2..=MAX_PIXELS).contains(&file.pixels) {
        return Err(bad(
            "pixels",
            format!("must be in 2..={MAX_PIXELS} (got {})", file.pixels),
        ));
    }
    for (field, x) in [("x1", file.x1), ("x2", file.x2)] {
        for (c, &v) in x.iter().enumerate() {
            if !(v.is_finite() && (0.0..=file.side).contains(&v)) {
                return Err(bad(
                    format!("{field}[{c}]"),
                    format!("must lie in [0, side = {}] (got {v})", file.side),
                ));
            }
        }
    }
    if file.x1 == file.x2 {
        return Err(bad("x2", "must differ from x1"));
    }
    if !file.illumination_deg.is_finite() {
        return Err(bad(
            "illumination_deg",
            format!("must be finite (got {})", file.illumination_deg),
        ));
    }
    let views = &file.view_offsets_deg;
    if views.is_empty() || views.len() > MAX_VIEWS {
        return Err(bad(
            "view_offsets_deg",
            format!("must list 1 to {MAX_VIEWS} angles (got {})", views.len()),
        ));
    }
    for (j, &a) in views.iter().enumerate() {
        if !(a.is_finite() && a > -180.0 && a <= 180.0) {
            return Err(bad(
                format!("view_offsets_deg[{j}]"),
                format!("must be in (-180, 180] (got {a})"),
            ));
        }
    }
    let r = &file.render;
    if !(2..=1024).contains(&r.groups) {
        return Err(bad(
            "render.groups",
            format!("must be in 2..=1024 (got {})", r.groups),
        ));
    }
    let least = 16 * r.groups as u64;
    if r.samples < least || r.samples > 1 << 36 {
        return Err(bad(
            "render.samples",
            format!(
                "must be in {least}..=2^36 (16 per jackknife group; got {})",
                r.samples
            ),
        ));
    }
    Ok(PermutationsStudy {
        file,
        name,
        origin: origin.to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
side = 20.0
pixels = 32
x1 = [10.0, 10.0]
x2 = [14.0, 12.5]
illumination_deg = 90.0
view_offsets_deg = [0.0, 20.0]

[render]
samples = 4096
groups = 8
"#;

    fn load(text: &str) -> Result<PermutationsStudy, LoadError> {
        load_permutations_str(text, "p.toml", "p", &StudyOverrides::default())
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
        assert_eq!(s.name, "p");
        assert_eq!(s.file.render.seed, 1);
    }

    #[test]
    fn bad_studies_name_their_field() {
        refused("side = 20.0", "side = -1.0", "side");
        refused("side = 20.0", "side = nan", "side");
        refused("side = 20.0", "side = 1e9", "side");
        refused("pixels = 32", "pixels = 1", "pixels");
        refused("x1 = [10.0, 10.0]", "x1 = [10.0, 30.0]", "x1[1]");
        refused("x1 = [10.0, 10.0]", "x1 = [10.0]", "x1");
        refused("x2 = [14.0, 12.5]", "x2 = [10.0, 10.0]", "x2");
        refused("x2 = [14.0, 12.5]", "x2 = [-1.0, 12.5]", "x2[0]");
        refused(
            "illumination_deg = 90.0",
            "illumination_deg = inf",
            "illumination_deg",
        );
        refused("[0.0, 20.0]", "[]", "view_offsets_deg");
        refused("[0.0, 20.0]", "[0.0, 200.0]", "view_offsets_deg[1]");
        refused("samples = 4096", "samples = 10", "render.samples");
        refused("groups = 8", "groups = 1", "render.groups");
        refused("pixels = 32", "pixels = 32\npixel = 3", "pixel");
    }
}
