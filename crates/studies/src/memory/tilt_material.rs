//! The rows of a memory-tilt study: one material each (mean free path, albedo, a
//! Henyey-Greenstein phase function or a mixture of lobes), and the side the slab is seen from.
//! A study lists either `g = [...]` (one HG row per value, the study's mean free path, lossless:
//! Bar et al. 2019 Fig. 10c, 2023 Fig. 6) or `[[material]]` tables (Fig. 10b: albedo; 10d:
//! similarity theory, pairs of `g` and mean free path; 10e: HG mixtures of zero mean cosine).
//!
//! ```toml
//! geometry = "reflection"        # or "transmission" (the default)
//! [[material]]
//! label = "albedo 0.9"           # legend (default: from the values)
//! mean_free_path_um = 100.0      # 1 / sigma_t (default: the study's mean_free_path_um)
//! albedo = 0.9                   # sigma_s / sigma_t in (0, 1] (default 1)
//! g = 0.0                        # HG mean cosine in (-1, 1), or with weights, one per lobe:
//! # weights = [0.5, 0.5]         # an HG mixture, weights > 0 normalised to sum 1
//! # g = [0.8, -0.8]
//! ```

use serde::{Deserialize, Serialize};
use speckle_phase::{HgMixture, Phase};
use speckle_scene::SceneError;
use speckle_scene::validate::{invalid as bad, number, positive};
use std::sync::Arc;

/// Where the far-field sensors look from.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TiltGeometry {
    /// Sensors `v_n = i_n` below the slab (forward scattering).
    #[default]
    Transmission,
    /// Sensors `v_n = (sin theta_n, 0, -cos theta_n)` above the lit face, `i_n` mirrored in the
    /// slab's plane, so `v_n - i_n` has no lateral part for every `n` (the backscattering memory
    /// effect; `v_0 = -i_0` is the exact backscattering direction).
    Reflection,
}

/// `g` of a `[[material]]`: one mean cosine, or one per lobe of a mixture.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(untagged)]
pub enum MaterialG {
    /// One Henyey-Greenstein lobe.
    One(f64),
    /// The lobes of a mixture (with `weights`).
    Lobes(Vec<f64>),
}

/// A `[[material]]` table as written.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    /// Legend of the row.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub label: Option<String>,
    /// `1 / sigma_t`, micrometres (default: the study's `mean_free_path_um`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mean_free_path_um: Option<f64>,
    /// `sigma_s / sigma_t` (default 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub albedo: Option<f64>,
    /// The mean cosine, or one per lobe with `weights`.
    pub g: MaterialG,
    /// The lobes' weights of a mixture.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub weights: Option<Vec<f64>>,
}

/// One row of a study, validated.
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    /// Legend.
    pub label: String,
    /// `1 / sigma_t`, micrometres.
    pub mean_free_path: f64,
    /// `sigma_s / sigma_t`.
    pub albedo: f64,
    /// `(weight, g)` lobes, weights summing to 1; one lobe `(1, g)` for a plain HG.
    pub lobes: Vec<(f64, f64)>,
    /// The mean cosine `sum w g`.
    pub mean_cosine: f64,
}

impl Material {
    /// A lossless Henyey-Greenstein row (the `g = [...]` form).
    pub fn hg(g: f64, mean_free_path: f64) -> Self {
        Material {
            label: format!("g = {g}"),
            mean_free_path,
            albedo: 1.0,
            lobes: vec![(1.0, g)],
            mean_cosine: g,
        }
    }

    /// `sigma_s`, per micrometre.
    pub fn sigma_s(&self) -> f64 {
        self.albedo / self.mean_free_path
    }

    /// `sigma_a`, per micrometre.
    pub fn sigma_a(&self) -> f64 {
        (1.0 - self.albedo) / self.mean_free_path
    }

    /// The transport mean free path `1 / (sigma_s (1 - g) + sigma_a)`, micrometres
    /// (`l / (1 - g)` when lossless).
    pub fn transport_mfp(&self) -> f64 {
        self.mean_free_path / (self.albedo * (1.0 - self.mean_cosine) + (1.0 - self.albedo))
    }

    /// The phase function: [`Phase::hg`] for one lobe, an [`HgMixture`] otherwise.
    pub fn phase(&self) -> Result<Phase, speckle_phase::PhaseError> {
        match self.lobes.as_slice() {
            [(_, g)] => Phase::hg(*g),
            lobes => Ok(Phase::HgMixture(Arc::new(HgMixture::new(lobes)?))),
        }
    }
}

