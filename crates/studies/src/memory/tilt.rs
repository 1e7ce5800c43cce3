//! The memory effect against the tilt for a sweep of materials at one wavelength (Bar et al.
//! 2023, Sec. 6, Fig. 6; Bar et al. 2019, Figs. 10b-e), the study of `speckle memory-tilt`,
//! against the C1 term of Feng, Kane, Lee and Stone 1988 (the paper's ref. [5]).
//!
//! A slab, `L` thick along z and `lateral_factor L` wide, is lit by plane waves `i_n` tilted by
//! `theta_n` from +z about +y and seen by far-field sensors: in transmission `v_n = i_n`, the
//! geometry of [`super::Study`] (one curve per material instead of per wavelength, same render,
//! same jackknife), in reflection `v_n` is `i_n` mirrored in the slab's plane
//! ([`TiltGeometry`]). The normalised intensity correlation (Siegert) `C(theta_n) = |C_0n|^2 /
//! (C_00 C_nn)` of the pairs `(i_0, v_0)` and `(i_n, v_n)` is the paper's
//! `|C^{i, i + dtheta}_{v, v + dtheta}|^2` normalised to 1 at `dtheta = 0`. The rows are either
//! `g = [...]` (lossless Henyey-Greenstein scatterers of one mean free path `l`, so the transport
//! mean free path `l* = l / (1 - g)` varies) or `[[material]]` tables, each with its own mean
//! free path, albedo and HG lobes ([`super::tilt_material`]).
//!
//! Theory (the C1 term in the diffusion limit, `L >> l*`): `C1(theta) = (k theta L)^2 /
//! sinh^2(k theta L)` with `k = 2 pi / lambda` (Bar et al. 2019, Eq. 39, which quotes it from
//! Feng et al. 1988; `shared/notes/spatiotemporal-2023.md` Sec. 8.2). The outputs also give it
//! with `L` replaced by `L + 2 z_e`, `z_e = 0.7104 l*` (the Milne extrapolation length of the
//! diffusion solution), per `g`: the spread of the two is the model's uncertainty at finite
//! thickness (`tests/memory_effect.rs`). The paper's finding: for the thinner slab the Monte
//! Carlo curve agrees with C1 at `g = 0` only (the diffusion limit is not reached for large
//! `g`); for the thicker one also at `g = 0.9`.

use super::render::{Curve, MILNE_ZE, eq39, render_groups, slab_tracer_json, tilt_scene};
use super::study::{
    StudyOutput, StudyOverrides, StudyRender, check_render, default_lateral_factor, parse, tilts,
};
use super::tilt_material::{Material, MaterialSpec, TiltGeometry};
use crate::StudyError;
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use speckle_estimators::{EstimatorError, Progress, Scene};
use speckle_medium::HomogeneousBox;
use speckle_phase::Phase;
use speckle_scene::safe::{Access, Files};
use speckle_scene::validate::{invalid as bad, number, positive};
use speckle_scene::{LoadError, SceneError, load};
use std::f64::consts::{PI, TAU};
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

/// Most rows (values of `g` or materials) a study may list.
pub const MAX_G: usize = 16;

/// Largest extinction optical depth `L / l` of a row (the cost grows with it).
pub const MAX_TILT_OPTICAL_DEPTH: f64 = 200.0;

