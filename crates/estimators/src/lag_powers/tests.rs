use super::kernels::exp_neg;
use super::*;
use num_complex::Complex64;
use speckle_stats::BatchSum;

#[test]
fn powers_are_the_exponentials_to_rounding_and_stop_before_subnormals() {
    for (lags, x) in [
        ((1..=64).map(|m| m as f64 * 0.05).collect::<Vec<_>>(), 0.03),
        // Bases either side of the least whose 57th power is above `TINY` (`1.2e-5`).
        ((1..=64).map(|m| m as f64 * 0.05).collect(), 10.9),
        ((1..=64).map(|m| m as f64 * 0.05).collect(), 11.7),
        (vec![0.0, 0.4, -0.8, 1.2, 2.0, 0.4], 1.2),
        (vec![0.1, 0.7, 0.3], 69.0),
        (vec![0.0, 2e-7, 5e-7, 1e-6, 1.5e-5], 1e-3),
    ] {
        let p = Powers::of(&lags).unwrap();
        let mut s = PowerSums::new(&p, 2);
        s.add(&[(1, Complex64::new(2.0, -1.0), x)]);
        let mut sums = vec![
            BatchSum::new(
                speckle_stats::Layout::GeneralDiagonal,
                2,
                &Default::default()
            );
            lags.len()
        ];
        let mut buf = vec![Complex64::ZERO; 2];
        s.flush(&mut sums, |l| l, &mut buf);
        for (l, sum) in sums.into_iter().enumerate() {
            let got = sum.finish();
            let m = (lags[l].abs() / p.delta).round() as i32;
            let want = if lags[l] == 0.0 {
                Complex64::ZERO
            } else {
                Complex64::new(2.0, -1.0) * (-m as f64 * x).exp()
            };
            assert_eq!(got[0], Complex64::ZERO);
            // An ulp of `r` is `m` ulps of `r^m`, and the products add a few; the
            // reference `exp(-m x)` carries the rounding of `m x` (relative `m x eps / 2`).
            let tol = if want.norm() < 1e-250 {
                1e-250
            } else {
                ((m + 16) as f64 * 2.0 + m as f64 * x / 2.0) * f64::EPSILON * want.norm()
            };
            assert!(
                (got[1] - want).norm() <= tol,
                "lag {l}: {} vs {want}",
                got[1]
            );
            assert!(got[1].re == 0.0 || got[1].re.abs() >= f64::MIN_POSITIVE);
        }
    }
}

/// Every instruction set gives bitwise the same sums: the dispatched loops against the
/// plain (one lane) ones, on regular and gathered lags and on multi-tau grids (segments, also
/// with lags of equal `|t|` and a gap that is not a multiple of the one before), with powers
/// that underflow part of the way.
#[test]
fn every_instruction_set_gives_the_same_sums() {
    let mut odd = multi_tau(false);
    odd.extend([-odd[20], odd[63] + 100.0 * odd[1]]);
    for lags in [
        (1..=64).map(|m| m as f64 * 0.05).collect::<Vec<_>>(),
        (1..=100).map(|m| m as f64 * 0.05).collect(),
        vec![
            0.0, 2e-7, 5e-7, 1e-6, 2e-6, 3e-6, 4e-6, 5e-6, 6e-6, 8e-6, 1e-5,
        ],
        multi_tau(false),
        multi_tau(true),
        odd,
    ] {
        let p = Powers::of(&lags).unwrap();
        let (mut fast, mut plain) = (PowerSums::new(&p, 3), PowerSums::new(&p, 3));
        plain.arch = pulp::Arch::Scalar;
        let terms: Vec<_> = (0..40)
            .map(|i| {
                let x = [1e-3, 0.1, 0.7, 6.9, 92.0][i % 5] * (1.0 + 1e-3 * i as f64);
                let z = Complex64::new(1.0 + i as f64, if i % 3 == 0 { 0.0 } else { -0.5 });
                (i % 3, z, x)
            })
            .collect();
        fast.add(&terms);
        plain.add(&terms);
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&fast.re), bits(&plain.re));
        assert_eq!(bits(&fast.im), bits(&plain.im));
        assert!(fast.re.iter().any(|x| *x != 0.0));
    }
}

