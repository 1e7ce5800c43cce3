//! Limits (small particles, Rayleigh, large spheres), identities (optical theorem, energy),
//! the tables built from the amplitudes, and refusals naming the field.

use super::*;

#[test]
fn small_particle_series_of_the_coefficients() {
    // Bohren & Huffman (1983) small-x expansion of the coefficients (ch. 5, p. 131):
    //   a_1 = -i (2x^3/3) K - i (2x^5/5) (m^2 - 2)(m^2 - 1) / (m^2 + 2)^2 + (4x^6/9) K^2 + O(x^7),
    //   b_1 = -i x^5 (m^2 - 1) / 45 + O(x^7),  a_2 = -i x^5 (m^2 - 1) / (15 (2m^2 + 3)) + O(x^7),
    // K = (m^2 - 1) / (m^2 + 2). The remainders must shrink as x^7.
    let i = Complex64::I;
    for m in [
        c(1.5, 0.0),
        c(1.5, 0.1),
        c(1.33, 0.0),
        c(0.75, 0.0),
        c(10.0, 10.0),
    ] {
        let m2 = m * m;
        let k = (m2 - 1.0) / (m2 + 2.0);
        let mut previous: Option<f64> = None;
        for x in [1e-1, 1e-2, 1e-3] {
            let mie = sphere(x, m);
            let (a, b) = mie.coefficients();
            let x3 = x * x * x;
            let x5 = x3 * x * x;
            let a1 = -i * (2.0 * x3 / 3.0) * k
                - i * (2.0 * x5 / 5.0) * (m2 - 2.0) * (m2 - 1.0) / ((m2 + 2.0) * (m2 + 2.0))
                + (4.0 * x3 * x3 / 9.0) * k * k;
            let b1 = -i * x5 * (m2 - 1.0) / 45.0;
            let a2 = -i * x5 * (m2 - 1.0) / (15.0 * (2.0 * m2 + 3.0));
            let r = [(a[0] - a1).norm(), (b[0] - b1).norm(), (a[1] - a2).norm()]
                .into_iter()
                .fold(0.0, f64::max);
            let scaled = r / x.powi(7);
            assert!(
                scaled < 10.0 * m2.norm().powi(2),
                "m = {m}, x = {x}: remainder {r:e}"
            );
            if let Some(p) = previous {
                // Remainder / x^7 settles (does not grow as x falls): it is O(x^7).
                assert!(scaled < 1.5 * p + 1e-3, "m = {m}, x = {x}: {scaled} vs {p}");
            }
            previous = Some(scaled);
        }
    }
}

#[test]
fn rayleigh_limit_at_x_1e_3() {
    // Q_sca = (8/3) x^4 |K|^2 (1 + (6/5) x^2 Re((m^2 - 2)/(m^2 + 2)) + O(x^3)), from the series
    // above (|a_1|^2 dominates; b_1, a_2 enter at O(x^6) relative);
    // g = (9/4) x^2 [(2/135) Re(K conj(m^2 - 1)) + (2/45) Re(K conj((m^2-1)/(2m^2+3)))] / |K|^2
    // + O(x^4), from g Q_sca = (4/x^2)(3/2) Re(a_1 b_1* + a_1 a_2*) (BH p. 120).
    let x: f64 = 1e-3;
    for m in [
        c(1.5, 0.0),
        c(1.33, 0.0),
        c(1.5, 0.1),
        c(1.55, 1e-3),
        c(10.0, 10.0),
    ] {
        let mie = sphere(x, m);
        let m2 = m * m;
        let k = (m2 - 1.0) / (m2 + 2.0);
        let leading = 8.0 / 3.0 * x.powi(4) * k.norm_sqr();
        let correction = 1.2 * x * x * ((m2 - 2.0) / (m2 + 2.0)).re;
        let rel = mie.q_sca() / leading - 1.0;
        assert!(
            (rel - correction).abs() < 10.0 * x.powi(3),
            "m = {m}: {rel:e} vs {correction:e}"
        );
        // The correction itself is resolved: the leading term alone is off by ~x^2.
        assert!(mie.q_sca().is_finite() && mie.q_sca() > 0.0);
        let g = 2.25
            * x
            * x
            * ((2.0 / 135.0) * (k * (m2 - 1.0).conj()).re
                + (2.0 / 45.0) * (k * ((m2 - 1.0) / (2.0 * m2 + 3.0)).conj()).re)
            / k.norm_sqr();
        // The expansion is in x and |m| x: relative remainder O((|m| x)^2).
        let bound = 10.0 * (m.norm() * x).powi(2);
        assert!(
            (mie.asymmetry() / g - 1.0).abs() < bound,
            "m = {m}: g = {:e} vs {g:e}",
            mie.asymmetry()
        );
        // Q_abs = 4 x Im K (1 + O((|m| x)^2)) (BH Sec. 5.2).
        if m.im > 0.0 {
            let q_abs = 4.0 * x * k.im;
            assert!((mie.q_abs() / q_abs - 1.0).abs() < bound, "m = {m}");
        }
    }
    // x = 1e-6, the smallest supported size: still finite and Rayleigh.
    let mie = sphere(1e-6, c(1.5, 0.0));
    let k = (2.25 - 1.0) / (2.25 + 2.0);
    assert!((mie.q_sca() / (8.0 / 3.0 * 1e-24 * k * k) - 1.0).abs() < 1e-10);
    assert!(mie.asymmetry().abs() < 1e-12);
}