/// A memory-tilt study file (TOML, unknown keys rejected). Lengths in micrometres.
///
/// ```toml
/// name = "fig6a"                  # output prefix (default: the file's stem)
/// wavelength_um = 0.5             # wavelength in the medium
/// mean_free_path_um = 3000.0      # l = 1 / sigma_t, the same for every row (the default of
///                                 # [[material]]'s)
/// thickness_um = 30000.0          # slab thickness L
/// lateral_factor = 100.0          # slab width / L (default 100, at least 1)
/// geometry = "transmission"       # or "reflection"
/// g = [0.0, 0.9, 0.95]            # Henyey-Greenstein mean cosines, one curve each, lossless;
///                                 # or [[material]] tables (super::tilt_material), not both
/// # the tilts, exactly one of (strictly increasing from 0):
/// #   angles_mdeg = [0.0, 0.05, ...]   (millidegrees)
/// #   k_theta_l = [0.0, 0.5, ...]      (k theta L, k = 2 pi / wavelength_um)
/// k_theta_l = [0.0, 0.5, 1.0]
///
/// [render]
/// paths = 400000                  # sub-paths per g, split over the groups
/// seed = 1
/// groups = 16                     # independent renders per g (jackknife)
/// coherence = "forward_only"      # or "forward_and_reversed"
///
/// [output]
/// dir = "out"
/// ```
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TiltFile {
    /// Output prefix (default: the stem of the file name).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Wavelength in the medium, micrometres.
    pub wavelength_um: f64,
    /// Mean free path `l = 1 / sigma_t`, micrometres: every row's with `g`, the default of
    /// `[[material]]`'s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mean_free_path_um: Option<f64>,
    /// Slab thickness `L`, micrometres.
    pub thickness_um: f64,
    /// Slab width over thickness.
    #[serde(default = "default_lateral_factor")]
    pub lateral_factor: f64,
    /// Where the sensors are.
    #[serde(default)]
    pub geometry: TiltGeometry,
    /// Henyey-Greenstein mean cosines, one lossless row each.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub g: Option<Vec<f64>>,
    /// The rows as materials (instead of `g`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub material: Option<Vec<MaterialSpec>>,
    /// Tilts in millidegrees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub angles_mdeg: Option<Vec<f64>>,
    /// Tilts as `k theta L`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub k_theta_l: Option<Vec<f64>>,
    /// `[render]`.
    #[serde(default)]
    pub render: StudyRender,
    /// `[output]`.
    #[serde(default)]
    pub output: StudyOutput,
    /// `[fit]`: `g` fitted to a measured curve ([`super::TiltFitSpec`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fit: Option<super::TiltFitSpec>,
}

/// A validated memory-tilt study.
#[derive(Debug, Clone)]
pub struct TiltStudy {
    /// The document as parsed, with the command-line values filled in.
    pub file: TiltFile,
    /// Output prefix.
    pub name: String,
    /// Where the study came from.
    pub origin: String,
    /// Wavelength, micrometres.
    pub wavelength: f64,
    /// Slab thickness `L`, micrometres.
    pub thickness: f64,
    /// Slab width, micrometres.
    pub width: f64,
    /// Where the sensors are.
    pub geometry: TiltGeometry,
    /// The rows, one curve each.
    pub materials: Vec<Material>,
    /// Tilts, radians, `theta_0 = 0`.
    pub angles: Vec<f64>,
    /// The fit of `g` to a measured curve, when the file has `[fit]`.
    pub fit: Option<super::TiltFit>,
}

/// Loads and validates a memory-tilt study file.
pub fn load_tilt_file(path: &Path, overrides: &StudyOverrides) -> Result<TiltStudy, LoadError> {
    let (text, stem) = load::read_input(path, "study")?;
    let base = path.parent().unwrap_or(Path::new("."));
    load_tilt(&text, &path.display().to_string(), &stem, overrides, base)
}

/// Loads and validates a memory-tilt study from its text: `origin` names it in errors,
/// `default_name` is the output prefix when the study sets none.
pub fn load_tilt_str(
    text: &str,
    origin: &str,
    default_name: &str,
    overrides: &StudyOverrides,
) -> Result<TiltStudy, LoadError> {
    load_tilt(text, origin, default_name, overrides, Path::new("."))
}

/// [`load_tilt_str`] with the folder `base` that `[fit]`'s data file is relative to.
fn load_tilt(
    text: &str,
    origin: &str,
    default_name: &str,
    overrides: &StudyOverrides,
    base: &Path,
) -> Result<TiltStudy, LoadError> {
    let mut file: TiltFile = parse(text).map_err(|e| e.in_document(origin))?;
    overrides
        .apply(&mut file.render, &mut file.output)
        .map_err(|e| e.in_document(origin))?;
    let access = if overrides.allow_outside {
        Access::trusting()
    } else {
        Access::CONFINED
    };
    let files = Files { base, access };
    validate(file, origin, default_name, files).map_err(|e| LoadError::from(e).in_document(origin))
}

