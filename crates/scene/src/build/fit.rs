//! `[fit]`: the parameters `speckle fit` fits and the measurement it fits them to, validated
//! against the scene (`docs/fitting.md`). The measurement file is read here, through the same
//! confined, size-limited path as every input, and every value is checked before a fit starts.

use crate::SceneError;
use crate::safe::{Files, MAX_TABLE_BYTES};
use crate::schema::{FitSpec, SceneFile};
use crate::validate::invalid;
use std::path::Path;

/// The most parameters of one fit.
pub const MAX_FIT_PARAMETERS: usize = 8;

/// The most rows of a measurement file.
pub const MAX_MEASUREMENT_ROWS: usize = 100_000;

/// What a measurement holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quantity {
    /// The normalised field correlation `|g1(t)|` of one pair against the lag.
    G1,
    /// The intensity correlation `g2(t) = 1 + beta |g1(t)|^2` of one pair against the lag.
    G2,
    /// The readings of the pairs (intensities, absolute units times `scale`).
    Intensity,
}

impl Quantity {
    /// The first column of its measurement file in a scene of `pairs` pairs.
    pub fn abscissa(self, pairs: usize) -> Abscissa {
        match self {
            Quantity::Intensity => Abscissa::Pair(pairs),
            Quantity::G1 | Quantity::G2 => Abscissa::Increasing("lag"),
        }
    }

    /// The name in scene files (`[fit] quantity`).
    pub fn name(self) -> &'static str {
        match self {
            Quantity::G1 => "g1",
            Quantity::G2 => "g2",
            Quantity::Intensity => "intensity",
        }
    }
}

/// A parameter a fit can change.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum FitField {
    /// The diffusion coefficient of one material, or one value shared by several (tied), or of
    /// every material with a uniform motion.
    Diffusion {
        /// The materials, increasing (`None`: the one motion of every material).
        materials: Option<Vec<usize>>,
    },
    /// The scattering coefficient of a homogeneous medium.
    SigmaS,
    /// The absorption coefficient of a homogeneous medium.
    SigmaA,
    /// The coherence factor `beta` of `g2`.
    Beta,
    /// A factor on every intensity.
    Scale,
}

/// A validated entry of `[[fit.parameters]]`.
#[derive(Debug, Clone, PartialEq)]
pub struct FitParameter {
    /// The field as written (`motion.materials[3].diffusion`).
    pub name: String,
    /// What it changes.
    pub field: FitField,
    /// The range searched, `low < high`.
    pub range: [f64; 2],
    /// The value the fit starts from: the scene's, or the middle of the range (geometric
    /// where `low > 0`).
    pub start: f64,
}

/// A measurement: abscissae (lags, or pair indices for intensities), values and optional
/// standard errors.
#[derive(Debug, Clone, PartialEq)]
pub struct Measurement {
    /// The file as messages show it.
    pub origin: String,
    /// Lags (strictly increasing, >= 0) or pair indices (distinct).
    pub x: Vec<f64>,
    /// The measured values.
    pub y: Vec<f64>,
    /// Their standard errors (> 0), when the file gives them.
    pub stderr: Option<Vec<f64>>,
}

/// Validated `[fit]`.
#[derive(Debug, Clone, PartialEq)]
pub struct FitSettings {
    /// What the measurement holds.
    pub quantity: Quantity,
    /// The pair of a `g1` or `g2` curve.
    pub pair: usize,
    /// The parameters.
    pub parameters: Vec<FitParameter>,
    /// The measurement, when the scene names one (`speckle fit --data` may give it).
    pub data: Option<Measurement>,
    /// Jackknife groups.
    pub groups: usize,
    /// Confidence level.
    pub level: f64,
}

/// What [`build`] needs to know of the scene.
#[derive(Debug, Clone, Copy)]
pub struct SceneFacts {
    /// Number of pairs.
    pub pairs: usize,
    /// Whether the sensors are detectors.
    pub detectors: bool,
    /// Whether the medium is one homogeneous material given by coefficients.
    pub homogeneous: bool,
}

