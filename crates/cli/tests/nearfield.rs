//! End to end: the path-traced commands render scenes with Gaussian-beam sources and sensors
//! (near-field connections, Bar et al. 2020); the speckle mean written beside them is NaN for
//! beam pairs, with a warning; the commands that do not take beams exit with
//! code 2 naming the endpoint.

mod common;
use common::*;

const SCENE: &str = include_str!("../../fuzz/corpus/gaussian_beams_isotropic.toml");

#[test]
fn covariance_and_intensity_render_gaussian_beams() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "g.toml", SCENE);
    let s = scene.to_str().unwrap();
    for command in ["covariance", "intensity"] {
        let o = speckle(dir.path(), &[command, s, "--out", "out", "-q", "--no-png"]);
        assert!(o.status.success(), "{command}: {}", stderr(&o));
        if command == "covariance" {
            // The NaN means are announced.
            let e = stderr(&o);
            assert!(
                e.contains("gaussian_beam endpoint is not implemented"),
                "{e}"
            );
        }
    }
    let out = dir.path().join("out");
    let cov = npy_f64(&out.join("gaussian_beams_isotropic.cov.npy"));
    let intensity = npy_f64(&out.join("gaussian_beams_isotropic.intensity.npy"));
    // J = 2 pairs: a 2 x 2 complex covariance whose diagonal is the intensity, bitwise.
    assert_eq!((cov.len(), intensity.len()), (8, 2));
    for j in 0..2 {
        assert_eq!(
            cov[2 * (3 * j)].to_bits(),
            intensity[j].to_bits(),
            "pair {j}"
        );
        assert!(intensity[j] > 0.0 && intensity[j].is_finite());
    }
    let mean = npy_f64(&out.join("gaussian_beams_isotropic.mean.npy"));
    assert!(mean.iter().all(|m| m.is_nan()), "{mean:?}");
    for command in ["fields", "mean", "g1"] {
        let o = speckle(dir.path(), &[command, s, "-q"]);
        assert_eq!(o.status.code(), Some(2), "{command}: {}", stderr(&o));
        let e = stderr(&o);
        assert!(
            e.contains("sources[0]") || e.contains("sensors[0]") || e.contains("motion"),
            "{command}: {e}"
        );
    }
}