fn validate(
    file: TiltFile,
    origin: &str,
    default_name: &str,
    files: Files,
) -> Result<TiltStudy, SceneError> {
    let name = file
        .name
        .clone()
        .unwrap_or_else(|| default_name.to_string());
    speckle_scene::validate::name(&name)?;
    let wavelength = positive("wavelength_um", file.wavelength_um)?;
    let mfp = file
        .mean_free_path_um
        .map(|l| positive("mean_free_path_um", l))
        .transpose()?;
    let thickness = positive("thickness_um", file.thickness_um)?;
    let lateral = positive("lateral_factor", file.lateral_factor)?;
    if lateral < 1.0 {
        return Err(bad(
            "lateral_factor",
            format!(
                "must be >= 1: the slab is at least as wide as it is thick (got {})",
                number(lateral)
            ),
        ));
    }
    let materials = rows(&file, mfp)?;
    for (i, m) in materials.iter().enumerate() {
        let od = thickness / m.mean_free_path;
        if od > MAX_TILT_OPTICAL_DEPTH {
            let field = match &file.material {
                Some(list) if list[i].mean_free_path_um.is_some() => {
                    format!("material[{i}].mean_free_path_um")
                }
                _ => "thickness_um".to_string(),
            };
            return Err(bad(
                field,
                format!(
                    "gives an optical depth L / l of {od:.4e}; at most \
                     {MAX_TILT_OPTICAL_DEPTH} can be rendered"
                ),
            ));
        }
    }
    let angles = tilts(
        ("angles_mdeg", file.angles_mdeg.as_deref()),
        file.k_theta_l.as_deref(),
        PI / 180.0 / 1000.0,
        wavelength / (TAU * thickness),
    )?;
    check_render(&file.render)?;
    let fit = match &file.fit {
        Some(_) if file.g.is_none() => {
            return Err(bad(
                "fit",
                "fits g between the rows of a g = [...] list (one mean free path, lossless); \
                 the study lists [[material]] tables",
            ));
        }
        Some(spec) => {
            // The tilts in the unit the file lists them in.
            let listed = file
                .angles_mdeg
                .as_deref()
                .or(file.k_theta_l.as_deref())
                .unwrap_or_default();
            let gs: Vec<f64> = materials.iter().map(|m| m.mean_cosine).collect();
            Some(super::tilt_fit::validate(spec, &gs, listed, files)?)
        }
        None => None,
    };
    Ok(TiltStudy {
        name,
        origin: origin.to_string(),
        wavelength,
        thickness,
        width: lateral * thickness,
        geometry: file.geometry,
        materials,
        angles,
        fit,
        file,
    })
}

/// The rows of `file`: its `g` list (lossless, mean free path `mfp`) or its `[[material]]`s.
fn rows(file: &TiltFile, mfp: Option<f64>) -> Result<Vec<Material>, SceneError> {
    let count = |n: usize, field: &str| {
        if n == 0 || n > MAX_G {
            Err(bad(field, format!("must list 1 to {MAX_G} rows (got {n})")))
        } else {
            Ok(())
        }
    };
    match (&file.g, &file.material) {
        (Some(gs), None) => {
            count(gs.len(), "g")?;
            let l = mfp.ok_or_else(|| {
                bad(
                    "mean_free_path_um",
                    "is needed with g = [...] (every row's)",
                )
            })?;
            gs.iter()
                .enumerate()
                .map(|(i, &g)| {
                    if g.is_finite() && (0.0..1.0).contains(&g) {
                        Ok(Material::hg(g, l))
                    } else {
                        Err(bad(
                            format!("g[{i}]"),
                            format!("must be in [0, 1) (got {})", number(g)),
                        ))
                    }
                })
                .collect()
        }
        (None, Some(list)) => {
            count(list.len(), "material")?;
            list.iter()
                .enumerate()
                .map(|(i, m)| super::tilt_material::validate(i, m, mfp))
                .collect()
        }
        _ => Err(bad(
            "g | material",
            "give exactly one: g = [...] (lossless HG rows) or [[material]] tables",
        )),
    }
}

impl TiltStudy {
    /// The rows' mean cosines.
    pub fn gs(&self) -> Vec<f64> {
        self.materials.iter().map(|m| m.mean_cosine).collect()
    }

    /// Wavenumber `k = 2 pi / lambda`, per micrometre.
    pub fn k(&self) -> f64 {
        TAU / self.wavelength
    }