/// [`exp_neg`] against the library's `exp`: within 2 ulps over the range, exact at zero,
/// zero past 700.
#[test]
fn exponentials_are_within_two_ulps() {
    let mut worst: f64 = 0.0;
    for i in 0..200_000 {
        let x = 700.0 * (i as f64 / 200_000.0).powi(3);
        let (got, want) = (exp_neg(x), (-x).exp());
        worst = worst.max((got - want).abs() / (want * f64::EPSILON));
    }
    assert!(worst <= 2.0, "{worst} ulps");
    assert_eq!(exp_neg(0.0), 1.0);
    assert_eq!(exp_neg(700.5), 0.0);
    assert_eq!(exp_neg(f64::INFINITY), 0.0);
}

/// Terms held while their exponent repeats ([`PowerSums::add_held`]) give the sums of
/// [`PowerSums::add`] to rounding, and a flush releases what is held.
#[test]
fn held_terms_give_the_same_sums() {
    let lags: Vec<f64> = (0..40).map(|m| m as f64 * 0.1).collect();
    let p = Powers::of(&lags).unwrap();
    let terms: Vec<_> = (0..30)
        .map(|i| {
            let x = if i % 7 == 6 {
                0.3
            } else {
                0.01 * (1 + i % 2) as f64
            };
            (i % 2, Complex64::new(1.0 + i as f64, 0.1 * i as f64), x)
        })
        .collect();
    let flushed = |held: bool| {
        let mut s = PowerSums::new(&p, 2);
        for chunk in terms.chunks(4) {
            if held {
                s.add_held(chunk);
            } else {
                s.add(chunk);
            }
        }
        let mut sums = vec![
            BatchSum::new(
                speckle_stats::Layout::GeneralDiagonal,
                2,
                &Default::default()
            );
            lags.len()
        ];
        s.flush(&mut sums, |l| l, &mut [Complex64::ZERO; 2]);
        sums.into_iter().map(|b| b.finish()).collect::<Vec<_>>()
    };
    let (a, b) = (flushed(true), flushed(false));
    for (l, (x, y)) in a.iter().zip(&b).enumerate().skip(1) {
        for e in 0..2 {
            assert!(y[e].norm() > 1.0, "lag {l}");
            assert!(
                (x[e] - y[e]).norm() <= 1e-14 * y[e].norm(),
                "lag {l}: {x:?} {y:?}"
            );
        }
    }
}

/// The terms of slot sums' tests: `entries` entries of three combinations, over several
/// vertices, with bases from near one to ones that underflow within the lags.
fn slot_terms(entries: usize, vertices: usize) -> Vec<Vec<(usize, usize, f64, f64)>> {
    (0..vertices)
        .map(|v| {
            let mut terms = Vec::new();
            for e in 0..entries {
                for c in 0..3 {
                    let i = (v * entries + e) * 3 + c;
                    let x = [1e-3, 0.1, 0.7, 6.9, 92.0, 2e-3, 0.3][i % 7] * (1.0 + 1e-3 * i as f64);
                    // Some combinations left out (not set) and some negative.
                    if i % 11 != 4 {
                        terms.push((e, c, (1.0 + i as f64) * if c == 1 { -0.3 } else { 1.0 }, x));
                    }
                }
            }
            terms
        })
        .collect()
}

/// Slot sums after flushing, per lag and entry.
fn slot_sums(
    lags: &[f64],
    entries: usize,
    arch: Option<pulp::Arch>,
    terms: &[Vec<(usize, usize, f64, f64)>],
) -> Vec<Vec<Complex64>> {
    let p = Powers::of(lags).unwrap();
    let mut s = SlotSums::new(&p, entries, 3);
    if let Some(a) = arch {
        s.arch = a;
    }
    for vertex in terms {
        let mut t = s.terms();
        for &(e, c, z, x) in vertex {
            t.set(e, c, z, x);
        }
        s.add();
    }
    let layout = speckle_stats::Layout::GeneralDiagonal;
    let mut sums = vec![BatchSum::new(layout, entries, &Default::default()); lags.len()];
    let mut buf = vec![Complex64::ZERO; entries];
    s.flush(&mut sums, |l| l, &mut buf);
    sums.into_iter().map(|b| b.finish()).collect()
}