// ---------------------------------------------------------------------------------------
// Internal consistency.

/// Sizes and indices of the consistency tests.
fn consistency_cases() -> Vec<(f64, Complex64)> {
    let mut cases = Vec::new();
    for x in [0.3, 3.0, 10.0, 100.0, 1000.0] {
        for m in [
            c(1.5, 0.0),
            c(1.33, 0.0),
            c(1.5, 0.1),
            c(1.55, 1e-3),
            c(10.0, 10.0),
            c(1.0 + 1e-6, 0.0),
            c(0.75, 0.0),
        ] {
            cases.push((x, m));
        }
    }
    cases
}

#[test]
fn optical_theorem_and_backscatter_match_the_series() {
    for (x, m) in consistency_cases() {
        let mie = sphere(x, m);
        let (f1, f2) = mie.s1_s2(1.0);
        assert!((f1 - f2).norm() <= 1e-12 * f1.norm());
        // Optical theorem: Q_ext = (4 / x^2) Re S(0).
        let q = 4.0 / (x * x) * f1.re;
        assert!((q / mie.q_ext() - 1.0).abs() < 1e-12, "x = {x}, m = {m}");
        // S2(180) = -S1(180) and Q_back = 4 |S1(180)|^2 / x^2. The sums cancel down to
        // |S(180)| (3e-7 |S(0)| for m = 1 + 1e-6, x = 1000): compare |S1(180)| with the
        // series' sqrt(Q_back) x / 2 on the scale of the terms, |S(0)|.
        let (b1, b2) = mie.s1_s2(-1.0);
        assert!((b1 + b2).norm() <= 1e-12 * b1.norm());
        let d = b1.norm() - mie.q_back().sqrt() * x / 2.0;
        assert!(d.abs() < 1e-13 * f1.norm(), "x = {x}, m = {m}: {d:e}");
    }
}

#[test]
fn quadrature_of_the_amplitudes_matches_q_sca_and_g() {
    // |S1|^2 + |S2|^2 is a polynomial of degree 2N in mu, so Gauss-Legendre with N + 2 nodes
    // integrates it (and mu times it) exactly: Q_sca = (1/x^2) int (|S1|^2 + |S2|^2) dmu,
    // g Q_sca = (1/x^2) int mu (|S1|^2 + |S2|^2) dmu (BH Sec. 3.4).
    for (x, m) in consistency_cases() {
        if m.re == 1.0 + 1e-6 && x < 1.0 {
            continue; // Q_sca ~ 1e-15: the relative checks below are meaningless.
        }
        let mie = sphere(x, m);
        let (mut q, mut gq) = (0.0, 0.0);
        for (mu, w) in gauss_legendre(mie.terms() + 2) {
            let (s1, s2) = mie.s1_s2(mu);
            let i = s1.norm_sqr() + s2.norm_sqr();
            q += w * i;
            gq += w * mu * i;
        }
        q /= x * x;
        gq /= x * x;
        assert!(
            (q / mie.q_sca() - 1.0).abs() < 1e-10,
            "x = {x}, m = {m}: {q} vs {}",
            mie.q_sca()
        );
        assert!(
            (gq / q - mie.asymmetry()).abs() < 1e-10,
            "x = {x}, m = {m}: {} vs {}",
            gq / q,
            mie.asymmetry()
        );
    }
}

