//! Checks of single values, each returning a [`SceneError`] that names the field: the one set of
//! messages every input of the workspace uses (scene files, study files, tool options).

use crate::SceneError;
use speckle_medium::{DVec3, Dimension};
use std::fmt::Display;

/// A [`SceneError::InvalidInput`] naming `field`.
pub fn invalid(field: impl Display, reason: impl Display) -> SceneError {
    SceneError::InvalidInput {
        field: field.to_string(),
        reason: reason.to_string(),
    }
}

/// `v` if finite and > 0.
pub fn positive(field: impl Display, v: f64) -> Result<f64, SceneError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(invalid(field, format!("must be finite and > 0 (got {v})")))
    }
}

/// `v` if finite and >= 0.
pub fn non_negative(field: impl Display, v: f64) -> Result<f64, SceneError> {
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err(invalid(field, format!("must be finite and >= 0 (got {v})")))
    }
}

/// `v` if finite.
pub fn finite(field: impl Display, v: f64) -> Result<f64, SceneError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(invalid(field, format!("must be finite (got {v})")))
    }
}

/// Longest output prefix: file names add at most about 50 characters to it
/// (`.wave.r12345.s123.png`, `.cov_multiple.npy`), within the 255 bytes file systems allow.
pub const MAX_NAME_CHARS: usize = 200;

/// An output prefix: non-empty, at most [`MAX_NAME_CHARS`] characters, not starting with `.`,
/// letters, digits, `_`, `-` and `.` only (so that it names files in the output directory and
/// nowhere else).
pub fn name(name: &str) -> Result<(), SceneError> {
    if name.len() > MAX_NAME_CHARS {
        return Err(invalid(
            "name",
            format!(
                "has {} characters, more than {MAX_NAME_CHARS}: the output files' names would be \
                 longer than file systems allow",
                name.chars().count()
            ),
        ));
    }
    let ok = !name.is_empty()
        && !name.starts_with('.')
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.'));
    if ok {
        Ok(())
    } else {
        Err(invalid(
            "name",
            format!(
                "must be non-empty, not start with '.', and use only letters, digits, '_', '-' \
                 and '.' (got \"{}\")",
                crate::safe::excerpt(name)
            ),
        ))
    }
}

/// `x` as a message shows it: as Rust writes it when of ordinary size, in exponent form when
/// it is very large or very small (a length of 1e300 written out has 300 digits).
pub fn number(x: f64) -> String {
    if x != 0.0 && x.is_finite() && !(1e-4..1e6).contains(&x.abs()) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

/// A vector of finite components (`field[i]` names a bad one).
pub fn vec3(field: &str, v: [f64; 3]) -> Result<DVec3, SceneError> {
    for (i, c) in v.iter().enumerate() {
        finite(format!("{field}[{i}]"), *c)?;
    }
    Ok(DVec3::from_array(v))
}

/// The smallest non-zero component of a direction, relative to its length.
pub const MIN_COMPONENT: f64 = 1e-100;

/// The index of a component of the unit vector `u` that is not zero but below
/// [`MIN_COMPONENT`]: such a component makes differences of directions whose squares underflow,
/// and NaN results.
fn negligible_component(u: DVec3) -> Option<usize> {
    (0..3).find(|&i| u[i] != 0.0 && u[i].abs() < MIN_COMPONENT)
}

/// A finite non-zero vector, normalised; a non-zero component below [`MIN_COMPONENT`] of its
/// length is refused.
pub fn direction(field: &str, v: [f64; 3]) -> Result<DVec3, SceneError> {
    let d = vec3(field, v)?;
    let len = d.length();
    if len > 0.0 && len.is_finite() {
        // Refused, not rounded to 0 behind the user's back.
        if let Some(i) = negligible_component(d / len) {
            return Err(invalid(
                format!("{field}[{i}]"),
                format!(
                    "{:e} is not zero but negligible beside the vector's length {len:e} (below \
                     {MIN_COMPONENT:e} of it), so products of it underflow; write 0",
                    v[i]
                ),
            ));
        }
        Ok(d / len)
    } else {
        Err(invalid(
            field,
            format!("must be a non-zero vector (got {v:?})"),
        ))
    }
}

/// A direction that a generator (tilts, far grids, far arcs) computed from the angle in `field`:
/// refused, naming that field, when it is not a finite unit vector (an angle such as 1e300
/// degrees) or a component is not zero but below [`MIN_COMPONENT`] (an angle such as 1e-300
/// degrees).
pub fn generated_direction(field: &str, angle_deg: f64, u: DVec3) -> Result<DVec3, SceneError> {
    if !u.is_finite() || u == DVec3::ZERO {
        return Err(invalid(
            field,
            format!(
                "{angle_deg:e} degrees gives no direction (its sine and cosine are lost at this \
                 size); use an angle of ordinary size"
            ),
        ));
    }
    match negligible_component(u) {
        None => Ok(u),
        Some(i) => Err(invalid(
            field,
            format!(
                "{angle_deg:e} degrees gives a direction whose component {i} is {:e}: not zero \
                 but below {MIN_COMPONENT:e}, so products of it underflow; use 0 or an angle of \
                 ordinary size",
                u[i]
            ),
        )),
    }
}

/// `v` after checking that it lies in the plane `z = 0` when `dim` is flatland.
pub fn planar(field: &str, v: DVec3, dim: Dimension) -> Result<DVec3, SceneError> {
    if dim == Dimension::Two && v.z != 0.0 {
        return Err(invalid(
            format!("{field}[2]"),
            format!(
                "must be 0 in flatland (dimension = 2): everything lies in the plane z = 0 \
                 (got {})",
                v.z
            ),
        ));
    }
    Ok(v)
}

/// A finite position, in the plane `z = 0` in flatland.
pub fn position(field: &str, v: [f64; 3], dim: Dimension) -> Result<DVec3, SceneError> {
    planar(field, vec3(field, v)?, dim)
}

/// A unit direction, in the plane `z = 0` in flatland.
pub fn flat_direction(field: &str, v: [f64; 3], dim: Dimension) -> Result<DVec3, SceneError> {
    planar(field, vec3(field, v)?, dim)?;
    direction(field, v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_name_the_field() {
        assert_eq!(
            positive("medium.mean_free_path", -1.0)
                .unwrap_err()
                .to_string(),
            "medium.mean_free_path: must be finite and > 0 (got -1)"
        );
        assert_eq!(
            direction("sources[2].direction", [0.0; 3])
                .unwrap_err()
                .to_string(),
            "sources[2].direction: must be a non-zero vector (got [0.0, 0.0, 0.0])"
        );
        assert!(
            vec3("d", [0.0, f64::NAN, 1.0])
                .unwrap_err()
                .to_string()
                .starts_with("d[1]: must be finite")
        );
        assert!(name("a-b_c.d").is_ok());
        for bad in ["", ".x", "a/b", "a b"] {
            assert!(name(bad).is_err(), "{bad:?}");
        }
        let flat = planar("p", DVec3::new(0.0, 1.0, 0.5), Dimension::Two).unwrap_err();
        assert!(flat.to_string().starts_with("p[2]: must be 0 in flatland"));
    }
}
