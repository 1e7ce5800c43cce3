//! Tests of the Mie series: published reference values (`references`), and limits,
//! identities and refusals (`properties`).

use super::series::{log_derivatives, log_derivatives_from, riccati_psi, riccati_psi_from};
use super::*;
use crate::PhaseFunction;
use crate::testing::gauss_legendre;

mod properties;
mod references;

fn c(re: f64, im: f64) -> Complex64 {
    Complex64::new(re, im)
}

fn sphere(x: f64, m: Complex64) -> MieSphere {
    MieSphere::from_size_parameter(x, m).unwrap()
}

/// Asserts that `computed` rounds to `printed`, a value published with `digits` significant
/// digits: `|computed - printed| <= 0.5` unit in the last printed digit (the factor 1.001
/// only absorbs this code's own rounding error at the boundary).
fn assert_printed(what: &str, computed: f64, printed: f64, digits: i32) {
    assert_printed_units(what, computed, printed, digits, 0.5);
}

/// As [`assert_printed`], within `units` units of the last printed digit.
fn assert_printed_units(what: &str, computed: f64, printed: f64, digits: i32, units: f64) {
    let ulp = if printed == 0.0 {
        10f64.powi(-digits)
    } else {
        10f64.powi(printed.abs().log10().floor() as i32 - (digits - 1))
    };
    let err = (computed - printed).abs();
    assert!(
        err <= (units + 5e-4) * ulp,
        "{what}: computed {computed:.9e}, published {printed:e} ({digits} digits): off by {:.2} units",
        err / ulp
    );
}

/// Asserts that `computed` matches a value printed with `decimals` decimals.
fn assert_decimals(what: &str, computed: f64, printed: f64, decimals: i32) {
    let ulp = 10f64.powi(-decimals);
    let err = (computed - printed).abs();
    assert!(
        err <= 0.5005 * ulp,
        "{what}: computed {computed:.7}, published {printed} ({decimals} decimals)"
    );
}

// ---------------------------------------------------------------------------------------
// Published reference values.