#[test]
fn real_index_conserves_energy_term_by_term() {
    // For real m every partial wave conserves energy: Re a_n = |a_n|^2, Re b_n = |b_n|^2,
    // hence Q_ext = Q_sca. This fails visibly if D_n or psi_n are off (e.g. with a
    // recurrence start too close to the turning point).
    for x in [0.01, 1.0, 30.0, 1000.0, 1e4, 2e4] {
        for m in [1.5, 1.33, 0.75, 1.0 + 1e-6, 3.0, 100.0] {
            let mie = sphere(x, c(m, 0.0));
            let (a, b) = mie.coefficients();
            for (n, (an, bn)) in a.iter().zip(b).enumerate() {
                assert!(
                    (an.re - an.norm_sqr()).abs() < 1e-12,
                    "x = {x}, m = {m}, a_{}",
                    n + 1
                );
                assert!(
                    (bn.re - bn.norm_sqr()).abs() < 1e-12,
                    "x = {x}, m = {m}, b_{}",
                    n + 1
                );
            }
            assert!(
                (mie.q_ext() / mie.q_sca() - 1.0).abs() < 1e-9,
                "x = {x}, m = {m}: {} vs {}",
                mie.q_ext(),
                mie.q_sca()
            );
            assert_eq!(mie.q_abs(), 0.0);
        }
    }
}

#[test]
fn absorbing_spheres_absorb() {
    for (x, m) in consistency_cases() {
        if m.im > 0.0 {
            let mie = sphere(x, m);
            assert!(
                mie.q_abs() > 0.0 && mie.q_abs() < mie.q_ext(),
                "x = {x}, m = {m}"
            );
            for (an, bn) in mie.a.iter().zip(&mie.b) {
                // 0 <= |a_n|^2 <= Re a_n for an absorbing sphere.
                assert!(an.norm_sqr() <= an.re + 1e-15 && bn.norm_sqr() <= bn.re + 1e-15);
            }
        }
    }
}

#[test]
fn recurrence_starts_are_converged() {
    // Starting the downward recurrences three times farther changes nothing.
    for z in [
        c(1500.0, 0.0),
        c(1.33e4, 0.0),
        c(3e4, 0.0),
        c(1.55e3, 1.55),
        c(1e5, 1e5),
        c(5.0, 0.0),
    ] {
        let n_max = MieSphere::terms_for(z.re.min(2e4));
        let d = log_derivatives(z, n_max);
        let far = log_derivatives_from(z, n_max, 3 * (n_max.max(z.norm() as usize)) + 100);
        for (n, (u, v)) in d.iter().zip(&far).enumerate() {
            assert!(
                (u - v).norm() <= 1e-13 * v.norm().max(1.0),
                "z = {z}, D_{n}: {u} vs {v}"
            );
        }
    }
    for x in [1e-6, 1e-3, 0.5, 7.0, 100.0, 2e4] {
        let n_max = MieSphere::terms_for(x);
        let psi = riccati_psi(x, n_max);
        let far = riccati_psi_from(x, n_max, 3 * n_max + 100);
        for (n, (u, v)) in psi.iter().zip(&far).enumerate() {
            assert!(
                (u - v).abs() <= 1e-13 * v.abs(),
                "x = {x}, psi_{n}: {u} vs {v}"
            );
        }
    }
    // psi_1 = sin x / x - cos x and psi_2 = (3/x^2 - 1) sin x - 3 cos x / x, by their series
    // for small x (the closed forms cancel) and directly for x = 2.
    let x: f64 = 1e-3;
    let psi = riccati_psi(x, 2);
    let x2 = x * x;
    assert!((psi[1] / (x2 / 3.0 * (1.0 - x2 / 10.0)) - 1.0).abs() < 1e-13);
    assert!((psi[2] / (x * x2 / 15.0 * (1.0 - x2 / 14.0)) - 1.0).abs() < 1e-13);
    let x: f64 = 2.0;
    let psi = riccati_psi(x, 5);
    assert!((psi[1] - (x.sin() / x - x.cos())).abs() < 1e-15);
    assert!((psi[2] - ((3.0 / (x * x) - 1.0) * x.sin() - 3.0 * x.cos() / x)).abs() < 1e-15);
}