    /// `k theta L` of each tilt.
    pub fn k_theta_l(&self) -> Vec<f64> {
        let kl = self.k() * self.thickness;
        self.angles.iter().map(|t| kl * t).collect()
    }

    /// The library scene of row `w`.
    pub fn scene(&self, w: usize) -> Result<Scene<HomogeneousBox, Phase>, EstimatorError> {
        let m = &self.materials[w];
        let phase = m.phase().map_err(|e| EstimatorError::InvalidInput {
            field: format!("row {w} ({})", m.label),
            reason: e.to_string(),
        })?;
        tilt_scene(
            self.width,
            self.thickness,
            (m.sigma_s(), m.sigma_a()),
            phase,
            self.wavelength,
            &self.angles,
            self.geometry == TiltGeometry::Reflection,
        )
    }

    /// The rough cost on `threads` threads (as [`super::Study::estimate`]).
    pub fn estimate(&self, threads: usize) -> speckle_scene::cost::Estimate {
        use speckle_scene::cost::{covariance_seconds, expected_vertices};
        let n = self.angles.len() as f64;
        let paths = self.file.render.paths as f64;
        let seconds: f64 = self
            .materials
            .iter()
            .map(|m| {
                let t = 1.0 / m.mean_free_path;
                let taus = [t * self.width, t * self.width, t * self.thickness];
                let dim = speckle_medium::Dimension::Three;
                let v = expected_vertices(&taus, m.albedo, m.mean_cosine, dim, u32::MAX);
                covariance_seconds(paths, v, 2.0 * n, n)
            })
            .sum();
        let groups = self.file.render.groups as f64;
        speckle_scene::cost::Estimate {
            bytes: 16.0 * n * n * (8.0 + 4.0 * threads as f64) * groups.min(4.0)
                + 1e6 * self.materials.len() as f64,
            memory_field: "k_theta_l".into(),
            seconds: seconds / threads.max(1) as f64,
            time_field: "render.paths".into(),
            vertices_per_path: 0.0,
        }
    }

    /// Renders every row: `render.groups` independent covariance renders each, group `i` of
    /// row `w` seeded with `derive_seed(seed, w groups + i)`; `progress` counts paths over all.
    pub fn render(&self, progress: &dyn Progress) -> Result<MemoryTilt, StudyError> {
        let start = Instant::now();
        let x = self.k_theta_l();
        let mut rows = Vec::with_capacity(self.materials.len());
        for (w, m) in self.materials.iter().enumerate() {
            let curve = render_groups(&self.scene(w)?, &self.file.render, w, progress)?;
            let leff = self.thickness + 2.0 * MILNE_ZE * m.transport_mfp();
            rows.push(TiltRow {
                g: m.mean_cosine,
                label: m.label.clone(),
                extrapolated: x.iter().map(|&x| eq39(x * leff / self.thickness)).collect(),
                curve,
            });
        }
        Ok(MemoryTilt {
            c1: x.iter().map(|&x| eq39(x)).collect(),
            k_theta_l: x,
            rows,
            wall: start.elapsed().as_secs_f64(),
        })
    }
}

/// One row of a [`MemoryTilt`].
#[derive(Debug, Clone)]
pub struct TiltRow {
    /// The mean cosine.
    pub g: f64,
    /// The legend ([`Material::label`]).
    pub label: String,
    /// The Monte Carlo curve.
    pub curve: Curve,
    /// C1 with `L + 2 z_e`, `z_e = 0.7104 l*` ([`Material::transport_mfp`]).
    pub extrapolated: Vec<f64>,
}

/// The result of a memory-tilt study.
#[derive(Debug, Clone)]
pub struct MemoryTilt {
    /// One row per material, in the study's order.
    pub rows: Vec<TiltRow>,
    /// `k theta L` of each tilt.
    pub k_theta_l: Vec<f64>,
    /// C1, `(k theta L)^2 / sinh^2(k theta L)`, per tilt (a transmission theory: not written
    /// nor drawn in reflection).
    pub c1: Vec<f64>,
    /// Wall time, seconds.
    pub wall: f64,
}