/// Slot sums are `sum z exp(-m x)` to rounding (each power `m` products, each sum a few
/// dozen terms of either sign: the tolerance is `(m + 16) eps` of the sum of the terms'
/// magnitudes, plus the reference's own rounding of `m x`), with powers below `TINY` left
/// out, on regular lags, gathered lags (with a zero lag and two lags of equal `|t|`), for
/// many entries (vector lanes) and for few (the [`PowerSums`] route).
#[test]
fn slot_sums_are_the_exponentials_to_rounding() {
    let regular: Vec<f64> = (1..=64).map(|m| m as f64 * 0.05).collect();
    let gathered = vec![0.0, 0.4, -0.8, 1.2, 2.0, 0.4, 6.0];
    // (37 and 42 entries: blocks of eight lanes four at a time on wide vectors, then the
    // rest.)
    for (lags, entries) in [
        (&regular, 11),
        (&gathered, 9),
        (&regular, 37),
        (&gathered, 42),
        (&regular, 2),
        (&gathered, 1),
    ] {
        let p = Powers::of(lags).unwrap();
        let terms = slot_terms(entries, 3);
        let got = slot_sums(lags, entries, None, &terms);
        for (l, (t, row)) in lags.iter().zip(&got).enumerate() {
            let m = (t.abs() / p.delta).round();
            for (e, g) in row.iter().enumerate() {
                let (mut want, mut size, mut cond) = (0.0, 0.0, 0.0);
                for &(_, _, z, x) in terms.iter().flatten().filter(|t| t.0 == e) {
                    let v = if *t == 0.0 { 0.0 } else { z * (-m * x).exp() };
                    if v.abs() >= PowerSums::TINY {
                        want += v;
                        size += v.abs();
                        cond += v.abs() * m * x / 2.0;
                    }
                }
                let tol = ((m + 16.0) * size + cond) * f64::EPSILON + 1e-250;
                assert_eq!(g.im, 0.0);
                assert!(
                    (g.re - want).abs() <= tol,
                    "lag {l}, entry {e} of {entries}: {} vs {want} (tolerance {tol:e})",
                    g.re
                );
            }
        }
    }
}

/// Slot sums on every instruction set are bitwise the plain (one lane) loops', on regular
/// and gathered lags, on multi-tau grids (exact and rounded: the twin sums) and on a rounded
/// grid (its gaps' Taylor polynomials).
#[test]
fn slot_sums_are_the_same_on_every_instruction_set() {
    let regular: Vec<f64> = (1..=64).map(|m| m as f64 * 0.05).collect();
    let gathered = vec![0.0, 0.4, -0.8, 1.2, 2.0, 0.4, 6.0];
    let grids = [
        regular,
        gathered,
        multi_tau(false),
        multi_tau(true),
        seven_digits(),
    ];
    // (19 entries: three blocks, two at a time and one; 45: six, four at a time on wide
    // vectors and two.)
    for (lags, entries) in grids.iter().flat_map(|g| [(g, 19), (g, 45)]) {
        let terms = slot_terms(entries, 4);
        let fast = slot_sums(lags, entries, None, &terms);
        let plain = slot_sums(lags, entries, Some(pulp::Arch::Scalar), &terms);
        let bits = |v: &[Vec<Complex64>]| {
            v.iter()
                .flatten()
                .map(|z| (z.re.to_bits(), z.im.to_bits()))
                .collect::<Vec<_>>()
        };
        assert_eq!(bits(&fast), bits(&plain));
        assert!(fast.iter().flatten().any(|z| z.re != 0.0));
    }
}

#[test]
fn irregular_lags_take_no_powers() {
    assert!(Powers::of(&[0.1, 0.1 * std::f64::consts::PI]).is_none());
    assert!(Powers::of(&[0.0]).is_none());
    assert!(Powers::of(&[0.1, 100.0]).is_none());
    assert!(Powers::of(&[0.1, 0.1 + 1e-4]).is_none());
    assert!(Powers::of(&[0.1, 0.3 * (1.0 + 2e-5)]).is_none());
    // Within rounding: a second sum at the stretched step.
    let p = Powers::of(&[0.1, 0.1 + 1e-9]).unwrap();
    assert!((p.eta - 1e-8).abs() < 1e-12 && p.rounding[0] == 0.0);
    assert_eq!(Powers::of(&[0.1, 0.3]).unwrap().eta, 0.0);
}

/// A lag grid written to seven significant digits (`i 2e-5 / 63`, as a correlator gives it):
/// `|t| = m delta (1 + eps)`, `|eps|` up to `3.7e-7` (the step, the first lag, is rounded too).
fn seven_digits() -> Vec<f64> {
    (0..=64)
        .map(|i| format!("{:.6e}", i as f64 * 2e-5 / 63.0).parse().unwrap())
        .collect()
}

