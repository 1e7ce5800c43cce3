//! The far-field mean's integral over the box (see the parent module's docs, "Which legs are
//! attenuated" and "Evaluation"): the composite Gauss-Legendre face quadrature and the
//! closed-form depth integrals of one or both legs.

use glam::DVec3;
use num_complex::Complex64;

const GL4: [(f64, f64); 4] = [
    (-0.861_136_311_594_052_6, 0.347_854_845_137_453_9),
    (-0.339_981_043_584_856_3, 0.652_145_154_862_546_1),
    (0.339_981_043_584_856_3, 0.652_145_154_862_546_1),
    (0.861_136_311_594_052_6, 0.347_854_845_137_453_9),
];

/// `int_box e^{ik (i - v).x} T(x) dx` with the legs `T` of the parent module docs: `tau_out` on the
/// part of the box whose sensor leg exits through a face the incident wave does not enter,
/// `tau_in tau_out` where it exits through a face the incident wave enters. See
/// [`box_integral_refined`].
#[cfg(test)]
pub(super) fn box_integral(
    b: &speckle_medium::Aabb,
    k: f64,
    sigma_t: f64,
    i: DVec3,
    v: DVec3,
) -> Complex64 {
    box_integral_refined(b, k, sigma_t, i, v, 1, &|| false).expect("never cancelled")
}

/// [`box_integral`] with `refine` times the panels per axis (tests estimate the quadrature error
/// by halving the panel width). Each point is written `x = y - t v` with `y` on the face where
/// the ray along `v` exits, `dx = |n . v| dy dt`; the `t` integral is closed form. For a
/// flatland rectangle the zero `z` extent gets a one-point rule of weight 1, which turns the face
/// integrals into edge integrals.
pub(super) fn box_integral_refined(
    b: &speckle_medium::Aabb,
    k: f64,
    sigma_t: f64,
    i: DVec3,
    v: DVec3,
    refine: usize,
    cancelled: &dyn Fn() -> bool,
) -> Option<Complex64> {
    let q = i - v;
    // alpha = sigma_t / 2 + i k q.v: int_0^T e^{-alpha t} dt = (1 - e^{-alpha T}) / alpha.
    let alpha = Complex64::new(0.5 * sigma_t, k * q.dot(v));
    let g = |t: f64| {
        if alpha.norm() * t < 1e-8 {
            Complex64::new(t, 0.0)
        } else {
            (Complex64::new(1.0, 0.0) - (-alpha * t).exp()) / alpha
        }
    };
    let (lo, hi) = (b.min(), b.max());
    let mut total = Complex64::new(0.0, 0.0);
    for axis in 0..3 {
        let vn = v[axis];
        if vn == 0.0 {
            continue;
        }
        let plane = if vn > 0.0 { hi[axis] } else { lo[axis] };
        // The incident wave enters through this face (i . n_F < 0): reflection, both legs.
        let both_legs = i[axis] * vn < 0.0;
        let (a1, a2) = ((axis + 1) % 3, (axis + 2) % 3);
        let rule = |a: usize| -> Vec<(f64, f64)> {
            let ext = hi[a] - lo[a];
            if ext == 0.0 {
                return vec![(lo[a], 1.0)];
            }
            let rate = k * q.length() + sigma_t;
            let n = ((ext * rate).ceil() as usize).clamp(48, 512) * refine;
            let h = ext / n as f64;
            (0..n)
                .flat_map(|p| {
                    GL4.iter()
                        .map(move |&(x, w)| (lo[a] + h * (p as f64 + 0.5 + 0.5 * x), 0.5 * h * w))
                })
                .collect()
        };
        let (r1, r2) = (rule(a1), rule(a2));
        let mut face = Complex64::new(0.0, 0.0);
        for &(c1, w1) in &r1 {
            if cancelled() {
                return None;
            }
            for &(c2, w2) in &r2 {
                let mut y = DVec3::ZERO;
                y[axis] = plane;
                y[a1] = c1;
                y[a2] = c2;
                let t = b.exit_distance(y, -v);
                let legs = if both_legs {
                    two_leg_integral(b, sigma_t, alpha, i, v, y, t)
                } else {
                    g(t)
                };
                face += Complex64::from_polar(w1 * w2, k * q.dot(y)) * legs;
            }
        }
        total += face * vn.abs();
    }
    Some(total)
}