impl MemoryTilt {
    /// The output arrays (float64, C order): `(key, shape, data, content)`.
    pub fn arrays(&self, s: &TiltStudy) -> Vec<super::Array> {
        let (ng, na) = (self.rows.len(), s.angles.len());
        let stack = |f: &dyn Fn(&TiltRow) -> &[f64]| -> Vec<f64> {
            self.rows
                .iter()
                .flat_map(|r| f(r).iter().copied())
                .collect()
        };
        let transmission = s.geometry == TiltGeometry::Transmission;
        let mut arrays = vec![
            super::Array {
                key: "memory_tilt",
                shape: vec![ng, na],
                data: stack(&|r| &r.curve.c),
                content: "(n_g, n_angles): C(theta) = |C_0n|^2 / (C_00 C_nn), Monte Carlo",
            },
            super::Array {
                key: "memory_tilt_stderr",
                shape: vec![ng, na],
                data: stack(&|r| &r.curve.se),
                content: "(n_g, n_angles): its jackknife standard error over render.groups \
                          independent renders",
            },
            super::Array {
                key: "memory_tilt_angles_mdeg",
                shape: vec![na],
                data: s.angles.iter().map(|t| t.to_degrees() * 1000.0).collect(),
                content: "(n_angles,): theta in millidegrees, the tilt of both the plane wave \
                          and the sensor from +z about +y",
            },
            super::Array {
                key: "memory_tilt_g",
                shape: vec![ng],
                data: s.gs(),
                content: "(n_g,): the mean cosine of each row's phase function",
            },
            super::Array {
                key: "memory_tilt_mean_free_path_um",
                shape: vec![ng],
                data: s.materials.iter().map(|m| m.mean_free_path).collect(),
                content: "(n_g,): each row's mean free path 1 / sigma_t, micrometres",
            },
            super::Array {
                key: "memory_tilt_albedo",
                shape: vec![ng],
                data: s.materials.iter().map(|m| m.albedo).collect(),
                content: "(n_g,): each row's albedo sigma_s / sigma_t",
            },
        ];
        if transmission {
            arrays.push(super::Array {
                key: "memory_tilt_c1",
                shape: vec![na],
                data: self.c1.clone(),
                content: "(n_angles,): the C1 term in the diffusion limit, (k theta L)^2 / \
                          sinh^2(k theta L), k = 2 pi / wavelength_um, L = thickness_um",
            });
            arrays.push(super::Array {
                key: "memory_tilt_c1_extrapolated",
                shape: vec![ng, na],
                data: stack(&|r| &r.extrapolated),
                content: "(n_g, n_angles): C1 with L replaced by L + 2 z_e, z_e = 0.7104 l* \
                          (Milne), l* = 1 / (sigma_s (1 - g) + sigma_a)",
            });
        }
        arrays
    }

    /// The figure: one curve per `g` with its error bars, and C1, against the tilt in
    /// millidegrees.
    pub fn figure(&self, s: &TiltStudy) -> crate::curves::Figure {
        use crate::curves::{Curve as Line, Figure};
        let mdeg: Vec<f64> = s.angles.iter().map(|t| t.to_degrees() * 1000.0).collect();
        let mut curves: Vec<Line> = self
            .rows
            .iter()
            .map(|r| Line {
                label: r.label.clone(),
                x: mdeg.clone(),
                y: r.curve.c.clone(),
                err: r.curve.se.clone(),
            })
            .collect();
        let transmission = s.geometry == TiltGeometry::Transmission;
        if transmission {
            curves.push(Line {
                label: "C1 (diffusion)".into(),
                x: mdeg,
                y: self.c1.clone(),
                err: vec![],
            });
        }
        let mfps: Vec<f64> = s.materials.iter().map(|m| m.mean_free_path).collect();
        let mfp = if mfps.iter().all(|&l| l == mfps[0]) {
            format!("mean free path {} um", mfps[0])
        } else {
            "mean free paths in the legend".into()
        };
        Figure {
            title: format!(
                "{}: memory effect against the tilt, in {}",
                s.name,
                if transmission {
                    "transmission"
                } else {
                    "reflection"
                }
            ),
            subtitle: format!(
                "L = {} um, {mfp}, lambda = {} um; {} paths per row; error bars: one jackknife \
                 SE",
                s.thickness, s.wavelength, s.file.render.paths
            ),
            x_label: "tilt d theta (millidegrees)".into(),
            x_unit: None,
            x_log: false,
            y_label: "|C(i, i + d theta; v, v + d theta)|^2, normalised".into(),
            curves,
        }
    }

