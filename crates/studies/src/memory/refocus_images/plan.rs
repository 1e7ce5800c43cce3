//! The `[images]` section of a refocusing study: its file format, its limits, the cases and
//! pixels it images ([`ImagePlan`]) and its validation.

use crate::memory::refocus::optimal_tilt;
use serde::{Deserialize, Serialize};
use speckle_scene::SceneError;
use speckle_scene::validate::{invalid as bad, positive};

/// Most image pixels per side (`images.n_pixels`).
pub const MAX_IMAGE_PIXELS: usize = 63;
/// Most imaged displacements (`images.delta_um`).
pub const MAX_IMAGE_DISPLACEMENTS: usize = 8;
/// Most field realizations (`images.realizations`).
pub const MAX_IMAGE_REALIZATIONS: usize = 4096;
/// Most pairs (source, camera pixel) of the image scene.
pub const MAX_IMAGE_PAIRS: usize = 1 << 20;
/// Most fields held at once, `realizations x pairs` (16 bytes each).
pub const MAX_IMAGE_FIELDS: usize = 1 << 27;

/// `[images]` of a refocusing study file: the rendered refocused fields (Fig. 13 top).
///
/// ```toml
/// [images]
/// delta_um = [1.0, 2.0]   # imaged displacements (each shift only and shift + tilt; 0 is added)
/// half_width_um = 4.0     # the image: n_pixels focal points along x, +-half_width around the target
/// n_pixels = 21           # odd
/// n_rows = 1              # odd: rows along y at the same pitch (default 1, a line)
/// realizations = 64       # independent transmission matrices
/// paths = 20000           # sub-paths per realization
/// ```
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RefocusImagesFile {
    /// Imaged displacements, micrometres (positive, increasing, at most `delta_max_um`).
    pub delta_um: Vec<f64>,
    /// Half width of the image around the target, micrometres.
    pub half_width_um: f64,
    /// Pixels along x (odd; the middle one is the target).
    pub n_pixels: usize,
    /// Rows along y at the pixel pitch (odd, default 1: a line through the target).
    #[serde(default = "one")]
    pub n_rows: usize,
    /// Independent field realizations.
    pub realizations: usize,
    /// Sub-paths per realization.
    pub paths: u64,
}

fn one() -> usize {
    1
}

/// One refocusing attempt of the images.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageCase {
    /// Focus displacement `Delta = Delta_a`, micrometres.
    pub delta: f64,
    /// Tilt `theta`, radians (0: shift only).
    pub theta: f64,
    /// Shift of the pattern on face `b`, `Delta_b = Delta + L theta`, micrometres.
    pub delta_b: f64,
}

impl ImageCase {
    /// A short label.
    pub fn label(&self) -> String {
        if self.delta == 0.0 {
            "Delta = 0".into()
        } else if self.theta == 0.0 {
            format!("Delta = {} um, shift only", self.delta)
        } else {
            format!(
                "Delta = {} um, shift + tilt ({:.1} mrad)",
                self.delta,
                self.theta * 1e3
            )
        }
    }
}

/// The validated `[images]` of a study.
#[derive(Debug, Clone)]
pub struct ImagePlan {
    /// The section as parsed.
    pub file: RefocusImagesFile,
    /// The cases: `Delta = 0`, then shift only and shift and tilt for every imaged `Delta`.
    pub cases: Vec<ImageCase>,
    /// Pixel offsets from the target along x, micrometres (symmetric, middle 0).
    pub offsets: Vec<f64>,
    /// Row offsets along y, micrometres (the same pitch, middle 0).
    pub rows: Vec<f64>,
}

impl ImagePlan {
    /// Pixels per image.
    pub fn pixels(&self) -> usize {
        self.offsets.len() * self.rows.len()
    }

    /// The pixels of the check: the target, then the middles of the edges (`+x, -x`, and `+y,
    /// -y` with more than one row), as (column, row) of the image (row `iy`, column `ix`, pixel
    /// `iy n_pixels + ix`).
    pub fn check_pixels(&self) -> Vec<(usize, usize)> {
        let (n, h) = (self.offsets.len(), self.rows.len());
        let (c, r) = (n / 2, h / 2);
        let mut v = vec![(c, r), (n - 1, r), (0, r)];
        if h > 1 {
            v.extend([(c, h - 1), (c, 0)]);
        }
        v
    }
}