/// Builds `[fit]` of `file` (errors name `fit.quantity`, `fit.pair`, `fit.parameters[i].field`,
/// `fit.parameters[i].range`, `fit.groups`, `fit.level`, `fit.data`).
pub fn build(
    spec: &FitSpec,
    file: &SceneFile,
    facts: SceneFacts,
    files: Files,
) -> Result<FitSettings, SceneError> {
    if !facts.detectors {
        return Err(invalid(
            "sensors",
            "`speckle fit` fits the readings of detectors (`type = \"detector\"`)",
        ));
    }
    let quantity = match spec.quantity.as_str() {
        "g1" => Quantity::G1,
        "g2" => Quantity::G2,
        "intensity" => Quantity::Intensity,
        q => {
            return Err(invalid(
                "fit.quantity",
                format!(
                    "must be \"g1\", \"g2\" or \"intensity\" (got {:?})",
                    excerpt(q)
                ),
            ));
        }
    };
    let pair = spec.pair.unwrap_or(0);
    if pair >= facts.pairs {
        return Err(invalid(
            "fit.pair",
            format!("the scene has {} pair(s) (got {pair})", facts.pairs),
        ));
    }
    if quantity != Quantity::Intensity && file.motion.is_none() {
        return Err(invalid(
            "motion",
            format!(
                "a {} fit needs `[motion]` (the motions the paths are rendered at)",
                quantity.name()
            ),
        ));
    }
    if spec.parameters.is_empty() || spec.parameters.len() > MAX_FIT_PARAMETERS {
        return Err(invalid(
            "fit.parameters",
            format!(
                "give 1 to {MAX_FIT_PARAMETERS} parameters (got {})",
                spec.parameters.len()
            ),
        ));
    }
    let mut parameters: Vec<FitParameter> = vec![];
    for (i, p) in spec.parameters.iter().enumerate() {
        let at = format!("fit.parameters[{i}]");
        let parameter = parameter(&at, &p.field, p.range, quantity, file, facts)?;
        if parameters.iter().any(|q| q.field == parameter.field) {
            return Err(invalid(
                format!("{at}.field"),
                format!("{:?} is fitted twice", excerpt(&p.field)),
            ));
        }
        if let FitField::Diffusion {
            materials: Some(mine),
        } = &parameter.field
        {
            let other = parameters.iter().find_map(|q| match &q.field {
                FitField::Diffusion {
                    materials: Some(theirs),
                } => mine.iter().find(|m| theirs.contains(m)),
                _ => None,
            });
            if let Some(m) = other {
                return Err(invalid(
                    format!("{at}.field"),
                    format!("material {m}'s diffusion is fitted twice"),
                ));
            }
        }
        parameters.push(parameter);
    }
    let groups = spec.groups.unwrap_or(32);
    if !(4..=128).contains(&groups) {
        return Err(invalid(
            "fit.groups",
            format!("must lie in 4..=128 (got {groups})"),
        ));
    }
    let level = spec.level.unwrap_or(0.95);
    if !(level > 0.0 && level < 1.0) {
        return Err(invalid(
            "fit.level",
            format!("must lie in (0, 1) (got {level})"),
        ));
    }
    let data = match &spec.data {
        Some(path) => Some(read_measurement(files, path, quantity, facts.pairs)?),
        None => None,
    };
    Ok(FitSettings {
        quantity,
        pair,
        parameters,
        data,
        groups,
        level,
    })
}

/// A field name quoted in a message: at most 60 characters, control characters escaped.
fn excerpt(s: &str) -> String {
    s.chars()
        .take(60)
        .flat_map(char::escape_default)
        .collect::<String>()
}