/// `int_0^T e^{-alpha t} e^{-sigma_t d_in(y - t v) / 2} dt`, `alpha = sigma_t / 2 + i k q.v`,
/// `d_in(x)` the distance from `x` to the boundary along `-i`.
///
/// Along the segment, `d_in(y - t v) = min_a (c_a + s_a t)` over the axes `a` with `i_a != 0`:
/// the boundary plane of axis `a` behind `x` (at `lo_a` when `i_a > 0`, `hi_a` when `i_a < 0`)
/// is at distance `c_a = (y_a - lo_a) / i_a` or `(hi_a - y_a) / (-i_a)` from `y`, and
/// `s_a = -v_a / i_a` in both cases. On a piece `[t0, t1]` where line `a` is the minimum, the
/// integrand is `e^{-alpha t0 - sigma_t d_in(t0) / 2} e^{-beta (t - t0)}` with
/// `beta = alpha + sigma_t s_a / 2`, integrated in closed form ([`exp_integral`]).
fn two_leg_integral(
    b: &speckle_medium::Aabb,
    sigma_t: f64,
    alpha: Complex64,
    i: DVec3,
    v: DVec3,
    y: DVec3,
    t_exit: f64,
) -> Complex64 {
    let (lo, hi) = (b.min(), b.max());
    let mut lines = [(0.0, 0.0); 3];
    let mut nl = 0;
    for a in 0..3 {
        // A component below 1e-12 counts as parallel to the face: its distance, above 1e12
        // times the point's offset from the plane, passes every other line's within the box
        // except in a sliver of relative width 1e-12, and computed it would carry an error of
        // 1e-16 times itself (1e5 box sizes for i_a = 1e-19), which made NaN and 1e196 means.
        let c = if i[a] > PARALLEL {
            (y[a] - lo[a]) / i[a]
        } else if i[a] < -PARALLEL {
            (hi[a] - y[a]) / -i[a]
        } else {
            continue;
        };
        lines[nl] = (c.max(0.0), -v[a] / i[a]);
        nl += 1;
    }
    let lines = &lines[..nl];
    // Breakpoints: 0, T and every crossing of two lines inside (0, T).
    let mut cuts = [0.0; 5];
    let mut nc = 0;
    for (m, &(cm, sm)) in lines.iter().enumerate() {
        for &(cn, sn) in &lines[m + 1..] {
            if sm != sn {
                let t = (cn - cm) / (sm - sn);
                if t > 0.0 && t < t_exit {
                    cuts[nc] = t;
                    nc += 1;
                }
            }
        }
    }
    cuts[nc] = t_exit;
    nc += 1;
    let cuts = &mut cuts[..nc];
    cuts.sort_unstable_by(f64::total_cmp);
    let depth = |t: f64| {
        lines
            .iter()
            .map(|&(c, s)| (c + s * t, s))
            .min_by(|p, q| p.0.total_cmp(&q.0))
            .unwrap_or((f64::INFINITY, 0.0))
    };
    let mut acc = Complex64::new(0.0, 0.0);
    let mut t0 = 0.0;
    for &t1 in cuts.iter() {
        if t1 > t0 {
            // The minimising line on (t0, t1), and d_in(t0) on it.
            let (_, s) = depth(0.5 * (t0 + t1));
            let d0 = depth(t0).0.max(0.0);
            let start = Complex64::new(-0.5 * sigma_t * d0, 0.0) - alpha * t0;
            let beta = alpha + Complex64::new(0.5 * sigma_t * s, 0.0);
            let w = beta * (t1 - t0);
            acc += if w.re > -500.0 {
                start.exp() * exp_integral(beta, t1 - t0)
            } else {
                // A line of huge slope (an incident direction almost parallel to a face:
                // i_a ~ 1e-19 gives s ~ 1e19), where e^{-w} overflows while e^{start} is 0: the
                // same integral as (e^{start} - e^{end}) / beta with the end's exponent from
                // the depth there (>= 0), so that both terms stay at most 1.
                let d1 = depth(t1).0.max(0.0);
                let end = Complex64::new(-0.5 * sigma_t * d1, 0.0) - alpha * t1;
                (start.exp() - end.exp()) / beta
            };
        }
        t0 = t1;
    }
    acc
}

/// Components of the incident direction at most this are parallel to a face
/// ([`two_leg_integral`]).
const PARALLEL: f64 = 1e-12;

/// `int_0^T e^{-z t} dt = (1 - e^{-z T}) / z`, by its Taylor series
/// `T (1 - w/2 + w^2/6 - w^3/24)`, `w = z T`, where `|w| < 1e-3` (truncation below 1e-14).
fn exp_integral(z: Complex64, t: f64) -> Complex64 {
    let w = z * t;
    if w.norm() < 1e-3 {
        t * (1.0 - w * (0.5 - w * (1.0 / 6.0 - w / 24.0)))
    } else {
        (1.0 - (-w).exp()) / z
    }
}
