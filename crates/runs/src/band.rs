//! The half-width of a covariance band chosen before rendering (issue 29, item 3; `speckle
//! covariance --band auto`): from a pilot's own correlation curve of the image's central pixel
//! under sensor tilts of whole pixels along both axes of the image
//! (`speckle_estimators::pilot_correlation`, as `speckle plan`'s grain), the band keeps every
//! offset at which the pilot's `|C(s)| / C(0)` reaches `epsilon`.
//!
//! The pilot's curve, not the Gaussian of `speckle plan`'s moments: a plane wave on a box
//! lights a face with sharp edges, whose correlation has the side lobes of a `sinc` (decaying
//! as one over the offset: 0.20, 0.11 and 0.076 at 3, 5 and 7 pixels of the 60-wavelength slab
//! of `crates/cli/tests/band.rs`, where the Gaussian predicts 0.02 at 3 pixels). The curve is
//! one pixel's (far-field grains are nearly the same across an image) and carries the pilot's
//! noise, about `1 / sqrt(paths)` in `|C| / C(0)`: an `epsilon` below it keeps the whole image.
//! The band render's `edge_correlation` measures what is left where the band stops.

use crate::RunError;
use crate::plan::pilot_paths;
use glam::DVec3;
use speckle_estimators::{EstimatorError, Sensor, Source, pilot_correlation};
use speckle_scene::Problem;
use speckle_stats::Progress;

/// A band's half-width chosen by [`band_radius`], with what it rests on.
#[derive(Debug, Clone, PartialEq)]
pub struct BandChoice {
    /// The half-width in pixels.
    pub radius: usize,
    /// The correlation `|C| / C(0)` below which offsets are dropped.
    pub epsilon: f64,
    /// The pair whose curve was rendered (the central pixel, first source).
    pub pair: usize,
    /// Paths of the pilot.
    pub paths: u64,
    /// The pilot's `|C(s)| / C(0)` at offsets of `1 ..` pixels along the image's x and y axes
    /// (empty along an axis of one pixel).
    pub curves: [Vec<f64>; 2],
    /// Whether the radius reaches the image's edge (every offset the image has is kept up to
    /// it; the dense covariance is then the better render).
    pub whole_image: bool,
}

fn bad(field: &str, reason: String) -> RunError {
    RunError::Estimator(EstimatorError::InvalidInput {
        field: field.into(),
        reason,
    })
}

/// Chooses the half-width of the band of `p`'s image covariance that keeps every pixel offset
/// at which a pilot (`paths`, see [`pilot_paths`]; the scene's seed and sampling) of the
/// central pixel's correlation under sensor tilts reaches `epsilon` (the module docs). Errors
/// name `--epsilon` (not in `(0, 1)`), `sensors` (no far-field image of at least two pixels)
/// and `sources` (the first source is not a plane wave).
pub fn band_radius(
    p: &Problem,
    epsilon: f64,
    paths: Option<u64>,
    progress: &dyn Progress,
) -> Result<BandChoice, RunError> {
    if !(epsilon > 0.0 && epsilon < 1.0) {
        return Err(bad(
            "--epsilon",
            format!("must lie strictly between 0 and 1 (got {epsilon})"),
        ));
    }
    let grid = p
        .grid
        .as_ref()
        .filter(|g| g.kind == "far_grid" && g.nx * g.ny > 1)
        .ok_or_else(|| {
            bad(
                "sensors",
                "--band auto needs sensors that form one far-field image (a far_grid of at \
                 least two pixels)"
                    .into(),
            )
        })?;
    if !matches!(p.scene.sources().first(), Some(Source::PlaneWave { .. })) {
        return Err(bad(
            "sources",
            "--band auto needs a plane-wave first source for its pilot".into(),
        ));
    }
    let (nx, ny) = (grid.nx, grid.ny);
    let direction = |ix: usize, iy: usize| match p.scene.sensors()[iy * nx + ix] {
        Sensor::FarField { direction } => direction,
        _ => DVec3::ZERO,
    };
    // The central pixel, and its neighbours before it along each axis.
    let (cx, cy) = (nx / 2, ny / 2);
    let pair = cy * nx + cx;
    let mut o = crate::covariance_options(p);
    o.paths = pilot_paths(p, paths, pair)?;
    let centre = direction(cx, cy);
    let along = |n: usize, neighbour: DVec3| -> Result<Vec<f64>, RunError> {
        if n < 2 {
            return Ok(Vec::new());
        }
        let step = neighbour - centre;
        let (e, h) = (step.normalize(), step.length());
        let s: Vec<f64> = (1..n).map(|k| k as f64 * h).collect();
        let c = pilot_correlation(&p.scene, pair, e, false, &s, &o, progress)?;
        Ok(c.into_iter().map(|c2| c2.max(0.0).sqrt()).collect())
    };
    let curves = [
        along(
            nx,
            if nx > 1 {
                direction(cx - 1, cy)
            } else {
                centre
            },
        )?,
        along(
            ny,
            if ny > 1 {
                direction(cx, cy - 1)
            } else {
                centre
            },
        )?,
    ];
    // The largest offset whose correlation reaches epsilon, on either axis.
    let reach = curves
        .iter()
        .filter_map(|c| c.iter().rposition(|&r| r >= epsilon).map(|k| k + 1))
        .max()
        .unwrap_or(1);
    let most = nx.max(ny) - 1;
    Ok(BandChoice {
        radius: reach.clamp(1, most),
        epsilon,
        pair,
        paths: o.paths,
        curves,
        whole_image: reach >= most,
    })
}