#[test]
fn large_spheres_are_finite_and_extinction_tends_to_two() {
    // Extinction paradox: Q_ext -> 2 for x -> infinity; the approach is ~ x^(-2/3)
    // (van de Hulst 1957, Sec. 17.2; Nussenzveig & Wiscombe 1980).
    for m in [c(1.5, 0.0), c(1.33, 0.0), c(1.5, 0.1), c(10.0, 10.0)] {
        for x in [1e3, 1e4, 2e4] {
            let mie = sphere(x, m);
            let values = [mie.q_ext(), mie.q_sca(), mie.q_back(), mie.asymmetry()];
            assert!(
                values.iter().all(|v| v.is_finite()),
                "x = {x}, m = {m}: {values:?}"
            );
            assert!(
                (mie.q_ext() - 2.0).abs() < 3.0 * x.powf(-2.0 / 3.0),
                "x = {x}, m = {m}: Q_ext = {}",
                mie.q_ext()
            );
            assert!(mie.asymmetry() > 0.5 && mie.asymmetry() < 1.0);
            let (s1, s2) = mie.s1_s2(0.3);
            assert!(s1.re.is_finite() && s2.im.is_finite());
        }
    }
}

#[test]
fn physical_constructor_scales_lengths() {
    // Polystyrene (n = 1.59) in water (n = 1.33), radius 0.5 um, lambda0 = 0.633 um.
    let m = c(1.59 / 1.33, 0.0);
    let mie = MieSphere::new(0.5, m, 1.33, 0.633).unwrap();
    let x = 2.0 * PI * 1.33 * 0.5 / 0.633;
    assert!((mie.size_parameter() - x).abs() < 1e-12);
    assert!((mie.wavenumber() - 2.0 * PI * 1.33 / 0.633).abs() < 1e-12);
    let unit = sphere(x, m);
    assert!((mie.q_sca() - unit.q_sca()).abs() < 1e-14);
    assert!((mie.c_sca() - PI * 0.25 * mie.q_sca()).abs() < 1e-14);
    assert!((mie.c_ext() - mie.c_sca() - mie.c_abs()).abs() < 1e-14);
    assert!((mie.c_back() - PI * 0.25 * mie.q_back()).abs() < 1e-14);
    assert!((unit.c_sca() - PI * x * x * unit.q_sca()).abs() < 1e-12);
    assert_eq!(mie.terms(), MieSphere::terms_for(x));
    assert_eq!(mie.relative_index(), m);
    assert_eq!(mie.radius(), 0.5);
    // |f|^2 integrates to C_sca (unit of the constructor: um^2).
    let mut total = 0.0;
    for (mu, w) in gauss_legendre(mie.terms() + 2) {
        total += 2.0 * PI * w * mie.unpolarized_amplitude(mu).norm_sqr();
    }
    assert!((total / mie.c_sca() - 1.0).abs() < 1e-12);
}

// ---------------------------------------------------------------------------------------
// The scalar amplitude table.

#[test]
fn scalar_amplitude_phase_and_backscatter_limit() {
    for (x, m) in [
        (3.0, c(1.5, 0.0)),
        (50.0, c(1.33, 0.01)),
        (7.0, c(10.0, 10.0)),
    ] {
        let mie = sphere(x, m);
        for mu in [-0.7, 0.0, 0.4, 1.0] {
            let (s1, s2) = mie.s1_s2(mu);
            let f = mie.unpolarized_amplitude(mu);
            assert!(
                (f.norm_sqr() - 0.5 * (s1.norm_sqr() + s2.norm_sqr())).abs() < 1e-12 * f.norm_sqr()
            );
            // arg f = arg(i (S1 + S2)).
            let d = (f * (Complex64::I * (s1 + s2)).conj()).arg();
            assert!(d.abs() < 1e-12, "x = {x}, m = {m}, mu = {mu}");
        }
        // At mu = -1, S1 + S2 = 0; the phase is the limit from mu > -1.
        let back = mie.unpolarized_amplitude(-1.0);
        let near = mie.unpolarized_amplitude(-1.0 + 1e-9);
        assert!(
            (back / back.norm() - near / near.norm()).norm() < 1e-6,
            "x = {x}, m = {m}"
        );
        let (s1, _) = mie.s1_s2(-1.0);
        assert!((back.norm() - s1.norm()).abs() < 1e-12 * s1.norm());
    }
}

