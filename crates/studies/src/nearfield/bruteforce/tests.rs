use super::*;

const GOOD: &str = "size = [16.0, 6.0]\nmean_free_path = 12.0\nconcentration = 50.0\n\
                    focus_depth = 0.5\nsource_offset = 1.0\nsensor_shift = 0.75\n";

fn load(text: &str) -> Result<BruteForceStudy, LoadError> {
    load_bruteforce_str(text, "t.toml", "t", &StudyOverrides::default())
}

fn refused(text: &str, field: &str) {
    let e = load(text).unwrap_err().to_string();
    assert!(e.contains(field), "{field} not named: {e}");
}

#[test]
fn bad_input_names_the_field() {
    assert!(load(GOOD).is_ok());
    refused(&GOOD.replace("12.0", "-1.0"), "mean_free_path");
    refused(&GOOD.replace("50.0", "0.5"), "concentration");
    refused(&GOOD.replace("0.75", "9.0"), "sensor_shift");
    refused(
        &GOOD.replace("focus_depth = 0.5", "focus_depth = 3.5"),
        "focus_depth",
    );
    refused(&format!("{GOOD}nodes = 4\n"), "nodes");
    refused(&format!("{GOOD}nodes = 30\n"), "binary_nodes");
    refused(&format!("{GOOD}binary_nodes = 19\n"), "binary_nodes");
    refused(&format!("{GOOD}theta_max = 4.0\n"), "theta_max");
    refused(&format!("{GOOD}theta_max = 1.6\n"), "theta_max");
    refused(
        &format!("{GOOD}[render]\nbiased_paths = 40000\n"),
        "render.biased_paths",
    );
    refused(
        &format!("{GOOD}[render]\nchunk = 100000000\n"),
        "render.chunk",
    );
    refused(
        &format!("{GOOD}[render]\nnear_paths = 1\n"),
        "render.near_paths",
    );
    refused(
        &format!("{GOOD}[render]\npaths = 18446744073709551615\n"),
        "render.paths",
    );
    refused(&format!("{GOOD}colour = 1\n"), "colour");
    refused("size = [16.0, 6.0]\n", "mean_free_path");
}

#[test]
fn the_binary_half_width_has_the_apodized_second_moment() {
    // Over the whole circle the apodized mask is the von Mises density, whose E[sin^2 t] is
    // (1 - I_2 / I_0) / 2 = I_1(gamma) / (gamma I_0(gamma)) (I_0 - I_2 = 2 I_1 / gamma);
    // theta_max = 1.5 cuts the mask at e^(-46) of its peak (gamma = 50).
    for gamma in [50.0, 1e4] {
        let a = binary_half_width(gamma, 1.5);
        let want = speckle_vmf::bessel_ratio_over_z(Complex64::new(gamma, 0.0)).re;
        let got = 0.5 - (2.0 * a).sin() / (4.0 * a);
        assert!(
            (got / want - 1.0).abs() < 1e-10,
            "gamma {gamma}: {got} against {want}"
        );
        // Small angles: 1/2 - sin(2a) / (4a) = a^2 / 3 - a^4 / 15 + ... and I_1 / (gamma
        // I_0) = (1 - 1 / (2 gamma) + ...) / gamma, so sin a = sqrt(3 / gamma) (1 + O(a^2)).
        let small = (3.0 / gamma).sqrt();
        let tol = if gamma > 100.0 { 1e-3 } else { 0.05 };
        assert!(
            (a.sin() / small - 1.0).abs() < tol,
            "gamma {gamma}: a = {a}"
        );
    }
    // The shipped study's: the binary aperture lies inside the quadrature's range.
    let s = load(GOOD).unwrap();
    let a = s.binary_half_width();
    let nodes = s.aperture(DVec3::Y);
    let inside = nodes.iter().filter(|n| n.binary > 0.0).count();
    assert_eq!(inside, s.file.binary_nodes);
    for n in &nodes {
        let t = n.dir.x.atan2(n.dir.y).abs();
        assert!(n.binary == 0.0 || t < a, "binary weight at {t} beyond {a}");
    }
    let sum = |f: fn(&Node) -> f64| nodes.iter().map(f).sum::<f64>();
    assert!((sum(|n| n.binary) - 1.0).abs() < 1e-14);
    assert!((sum(|n| n.apodized) - 1.0).abs() < 1e-14);
}

#[test]
fn axial_attenuation_attenuates_each_plane_wave_along_its_apertures_axis() {
    use speckle_endpoints::Endpoints;
    let s = load(GOOD).unwrap();
    let (k, st) = (s.k(), 1.0 / s.file.mean_free_path);
    let plain = s.medium().unwrap();
    let axial = AxialAttenuation {
        inner: s.medium().unwrap(),
        axis: DVec3::Y,
    };
    // The box spans y in [-3, 3]; from x a plane wave about +y comes from y = -3, a sensor
    // about +y reads towards y = +3, one about -y towards y = -3.
    let x = DVec3::new(1.3, -0.4, 0.0);
    let (w_s, w_t, w_r) = (
        rotate(DVec3::Y, 0.3),
        rotate(DVec3::Y, -0.5),
        rotate(-DVec3::Y, 0.2),
    );
    let src = [Source::plane_wave(w_s).unwrap()];
    let sen = [
        Sensor::far_field(w_t).unwrap(),
        Sensor::far_field(w_r).unwrap(),
    ];
    let want = [
        (0.5 * st * (x.y + 3.0), k * w_s.dot(x)),
        (0.5 * st * (3.0 - x.y), -k * w_t.dot(x)),
        (0.5 * st * (x.y + 3.0), -k * w_r.dot(x)),
    ];
    fn legs<M: Medium>(m: &M, k: f64, x: DVec3, src: &[Source], sen: &[Sensor]) -> Vec<Complex64> {
        let (a, b) = (Endpoints::sources(m, k, src), Endpoints::sensors(m, k, sen));
        let (mut la, mut lb) = (a.legs(), b.legs());
        a.connect(x, &mut la);
        b.connect(x, &mut lb);
        vec![la.amp(0), lb.amp(0), lb.amp(1)]
    }
    let got = legs(&axial, k, x, &src, &sen);
    for (g, (tau, phase)) in got.iter().zip(want) {
        let w = Complex64::from_polar((-tau).exp(), phase);
        assert!((g - w).norm() < 1e-12, "{g} against {w}");
    }
    // In the box itself the oblique legs are attenuated along their own directions, longer.
    let own = legs(&plain, k, x, &src, &sen);
    for (o, g) in own.iter().zip(&got) {
        assert!(o.norm() < g.norm() * (1.0 - 1e-3), "{o} against {g}");
    }
}

#[test]
fn the_shipped_study_loads() {
    let text = include_str!("../../../../../scenes/fig7_bruteforce.toml");
    let s = load(text).unwrap();
    assert_eq!(s.name, "fig7_bruteforce");
    assert_eq!(s.chunk_seed(2), 1002);
}

#[test]
fn the_command_line_replaces_paths_and_seed() {
    let o = StudyOverrides {
        paths: Some(64),
        seed: Some(5),
        ..Default::default()
    };
    let s = load_bruteforce_str(GOOD, "t.toml", "t", &o).unwrap();
    assert_eq!((s.file.render.paths, s.file.render.seed), (64, 5));
    assert_eq!(s.chunk_seed(3), derive_seed(5, 1) + 3);
}