/// Checks power sums of two entries at `lags` against `sum z exp(-x |t| / delta)`, to the
/// rounding of powers (`m + 16` ulps, and the reference's rounding of `m x`) plus the rounding
/// interpolation's bound `0.54 eta^2` of the terms' weights.
fn check_power_sums(lags: &[f64], xs: &[f64], eta: f64) {
    let p = Powers::of(lags).unwrap();
    let z = Complex64::new(2.0, -1.0);
    let mut s = PowerSums::new(&p, 2);
    for &x in xs {
        s.add(&[(1, z, x)]);
    }
    let layout = speckle_stats::Layout::GeneralDiagonal;
    let mut sums = vec![BatchSum::new(layout, 2, &Default::default()); lags.len()];
    let mut buf = vec![Complex64::ZERO; 2];
    s.flush(&mut sums, |l| l, &mut buf);
    let x_max = xs.iter().copied().fold(0.0, f64::max);
    for (l, sum) in sums.into_iter().enumerate() {
        let got = sum.finish()[1];
        let u = lags[l] / p.delta;
        let (mut want, mut size, mut weights) = (Complex64::ZERO, 0.0, 0.0);
        for &x in xs {
            let v = z * (-u * x).exp();
            if lags[l] != 0.0 && v.norm() >= PowerSums::TINY {
                want += v;
                size += v.norm();
                weights += z.norm();
            }
        }
        let tol = ((u + 16.0) * 2.0 + u * x_max / 2.0) * f64::EPSILON * size
            + 0.54 * eta * eta * weights
            + 1e-250;
        assert!((got - want).norm() <= tol, "lag {l}: {got} vs {want}");
    }
}

/// [`check_power_sums`] for slot sums of `entries` entries, with `slack` (relative to the terms'
/// weights) in place of the interpolation's bound.
fn check_slot_sums(lags: &[f64], entries: usize, slack: f64) {
    let p = Powers::of(lags).unwrap();
    let terms = slot_terms(entries, 3);
    let got = slot_sums(lags, entries, None, &terms);
    for (l, (t, row)) in lags.iter().zip(&got).enumerate() {
        let u = t / p.delta;
        for (e, g) in row.iter().enumerate() {
            let (mut want, mut size, mut cond, mut weights) = (0.0, 0.0, 0.0, 0.0);
            for &(_, _, z, x) in terms.iter().flatten().filter(|t| t.0 == e) {
                let v = if *t == 0.0 { 0.0 } else { z * (-u * x).exp() };
                if v.abs() >= PowerSums::TINY {
                    want += v;
                    size += v.abs();
                    cond += v.abs() * u * x / 2.0;
                    weights += z.abs();
                }
            }
            let tol = ((u + 16.0) * size + cond) * f64::EPSILON + slack * weights + 1e-250;
            assert!(
                (g.re - want).abs() <= tol,
                "lag {l}, entry {e} of {entries}: {} vs {want} (tolerance {tol:e})",
                g.re
            );
        }
    }
}

/// Lags that are multiples of one step only to within their rounding take powers of the step,
/// and the interpolation between the sums at the step and at the stretched step gives
/// `sum z exp(-x |t| / delta)` at each lag's own `|t|` to within the powers' rounding and
/// `0.54 eta^2 = 7.3e-14` of the terms' weights `|z|` (the interpolation's bound): power sums
/// (two entries) and slot sums of two entries (the power sums' route; slot sums of more take
/// their own gaps, [`rounded_lags_take_their_own_gaps`]). Taking the nearest multiple instead
/// is off by up to `3.7e-7 m x` of the terms' values.
#[test]
fn rounded_lags_are_interpolated_between_two_steps() {
    let lags = seven_digits();
    let p = Powers::of(&lags).unwrap();
    assert!(p.eta != 0.0 && p.eta.abs() < 6e-7, "{}", p.eta);
    assert_eq!(p.order.len(), 64);
    check_power_sums(&lags, &[1e-3, 0.02, 0.3, 2.5], p.eta);
    check_slot_sums(&lags, 2, 0.54 * p.eta * p.eta);
}