/// One parameter entry, checked.
fn parameter(
    at: &str,
    name: &str,
    range: [f64; 2],
    quantity: Quantity,
    file: &SceneFile,
    facts: SceneFacts,
) -> Result<FitParameter, SceneError> {
    let field_err = |reason: String| invalid(format!("{at}.field"), reason);
    let motion = file.motion.as_ref();
    // The field, and the scene's value of it (None: no value in the scene).
    let (field, value, low_min): (FitField, Option<f64>, f64) = match name {
        "motion.diffusion" => {
            let m = motion
                .filter(|m| m.materials.is_none())
                .ok_or_else(|| field_err("needs `[motion]` with one `diffusion` for the whole medium (with `[[motion.materials]]`, fit `motion.materials[i].diffusion`)".into()))?;
            (
                FitField::Diffusion { materials: None },
                Some(m.diffusion.unwrap_or(0.0)),
                0.0,
            )
        }
        "medium.sigma_s" | "medium.sigma_a" => {
            if !facts.homogeneous {
                return Err(field_err(format!(
                    "{name} can be fitted only in a homogeneous medium given by sigma_s and \
                     sigma_a (not layers, a grid or particles): the records keep one path \
                     length per path"
                )));
            }
            let s = file.medium.sigma_s;
            let a = file.medium.sigma_a;
            if name == "medium.sigma_s" {
                if s.is_none() {
                    return Err(field_err(
                        "give the medium by `sigma_s` (and `sigma_a`) to fit sigma_s".into(),
                    ));
                }
                (FitField::SigmaS, s, f64::MIN_POSITIVE)
            } else {
                if s.is_none() {
                    return Err(field_err(
                        "give the medium by `sigma_s` and `sigma_a` to fit sigma_a".into(),
                    ));
                }
                (FitField::SigmaA, Some(a.unwrap_or(0.0)), 0.0)
            }
        }
        "beta" => {
            if quantity != Quantity::G2 {
                return Err(field_err("beta is fitted only to a g2 curve".into()));
            }
            (FitField::Beta, None, f64::MIN_POSITIVE)
        }
        "scale" => {
            if quantity != Quantity::Intensity {
                return Err(field_err("scale is fitted only to intensities".into()));
            }
            (FitField::Scale, None, f64::MIN_POSITIVE)
        }
        _ => {
            let Some(list) = name
                .strip_prefix("motion.materials[")
                .and_then(|r| r.strip_suffix("].diffusion"))
            else {
                return Err(field_err(format!(
                    "{:?} is not a field a fit can change (motion.diffusion, \
                     motion.materials[i].diffusion, motion.materials[i,j,..].diffusion (one \
                     value shared), medium.sigma_s, medium.sigma_a, beta, scale)",
                    excerpt(name)
                )));
            };
            let mut indices = vec![];
            for i in list.split(',') {
                let i = i.trim().parse::<usize>().map_err(|_| {
                    field_err(format!(
                        "{:?}: the materials are indices separated by commas, as in \
                         motion.materials[3,4].diffusion",
                        excerpt(name)
                    ))
                })?;
                if indices.contains(&i) {
                    return Err(field_err(format!("material {i} is named twice")));
                }
                indices.push(i);
            }
            indices.sort_unstable();
            let motions = motion.and_then(|m| m.materials.as_ref()).ok_or_else(|| {
                field_err("needs `[[motion.materials]]` (one motion per material)".into())
            })?;
            let mut values = vec![];
            for &i in &indices {
                let m = motions.get(i).ok_or_else(|| {
                    field_err(format!(
                        "material {i} does not exist ({} material motions)",
                        motions.len()
                    ))
                })?;
                values.push(m.diffusion);
            }
            // Tied materials start from their common value, or the range's middle.
            let value = values.iter().all(|&v| v == values[0]).then_some(values[0]);
            (
                FitField::Diffusion {
                    materials: Some(indices),
                },
                value,
                0.0,
            )
        }
    };
    if quantity == Quantity::Intensity && matches!(field, FitField::Diffusion { .. }) {
        return Err(field_err(
            "an intensity does not depend on the motion; fit it to a g1 or g2 curve".into(),
        ));
    }
    let [low, high] = range;
    if !(low.is_finite() && high.is_finite() && low >= low_min && low < high) {
        return Err(invalid(
            format!("{at}.range"),
            format!(
                "needs finite low < high, low {} (got [{low}, {high}])",
                if low_min > 0.0 { "> 0" } else { ">= 0" }
            ),
        ));
    }
    if field == FitField::Beta && high > 1.0 {
        return Err(invalid(
            format!("{at}.range"),
            format!("beta lies in (0, 1] (got [{low}, {high}])"),
        ));
    }
    let middle = if low > 0.0 {
        (low * high).sqrt()
    } else {
        0.5 * (low + high)
    };
    let start = match (&field, value) {
        // The coefficients are the centre of the re-weighting: the render's.
        (FitField::SigmaS | FitField::SigmaA, Some(v)) if !(low..=high).contains(&v) => {
            return Err(invalid(
                format!("{at}.range"),
                format!(
                    "the paths are rendered at the scene's {name} = {v}, which must lie in the \
                     range (got [{low}, {high}])"
                ),
            ));
        }
        (_, Some(v)) if v > low && v < high => v,
        _ => middle,
    };
    Ok(FitParameter {
        name: name.to_string(),
        field,
        range,
        start,
    })
}

