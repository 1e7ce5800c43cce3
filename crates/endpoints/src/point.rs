//! The point kind: an isotropic point source `exp(i k r) / r` at `p` (in flatland
//! `exp(i k r) / sqrt(r)`, the far zone of a Hankel-function source) and, its reciprocal, a point
//! sensor reading the field at `p` (Bar et al. 2019, Eq. 13). Everything about this kind is here:
//! validation, the scalar leg, the vectorised kernel and its exact vacuum field for the wave
//! solver.
//!
//! Point endpoints may lie outside the medium, on its boundary or inside it. Next to the
//! endpoint the `1/r^2` connection would give a plain estimator infinite variance; the path
//! sampler therefore samples first vertices around point endpoints inside or near the medium
//! and weighs both orders of every path by the balance heuristic
//! (`speckle_paths::Tracer::with_point_endpoints`), so that the density cancels the `1/r^2` at
//! both ends.

use crate::kernels::BoxMedium;
use crate::{EndpointError, Leg, Side, check, fastmath};
use glam::DVec3;
use num_complex::Complex64;
use speckle_medium::{Dimension, Medium, field_attenuation};

/// Geometric spreading of a spherical (3D, `1 / r`) or cylindrical (flatland, `1 / sqrt(r)`)
/// wave over the distance `r`.
#[inline]
pub(crate) fn spreading(dimension: Dimension, r: f64) -> f64 {
    match dimension {
        Dimension::Three => 1.0 / r,
        Dimension::Two => 1.0 / r.sqrt(),
    }
}

/// Validates a position: finite, in the plane `z = 0` in flatland.
pub(crate) fn validated<M: Medium>(field: &str, p: DVec3, m: &M) -> Result<DVec3, EndpointError> {
    check::in_plane(field, p, m.dimension())?;
    if !p.is_finite() {
        return Err(check::invalid(
            field,
            format!("position {p} must be finite"),
        ));
    }
    Ok(p)
}

/// The leg between the point endpoint at `p` and `x`: `tau xi = exp(-sigma_t L / 2) e^{ikr} /
/// r` (`1/sqrt(r)` in flatland), `L` the length of the segment inside the medium; its direction
/// runs from `p` to `x` for a source and from `x` to `p` for a sensor.
#[inline]
pub(crate) fn leg<M: Medium>(m: &M, k: f64, p: DVec3, x: DVec3, side: Side) -> Leg {
    let (d, depth) = match side {
        Side::Source => (x - p, m.optical_depth(p, x)),
        Side::Sensor => (p - x, m.optical_depth(x, p)),
    };
    let r = d.length();
    Leg {
        amp: Complex64::from_polar(
            field_attenuation(depth) * spreading(m.dimension(), r),
            k * r,
        ),
        dir: d / r,
    }
}

/// Point endpoints, structure of arrays of their positions.
#[derive(Debug, Clone, Default)]
pub(crate) struct Run {
    p: [Vec<f64>; 3],
}

impl Run {
    /// Appends the endpoint at `p`.
    pub(crate) fn push(&mut self, p: DVec3) {
        for a in 0..3 {
            self.p[a].push(p[a]);
        }
    }

    /// The kernel: distance `r`, direction, chord through the box, and
    /// `exp(-sigma_t L / 2) spreading(r) exp(i k r)` (Eq. 13 with `1/r`, or `1/sqrt(r)` in
    /// flatland). `side` is `+1` for sensors (direction `p - x`), `-1` for sources (`x - p`).
    /// Returns false if a phase was out of the range of the vectorised `sin_cos`.
    /// Compiled for the CPU's widest vector instructions, chosen at run time (`pulp`); bitwise
    /// the same on every instruction set (no contraction into fused multiply-adds).
    #[inline(never)]
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn connect<const THREE: bool>(
        &self,
        g: &BoxMedium,
        k: f64,
        side: f64,
        x: DVec3,
        re: &mut [f64],
        im: &mut [f64],
        dir: [&mut [f64]; 3],
    ) -> bool {
        // A generic `WithSimd` (not a closure) is monomorphised inside each instruction set's
        // function, so the loop is inlined and vectorised there.
        struct Op<'a, const THREE: bool> {
            run: &'a Run,
            g: &'a BoxMedium,
            k: f64,
            side: f64,
            x: DVec3,
            re: &'a mut [f64],
            im: &'a mut [f64],
            dir: [&'a mut [f64]; 3],
        }
        impl<const THREE: bool> pulp::WithSimd for Op<'_, THREE> {
            type Output = bool;
            #[inline(always)]
            fn with_simd<S: pulp::Simd>(self, _: S) -> bool {
                let o = self;
                o.run
                    .connect_lanes::<THREE>(o.g, o.k, o.side, o.x, o.re, o.im, o.dir)
            }
        }
        pulp::Arch::new().dispatch(Op::<THREE> {
            run: self,
            g,
            k,
            side,
            x,
            re,
            im,
            dir,
        })
    }

    /// The loop of [`Run::connect`], inlined into each instruction set's version.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn connect_lanes<const THREE: bool>(
        &self,
        g: &BoxMedium,
        k: f64,
        side: f64,
        x: DVec3,
        re: &mut [f64],
        im: &mut [f64],
        dir: [&mut [f64]; 3],
    ) -> bool {
        let n = re.len();
        let (px, py, pz) = (&self.p[0][..n], &self.p[1][..n], &self.p[2][..n]);
        let im = &mut im[..n];
        let [dx, dy, dz] = dir;
        let (dx, dy, dz) = (&mut dx[..n], &mut dy[..n], &mut dz[..n]);
        let mut in_range = true;
        for i in 0..n {
            // w = p - x; for a sensor the leg runs along w, for a source along -w. Both cross
            // the same chord of the box, from x to where the segment leaves it.
            let w = DVec3::new(px[i] - x.x, py[i] - x.y, pz[i] - x.z);
            let r = (w.x * w.x + w.y * w.y + w.z * w.z).sqrt();
            let inv = 1.0 / r;
            let unit = side * inv;
            let depth_half = g.half_sigma_t * g.chord_fraction(x, w) * r;
            let spread = if THREE { inv } else { inv.sqrt() };
            let att = fastmath::exp(-depth_half) * spread;
            let phase = k * r;
            let (s, co) = fastmath::sin_cos_reduced(phase);
            in_range &= fastmath::in_sin_cos_range(phase);
            re[i] = att * co;
            im[i] = att * s;
            dx[i] = w.x * unit;
            dy[i] = w.y * unit;
            dz[i] = w.z * unit;
        }
        in_range
    }
}

/// The mean field between two points `p` (source) and `q` (sensor): the attenuated direct path
/// `tau e^{ikr} / r` (Eq. 20).
pub(crate) fn direct_mean<M: Medium>(m: &M, k: f64, p: DVec3, q: DVec3) -> Complex64 {
    let r = (q - p).length();
    Complex64::from_polar(
        field_attenuation(m.optical_depth(p, q)) * spreading(m.dimension(), r),
        k * r,
    )
}