#[test]
fn table_is_normalised_and_its_mean_cosine_is_g() {
    for (x, m) in [
        (0.5, c(1.5, 0.0)),
        (5.0, c(1.33, 0.0)),
        (10.0, c(1.5, 0.0)),
        (10.0, c(1.5, 0.1)),
        (100.0, c(1.5, 0.0)),
        (100.0, c(1.55, 1e-3)),
        (300.0, c(10.0, 10.0)),
        (30.0, c(3.0, 0.0)),
        (100.0, c(0.75, 0.0)),
        (1000.0, c(1.5, 0.0)),
    ] {
        let mie = sphere(x, m);
        let n = mie.recommended_angles();
        let table = mie.to_tabulated(n).unwrap();
        assert_eq!(table.len(), n);
        // The table is piecewise linear in mu between the nodes cos(pi j / (n - 1)): the
        // trapezoid rule over those nodes integrates it exactly.
        let last = n - 1;
        let nodes: Vec<f64> = (0..n)
            .map(|j| -(PI * j as f64 / last as f64).cos())
            .collect();
        let (mut m0, mut m1) = (0.0, 0.0);
        for w in nodes.windows(2) {
            let (a, b) = (w[0], w[1]);
            let (ra, rb) = (table.density(a), table.density(b));
            m0 += 2.0 * PI * (b - a) * 0.5 * (ra + rb);
            m1 += 2.0 * PI * (b - a) * (ra * (2.0 * a + b) + rb * (a + 2.0 * b)) / 6.0;
        }
        assert!((m0 - 1.0).abs() < 1e-9, "x = {x}, m = {m}: norm {m0}");
        assert!((m1 - table.mean_cosine()).abs() < 1e-9);
        let dg = table.mean_cosine() - mie.asymmetry();
        assert!(dg.abs() < 1e-4, "x = {x}, m = {m}: table g off by {dg:e}");
        let dn = table.input_norm() / mie.c_sca() - 1.0;
        assert!(dn.abs() < 5e-4, "x = {x}, m = {m}: C_sca off by {dn:e}");
        // Node values are the normalised scalar amplitude f / sqrt(C_sca).
        for j in [0, n / 3, n - 2, n - 1] {
            let mu = nodes[j];
            let s = table.amplitude(mu);
            let f = mie.unpolarized_amplitude(mu) / table.input_norm().sqrt();
            assert!(
                (s - f).norm() < 1e-9 * f.norm(),
                "x = {x}, m = {m}, node {j}"
            );
        }
    }
}

#[test]
fn rayleigh_table_is_dipolar() {
    // x << 1: rho ~ (1 + mu^2), g ~ 0, constant phase.
    let mie = sphere(1e-3, c(1.5, 0.0));
    let table = mie.to_tabulated(721).unwrap();
    assert!(table.mean_cosine().abs() < 1e-6);
    assert!((table.density(1.0) / table.density(0.0) - 2.0).abs() < 1e-5);
    // rho = 3 (1 + mu^2) / (16 pi).
    assert!((table.density(1.0) - 3.0 / (8.0 * PI)).abs() < 1e-5);
    let p = (table.amplitude(0.3) / table.amplitude(-0.8)).arg();
    assert!(p.abs() < 1e-5);
}

// ---------------------------------------------------------------------------------------
// Invalid input.

fn message(r: Result<MieSphere, PhaseError>) -> String {
    match r {
        Err(PhaseError::InvalidMie(m)) => m,
        other => panic!("expected an InvalidMie error, got {other:?}"),
    }
}