/// Validates `[images]` against the study (`delta_max` and the slab's `width`, `thickness`).
pub(in crate::memory) fn validate(
    f: &RefocusImagesFile,
    delta_max: f64,
    width: f64,
    thickness: f64,
    n_tau: usize,
) -> Result<ImagePlan, SceneError> {
    let d = &f.delta_um;
    if d.is_empty() || d.len() > MAX_IMAGE_DISPLACEMENTS {
        return Err(bad(
            "images.delta_um",
            format!(
                "must hold 1 to {MAX_IMAGE_DISPLACEMENTS} displacements (got {})",
                d.len()
            ),
        ));
    }
    for (j, &v) in d.iter().enumerate() {
        if !(v.is_finite() && v > 0.0 && v <= delta_max) {
            return Err(bad(
                "images.delta_um",
                format!("each must be in (0, delta_max_um = {delta_max}] (got {v})"),
            ));
        }
        if j > 0 && v <= d[j - 1] {
            return Err(bad(
                "images.delta_um",
                format!("must increase (got {} then {v})", d[j - 1]),
            ));
        }
    }
    let hw = positive("images.half_width_um", f.half_width_um)?;
    if delta_max / 2.0 + hw >= width / 2.0 {
        return Err(bad(
            "images.half_width_um",
            format!(
                "the image reaches {} um from the axis, outside the slab (width_um / 2 = {})",
                delta_max / 2.0 + hw,
                width / 2.0
            ),
        ));
    }
    let n = f.n_pixels;
    if n < 3 || n.is_multiple_of(2) || n > MAX_IMAGE_PIXELS {
        return Err(bad(
            "images.n_pixels",
            format!("must be odd and in 3..={MAX_IMAGE_PIXELS} (got {n})"),
        ));
    }
    let rows = f.n_rows;
    if rows.is_multiple_of(2) || rows > n {
        return Err(bad(
            "images.n_rows",
            format!("must be odd and at most n_pixels = {n} (got {rows})"),
        ));
    }
    if !(2..=MAX_IMAGE_REALIZATIONS).contains(&f.realizations) {
        return Err(bad(
            "images.realizations",
            format!(
                "must be in 2..={MAX_IMAGE_REALIZATIONS} (got {})",
                f.realizations
            ),
        ));
    }
    if f.paths == 0 {
        return Err(bad("images.paths", "must be positive (got 0)"));
    }
    let cases = 1 + 2 * d.len();
    let pairs = cases * (n * rows + 1) * n_tau;
    if pairs > MAX_IMAGE_PAIRS {
        return Err(bad(
            "images.n_pixels",
            format!(
                "gives {pairs} pairs (cases x (n_pixels n_rows + 1) x n_tau); at most \
                 {MAX_IMAGE_PAIRS}"
            ),
        ));
    }
    if pairs * f.realizations > MAX_IMAGE_FIELDS {
        return Err(bad(
            "images.realizations",
            format!(
                "gives {} fields (realizations x {pairs} pairs); at most {MAX_IMAGE_FIELDS}",
                pairs * f.realizations
            ),
        ));
    }
    let mut list = vec![ImageCase {
        delta: 0.0,
        theta: 0.0,
        delta_b: 0.0,
    }];
    for &v in d {
        let t = optimal_tilt(v, thickness);
        list.push(ImageCase {
            delta: v,
            theta: 0.0,
            delta_b: v,
        });
        list.push(ImageCase {
            delta: v,
            theta: t,
            delta_b: v + thickness * t,
        });
    }
    let h = (n / 2) as f64;
    let pitch = hw / h;
    let hr = (rows / 2) as f64;
    Ok(ImagePlan {
        file: f.clone(),
        cases: list,
        offsets: (0..n).map(|i| hw * (i as f64 - h) / h).collect(),
        rows: (0..rows).map(|i| pitch * (i as f64 - hr)).collect(),
    })
}
