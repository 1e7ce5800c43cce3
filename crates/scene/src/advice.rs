//! Advice printed before a render: scenes that are valid but that an estimator renders poorly.
//!
//! - A point sensor on (or within a mean free path of) a face of the medium, many mean free
//!   paths from a point source: next-event connections reach it only from the vertices within
//!   about a mean free path of it, so its estimate has a heavy tail (docs/experiments-tissue.md:
//!   on the tissue cube, four seeds give 0.54 to 5.2 with 25-66% reported errors). A point
//!   detector at the same place (a `detector` without `radius`, with `weighting = "fluence"`
//!   and the full aperture) reads the same intensity with bounded variance (1.3-2.0% errors
//!   from 400 000 paths there).

use crate::Scene;
use speckle_endpoints::Sensor;
use speckle_medium::{Dimension, Medium};
use speckle_phase::PhaseFunction;

/// Source-sensor separations, in mean free paths, beyond which a point sensor on a face draws
/// the advice (the tissue cube of issue 25 is 50; the 2023 paper's DCS scene, 5).
pub const FACE_SENSOR_MEAN_FREE_PATHS: f64 = 20.0;

/// The advice for `scene`, one message per point sensor that draws it (naming `sensors[i]` and
/// the source), empty for most scenes.
pub fn warnings<M: Medium, P: PhaseFunction>(scene: &Scene<M, P>) -> Vec<String> {
    let m = scene.medium();
    let b = m.bounds();
    let (lo, hi) = (b.min(), b.max());
    let mut out = vec![];
    for (i, sensor) in scene.sensors().iter().enumerate() {
        let Sensor::Point { position: v } = *sensor else {
            continue;
        };
        // The extinction at the nearest point of the box, and the distance to its boundary.
        let inner = v.clamp(lo, hi);
        let sigma_t = m.sigma_t(inner);
        if !(sigma_t.is_finite() && sigma_t > 0.0) {
            continue;
        }
        let to_face = if b.contains(v) {
            let gap = (v - lo).min(hi - v);
            match m.dimension() {
                // A flatland box has no z extent: its faces are edges in the plane.
                Dimension::Two => gap.x.min(gap.y),
                Dimension::Three => gap.min_element(),
            }
        } else {
            (v - inner).length()
        };
        if to_face * sigma_t > 1.0 {
            continue;
        }
        let far = scene.sources().iter().enumerate().find_map(|(j, s)| {
            let p = s.point_position()?;
            let n = (p - v).length() * sigma_t;
            (n >= FACE_SENSOR_MEAN_FREE_PATHS).then_some((j, n))
        });
        if let Some((j, n)) = far {
            out.push(format!(
                "sensors[{i}] is a point on a face of the medium, {n:.0} mean free paths from \
                 sources[{j}]: next-event connections reach it only from vertices within about a \
                 mean free path, so its estimate has a heavy tail; a point `detector` there (no \
                 `radius`, weighting = \"fluence\", the full aperture) reads the same intensity \
                 and converges (docs/experiments-tissue.md)"
            ));
        }
    }
    out
}
