//! The sampling study file (TOML): its format, its loading with the command line's overrides,
//! and its validation into a [`SamplingStudy`].

use super::case::SamplingCase;
use crate::memory::study::parse;
use crate::memory::{StudyOutput, StudyOverrides};
use serde::{Deserialize, Serialize};
use speckle_paths::BeamStrategy;
use speckle_phase::{Dimension, Phase, VmfMixture};
use speckle_scene::schema::BeamsSpec;
use speckle_scene::validate::{invalid as bad, number, positive};
use speckle_scene::{LoadError, SceneError, load};
use std::path::Path;
use std::sync::Arc;

/// Most cases a study may list.
pub const MAX_CASES: usize = 16;
/// Most path counts of a sweep.
pub const MAX_STEPS: usize = 12;

/// A sampling-gain study file (TOML, unknown keys rejected). Lengths in wavelengths.
///
/// ```toml
/// name = "fig9_sampling_gain"     # output prefix (default: the file's stem)
/// strategies = ["off", "position", "position_and_direction"]   # gains are over the first
///
/// [[cases]]
/// name = "small box"
/// dimension = 3                   # or 2 (flatland, isotropic only)
/// size = [6.0, 3.0]               # lateral, depth (3D: lateral x lateral x depth)
/// mean_free_path = 3.0
/// concentration = 16.0            # of every beam
/// amplitude = [[0.0, 0.2], [6.0, 1.0], [-1.5, 0.1]]  # vMF lobes (gamma, alpha); default isotropic
/// reflection = true               # a sensor looking back at the first source (default false)
///
/// [render]
/// paths = 32000                   # the largest path count of the sweep
/// steps = 3                       # path counts paths / ratio^k, k = steps - 1 .. 0
/// ratio = 4
/// reference_paths = 128000        # the reference (position_and_direction) per case
/// seed = 1
/// ```
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SamplingFile {
    /// Output prefix (default: the stem of the file name).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// The strategies, the first the baseline of the gains.
    #[serde(default = "default_strategies")]
    pub strategies: Vec<BeamsSpec>,
    /// The cases.
    pub cases: Vec<CaseFile>,
    /// `[render]`.
    #[serde(default)]
    pub render: SamplingRender,
    /// `[output]`.
    #[serde(default)]
    pub output: StudyOutput,
}

fn default_strategies() -> Vec<BeamsSpec> {
    vec![
        BeamsSpec::Off,
        BeamsSpec::Position,
        BeamsSpec::PositionAndDirection,
    ]
}

/// `[[cases]]` of a sampling study.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CaseFile {
    /// Its name in reports.
    pub name: String,
    /// 3 (default) or 2.
    #[serde(default = "default_dimension")]
    pub dimension: u32,
    /// `[lateral, depth]`.
    pub size: [f64; 2],
    /// Mean free path.
    pub mean_free_path: f64,
    /// The beams' concentration.
    #[serde(default = "default_concentration")]
    pub concentration: f64,
    /// vMF amplitude lobes `[gamma, alpha]` (3D); isotropic when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub amplitude: Option<Vec<[f64; 2]>>,
    /// Whether a sensor looks back at the first source's focus.
    #[serde(default)]
    pub reflection: bool,
}

fn default_dimension() -> u32 {
    3
}

fn default_concentration() -> f64 {
    16.0
}

/// `[render]` of a sampling study.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SamplingRender {
    /// The largest path count (`--paths` replaces it).
    pub paths: u64,
    /// Path counts in the sweep.
    pub steps: usize,
    /// The ratio of successive path counts.
    pub ratio: u64,
    /// Paths of each case's reference render.
    pub reference_paths: u64,
    /// Seed (`--seed` replaces it).
    pub seed: u64,
}

impl Default for SamplingRender {
    fn default() -> Self {
        Self {
            paths: 32_000,
            steps: 3,
            ratio: 4,
            reference_paths: 128_000,
            seed: 1,
        }
    }
}

/// A validated sampling study.
#[derive(Debug, Clone)]
pub struct SamplingStudy {
    /// The document as parsed, with the command-line values filled in.
    pub file: SamplingFile,
    /// Output prefix.
    pub name: String,
    /// Where the study came from.
    pub origin: String,
    /// The cases.
    pub cases: Vec<SamplingCase>,
    /// The strategies.
    pub strategies: Vec<BeamStrategy>,
    /// The path counts, increasing.
    pub paths: Vec<u64>,
}

/// Loads and validates a sampling study file.
pub fn load_sampling_file(
    path: &Path,
    overrides: &StudyOverrides,
) -> Result<SamplingStudy, LoadError> {
    let (text, stem) = load::read_input(path, "study")?;
    load_sampling_str(&text, &path.display().to_string(), &stem, overrides)
}

/// Loads and validates a sampling study from its text (`origin` names it in errors,
/// `default_name` is the output prefix when the file sets none).
pub fn load_sampling_str(
    text: &str,
    origin: &str,
    default_name: &str,
    overrides: &StudyOverrides,
) -> Result<SamplingStudy, LoadError> {
    let mut file: SamplingFile = parse(text).map_err(|e| e.in_document(origin))?;
    let r = &mut file.render;
    overrides
        .apply_to(&mut r.paths, &mut r.seed, &mut file.output)
        .map_err(|e| e.in_document(origin))?;
    validate(file, origin, default_name).map_err(|e| LoadError::from(e).in_document(origin))
}

