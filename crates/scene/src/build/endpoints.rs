//! Sources and sensors: `[[sources]]` and `[[sensors]]` expanded in order, generators
//! (`plane_tilts`, `far_grid`, `far_arc`, `point_grid`) included, with a description of every
//! expanded endpoint and the layout of a sensor image.
//!
//! Conventions (README, "Scene format"): generators start at `+z` (`+y` in flatland) and rotate
//! about `+y` (`+z` in flatland, where the axis must be `+-z`) by the right-hand rule; a
//! `far_grid` is the image `unit(tan(tx) e1 + tan(ty) e2 + c)` with `e1 = unit(y x c)` (or
//! `unit(x x c)` when `c` is along `y`) and `e2 = c x e1`; grids are row-major, `iy` slow.

use super::MAX_ENDPOINTS;
use crate::SceneError;
use crate::schema::{SensorSpec, SourceSpec, WeightingSpec};
use crate::validate::{
    MIN_COMPONENT, direction, finite, flat_direction, generated_direction, invalid, position,
};
use serde::Serialize;
use speckle_endpoints::{Detector, EndpointError, GaussianBeam, Sensor, Source, Weighting};
use speckle_medium::{Aabb, DVec3, Dimension};

/// One expanded source or sensor, as the sidecars describe it.
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct EndpointInfo {
    /// Index of the `[[sources]]` or `[[sensors]]` entry it came from.
    pub entry: usize,
    /// `"plane"` (a plane wave), `"point"`, `"far"` (a far-field sensor), `"gaussian_beam"`,
    /// `"detector"` or `"fibre"` (a fibre source).
    #[serde(rename = "type")]
    pub kind: &'static str,
    /// Unit propagation or viewing direction.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub direction: Option<[f64; 3]>,
    /// Position of a point endpoint.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub position: Option<[f64; 3]>,
    /// `plane_tilts`: the tilt, degrees.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tilt_deg: Option<f64>,
    /// Grids: the column.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ix: Option<usize>,
    /// Grids: the row.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub iy: Option<usize>,
    /// `far_grid`: the angle along `e1`, degrees.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub theta_x_deg: Option<f64>,
    /// `far_grid`: the angle along `e2`, degrees.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub theta_y_deg: Option<f64>,
    /// `far_arc`: the index along the arc.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub k: Option<usize>,
    /// `far_arc`: the rotation angle, degrees.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub angle_deg: Option<f64>,
    /// A Gaussian beam's aperture concentration.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub concentration: Option<f64>,
    /// A detector's radius.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub radius: Option<f64>,
    /// A detector's numerical aperture.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub numerical_aperture: Option<f64>,
    /// A detector's weighting (`"flux"` or `"fluence"`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub weighting: Option<&'static str>,
}

impl EndpointInfo {
    fn plane(entry: usize, d: DVec3) -> Self {
        Self {
            entry,
            kind: "plane",
            direction: Some(d.to_array()),
            ..Self::default()
        }
    }

    fn far(entry: usize, d: DVec3) -> Self {
        Self {
            entry,
            kind: "far",
            direction: Some(d.to_array()),
            ..Self::default()
        }
    }

    fn point(entry: usize, p: DVec3) -> Self {
        Self {
            entry,
            kind: "point",
            position: Some(p.to_array()),
            ..Self::default()
        }
    }

    /// A disc (a detector, or a fibre source: `kind`) of entry `entry`: its centre, radius and
    /// aperture, and `direction`, the way the light goes through it.
    fn disc(entry: usize, kind: &'static str, d: &Detector, direction: DVec3) -> Self {
        Self {
            entry,
            kind,
            position: Some(d.center().to_array()),
            direction: Some(direction.to_array()),
            radius: Some(d.radius()),
            numerical_aperture: Some(d.numerical_aperture()),
            ..Self::default()
        }
    }

    /// A Gaussian beam: its focus and the axis as given (propagation or viewing direction).
    fn gaussian(entry: usize, b: &GaussianBeam, axis: DVec3) -> Self {
        Self {
            entry,
            kind: "gaussian_beam",
            position: Some(b.focus.to_array()),
            direction: Some(axis.to_array()),
            concentration: Some(b.concentration),
            ..Self::default()
        }
    }
}

