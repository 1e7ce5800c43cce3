//! Refractive-index-mismatched faces (issue 25): slabs of index 1.4 in air against
//! adding-doubling (`iadpython`; `tests/data/iad_slab_n1.4.csv`, made by
//! `validation/iad/slab_reference.py`, accurate to about 1e-5).
//!
//! A plane wave of unit intensity at normal incidence on a slab (thickness 1, 100 x 100 wide),
//! two detectors of radius 20 centred on its faces (full aperture, flux): the readings are the
//! scattered reflectance and transmittance per unit incident irradiance, `R_scattered` and
//! `T_scattered` of the table (everything adding-doubling gives less the unscattered light,
//! which a path that starts at its first collision never carries). Eight rows, optical depths
//! 0.5 to 8, `g` 0 to 0.9, albedo 0.9 and 0.99, with and without the mismatch; every reading
//! within 4.5 standard errors, and each standard error under 2% of its value (measured: all
//! within 2.5, errors 0.3-1.8%). The mismatch matters far beyond the errors: at optical depth 8,
//! `g = 0.9`, albedo 0.99 the transmittance is 0.527 at n = 1.4 against 0.664 index-matched
//! (90 SE). The slab extends 30 thicknesses beyond the discs on every side, so its edges do not
//! show.
//!
//! Run time: about 15 s on two cores (release).

use speckle::endpoints::{Detector, Weighting};
use speckle::estimators::{CovarianceOptions, NoProgress, Scene, Source, render_detectors};
use speckle::medium::{Aabb, DVec3, HomogeneousBox, Interface};
use speckle::phase::Phase;

struct Row {
    n: f64,
    tau: f64,
    albedo: f64,
    g: f64,
    r: f64,
    t: f64,
}

fn table() -> Vec<Row> {
    let text = include_str!("data/iad_slab_n1.4.csv");
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (n, tau, a, g, r, t) = (
        col("n"),
        col("optical_thickness"),
        col("albedo"),
        col("g"),
        col("R_scattered"),
        col("T_scattered"),
    );
    lines
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.trim().parse().unwrap()).collect();
            Row {
                n: v[n],
                tau: v[tau],
                albedo: v[a],
                g: v[g],
                r: v[r],
                t: v[t],
            }
        })
        .collect()
}

#[test]
fn slab_reflectance_and_transmittance_match_adding_doubling() {
    let rows = table();
    assert_eq!(rows.len(), 36);
    let wanted = [
        (1.4, 0.5, 0.9, 0.0),
        (1.4, 0.5, 0.99, 0.9),
        (1.4, 2.0, 0.99, 0.5),
        (1.4, 2.0, 0.9, 0.9),
        (1.4, 8.0, 0.99, 0.9),
        (1.4, 8.0, 0.9, 0.0),
        (1.0, 2.0, 0.99, 0.0),
        (1.0, 8.0, 0.99, 0.9),
    ];
    let (half, radius) = (50.0, 20.0);
    for (n, tau, albedo, g) in wanted {
        let row = rows
            .iter()
            .find(|r| r.n == n && r.tau == tau && r.albedo == albedo && r.g == g)
            .unwrap();
        let b = Aabb::new(DVec3::new(-half, -half, 0.0), DVec3::new(half, half, 1.0)).unwrap();
        let m = HomogeneousBox::new(b, tau * albedo, tau * (1.0 - albedo)).unwrap();
        let detector = |z: f64| {
            Detector::new(
                "detector",
                &m,
                DVec3::new(0.0, 0.0, z),
                radius,
                1.0,
                None,
                1.0,
                Weighting::Flux,
            )
            .unwrap()
        };
        let detectors = vec![detector(0.0), detector(1.0)];
        let phase = if g == 0.0 {
            Phase::Isotropic
        } else {
            Phase::hg(g).unwrap()
        };
        let source = Source::plane_wave(DVec3::Z).unwrap();
        let mut scene =
            Scene::with_detectors(m, vec![phase], 1e-3, vec![source], detectors).unwrap();
        if n != 1.0 {
            scene = scene.with_interface(Interface::new(n, 1.0).unwrap());
        }
        let opts = CovarianceOptions {
            paths: 2_000_000,
            seed: 7,
            ..CovarianceOptions::default()
        };
        let est = render_detectors(&scene, None, &opts, &NoProgress)
            .unwrap()
            .unwrap();
        for (d, expect, what) in [(0, row.r, "R"), (1, row.t, "T")] {
            let (v, s) = est.total.get(d, 0);
            let z = (v.re - expect) / s.re;
            println!(
                "n {n}, tau {tau}, albedo {albedo}, g {g}: {what} {:.5} +- {:.5} against {expect:.5} ({z:+.2} SE)",
                v.re, s.re
            );
            assert!(
                s.re < 0.02 * expect,
                "{what}: unresolved {} +- {}",
                v.re,
                s.re
            );
            assert!(
                z.abs() < 4.5,
                "{what}: {} +- {} against {expect}",
                v.re,
                s.re
            );
        }
    }
}