    /// The terminal report.
    pub fn text(&self, s: &TiltStudy) -> String {
        let mut o = String::new();
        let dash = |x: f64| {
            if s.geometry == TiltGeometry::Transmission {
                format!("{x:.4}")
            } else {
                "-".into()
            }
        };
        for (r, m) in self.rows.iter().zip(&s.materials) {
            let _ = writeln!(
                o,
                "{}: {}: transport optical depth L / l* = {:.3}; {:.1} s",
                s.name,
                r.label,
                s.thickness / m.transport_mfp(),
                r.curve.wall
            );
            let _ = writeln!(
                o,
                "  {:>12}  {:>9}  {:>19}  {:>8}  {:>12}",
                "theta (mdeg)", "k theta L", "C (MC) +- SE", "C1 (L)", "C1 (L+2ze)"
            );
            for n in 0..s.angles.len() {
                let _ = writeln!(
                    o,
                    "  {:>12.5}  {:>9.4}  {:>9.4} +- {:<6.4}  {:>8}  {:>12}",
                    s.angles[n].to_degrees() * 1000.0,
                    self.k_theta_l[n],
                    r.curve.c[n],
                    r.curve.se[n],
                    dash(self.c1[n]),
                    dash(r.extrapolated[n])
                );
            }
        }
        o
    }

    /// The JSON sidecar: the study as parsed, the geometry, the render settings, the curves
    /// and the written `files`.
    pub fn describe(&self, s: &TiltStudy, files: Value, threads: usize) -> Value {
        let r = &s.file.render;
        let coherence = r.coherence.coherence();
        let transmission = s.geometry == TiltGeometry::Transmission;
        json!({
            "command": "memory-tilt",
            "study_file": s.origin,
            "study": serde_json::to_value(&s.file).unwrap_or(Value::Null),
            "geometry": {
                "slab_um": [s.width, s.width, s.thickness],
                "slab": "centred at the origin, thickness L along z; per row its mean free path, \
                         albedo and Henyey-Greenstein lobes",
                "sources": "plane waves exp(i k i_n . x), i_n tilted from +z towards +x by theta_n",
                "sensors": if transmission {
                    "far field in the directions v_n = i_n: transmission"
                } else {
                    "far field in the directions v_n = (sin theta_n, 0, -cos theta_n), i_n \
                     mirrored in the slab's plane: reflection"
                },
                "pairs": "(i_n, v_n), n = 0 .. n_angles - 1",
            },
            "theory": if transmission {
                "C1 (Feng, Kane, Lee and Stone 1988, as Bar et al. 2019 Eq. 39 quotes it): \
                 (k theta L)^2 / sinh^2(k theta L), valid for L >> l*"
            } else {
                "none in reflection (C1 is a transmission result)"
            },
            "render": {
                "paths_per_row": r.paths,
                "groups": r.groups,
                "seed": r.seed,
                "group_seeds": "group i of row w renders with derive_seed(render.seed, w groups + i)",
                "coherence": speckle_scene::build::render::coherence_name(coherence),
                "tracer": slab_tracer_json(coherence),
                "standard_errors": "jackknife over the groups (delete one group)",
                "threads": threads,
                "wall_time_s": self.wall,
            },
            "rows": self.rows.iter().zip(&s.materials).map(|(row, m)| json!({
                "label": row.label,
                "g": row.g,
                "lobes_weight_g": m.lobes,
                "mean_free_path_um": m.mean_free_path,
                "albedo": m.albedo,
                "transport_mean_free_path_um": m.transport_mfp(),
                "transport_optical_depth": s.thickness / m.transport_mfp(),
                "correlation": row.curve.c,
                "correlation_stderr": row.curve.se,
                "c1_extrapolated": if transmission { json!(row.extrapolated) } else { Value::Null },
                "single_scattering_fraction_c00": row.curve.single_fraction,
                "wall_time_s": row.curve.wall,
            })).collect::<Vec<_>>(),
            "k_theta_l": self.k_theta_l,
            "c1": if transmission { json!(self.c1) } else { Value::Null },
            "files": files,
        })
    }
}