/// Reads and checks a measurement file (`fit.data`; `embedded:NAME` names one embedded in the
/// binary, [`crate::examples::data`]) of `quantity` for a scene of `pairs` pairs.
pub fn read_measurement(
    files: Files,
    path: &Path,
    quantity: Quantity,
    pairs: usize,
) -> Result<Measurement, SceneError> {
    read_rows(files, path, quantity.abscissa(pairs))
}

/// Reads and checks a measurement file (`fit.data`, or `embedded:NAME`) whose first column is
/// an `abscissa` ([`parse_rows`]).
pub fn read_rows(files: Files, path: &Path, abscissa: Abscissa) -> Result<Measurement, SceneError> {
    let embedded = path
        .to_str()
        .and_then(|f| f.strip_prefix(crate::build::phase::EMBEDDED));
    let (text, shown) = match embedded {
        Some(name) => {
            let text = crate::examples::data(name).ok_or_else(|| {
                invalid(
                    "fit.data",
                    format!(
                        "no embedded table called {:?}; the embedded tables are: {}",
                        excerpt(name),
                        crate::examples::data_names().join(", ")
                    ),
                )
            })?;
            (text.to_string(), path.display().to_string())
        }
        None => files.read_text("fit.data", path, MAX_TABLE_BYTES)?,
    };
    parse_rows(&text, &shown, abscissa)
}

/// What the first column of a measurement holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Abscissa {
    /// Values `>= 0`, strictly increasing, called by this name in messages (`lag`, `tilt`).
    Increasing(&'static str),
    /// Pair indices below this count, each at most once, in any order.
    Pair(usize),
}

/// Parses a measurement of `quantity` for a scene of `pairs` pairs ([`parse_rows`]).
pub fn parse_measurement(
    text: &str,
    shown: &str,
    quantity: Quantity,
    pairs: usize,
) -> Result<Measurement, SceneError> {
    parse_rows(text, shown, quantity.abscissa(pairs))
}

