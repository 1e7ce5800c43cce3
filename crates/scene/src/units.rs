//! The units a scene declares for its numbers (`units = { length = "cm", time = "s" }`).
//!
//! The numbers of a scene are in one length unit (that of `wavelength`) and one time unit (that
//! of `motion.lags`, `D` in length^2 per time unit); the project never converts them. Declaring
//! the units names them in the JSON sidecars (`units.length`, `units.time`, and `derived.units`,
//! which the Python bindings return too) and lets the plots label their axes with SI prefixes
//! (`20 us` rather than `0.00002`).

use crate::SceneError;
use crate::schema::UnitsSpec;
use crate::validate::invalid;
use serde_json::{Value, json};

/// A declared unit: its symbol and its value in the SI base unit (metre or second).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Unit {
    /// The symbol as written (`"cm"`).
    pub symbol: &'static str,
    /// The SI base symbol (`"m"` or `"s"`).
    pub base: &'static str,
    /// One unit in the base unit (`0.01` for cm).
    pub scale: f64,
}

/// The lengths a scene may declare.
pub const LENGTHS: [(&str, f64); 5] = [
    ("m", 1.0),
    ("cm", 1e-2),
    ("mm", 1e-3),
    ("um", 1e-6),
    ("nm", 1e-9),
];

/// The times a scene may declare.
pub const TIMES: [(&str, f64); 4] = [("s", 1.0), ("ms", 1e-3), ("us", 1e-6), ("ns", 1e-9)];

/// The validated `units` of a scene (each `None` when not declared).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Units {
    /// The length unit.
    pub length: Option<Unit>,
    /// The time unit.
    pub time: Option<Unit>,
}

impl Units {
    /// Validates `units` (errors name `units.length` or `units.time` and list the choices).
    pub fn build(spec: Option<&UnitsSpec>) -> Result<Self, SceneError> {
        let Some(spec) = spec else {
            return Ok(Self::default());
        };
        let find = |field: &str, value: &Option<String>, table: &[(&'static str, f64)], base| {
            let Some(v) = value else {
                return Ok(None);
            };
            match table.iter().find(|(s, _)| *s == v.as_str()) {
                Some(&(symbol, scale)) => Ok(Some(Unit {
                    symbol,
                    base,
                    scale,
                })),
                None => Err(invalid(
                    field,
                    format!(
                        "must be one of {} (got {:?})",
                        table
                            .iter()
                            .map(|(s, _)| format!("\"{s}\""))
                            .collect::<Vec<_>>()
                            .join(", "),
                        crate::safe::printable(v)
                    ),
                )),
            }
        };
        Ok(Self {
            length: find("units.length", &spec.length, &LENGTHS, "m")?,
            time: find("units.time", &spec.time, &TIMES, "s")?,
        })
    }

    /// The units as JSON: `{ "length": "cm" | null, "time": "s" | null }`.
    pub fn json(&self) -> Value {
        json!({
            "length": self.length.map(|u| u.symbol),
            "time": self.time.map(|u| u.symbol),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn declared_units_and_bad_ones_naming_the_field() {
        let spec = UnitsSpec {
            length: Some("cm".into()),
            time: Some("s".into()),
        };
        let u = Units::build(Some(&spec)).unwrap();
        assert_eq!(u.length.unwrap().scale, 1e-2);
        assert_eq!(u.time.unwrap().base, "s");
        assert_eq!(u.json(), json!({"length": "cm", "time": "s"}));
        assert_eq!(Units::build(None).unwrap(), Units::default());
        let bad = UnitsSpec {
            length: Some("furlong".into()),
            time: None,
        };
        let e = Units::build(Some(&bad)).unwrap_err().to_string();
        assert!(e.starts_with("units.length") && e.contains("\"cm\""), "{e}");
        let bad = UnitsSpec {
            length: None,
            time: Some("sec".into()),
        };
        let e = Units::build(Some(&bad)).unwrap_err().to_string();
        assert!(e.starts_with("units.time"), "{e}");
    }
}