/// A `gaussian_beam` entry (`prefix` is `sources[i]` or `sensors[i]`): focus, axis (default
/// filled in) and exactly one of `concentration` and `numerical_aperture`. Returns the beam with
/// the axis as given (a sensor's source form reverses it).
fn gaussian_beam(
    prefix: &str,
    focus: [f64; 3],
    axis: &mut Option<[f64; 3]>,
    concentration: Option<f64>,
    numerical_aperture: Option<f64>,
    dim: Dimension,
) -> Result<GaussianBeam, SceneError> {
    let f = |k: &str| format!("{prefix}.{k}");
    let p = position(&f("focus"), focus, dim)?;
    let a = flat_direction(&f("axis"), *axis.get_or_insert(forward(dim)), dim)?;
    let built = match (concentration, numerical_aperture) {
        (Some(g), None) => GaussianBeam::new(prefix, p, a, g),
        (None, Some(na)) => GaussianBeam::with_numerical_aperture(prefix, p, a, na),
        _ => {
            return Err(invalid(
                f("concentration"),
                "give exactly one of concentration and numerical_aperture",
            ));
        }
    };
    built.map_err(|e| {
        let EndpointError::InvalidInput { field, reason } = e;
        invalid(field, reason)
    })
}

/// The layout of a sensor list that is one 2D grid (an image).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct SensorGrid {
    /// `"far_grid"` or `"point_grid"`.
    pub kind: &'static str,
    /// Columns.
    pub nx: usize,
    /// Rows.
    pub ny: usize,
}

/// The default propagation or viewing direction of generators: `+z`, or `+y` in flatland.
fn forward(dim: Dimension) -> [f64; 3] {
    match dim {
        Dimension::Three => [0.0, 0.0, 1.0],
        Dimension::Two => [0.0, 1.0, 0.0],
    }
}

/// Validates the start direction (`start_key`) and the rotation axis of a generator
/// (`plane_tilts`, `far_arc`), filling in their defaults: `+z` and `+y`, or `+y` and `+z` in
/// flatland, where the axis must be `+z` or `-z`. `f` names a field of the entry.
fn rotation(
    f: &dyn Fn(&str) -> String,
    start_key: &str,
    start: &mut Option<[f64; 3]>,
    axis: &mut Option<[f64; 3]>,
    dim: Dimension,
) -> Result<(DVec3, DVec3), SceneError> {
    let d = flat_direction(&f(start_key), *start.get_or_insert(forward(dim)), dim)?;
    let default_axis = match dim {
        Dimension::Three => [0.0, 1.0, 0.0],
        Dimension::Two => [0.0, 0.0, 1.0],
    };
    let v = *axis.get_or_insert(default_axis);
    let a = direction(&f("axis"), v)?;
    if dim == Dimension::Two && (a.x != 0.0 || a.y != 0.0) {
        return Err(invalid(
            f("axis"),
            format!(
                "must be [0, 0, 1] or [0, 0, -1] in flatland, so that the rotations stay in the \
                 plane z = 0 (got {v:?})"
            ),
        ));
    }
    if a.cross(d).length() < 1e-9 {
        return Err(invalid(
            f("axis"),
            format!("must not be parallel to the {start_key} (the rotations would do nothing)"),
        ));
    }
    Ok((d, a))
}

/// `v` rotated about the unit `axis` by `deg` degrees, normalised; exactly in the plane `z = 0`
/// in flatland.
fn rotated(v: DVec3, axis: DVec3, deg: f64, dim: Dimension) -> DVec3 {
    let r = rotate(v, axis, deg.to_radians()).normalize();
    match dim {
        Dimension::Three => r,
        Dimension::Two => DVec3::new(r.x, r.y, 0.0),
    }
}

/// Rodrigues' rotation of `v` about the unit `axis` by `angle` radians.
fn rotate(v: DVec3, axis: DVec3, angle: f64) -> DVec3 {
    let (s, c) = angle.sin_cos();
    v * c + axis.cross(v) * s + axis * axis.dot(v) * (1.0 - c)
}