fn strategy(s: BeamsSpec) -> BeamStrategy {
    match s {
        BeamsSpec::Off => BeamStrategy::Off,
        BeamsSpec::Position => BeamStrategy::Position,
        BeamsSpec::PositionAndDirection => BeamStrategy::PositionAndDirection,
    }
}

/// The name of a strategy as `render.beams` spells it.
pub fn strategy_name(s: BeamStrategy) -> &'static str {
    match s {
        BeamStrategy::Off => "off",
        BeamStrategy::Position => "position",
        BeamStrategy::PositionAndDirection => "position_and_direction",
    }
}

fn case(i: usize, c: &CaseFile) -> Result<SamplingCase, SceneError> {
    let f = |k: &str| format!("cases[{i}].{k}");
    if c.name.is_empty() || c.name.len() > 200 {
        return Err(bad(f("name"), "must have 1 to 200 characters"));
    }
    let dimension = match c.dimension {
        3 => Dimension::Three,
        2 => Dimension::Two,
        d => return Err(bad(f("dimension"), format!("must be 3 or 2 (got {d})"))),
    };
    let lat = positive(f("size[0]"), c.size[0])?;
    let depth = positive(f("size[1]"), c.size[1])?;
    let mfp = positive(f("mean_free_path"), c.mean_free_path)?;
    for (k, s) in [("size[0]", lat), ("size[1]", depth)] {
        if s > 1e4 {
            return Err(bad(
                f(k),
                format!("must be at most 1e4 wavelengths (got {})", number(s)),
            ));
        }
    }
    if lat <= 2.0 {
        return Err(bad(
            f("size[0]"),
            format!(
                "must exceed 2: the foci lie at lateral 0 and 1 (got {})",
                number(lat)
            ),
        ));
    }
    if depth.max(lat) / mfp > 50.0 {
        return Err(bad(
            f("mean_free_path"),
            format!(
                "gives an optical size of {:.4e}; at most 50",
                depth.max(lat) / mfp
            ),
        ));
    }
    let gamma = positive(f("concentration"), c.concentration)?;
    if !(1.0..=1e4).contains(&gamma) {
        return Err(bad(
            f("concentration"),
            format!("must be in [1, 1e4] (got {})", number(gamma)),
        ));
    }
    let phase = match (&c.amplitude, dimension) {
        (None, d) => Phase::isotropic(d),
        (Some(_), Dimension::Two) => {
            return Err(bad(
                f("amplitude"),
                "vMF amplitudes are 3D; flatland cases are isotropic",
            ));
        }
        (Some(lobes), Dimension::Three) => {
            let m = VmfMixture::new(lobes.iter().map(|l| (l[0], l[1])).collect())
                .map_err(|e| bad(f("amplitude"), e.to_string()))?;
            Phase::Vmf(Arc::new(m))
        }
    };
    Ok(SamplingCase {
        name: c.name.clone(),
        dimension,
        size: (lat, depth),
        mean_free_path: mfp,
        gamma,
        phase,
        reflection: c.reflection,
    })
}

fn validate(
    file: SamplingFile,
    origin: &str,
    default_name: &str,
) -> Result<SamplingStudy, SceneError> {
    let name = file
        .name
        .clone()
        .unwrap_or_else(|| default_name.to_string());
    speckle_scene::validate::name(&name)?;
    let n = &file.strategies;
    if n.is_empty() || n.len() > 3 {
        return Err(bad(
            "strategies",
            format!("must list 1 to 3 (got {})", n.len()),
        ));
    }
    for (i, s) in n.iter().enumerate() {
        if n[..i].contains(s) {
            return Err(bad(format!("strategies[{i}]"), "is listed twice"));
        }
    }
    if file.cases.is_empty() || file.cases.len() > MAX_CASES {
        return Err(bad(
            "cases",
            format!("must list 1 to {MAX_CASES} (got {})", file.cases.len()),
        ));
    }
    let cases = file
        .cases
        .iter()
        .enumerate()
        .map(|(i, c)| case(i, c))
        .collect::<Result<Vec<_>, _>>()?;
    let r = &file.render;
    if !(1..=MAX_STEPS).contains(&r.steps) {
        return Err(bad(
            "render.steps",
            format!("must be in 1..={MAX_STEPS} (got {})", r.steps),
        ));
    }
    if !(2..=100).contains(&r.ratio) {
        return Err(bad(
            "render.ratio",
            format!("must be in 2..=100 (got {})", r.ratio),
        ));
    }
    crate::nearfield::check_paths("render.paths", r.paths)?;
    crate::nearfield::check_paths("render.reference_paths", r.reference_paths)?;
    let mut paths = Vec::with_capacity(r.steps);
    let mut p = r.paths;
    for _ in 0..r.steps {
        paths.push(p);
        p /= r.ratio;
    }
    paths.reverse();
    if paths[0] < 8 {
        return Err(bad(
            "render.paths",
            format!(
                "the smallest path count, render.paths / render.ratio^(render.steps - 1), must \
                 be at least 8 (got {})",
                paths[0]
            ),
        ));
    }
    Ok(SamplingStudy {
        name,
        origin: origin.to_string(),
        strategies: n.iter().map(|s| strategy(*s)).collect(),
        cases,
        paths,
        file,
    })
}