/// Parses a measurement: comma-separated rows of 2 or 3 numbers (`#` comments and blank lines
/// skipped, an optional header line first), the first column an `abscissa`; errors name
/// `fit.data`, the file, line and column.
pub fn parse_rows(text: &str, shown: &str, abscissa: Abscissa) -> Result<Measurement, SceneError> {
    let at = |line: usize, col: usize, reason: String| {
        invalid(
            "fit.data",
            format!("{shown} line {line}, column {col}: {reason}"),
        )
    };
    let (mut x, mut y, mut e) = (vec![], vec![], vec![]);
    let mut columns = None;
    let mut header_allowed = true;
    for (n, raw) in text.lines().enumerate() {
        let line = n + 1;
        let row = raw.trim();
        if row.is_empty() || row.starts_with('#') {
            continue;
        }
        let cells: Vec<&str> = row.split(',').map(str::trim).collect();
        if header_allowed && cells[0].parse::<f64>().is_err() {
            header_allowed = false;
            continue;
        }
        header_allowed = false;
        if !(2..=3).contains(&cells.len()) {
            return Err(at(
                line,
                1,
                format!(
                    "a row has 2 or 3 columns ({}, value[, stderr]); got {}",
                    match abscissa {
                        Abscissa::Pair(_) => "pair",
                        Abscissa::Increasing(name) => name,
                    },
                    cells.len()
                ),
            ));
        }
        if *columns.get_or_insert(cells.len()) != cells.len() {
            return Err(at(
                line,
                1,
                format!(
                    "every row needs the same columns ({} above, {} here)",
                    columns.unwrap_or(0),
                    cells.len()
                ),
            ));
        }
        if x.len() == MAX_MEASUREMENT_ROWS {
            return Err(at(
                line,
                1,
                format!("more than {MAX_MEASUREMENT_ROWS} rows"),
            ));
        }
        let mut values = [0.0; 3];
        for (c, cell) in cells.iter().enumerate() {
            let v: f64 = cell
                .parse()
                .map_err(|_| at(line, c + 1, format!("{:?} is not a number", excerpt(cell))))?;
            if !v.is_finite() {
                return Err(at(line, c + 1, format!("{v} is not finite")));
            }
            values[c] = v;
        }
        let [a, b, s] = values;
        match abscissa {
            Abscissa::Pair(pairs) => {
                if a < 0.0 || a.fract() != 0.0 || a >= pairs as f64 {
                    return Err(at(line, 1, format!("a pair index in 0..{pairs} (got {a})")));
                }
                if x.contains(&a) {
                    return Err(at(line, 1, format!("pair {a} is given twice")));
                }
            }
            Abscissa::Increasing(name) => {
                if a < 0.0 {
                    return Err(at(line, 1, format!("{name}s are >= 0 (got {a})")));
                }
                if x.last().is_some_and(|&l| a <= l) {
                    return Err(at(
                        line,
                        1,
                        format!("{name}s must increase (got {a} after {})", x[x.len() - 1]),
                    ));
                }
            }
        }
        if cells.len() == 3 && s <= 0.0 {
            return Err(at(line, 3, format!("a standard error is > 0 (got {s})")));
        }
        x.push(a);
        y.push(b);
        e.push(s);
    }
    if x.len() < 2 {
        return Err(invalid(
            "fit.data",
            format!("{shown}: needs at least 2 rows of data (got {})", x.len()),
        ));
    }
    Ok(Measurement {
        origin: shown.to_string(),
        x,
        y,
        stderr: (columns == Some(3)).then_some(e),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Measurement, String> {
        parse_measurement(text, "m.csv", Quantity::G2, 1).map_err(|e| e.to_string())
    }

    #[test]
    fn a_curve_with_a_header_comments_and_errors_parses() {
        let m = parse("# measured\nlag,g2,stderr\n0,1.5,0.01\n1e-6, 1.4 ,0.01\n\n2e-6,1.3,0.02\n")
            .unwrap();
        assert_eq!(m.x, vec![0.0, 1e-6, 2e-6]);
        assert_eq!(m.y, vec![1.5, 1.4, 1.3]);
        assert_eq!(m.stderr, Some(vec![0.01, 0.01, 0.02]));
        let m = parse("0,1.5\n1,1.2\n").unwrap();
        assert_eq!(m.stderr, None);
    }

    #[test]
    fn bad_rows_are_named_by_line_and_column() {
        for (text, said) in [
            ("0,1.5\n1,x\n", "line 2, column 2"),
            ("0,1.5\n0,1.2\n", "line 2, column 1: lags must increase"),
            ("0,1.5\n1,NaN\n", "line 2, column 2"),
            ("0,1.5,0.1\n1,1.2\n", "line 2, column 1: every row"),
            ("0,1.5,0\n1,1.2,1\n", "line 1, column 3"),
            ("0,1.5,1,2\n", "line 1, column 1: a row has 2 or 3"),
            ("0,1.5\n", "at least 2 rows"),
            ("-1,1.5\n0,1\n", "lags are >= 0"),
            ("0,1\n1,inf\n", "line 2, column 2"),
        ] {
            let e = parse(text).unwrap_err();
            assert!(e.contains(said), "{text:?}: {e}");
            assert!(
                e.starts_with("fit.data: m.csv") || said.contains("rows"),
                "{e}"
            );
        }
        let e = parse_measurement("0,1\n0,2\n", "m.csv", Quantity::Intensity, 3).unwrap_err();
        assert!(e.to_string().contains("pair 0 is given twice"), "{e}");
        let e = parse_measurement("5,1\n0,2\n", "m.csv", Quantity::Intensity, 3).unwrap_err();
        assert!(e.to_string().contains("line 1, column 1"), "{e}");
    }

    /// A two-layer scene (three materials' motions) with the given `[[fit.parameters]]`.
    fn layered(parameters: &str) -> Result<crate::Problem, String> {
        let text = format!(
            r#"
wavelength = 785e-7
[medium]
size = [4.0, 4.0, 2.0]
center = [0.0, 0.0, 1.0]
layers = [0.3, 0.3, 1.4]
[[medium.materials]]
sigma_s = 10.0
phase = {{ type = "hg", g = 0.5 }}
[[medium.materials]]
sigma_s = 12.0
phase = {{ type = "hg", g = 0.5 }}
[[medium.materials]]
sigma_s = 14.0
phase = {{ type = "hg", g = 0.5 }}
[[sources]]
type = "point"
position = [-0.3, 0.0, 0.0]
[[sensors]]
type = "detector"
position = [0.3, 0.0, 0.0]
radius = 0.1
[[motion.materials]]
diffusion = 1e-8
[[motion.materials]]
diffusion = 0.0
[[motion.materials]]
diffusion = 1e-8
[motion]
lags = [0.0, 1e-6]
[fit]
quantity = "g1"
{parameters}
"#
        );
        let o = crate::Overrides::default();
        crate::load::load_str(&text, "t", std::path::Path::new("."), "t", &o)
            .map_err(|e| e.to_string())
    }

    fn parameter(field: &str) -> String {
        format!("[[fit.parameters]]\nfield = \"{field}\"\nrange = [1e-10, 1e-6]\n")
    }

    #[test]
    fn materials_diffusion_can_be_tied() {
        let p = layered(&parameter("motion.materials[2, 0].diffusion")).unwrap();
        let f = &p.fit.unwrap().parameters[0];
        assert_eq!(
            f.field,
            FitField::Diffusion {
                materials: Some(vec![0, 2])
            }
        );
        assert_eq!(f.start, 1e-8, "their common value");
        // Values that differ: the middle of the range.
        let p = layered(
            "[[fit.parameters]]\nfield = \"motion.materials[0,1].diffusion\"\n\
             range = [1e-10, 1e-4]",
        )
        .unwrap();
        let start = p.fit.unwrap().parameters[0].start;
        assert!((start / 1e-7 - 1.0).abs() < 1e-12, "{start}");
        let p = layered(&format!(
            "{}{}",
            parameter("motion.materials[1].diffusion"),
            parameter("motion.materials[0,2].diffusion")
        ))
        .unwrap();
        assert_eq!(p.fit.unwrap().parameters.len(), 2);
        for (parameters, said) in [
            (
                parameter("motion.materials[0,0].diffusion"),
                "fit.parameters[0].field: material 0 is named twice",
            ),
            (
                parameter("motion.materials[0,3].diffusion"),
                "fit.parameters[0].field: material 3 does not exist",
            ),
            (
                parameter("motion.materials[0,x].diffusion"),
                "indices separated by commas",
            ),
            (
                parameter("motion.materials[].diffusion"),
                "indices separated by commas",
            ),
            (
                format!(
                    "{}{}",
                    parameter("motion.materials[0,1].diffusion"),
                    parameter("motion.materials[2,1].diffusion")
                ),
                "fit.parameters[1].field: material 1's diffusion is fitted twice",
            ),
            (
                parameter("motion.diffusion"),
                "fit.parameters[0].field: needs `[motion]` with one `diffusion`",
            ),
        ] {
            let e = layered(&parameters).unwrap_err();
            assert!(e.contains(said), "{parameters}: {e}");
        }
    }
}