/// Expands `[[sources]]` around the medium's box `b`, filling in the defaults of generator
/// entries (so that the sidecar records them).
pub fn build_sources(
    specs: &mut [SourceSpec],
    b: &Aabb,
) -> Result<(Vec<Source>, Vec<EndpointInfo>), SceneError> {
    let dim = b.dimension();
    if specs.is_empty() {
        return Err(invalid(
            "sources",
            "at least one source is needed (add a [[sources]] table)",
        ));
    }
    let (mut out, mut desc) = (Vec::new(), Vec::new());
    for (i, s) in specs.iter_mut().enumerate() {
        let f = |k: &str| format!("sources[{i}].{k}");
        match s {
            SourceSpec::Plane { direction: d } => {
                let d = flat_direction(&f("direction"), *d, dim)?;
                out.push(Source::PlaneWave { direction: d });
                desc.push(EndpointInfo::plane(i, d));
            }
            SourceSpec::Point { position: p } => {
                let p = position(&f("position"), *p, dim)?;
                out.push(Source::Point { position: p });
                desc.push(EndpointInfo::point(i, p));
            }
            SourceSpec::GaussianBeam {
                focus,
                axis,
                concentration,
                numerical_aperture,
            } => {
                let b = gaussian_beam(
                    &format!("sources[{i}]"),
                    *focus,
                    axis,
                    *concentration,
                    *numerical_aperture,
                    dim,
                )?;
                out.push(Source::GaussianBeam(b));
                desc.push(EndpointInfo::gaussian(i, &b, b.axis));
            }
            SourceSpec::Fibre { position: p, .. } => {
                // A stand-in at the centre: [`build_fibres`] builds the fibre against the
                // medium, and the scene of detectors takes it (`Scene::with_emitters`).
                let p = position(&f("position"), *p, dim)?;
                out.push(Source::Point { position: p });
                desc.push(EndpointInfo {
                    kind: "fibre",
                    ..EndpointInfo::point(i, p)
                });
            }
            SourceSpec::PlaneTilts {
                direction: d,
                axis,
                tilts_deg,
            } => {
                let (d, a) = rotation(&f, "direction", d, axis, dim)?;
                if tilts_deg.is_empty() {
                    return Err(invalid(f("tilts_deg"), "at least one tilt is needed"));
                }
                for (k, t) in tilts_deg.iter().enumerate() {
                    let field = format!("{}[{k}]", f("tilts_deg"));
                    let t = finite(&field, *t)?;
                    let v = generated_direction(&field, t, rotated(d, a, t, dim))?;
                    out.push(Source::PlaneWave { direction: v });
                    desc.push(EndpointInfo {
                        tilt_deg: Some(t),
                        ..EndpointInfo::plane(i, v)
                    });
                }
            }
        }
        if out.len() > MAX_ENDPOINTS {
            return Err(invalid(
                "sources",
                format!("more than {MAX_ENDPOINTS} sources after expansion"),
            ));
        }
    }
    Ok((out, desc))
}

/// The image-plane frame `(e1, e2)` of a far-field grid around the unit `c`.
pub fn grid_frame(c: DVec3) -> (DVec3, DVec3) {
    let e1 = if DVec3::Y.cross(c).length() > 1e-9 {
        DVec3::Y.cross(c).normalize()
    } else {
        DVec3::X.cross(c).normalize()
    };
    (e1, c.cross(e1))
}

/// Grid coordinate `i` of `n` over the inclusive range `[lo, hi]` (the centre when `n = 1`).
fn lerp(range: [f64; 2], i: usize, n: usize) -> f64 {
    if n == 1 {
        0.5 * (range[0] + range[1])
    } else {
        range[0] + (range[1] - range[0]) * i as f64 / (n - 1) as f64
    }
}

/// The points `origin + ix step_x + iy step_y` of the grid of `sensors[i]`, row-major (`iy`
/// slow), as `(ix, iy, point)`: the counts checked, the steps non-zero where used, and the
/// farthest points finite (a step times a count may overflow); errors name the key.
fn grid_points(
    i: usize,
    origin: [f64; 3],
    step_x: [f64; 3],
    step_y: [f64; 3],
    nx: usize,
    ny: usize,
    dim: Dimension,
) -> Result<Vec<(usize, usize, DVec3)>, SceneError> {
    let f = |k: &str| format!("sensors[{i}].{k}");
    let o = position(&f("origin"), origin, dim)?;
    let sx = position(&f("step_x"), step_x, dim)?;
    let sy = position(&f("step_y"), step_y, dim)?;
    grid_counts(&format!("sensors[{i}]"), nx, ny)?;
    if nx > 1 && sx == DVec3::ZERO {
        return Err(invalid(f("step_x"), "must be non-zero when nx > 1"));
    }
    if ny > 1 && sy == DVec3::ZERO {
        return Err(invalid(f("step_y"), "must be non-zero when ny > 1"));
    }
    let (last_x, last_y) = (sx * (nx - 1) as f64, sy * (ny - 1) as f64);
    for (key, v) in [
        ("step_x", last_x),
        ("step_y", last_y),
        ("origin", o + last_x + last_y),
    ] {
        if !v.is_finite() {
            return Err(invalid(
                f(key),
                format!(
                    "the grid's points overflow (step times count is not finite: {:?})",
                    v.to_array()
                ),
            ));
        }
    }
    Ok((0..ny)
        .flat_map(|iy| (0..nx).map(move |ix| (ix, iy, o + sx * ix as f64 + sy * iy as f64)))
        .collect())
}