/// Slot sums of lags that are multiples of one step only to within their rounding take each
/// lag's gap from the one before as its own multiplier (five distinct gaps on the seven-digit
/// grid, one of them whole): `sum z exp(-x |t| / delta)` at each lag's own `|t|` to within the
/// powers' rounding and the shared gaps' bound `0.37 SAME m_max = 4.2e-14` of the terms'
/// weights, without the interpolation's slack; terms whose powers underflow included (their
/// factors as exponentials). A rounded multi-tau grid, of more distinct gaps, interpolates.
#[test]
fn rounded_lags_take_their_own_gaps() {
    use super::slots::{Gap, gaps_of};
    let lags = seven_digits();
    let p = Powers::of(&lags).unwrap();
    let (_, kinds) = gaps_of(&p).expect("gaps lag by lag");
    assert_eq!(kinds.len(), 5, "{kinds:?}");
    assert_eq!(kinds[0], Gap::Whole(1));
    assert!(
        kinds[1..]
            .iter()
            .all(|k| matches!(k, Gap::Real(1, d) if d.abs() < 4e-5))
    );
    for entries in [11, 37] {
        check_slot_sums(&lags, entries, 0.37 * 8.0 * f64::EPSILON * 64.0);
    }
    assert!(gaps_of(&Powers::of(&multi_tau(true)).unwrap()).is_none());
    assert!(gaps_of(&Powers::of(&multi_tau(false)).unwrap()).is_some());
}

/// A multi-tau grid: eight lags per level, the step doubling per level, 63 non-zero lags up
/// to 1912 steps (and, with `digits`, each lag written to seven significant digits).
fn multi_tau(digits: bool) -> Vec<f64> {
    let mut lags = vec![0.0];
    let (mut m, mut step) = (0, 1);
    while lags.len() < 64 {
        for _ in 0..8 {
            if lags.len() < 64 {
                m += step;
                let t = m as f64 * 3e-7 / 7.0;
                lags.push(if digits {
                    format!("{t:.6e}").parse().unwrap()
                } else {
                    t
                });
            }
        }
        step *= 2;
    }
    lags
}

/// A multi-tau grid is split into runs of equally spaced steps, one per level
/// ([`Powers::runs`]), and the sums are `sum z exp(-x |t| / delta)` at every lag to the
/// rounding of powers (`m + 16` ulps: the runs' bases are chained by squaring), plus, for
/// rounded lags, the interpolation's bound `0.54 eta^2` of the weights (`eta` the largest
/// rounding within a run): power sums and slot sums (eleven entries).
#[test]
fn multi_tau_lags_take_runs_of_their_own_steps() {
    for digits in [false, true] {
        let lags = multi_tau(digits);
        let p = Powers::of(&lags).unwrap();
        let runs = p.runs().expect("runs");
        assert_eq!(runs.len(), 8, "one run per level");
        let eta = runs.iter().map(|r| r.2.eta.abs()).fold(0.0, f64::max);
        assert!(digits == (eta > 0.0) && eta < 1e-5, "{eta}");
        check_power_sums(&lags, &[1e-4, 3e-3, 0.05, 0.9], eta);
        for entries in [11, 37] {
            check_slot_sums(&lags, entries, 0.54 * eta * eta);
        }
    }
}

/// A multi-tau grid with a lag of equal `|t|` (a zero gap) and a last gap that is not a
/// multiple of the one before: power sums (segments) and slot sums are still the exponentials
/// to the rounding of powers.
#[test]
fn sparse_grids_with_odd_gaps_are_the_exponentials() {
    let mut lags = multi_tau(false);
    lags.extend([lags[20], lags[63] + 100.0 * lags[1]]);
    let p = Powers::of(&lags).unwrap();
    assert!(p.runs().is_some() && p.eta == 0.0);
    check_power_sums(&lags, &[1e-4, 3e-3, 0.05, 0.9], 0.0);
    check_slot_sums(&lags, 11, 0.0);
}

/// A lane of a term whose powers underflow at once (`x = 1e200`: its rounded gaps' polynomial
/// arguments far outside their range) leaves the slot sums finite: its own term adds nothing
/// and its neighbours' sums are the exponentials.
#[test]
fn huge_exponents_leave_rounded_slot_sums_finite() {
    let lags = seven_digits();
    let terms = vec![vec![
        (0, 0, 1.0, 1e200),
        (1, 0, 2.0, 0.1),
        (2, 1, 1.0, 1e200),
    ]];
    let got = slot_sums(&lags, 11, None, &terms);
    let p = Powers::of(&lags).unwrap();
    for (t, row) in lags.iter().zip(&got).skip(1) {
        assert!(row.iter().all(|z| z.re.is_finite()), "{row:?}");
        assert_eq!(row[0].re, 0.0);
        let want = 2.0 * (-0.1 * t / p.delta).exp();
        assert!(
            (row[1].re - want).abs() <= 1e-13 * want,
            "{} vs {want}",
            row[1].re
        );
    }
}