/// Validates `material[i]` (`default_mfp`: the study's `mean_free_path_um`).
pub(super) fn validate(
    i: usize,
    m: &MaterialSpec,
    default_mfp: Option<f64>,
) -> Result<Material, SceneError> {
    let f = |k: &str| format!("material[{i}].{k}");
    let mean_free_path = match (m.mean_free_path_um, default_mfp) {
        (Some(l), _) => positive(f("mean_free_path_um"), l)?,
        (None, Some(l)) => l,
        (None, None) => {
            return Err(bad(
                f("mean_free_path_um"),
                "is needed: neither the material nor the study (mean_free_path_um) gives one",
            ));
        }
    };
    let albedo = m.albedo.unwrap_or(1.0);
    if !(albedo.is_finite() && albedo > 0.0 && albedo <= 1.0) {
        return Err(bad(
            f("albedo"),
            format!("must be in (0, 1] (got {})", number(albedo)),
        ));
    }
    let lobes: Vec<(f64, f64)> = match (&m.g, &m.weights) {
        (MaterialG::One(g), None) => vec![(1.0, *g)],
        (MaterialG::Lobes(gs), Some(ws)) => {
            if gs.is_empty() || gs.len() != ws.len() {
                return Err(bad(
                    f("g"),
                    format!(
                        "needs one g per weight, at least one ({} weights, {} g values)",
                        ws.len(),
                        gs.len()
                    ),
                ));
            }
            ws.iter().copied().zip(gs.iter().copied()).collect()
        }
        (MaterialG::One(_), Some(_)) => {
            return Err(bad(
                f("g"),
                "must list one value per weight when weights are given (an HG mixture)",
            ));
        }
        (MaterialG::Lobes(_), None) => {
            return Err(bad(
                f("weights"),
                "are needed with a list of g (an HG mixture); a single HG lobe takes g = number",
            ));
        }
    };
    // The mixture's own checks (weights > 0 and finite, |g| < 1), normalised weights.
    let mixture = HgMixture::new(&lobes).map_err(|e| bad(f("g"), e))?;
    let total: f64 = lobes.iter().map(|l| l.0).sum();
    let lobes: Vec<(f64, f64)> = lobes.iter().map(|&(w, g)| (w / total, g)).collect();
    use speckle_phase::PhaseFunction;
    let mean_cosine = mixture.mean_cosine();
    let label = match &m.label {
        Some(l) => l.clone(),
        None if lobes.len() == 1 => {
            format!(
                "g = {}, l = {} um, albedo {albedo}",
                lobes[0].1, mean_free_path
            )
        }
        None => format!(
            "HG mixture {}, l = {} um, albedo {albedo}",
            lobes
                .iter()
                .map(|(w, g)| format!("{w:.3} x {g}"))
                .collect::<Vec<_>>()
                .join(" + "),
            mean_free_path
        ),
    };
    Ok(Material {
        label,
        mean_free_path,
        albedo,
        lobes,
        mean_cosine,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(text: &str) -> MaterialSpec {
        super::super::study::parse(text).unwrap()
    }

    #[test]
    fn a_mixture_is_normalised_and_its_mean_cosine_is_the_weighted_one() {
        let m = validate(
            0,
            &spec("weights = [1.0, 3.0]\ng = [0.9, -0.3]"),
            Some(50.0),
        )
        .unwrap();
        assert_eq!(m.lobes, vec![(0.25, 0.9), (0.75, -0.3)]);
        assert!(m.mean_cosine.abs() < 1e-15, "{}", m.mean_cosine);
        assert_eq!(m.mean_free_path, 50.0);
        assert!(matches!(m.phase().unwrap(), Phase::HgMixture(_)));
        // Absorption shortens the transport mean free path: 1 / (sigma_s (1 - g) + sigma_a).
        let a = validate(
            1,
            &spec("g = 0.5\nalbedo = 0.5\nmean_free_path_um = 2.0"),
            None,
        )
        .unwrap();
        assert!((a.transport_mfp() - 2.0 / 0.75).abs() < 1e-15);
        assert!((a.sigma_s() - 0.25).abs() < 1e-15 && (a.sigma_a() - 0.25).abs() < 1e-15);
        assert!(matches!(a.phase().unwrap(), Phase::HenyeyGreenstein(_)));
    }

    #[test]
    fn bad_materials_name_the_field() {
        for (text, field) in [
            ("g = 1.0", "material[3].g"),
            ("g = 0.1\nalbedo = 0.0", "material[3].albedo"),
            ("g = 0.1\nalbedo = 1.5", "material[3].albedo"),
            (
                "g = 0.1\nmean_free_path_um = -1.0",
                "material[3].mean_free_path_um",
            ),
            ("g = [0.1, 0.2]", "material[3].weights"),
            ("g = 0.1\nweights = [1.0]", "material[3].g"),
            ("g = [0.1]\nweights = [1.0, 2.0]", "material[3].g"),
            ("g = [0.1, 0.2]\nweights = [1.0, -2.0]", "material[3].g"),
        ] {
            let e = validate(3, &spec(text), Some(1.0)).unwrap_err();
            assert!(e.to_string().contains(field), "{text}: {e}");
        }
        let e = validate(0, &spec("g = 0.1"), None).unwrap_err();
        assert!(
            e.to_string().contains("material[0].mean_free_path_um"),
            "{e}"
        );
    }
}