fn grid_counts(field: &str, nx: usize, ny: usize) -> Result<(), SceneError> {
    if nx == 0 {
        return Err(invalid(format!("{field}.nx"), "must be >= 1 (got 0)"));
    }
    if ny == 0 {
        return Err(invalid(format!("{field}.ny"), "must be >= 1 (got 0)"));
    }
    if nx.saturating_mul(ny) > MAX_ENDPOINTS {
        return Err(invalid(
            field,
            format!("nx * ny = {nx} * {ny} exceeds {MAX_ENDPOINTS} sensors"),
        ));
    }
    Ok(())
}

/// Expanded sensors, their descriptions and the layout of the image they form, if any.
pub type BuiltSensors = (Vec<Sensor>, Vec<EndpointInfo>, Option<SensorGrid>);

/// Expands `[[sensors]]` around the medium's box `b`, filling in the defaults of generator
/// entries. The sensors form an image when they are one `far_grid`, `point_grid` or
/// `gaussian_grid` entry with `nx, ny > 1`.
pub fn build_sensors(specs: &mut [SensorSpec], b: &Aabb) -> Result<BuiltSensors, SceneError> {
    let dim = b.dimension();
    if specs.is_empty() {
        return Err(invalid(
            "sensors",
            "at least one sensor is needed (add a [[sensors]] table)",
        ));
    }
    let (mut out, mut desc) = (Vec::new(), Vec::new());
    for (i, s) in specs.iter_mut().enumerate() {
        let e = format!("sensors[{i}]");
        let f = |k: &str| format!("sensors[{i}].{k}");
        match s {
            SensorSpec::Detector { .. } => {
                return Err(invalid(
                    e,
                    "a scene's sensors are either all detectors or none: detectors read \
                     intensities and temporal correlations, the other sensors fields",
                ));
            }
            SensorSpec::Far { direction: d } => {
                let d = flat_direction(&f("direction"), *d, dim)?;
                out.push(Sensor::FarField { direction: d });
                desc.push(EndpointInfo::far(i, d));
            }
            SensorSpec::Point { position: p } => {
                let p = position(&f("position"), *p, dim)?;
                out.push(Sensor::Point { position: p });
                desc.push(EndpointInfo::point(i, p));
            }
            SensorSpec::GaussianBeam {
                focus,
                axis,
                concentration,
                numerical_aperture,
            } => {
                let b = gaussian_beam(&e, *focus, axis, *concentration, *numerical_aperture, dim)?;
                out.push(Sensor::GaussianBeam(b));
                desc.push(EndpointInfo::gaussian(i, &b, b.axis));
            }
            SensorSpec::FarGrid {
                center,
                theta_x_deg,
                theta_y_deg,
                nx,
                ny,
            } => {
                if dim == Dimension::Two {
                    return Err(invalid(
                        e,
                        "far_grid is an image of 3D directions and has no flatland form; use \
                         far_arc (a fan of directions in the plane) in a dimension = 2 scene",
                    ));
                }
                let c = direction(&f("center"), *center)?;
                for (key, range) in [("theta_x_deg", *theta_x_deg), ("theta_y_deg", *theta_y_deg)] {
                    for (k, t) in range.iter().enumerate() {
                        let field = format!("{}[{k}]", f(key));
                        let t = finite(&field, *t)?;
                        if t.abs() >= 90.0 {
                            return Err(invalid(field, format!("must be in (-90, 90) (got {t})")));
                        }
                    }
                }
                grid_counts(&e, *nx, *ny)?;
                let (e1, e2) = grid_frame(c);
                for iy in 0..*ny {
                    let ty = lerp(*theta_y_deg, iy, *ny);
                    for ix in 0..*nx {
                        let tx = lerp(*theta_x_deg, ix, *nx);
                        let v = (e1 * tx.to_radians().tan() + e2 * ty.to_radians().tan() + c)
                            .normalize();
                        let tiny = |t: f64| t != 0.0 && t.to_radians().tan().abs() < MIN_COMPONENT;
                        let (key, t) = if tiny(tx) || !tiny(ty) {
                            ("theta_x_deg", tx)
                        } else {
                            ("theta_y_deg", ty)
                        };
                        let v = generated_direction(&f(key), t, v)?;
                        out.push(Sensor::FarField { direction: v });
                        desc.push(EndpointInfo {
                            ix: Some(ix),
                            iy: Some(iy),
                            theta_x_deg: Some(tx),
                            theta_y_deg: Some(ty),
                            ..EndpointInfo::far(i, v)
                        });
                    }
                }
            }
            SensorSpec::FarArc {
                center,
                axis,
                angles_deg,
                n,
            } => {
                let (c, a) = rotation(&f, "center", center, axis, dim)?;
                for (k, t) in angles_deg.iter().enumerate() {
                    finite(format!("{}[{k}]", f("angles_deg")), *t)?;
                }
                if *n == 0 || *n > MAX_ENDPOINTS {
                    return Err(invalid(
                        f("n"),
                        format!("must be in 1..={MAX_ENDPOINTS} (got {n})"),
                    ));
                }
                let [first, last] = *angles_deg;
                if !(last - first).is_finite() {
                    return Err(invalid(
                        f("angles_deg"),
                        format!(
                            "the range {first:e} to {last:e} degrees overflows; give angles of \
                             ordinary size"
                        ),
                    ));
                }
                for k in 0..*n {
                    let t = first + (last - first) * k as f64 / (*n - 1).max(1) as f64;
                    let v = generated_direction(&f("angles_deg"), t, rotated(c, a, t, dim))?;
                    out.push(Sensor::FarField { direction: v });
                    desc.push(EndpointInfo {
                        k: Some(k),
                        angle_deg: Some(t),
                        ..EndpointInfo::far(i, v)
                    });
                }
            }
            SensorSpec::PointGrid {
                origin,
                step_x,
                step_y,
                nx,
                ny,
            } => {
                for (ix, iy, p) in grid_points(i, *origin, *step_x, *step_y, *nx, *ny, dim)? {
                    out.push(Sensor::Point { position: p });
                    desc.push(EndpointInfo {
                        ix: Some(ix),
                        iy: Some(iy),
                        ..EndpointInfo::point(i, p)
                    });
                }
            }
            SensorSpec::GaussianGrid {
                origin,
                step_x,
                step_y,
                nx,
                ny,
                axis,
                concentration,
                numerical_aperture,
            } => {
                for (ix, iy, p) in grid_points(i, *origin, *step_x, *step_y, *nx, *ny, dim)? {
                    let b = gaussian_beam(
                        &e,
                        p.to_array(),
                        axis,
                        *concentration,
                        *numerical_aperture,
                        dim,
                    )?;
                    out.push(Sensor::GaussianBeam(b));
                    desc.push(EndpointInfo {
                        ix: Some(ix),
                        iy: Some(iy),
                        ..EndpointInfo::gaussian(i, &b, b.axis)
                    });
                }
            }
        }
        if out.len() > MAX_ENDPOINTS {
            return Err(invalid(
                "sensors",
                format!("more than {MAX_ENDPOINTS} sensors after expansion"),
            ));
        }
    }
    let grid = match specs {
        [SensorSpec::FarGrid { nx, ny, .. }] if *nx > 1 && *ny > 1 => Some(SensorGrid {
            kind: "far_grid",
            nx: *nx,
            ny: *ny,
        }),
        [SensorSpec::PointGrid { nx, ny, .. }] if *nx > 1 && *ny > 1 => Some(SensorGrid {
            kind: "point_grid",
            nx: *nx,
            ny: *ny,
        }),
        [SensorSpec::GaussianGrid { nx, ny, .. }] if *nx > 1 && *ny > 1 => Some(SensorGrid {
            kind: "gaussian_grid",
            nx: *nx,
            ny: *ny,
        }),
        _ => None,
    };
    Ok((out, desc, grid))
}