#[test]
fn invalid_inputs_name_the_field() {
    let m = c(1.5, 0.0);
    let cases: Vec<(Result<MieSphere, PhaseError>, &str)> = vec![
        (MieSphere::new(f64::NAN, m, 1.0, 0.5), "radius"),
        (MieSphere::new(0.0, m, 1.0, 0.5), "radius"),
        (MieSphere::new(-1.0, m, 1.0, 0.5), "radius"),
        (MieSphere::new(f64::INFINITY, m, 1.0, 0.5), "radius"),
        (
            MieSphere::new(1.0, c(1.5, -0.1), 1.0, 0.5),
            "relative_index: imaginary",
        ),
        (
            MieSphere::new(1.0, c(f64::NAN, 0.0), 1.0, 0.5),
            "relative_index: real",
        ),
        (
            MieSphere::new(1.0, c(1.5, f64::NAN), 1.0, 0.5),
            "relative_index: imaginary",
        ),
        (
            MieSphere::new(1.0, c(0.0, 1.0), 1.0, 0.5),
            "relative_index: real",
        ),
        (
            MieSphere::new(1.0, c(-1.5, 0.0), 1.0, 0.5),
            "relative_index: real",
        ),
        (
            MieSphere::new(1.0, c(800.0, 800.0), 1.0, 0.5),
            "relative_index: |m|",
        ),
        (MieSphere::new(1.0, m, f64::NAN, 0.5), "host_index"),
        (MieSphere::new(1.0, m, 0.0, 0.5), "host_index"),
        (MieSphere::new(1.0, m, 1.0, f64::INFINITY), "wavelength"),
        (MieSphere::new(1.0, m, 1.0, -0.5), "wavelength"),
        (MieSphere::new(1e-9, m, 1.0, 0.5), "size parameter"),
        (MieSphere::new(1e4, m, 1.0, 0.5), "size parameter"),
        (MieSphere::new(1e-300, m, 1.0, 1e300), "size parameter"),
        (
            MieSphere::from_size_parameter(f64::NAN, m),
            "size_parameter",
        ),
        (MieSphere::from_size_parameter(1e-7, m), "size_parameter"),
        (MieSphere::from_size_parameter(3e4, m), "size_parameter"),
        (MieSphere::from_size_parameter(-1.0, m), "size_parameter"),
        (
            MieSphere::from_size_parameter(1.0, c(1.5, -1e-12)),
            "relative_index",
        ),
    ];
    for (r, field) in cases {
        let msg = message(r);
        assert!(msg.starts_with(field), "{msg:?} should name {field:?}");
    }
    // Display carries the prefix.
    let e = MieSphere::new(f64::NAN, m, 1.0, 0.5).unwrap_err();
    assert!(e.to_string().starts_with("Mie sphere: radius:"), "{e}");
    // The limits themselves are accepted.
    assert!(MieSphere::from_size_parameter(MIE_MIN_SIZE_PARAMETER, m).is_ok());
    assert!(MieSphere::from_size_parameter(1.0, c(1000.0, 0.0)).is_ok());
    let mie = sphere(2.0, m);
    for n in [0, 1, MIE_MAX_TABLE_ANGLES + 1] {
        match mie.to_tabulated(n) {
            Err(PhaseError::InvalidMie(msg)) => assert!(msg.starts_with("n_angles"), "{msg}"),
            other => panic!("n_angles = {n}: {other:?}"),
        }
    }
    assert!(mie.to_tabulated(2).is_ok());
    // Outside [-1, 1] the amplitudes are NaN, not a clamped value.
    for mu in [f64::NAN, 1.0 + 1e-12, -2.0] {
        let (s1, s2) = mie.s1_s2(mu);
        assert!(s1.re.is_nan() && s2.im.is_nan());
        assert!(mie.unpolarized_amplitude(mu).re.is_nan());
    }
}

#[test]
fn a_sphere_matching_its_host_does_not_scatter() {
    let mie = sphere(10.0, c(1.0, 0.0));
    assert_eq!(mie.q_sca(), 0.0);
    assert_eq!(mie.q_ext(), 0.0);
    assert_eq!(mie.asymmetry(), 0.0);
    match mie.to_tabulated(100) {
        Err(PhaseError::InvalidMie(msg)) => assert!(msg.starts_with("relative_index")),
        other => panic!("{other:?}"),
    }
}
