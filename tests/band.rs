//! Covariances of whole images in bounded memory (issue 29, item 3): the band of an image's
//! covariance (`render_covariance_band`) against the dense render of the same scene, seed and
//! paths.
//!
//! Scene: a slab 20 x 20 x 2 wavelengths (mean free path 4, HG 0.5) lit by a plane wave, a
//! 32 x 32 far-field image 1.25 degrees apart (about half the grain `lambda / W`), `J = 1024`.
//! Checked: every kept entry of the band (radius 3 px) equals the dense covariance's entry to
//! rounding (the dense render sums through rank-`K` blocks, the band entry by entry), with the
//! same standard errors; offsets that leave the image are NaN; the band's edge correlation is
//! the dense matrix's on that ring; and what the band drops is small: the dense matrix's mean
//! normalised correlation beyond the band is below the edge's. Measured: printed
//! (`cargo test --profile ci --test band -- --nocapture`).

use speckle::estimators::{
    CovarianceOptions, ImageBand, NoProgress, Pair, Scene, Sensor, Source, render_covariance,
    render_covariance_band,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::phase::Phase;

const N: usize = 32;

fn scene() -> Scene<HomogeneousBox, Phase> {
    let b = Aabb::centered(DVec3::ZERO, DVec3::new(20.0, 20.0, 2.0)).unwrap();
    let m = HomogeneousBox::from_mean_free_path(b, 4.0, 1.0).unwrap();
    let step = 1.25f64.to_radians();
    let sensors = (0..N * N)
        .map(|i| {
            let (y, x) = ((i / N) as f64 - 15.5, (i % N) as f64 - 15.5);
            Sensor::far_field(DVec3::new((x * step).tan(), (y * step).tan(), 1.0)).unwrap()
        })
        .collect();
    let sources = vec![Source::plane_wave(DVec3::Z).unwrap()];
    Scene::new(
        m,
        Phase::hg(0.5).unwrap(),
        1.0,
        sources,
        sensors,
        Pair::all(1, N * N),
    )
    .unwrap()
}

#[test]
fn the_band_is_the_dense_covariance_near_its_diagonal() {
    let s = scene();
    let options = CovarianceOptions {
        paths: 4000,
        seed: 5,
        ..Default::default()
    };
    let r = 3;
    let band = ImageBand::of(&s, N, N, r).unwrap();
    let t0 = std::time::Instant::now();
    let b = render_covariance_band(&s, &options, &band, &NoProgress).unwrap();
    let t_band = t0.elapsed();
    let t0 = std::time::Instant::now();
    let d = render_covariance(&s, &options, &NoProgress).unwrap().total;
    let t_dense = t0.elapsed();
    let w = 2 * r + 1;
    let (mut max_rel, mut bitwise, mut kept) = (0.0f64, 0usize, 0usize);
    let (mut ring, mut beyond, mut beyond_n) = (0.0f64, 0.0, 0usize);
    let rho = |p: usize, q: usize| {
        d.value.get(p, q).norm() / (d.value.get(p, p).re * d.value.get(q, q).re).sqrt()
    };
    for y in 0..N {
        for x in 0..N {
            let p = y * N + x;
            for dy in 0..w {
                for dx in 0..w {
                    let e = ((y * N + x) * w + dy) * w + dx;
                    let (yy, xx) = (
                        y as isize + dy as isize - r as isize,
                        x as isize + dx as isize - r as isize,
                    );
                    let inside = (0..N as isize).contains(&yy) && (0..N as isize).contains(&xx);
                    if !inside {
                        assert!(b.value[e].re.is_nan() && b.std_error[e].im.is_nan());
                        continue;
                    }
                    let q = yy as usize * N + xx as usize;
                    // The dense render stores the upper triangle.
                    let (dv, ds) = if q >= p {
                        (d.value.get(p, q), d.std_error.get(p, q))
                    } else {
                        (d.value.get(q, p).conj(), d.std_error.get(q, p))
                    };
                    let scale = d.value.get(p, p).re;
                    max_rel = max_rel.max((b.value[e] - dv).norm() / scale);
                    assert!((b.std_error[e] - ds).norm() <= 1e-9 * ds.norm() + 1e-15 * scale);
                    bitwise += usize::from(b.value[e] == dv);
                    kept += 1;
                    if dy == 0 || dx == 0 || dy == w - 1 || dx == w - 1 {
                        ring = ring.max(rho(p, q));
                    }
                }
            }
            // Beyond the band: offsets r + 1 to 2 r along x, in the image.
            for dx in r + 1..=2 * r {
                if x + dx < N {
                    beyond += rho(p, p + dx);
                    beyond_n += 1;
                }
            }
        }
    }
    let edge = b.edge_correlation();
    let mean = b.mean_correlation();
    let beyond = beyond / beyond_n as f64;
    println!(
        "J = {}: band of radius {r}: {kept} kept entries ({bitwise} bitwise equal to the dense \
         render's), largest difference {max_rel:.2e} of the intensity; edge correlation {edge:.3} \
         (dense ring {ring:.3}); mean correlation at offsets 0, 1, 2, 3 along x: {:.3} {:.3} \
         {:.3} {:.3}, beyond the band (4-6 px) {beyond:.3}; time band {t_band:.2?}, dense \
         {t_dense:.2?}",
        N * N,
        mean[r * w + r],
        mean[r * w + r + 1],
        mean[r * w + r + 2],
        mean[r * w + r + 3]
    );
    assert_eq!(kept, band.entries().len());
    assert!(max_rel < 1e-12, "kept entries differ by {max_rel:e}");
    assert!((edge - ring).abs() < 1e-9 * ring, "edge {edge} vs {ring}");
    assert!((mean[r * w + r] - 1.0).abs() < 1e-12);
    assert!(
        beyond < mean[r * w + 2 * r],
        "beyond {beyond} vs edge mean {}",
        mean[r * w + 2 * r]
    );
}

#[test]
fn bands_refuse_what_they_cannot_be() {
    let s = scene();
    let e = ImageBand::of(&s, N, N, N).unwrap_err().to_string();
    assert!(e.starts_with("band:"), "{e}");
    let e = ImageBand::of(&s, 16, N, 1).unwrap_err().to_string();
    assert!(e.starts_with("sensors:"), "{e}");
    let e = ImageBand::new(1, 1 << 14, 1 << 14, 8)
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("band:") && e.contains("exceed"), "{e}");
    let listed = Scene::new(
        s.medium().clone(),
        Phase::hg(0.5).unwrap(),
        1.0,
        s.sources().to_vec(),
        s.sensors().to_vec(),
        (0..N * N)
            .rev()
            .map(|v| Pair {
                source: 0,
                sensor: v,
            })
            .collect(),
    )
    .unwrap();
    let e = ImageBand::of(&listed, N, N, 1).unwrap_err().to_string();
    assert!(e.starts_with("pairs:"), "{e}");
}