/// Built detectors and their descriptions.
pub type BuiltDetectors = (Vec<Detector>, Vec<EndpointInfo>);

/// The detectors of `[[sensors]]` when every entry is a `detector` (`None` when none is),
/// validated against `medium` with the index `outside_index` outside its faces (in which their
/// apertures are defined); an error naming the entry when detectors and other sensors are
/// mixed.
pub fn build_detectors<M: speckle_medium::Medium>(
    specs: &[SensorSpec],
    medium: &M,
    outside_index: f64,
) -> Result<Option<BuiltDetectors>, SceneError> {
    let is_detector = |s: &SensorSpec| matches!(s, SensorSpec::Detector { .. });
    if !specs.iter().any(is_detector) {
        return Ok(None);
    }
    if let Some(i) = specs.iter().position(|s| !is_detector(s)) {
        return Err(invalid(
            format!("sensors[{i}]"),
            "a scene's sensors are either all detectors or none: detectors read intensities \
             and temporal correlations, the other sensors fields",
        ));
    }
    if specs.len() > MAX_ENDPOINTS {
        return Err(invalid(
            "sensors",
            format!("more than {MAX_ENDPOINTS} sensors"),
        ));
    }
    if !(outside_index.is_finite() && outside_index >= 1.0) {
        return Err(invalid(
            "medium.host_index",
            format!(
                "must be finite and >= 1 with detectors (with an index-matched boundary it is \
                 the index outside the faces, in which their aperture is defined; got \
                 {outside_index})"
            ),
        ));
    }
    let (mut out, mut desc) = (Vec::new(), Vec::new());
    for (i, s) in specs.iter().enumerate() {
        let SensorSpec::Detector {
            position,
            radius,
            numerical_aperture,
            axis,
            weighting,
        } = s
        else {
            unreachable!("every entry is a detector");
        };
        let weighting = match weighting.unwrap_or(WeightingSpec::Flux) {
            WeightingSpec::Flux => Weighting::Flux,
            WeightingSpec::Fluence => Weighting::Fluence,
        };
        let (field, center) = (format!("sensors[{i}]"), DVec3::from_array(*position));
        let (na, axis) = (
            numerical_aperture.unwrap_or(outside_index),
            axis.map(DVec3::from_array),
        );
        let d = match radius {
            Some(r) => Detector::new(
                &field,
                medium,
                center,
                *r,
                na,
                axis,
                outside_index,
                weighting,
            )?,
            None => Detector::point(&field, medium, center, na, axis, outside_index, weighting)?,
        };
        desc.push(EndpointInfo {
            weighting: Some(match d.weighting() {
                Weighting::Flux => "flux",
                Weighting::Fluence => "fluence",
            }),
            ..EndpointInfo::disc(i, "detector", &d, d.axis())
        });
        out.push(d);
    }
    Ok(Some((out, desc)))
}

