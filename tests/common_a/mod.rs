//! Helpers shared by the statistical tests `single_scattering`, `intensity` and `backscatter`.
//!
//! These are independent re-implementations (box geometry, Henyey-Greenstein, Gauss-Legendre
//! nodes, direction frames), written from the formulas rather than from the library, so that
//! the references in the tests do not reuse the code they check.

#![allow(dead_code)]

use speckle::medium::DVec3;
use std::f64::consts::PI;

/// A closed axis-aligned box `[lo, hi]`.
#[derive(Debug, Clone, Copy)]
pub struct BoxGeom {
    /// Lower corner.
    pub lo: DVec3,
    /// Upper corner.
    pub hi: DVec3,
}

impl BoxGeom {
    /// A box of `size` centred on `center`.
    pub fn centered(center: DVec3, size: DVec3) -> Self {
        Self {
            lo: center - 0.5 * size,
            hi: center + 0.5 * size,
        }
    }

    /// Edge lengths.
    pub fn size(&self) -> DVec3 {
        self.hi - self.lo
    }

    /// Volume.
    pub fn volume(&self) -> f64 {
        let s = self.size();
        s.x * s.y * s.z
    }

    /// Distance from `x` (inside the box) to the boundary along the unit direction `d`.
    pub fn exit(&self, x: DVec3, d: DVec3) -> f64 {
        let mut t = f64::INFINITY;
        for a in 0..3 {
            let s = if d[a] > 0.0 {
                (self.hi[a] - x[a]) / d[a]
            } else if d[a] < 0.0 {
                (self.lo[a] - x[a]) / d[a]
            } else {
                f64::INFINITY
            };
            t = t.min(s);
        }
        t.max(0.0)
    }

    /// Length inside the box of the segment from `x` (inside) to `p` (outside). The box is
    /// convex, so the segment leaves it once and does not come back.
    pub fn inside_length_to(&self, x: DVec3, p: DVec3) -> f64 {
        let d = p - x;
        let r = d.length();
        self.exit(x, d / r).min(r)
    }
}

/// Henyey-Greenstein phase function `(1 - g^2) / (4 pi (1 + g^2 - 2 g mu)^(3/2))`.
pub fn hg_density(g: f64, mu: f64) -> f64 {
    (1.0 - g * g) / (4.0 * PI * (1.0 + g * g - 2.0 * g * mu).powf(1.5))
}

/// Henyey-Greenstein cosine from one uniform variate by inverting its CDF
/// `P(mu) = (1 - g^2) / (2 g) * ((1 + g^2 - 2 g mu)^(-1/2) - (1 + g)^(-1))`.
pub fn hg_sample_cos(g: f64, u: f64) -> f64 {
    if g.abs() < 1e-12 {
        return 2.0 * u - 1.0;
    }
    // Solve P(mu) = u for t = (1 + g^2 - 2 g mu)^(-1/2).
    let t = 2.0 * g * u / (1.0 - g * g) + 1.0 / (1.0 + g);
    ((1.0 + g * g - 1.0 / (t * t)) / (2.0 * g)).clamp(-1.0, 1.0)
}

/// Unit vector with polar angle `theta` from `axis_z` in the x-z plane: `(sin, 0, cos)`.
pub fn tilt_x(theta: f64) -> DVec3 {
    DVec3::new(theta.sin(), 0.0, theta.cos())
}

/// A direction with cosine `mu` to the unit vector `w` and azimuth `phi` around it.
pub fn rotate_about(w: DVec3, mu: f64, phi: f64) -> DVec3 {
    // Any vector not parallel to w, then Gram-Schmidt.
    let helper = if w.x.abs() < 0.6 { DVec3::X } else { DVec3::Y };
    let t = (helper - w * w.dot(helper)).normalize();
    let b = w.cross(t);
    let s = (1.0 - mu * mu).max(0.0).sqrt();
    (s * phi.cos()) * t + (s * phi.sin()) * b + mu * w
}

/// Gauss-Legendre nodes and weights on `[-1, 1]` (Newton iteration on `P_n`).
pub fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            // P_n(x) and P_n'(x) by the three-term recurrence.
            let (mut p0, mut p1) = (1.0, x);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            let pn = if n == 0 { 1.0 } else { p1 };
            let pm = if n == 1 { 1.0 } else { p0 };
            dp = n as f64 * (x * pn - pm) / (x * x - 1.0);
            let dx = pn / dp;
            x -= dx;
            if dx.abs() < 1e-16 {
                break;
            }
        }
        out.push((x, 2.0 / ((1.0 - x * x) * dp * dp)));
    }
    out
}

/// Composite Gauss-Legendre rule on `[a, b]` with `panels` equal panels of `order` nodes.
pub fn composite_rule(a: f64, b: f64, panels: usize, order: usize) -> Vec<(f64, f64)> {
    let gl = gauss_legendre(order);
    let h = (b - a) / panels as f64;
    let mut out = Vec::with_capacity(panels * order);
    for p in 0..panels {
        let c = a + h * (p as f64 + 0.5);
        for &(x, w) in &gl {
            out.push((c + 0.5 * h * x, 0.5 * h * w));
        }
    }
    out
}

/// Mean and standard error of the mean of per-sample values, from sums of values and squares.
pub fn mean_and_se(sum: f64, sum_sq: f64, n: u64) -> (f64, f64) {
    let n = n as f64;
    let mean = sum / n;
    let var = ((sum_sq - n * mean * mean) / (n - 1.0)).max(0.0);
    (mean, (var / n).sqrt())
}

#[test]
fn helpers_are_correct() {
    // Gauss-Legendre with 5 nodes integrates x^8 exactly: 2/9.
    let r = gauss_legendre(5);
    let s: f64 = r.iter().map(|(x, w)| w * x.powi(8)).sum();
    assert!((s - 2.0 / 9.0).abs() < 1e-14, "{s}");
    // HG is normalised with mean cosine g (fine composite rule in mu).
    for g in [0.0, 0.5, 0.6] {
        let rule = composite_rule(-1.0, 1.0, 200, 6);
        let m0: f64 = rule
            .iter()
            .map(|(m, w)| w * 2.0 * PI * hg_density(g, *m))
            .sum();
        let m1: f64 = rule
            .iter()
            .map(|(m, w)| w * 2.0 * PI * m * hg_density(g, *m))
            .sum();
        assert!(
            (m0 - 1.0).abs() < 1e-10 && (m1 - g).abs() < 1e-10,
            "{g}: {m0} {m1}"
        );
        // The sampler inverts the CDF: stratified samples reproduce the mean cosine g.
        let n = 200_000;
        let mean: f64 = (0..n)
            .map(|i| hg_sample_cos(g, (i as f64 + 0.5) / n as f64))
            .sum::<f64>()
            / n as f64;
        assert!((mean - g).abs() < 1e-6, "{g}: {mean}");
    }
    let b = BoxGeom::centered(DVec3::ZERO, DVec3::new(2.0, 4.0, 6.0));
    assert!((b.exit(DVec3::ZERO, DVec3::X) - 1.0).abs() < 1e-15);
    assert!((b.exit(DVec3::ZERO, -DVec3::Z) - 3.0).abs() < 1e-15);
    let d = DVec3::new(1.0, 1.0, 0.0).normalize();
    assert!((b.exit(DVec3::ZERO, d) - 2f64.sqrt()).abs() < 1e-14);
    let w = DVec3::new(0.3, -0.2, 0.9).normalize();
    let v = rotate_about(w, 0.4, 1.3);
    assert!((v.length() - 1.0).abs() < 1e-14 && (v.dot(w) - 0.4).abs() < 1e-14);
}