/// The fibre sources of `[[sources]]`, by entry (`None` for the other entries), validated
/// against `medium` with the index `outside_index` outside its faces, with their descriptions.
pub fn build_fibres<M: speckle_medium::Medium>(
    specs: &[SourceSpec],
    medium: &M,
    outside_index: f64,
) -> Result<Vec<Option<(Detector, EndpointInfo)>>, SceneError> {
    specs
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let SourceSpec::Fibre {
                position,
                radius,
                numerical_aperture,
                axis,
            } = s
            else {
                return Ok(None);
            };
            let f = Detector::fibre_source(
                &format!("sources[{i}]"),
                medium,
                DVec3::from_array(*position),
                *radius,
                numerical_aperture.unwrap_or(outside_index),
                axis.map(DVec3::from_array),
                outside_index,
            )?;
            let info = EndpointInfo::disc(i, "fibre", &f, -f.axis());
            Ok(Some((f, info)))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_frame_is_right_handed() {
        for c in [
            DVec3::Z,
            -DVec3::Z,
            DVec3::Y,
            DVec3::new(0.3, -0.2, 0.9).normalize(),
        ] {
            let (e1, e2) = grid_frame(c);
            assert!((e1.cross(e2) - c).length() < 1e-12, "{c}");
        }
        let (e1, e2) = grid_frame(DVec3::Z);
        assert!((e1 - DVec3::X).length() < 1e-15 && (e2 - DVec3::Y).length() < 1e-15);
    }
}
