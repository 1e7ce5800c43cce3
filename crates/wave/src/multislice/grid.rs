//! The transverse grid of one source and the slice-by-slice propagation through one
//! configuration (the module docs of `multislice` derive it).

use super::{
    APERTURE_ROLLOFF, EMISSION_DEPTH, LAYER_DAMPING, MAX_GRID_POINTS, MultisliceOptions,
    WINDOW_ROLLOFF, invalid,
};
use crate::{Kernel, WaveError, WaveScene};
use glam::DVec3;
use num_complex::Complex64;
use rustfft::{Fft, FftPlanner};
use speckle_medium::Medium;
use std::f64::consts::TAU;
use std::sync::Arc;

/// The propagation frame of a normal-incidence plane wave: the box axis it travels along, its
/// sign, and the transverse axes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Frame {
    pub(super) axis: usize,
    sign: f64,
    pub(super) across: [usize; 2],
    pub(super) flat: bool,
}

impl Frame {
    /// The frame of `direction` if it is a box axis (to 1e-12), else `None`.
    pub(super) fn of(direction: DVec3, flat: bool) -> Option<Self> {
        let axes = if flat { 2 } else { 3 };
        let axis = (0..axes).find(|&a| direction[a].abs() >= 1.0 - 1e-12)?;
        let across = if flat {
            [1 - axis, 2]
        } else {
            [(axis + 1) % 3, (axis + 2) % 3]
        };
        Some(Self {
            axis,
            sign: direction[axis].signum(),
            across,
            flat,
        })
    }

    /// Local `(x, y, z)`: transverse coordinates (`y = 0` in flatland) and depth.
    pub(super) fn local(&self, p: DVec3) -> [f64; 3] {
        let y = if self.flat { 0.0 } else { p[self.across[1]] };
        [p[self.across[0]], y, self.sign * p[self.axis]]
    }

    /// The global point of local `(x, y, z)`.
    pub(super) fn global(&self, x: f64, y: f64, z: f64) -> DVec3 {
        let mut p = DVec3::ZERO;
        p[self.across[0]] = x;
        if !self.flat {
            p[self.across[1]] = y;
        }
        p[self.axis] = self.sign * z;
        p
    }
}

/// One transverse axis of the grid.
#[derive(Debug, Clone)]
pub(super) struct Axis {
    pub(super) n: usize,
    pub(super) h: f64,
    /// Global coordinate of grid point 0.
    pub(super) lo: f64,
    pub(super) len: f64,
    /// Signed wavenumbers `2 pi m / L`, FFT order.
    q: Vec<f64>,
    /// Damping rate `alpha` at each grid point.
    alpha: Vec<f64>,
    /// The emission window: 1 in the kept region, falling as `cos^2` to 0 over the absorbers'
    /// inner [`WINDOW_ROLLOFF`] wavelengths (at most half of them).
    taper: Vec<f64>,
}

impl Axis {
    /// A single point: the missing second axis of flatland.
    fn single() -> Self {
        Self {
            n: 1,
            h: 1.0,
            lo: 0.0,
            len: 1.0,
            q: vec![0.0],
            alpha: vec![0.0],
            taper: vec![1.0],
        }
    }

    /// The points and width of an axis, or an error naming `spacing` when they exceed
    /// [`MAX_GRID_POINTS`] (checked before anything is allocated).
    fn size(
        lo_box: f64,
        hi_box: f64,
        lambda: f64,
        o: &MultisliceOptions,
    ) -> Result<(usize, f64), WaveError> {
        let least = (hi_box - lo_box) + 2.0 * (o.margin + o.absorber);
        // L = (M + 1/2) lambda: no mode exactly grazing.
        let len = ((least / lambda - 0.5).ceil().max(0.0) + 0.5) * lambda;
        let points = (len / o.spacing).ceil();
        if !points.is_finite() || points > MAX_GRID_POINTS as f64 {
            return Err(invalid(
                "spacing",
                format!(
                    "a transverse axis {len} wide would have {points:.0} points, more than the \
                     limit of {MAX_GRID_POINTS}: use a narrower box, margin or absorber"
                ),
            ));
        }
        Ok((smooth_size(points as usize), len))
    }

    fn new(
        lo_box: f64,
        hi_box: f64,
        (n, len): (usize, f64),
        lambda: f64,
        o: &MultisliceOptions,
    ) -> Self {
        let h = len / n as f64;
        let lo = lo_box - o.margin - o.absorber;
        let q = (0..n)
            .map(|m| {
                let signed = if 2 * m < n {
                    m as f64
                } else {
                    m as f64 - n as f64
                };
                TAU * signed / len
            })
            .collect();
        // Kept region [a, b] relative to lo; alpha_max W / (3 tan 80) = LAYER_DAMPING.
        let (a, b) = (o.absorber, o.absorber + (hi_box - lo_box) + 2.0 * o.margin);
        let alpha_max = if o.absorber > 0.0 {
            3.0 * LAYER_DAMPING * 80f64.to_radians().tan() / o.absorber
        } else {
            0.0
        };
        let depth = |j: usize| {
            let xi = j as f64 * h;
            if o.absorber > 0.0 {
                ((a - xi).max(xi - b).max(0.0) / o.absorber).min(1.0)
            } else {
                0.0
            }
        };
        let alpha = (0..n).map(|j| alpha_max * depth(j).powi(2)).collect();
        // The window: 1 in the kept region, falling as cos^2 over the absorber's inner part.
        let rolloff = (WINDOW_ROLLOFF * lambda).min(0.5 * o.absorber);
        let taper = (0..n)
            .map(|j| {
                let beyond = (a - j as f64 * h).max(j as f64 * h - b);
                if o.absorber == 0.0 || beyond <= 0.0 {
                    1.0
                } else if beyond >= rolloff {
                    0.0
                } else {
                    (0.5 * std::f64::consts::PI * beyond / rolloff)
                        .cos()
                        .powi(2)
                }
            })
            .collect();

        Self {
            n,
            h,
            lo,
            len,
            q,
            alpha,
            taper,
        }
    }
}

/// The smallest `2^a 3^b 5^c >= n` (fast FFT sizes).
pub(super) fn smooth_size(n: usize) -> usize {
    let mut m = n.max(1);
    loop {
        let mut r = m;
        for p in [2, 3, 5] {
            while r.is_multiple_of(p) {
                r /= p;
            }
        }
        if r == 1 {
            return m;
        }
        m += 1;
    }
}

/// The sizes of a propagation grid, for reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridInfo {
    /// Transverse points along each transverse axis (the second is 1 in flatland).
    pub points: [usize; 2],
    /// Transverse spacing along each axis.
    pub spacing: [f64; 2],
    /// Periodic width along each axis (margins and absorbers included).
    pub width: [f64; 2],
    /// Number of slices.
    pub slices: usize,
    /// Slice thickness `dz`.
    pub slice: f64,
    /// Slices beyond the box's back face, up to the exit plane (at least [`EMISSION_DEPTH`]
    /// wavelengths behind it, so that every scatterer has joined the grid).
    pub exit_slices: usize,
}

/// The grid and propagators of one source.
pub(super) struct Grid {
    pub(super) frame: Frame,
    pub(super) k: f64,
    pub(super) axes: [Axis; 2],
    pub(super) z0: f64,
    pub(super) dz: f64,
    pub(super) slices: usize,
    /// Slices plus exit slices: the slice boundaries after the first.
    pub(super) boundaries: usize,
    /// [`EMISSION_DEPTH`] wavelengths.
    emit_depth: f64,
    pub(super) kz: Vec<Complex64>,
    /// `e^{i k_z dz}`.
    step: Vec<Complex64>,
    /// `e^{-alpha dz}` at each grid point.
    mask: Vec<f64>,
    /// The emission window's taper at each grid point.
    taper: Vec<f64>,
    /// Number of grid points where the taper is non-zero.
    window: usize,
    /// The aperture's angles (full weight up to the first, none from the second), radians...
    cone: [f64; 2],
    /// ... and their tangents (the second capped at 1e6).
    cone_tan: [f64; 2],
    fft: [Arc<dyn Fft<f64>>; 2],
    ifft: [Arc<dyn Fft<f64>>; 2],
}

impl Grid {
    pub(super) fn new(
        scene: &WaveScene,
        frame: Frame,
        o: &MultisliceOptions,
    ) -> Result<Self, WaveError> {
        let lambda = scene.wavelength();
        let k = scene.wavenumber();
        let b = scene.medium().bounds();
        let (lo, hi) = (b.min(), b.max());
        let size = |i: usize| Axis::size(lo[frame.across[i]], hi[frame.across[i]], lambda, o);
        let s0 = size(0)?;
        let s1 = if frame.flat { (1, 1.0) } else { size(1)? };
        let points = s0.0 as f64 * s1.0 as f64;
        if points > MAX_GRID_POINTS as f64 {
            return Err(invalid(
                "spacing",
                format!(
                    "the grid would have {points:.0} transverse points, more than the limit of \
                     {MAX_GRID_POINTS}: use a narrower box, margin or absorber"
                ),
            ));
        }
        let ax = |i: usize, n| Axis::new(lo[frame.across[i]], hi[frame.across[i]], n, lambda, o);
        let axes = if frame.flat {
            [ax(0, s0), Axis::single()]
        } else {
            [ax(0, s0), ax(1, s1)]
        };
        let (za, zb) = {
            let (p, q) = (frame.sign * lo[frame.axis], frame.sign * hi[frame.axis]);
            (p.min(q), p.max(q))
        };
        let depth = zb - za;
        let slices = ((depth / o.slice).ceil() as usize).max(1);
        let dz = depth / slices as f64;
        let (n0, n1) = (axes[0].n, axes[1].n);
        let mut kz = Vec::with_capacity(n0 * n1);
        for l in 0..n1 {
            for m in 0..n0 {
                let s = k * k - axes[0].q[m].powi(2) - axes[1].q[l].powi(2);
                kz.push(if s >= 0.0 {
                    Complex64::new(s.sqrt(), 0.0)
                } else {
                    Complex64::new(0.0, (-s).sqrt())
                });
            }
        }
        let i = Complex64::i();
        let step = kz.iter().map(|z| (i * z * dz).exp()).collect();
        let mut mask = Vec::with_capacity(n0 * n1);
        let mut taper = Vec::with_capacity(n0 * n1);
        for l in 0..n1 {
            for m in 0..n0 {
                mask.push((-(axes[0].alpha[m] + axes[1].alpha[l]) * dz).exp());
                taper.push(axes[0].taper[m] * axes[1].taper[l]);
            }
        }
        let window = taper.iter().filter(|&&t| t > 0.0).count();
        let cut = o.aperture.to_radians();
        let pass = (o.aperture - APERTURE_ROLLOFF).to_radians();
        let emit_depth = EMISSION_DEPTH * lambda;
        let mut planner = FftPlanner::new();
        let fft = [planner.plan_fft_forward(n0), planner.plan_fft_forward(n1)];
        let ifft = [planner.plan_fft_inverse(n0), planner.plan_fft_inverse(n1)];
        Ok(Self {
            frame,
            k,
            axes,
            z0: za,
            dz,
            slices,
            boundaries: slices + (emit_depth / dz * (1.0 - 1e-12)).ceil() as usize,
            emit_depth,
            kz,
            step,
            mask,
            taper,
            window,
            cone: [pass, cut],
            cone_tan: [pass.tan(), cut.tan().min(1e6)],
            fft,
            ifft,
        })
    }

    pub(super) fn info(&self) -> GridInfo {
        GridInfo {
            points: [self.axes[0].n, self.axes[1].n],
            spacing: [self.axes[0].h, self.axes[1].h],
            width: [self.axes[0].len, self.axes[1].len],
            slices: self.slices,
            slice: self.dz,
            exit_slices: self.boundaries - self.slices,
        }
    }

    /// Estimated grid-point updates of one propagation with `n` scatterers.
    pub(super) fn work(&self, n: f64) -> f64 {
        let p = self.kz.len() as f64;
        let reach = (self.emit_depth + self.dz) * self.cone_tan[1];
        let across = |a: &Axis| {
            if a.n == 1 {
                1.0
            } else {
                (2.0 * reach / a.h + 2.0).min(a.n as f64)
            }
        };
        let emitted = (across(&self.axes[0]) * across(&self.axes[1])).min(self.window as f64);
        self.boundaries as f64 * p * p.log2().max(1.0) + n * (p + emitted)
    }

    /// In-place 2D FFT (forward scaled by `1 / P`, inverse unscaled) of `u` (rows of `n0`).
    fn transform(&self, u: &mut [Complex64], forward: bool, column: &mut Vec<Complex64>) {
        let (n0, n1) = (self.axes[0].n, self.axes[1].n);
        let plans = if forward { &self.fft } else { &self.ifft };
        plans[0].process(u);
        if n1 > 1 {
            column.resize(n1, Complex64::new(0.0, 0.0));
            for m in 0..n0 {
                for (l, c) in column.iter_mut().enumerate() {
                    *c = u[l * n0 + m];
                }
                plans[1].process(column);
                for (l, c) in column.iter().enumerate() {
                    u[l * n0 + m] = *c;
                }
            }
        }
        if forward {
            let s = 1.0 / (n0 * n1) as f64;
            u.iter_mut().for_each(|c| *c *= s);
        }
    }

    /// The aperture's weight at `lateral` from a scatterer `depth` behind the plane: 1 up to the
    /// pass angle, `cos^2` in the angle to 0 at the aperture.
    fn aperture_weight(&self, lateral: f64, depth: f64) -> f64 {
        if lateral <= depth * self.cone_tan[0] {
            return 1.0;
        }
        let angle = lateral.atan2(depth);
        if angle >= self.cone[1] {
            return 0.0;
        }
        let x = (angle - self.cone[0]) / (self.cone[1] - self.cone[0]);
        (0.5 * std::f64::consts::PI * x).cos().powi(2)
    }

    /// The first slice boundary (index) at least [`EMISSION_DEPTH`] wavelengths beyond depth
    /// `z`, where a scatterer there joins the grid.
    fn emission_boundary(&self, z: f64) -> usize {
        let slice = (((z - self.z0) / self.dz).floor().max(0.0) as usize).min(self.slices - 1);
        let at = ((z + self.emit_depth - self.z0) / self.dz * (1.0 - 1e-12)).ceil();
        (at.max(0.0) as usize).clamp(slice + 1, self.boundaries)
    }

    /// Propagates through scatterers `local` (grid-relative `(xi, eta, z)`, sorted by `z`):
    /// their exciting fields (same order) and the scattered field on the grid at the exit
    /// plane; `None` if cancelled.
    pub(super) fn propagate(
        &self,
        kernel: &Kernel,
        local: &[[f64; 3]],
        cancelled: &dyn Fn() -> bool,
    ) -> Option<(Vec<Complex64>, Vec<Complex64>)> {
        let (n0, n1) = (self.axes[0].n, self.axes[1].n);
        let tau = kernel.t_matrix();
        let zero = Complex64::new(0.0, 0.0);
        let i = Complex64::i();
        let mut u = vec![zero; n0 * n1];
        let mut column = Vec::new();
        let (mut ex, mut ey) = (vec![zero; n0], vec![zero; n1]);
        let mut psi = vec![zero; local.len()];
        let boundary: Vec<usize> = local.iter().map(|p| self.emission_boundary(p[2])).collect();
        // Scatterers of earlier slices not yet on the grid: coupled directly.
        let mut pending: Vec<usize> = Vec::new();
        let mut lit = false;
        let mut next = 0;
        for s in 0..self.boundaries {
            if cancelled() {
                return None;
            }
            let za = self.z0 + s as f64 * self.dz;
            let end = if s + 1 >= self.slices {
                local.len()
            } else {
                next + local[next..]
                    .iter()
                    .take_while(|p| p[2] < za + self.dz)
                    .count()
            };
            let members = next..end;
            next = end;
            if lit {
                self.transform(&mut u, true, &mut column);
            }
            for at in members.clone() {
                let p = local[at];
                // psi(o): the incident wave, the grid's field at z_a carried to o, and the
                // scatterers of earlier slices still between their depth and their emission.
                let mut sum = Complex64::from_polar(1.0, self.k * p[2]);
                if lit {
                    for (e, q) in ex.iter_mut().zip(&self.axes[0].q) {
                        *e = Complex64::from_polar(1.0, q * p[0]);
                    }
                    for (e, q) in ey.iter_mut().zip(&self.axes[1].q) {
                        *e = Complex64::from_polar(1.0, q * p[1]);
                    }
                    let before = p[2] - za;
                    let mut row = 0;
                    for y in &ey {
                        let mut line = zero;
                        for m in 0..n0 {
                            let kz = self.kz[row + m];
                            line += u[row + m] * (i * kz * before).exp() * ex[m];
                        }
                        sum += line * y;
                        row += n0;
                    }
                }
                for &q in &pending {
                    let o = local[q];
                    let r = ((p[0] - o[0]).powi(2) + (p[1] - o[1]).powi(2) + (p[2] - o[2]).powi(2))
                        .sqrt();
                    if r > 0.0 {
                        sum += tau * kernel.green(r) * psi[q];
                    }
                }
                psi[at] = sum;
            }
            // Boundary s + 1: the grid's field carried there and damped in the absorbers.
            pending.extend(members);
            let zb = za + self.dz;
            if lit {
                for (c, step) in u.iter_mut().zip(&self.step) {
                    *c *= step;
                }
                self.transform(&mut u, false, &mut column);
                for (c, m) in u.iter_mut().zip(&self.mask) {
                    *c *= m;
                }
            }
            // The screens, in real space: the free field `tau psi G` of each scatterer whose
            // emission plane this is, over the emission window.
            for &q in pending.iter().filter(|&&q| boundary[q] == s + 1) {
                let (o, a) = (local[q], tau * psi[q]);
                let depth = zb - o[2];
                // The aperture's reach on this plane, as index ranges along each axis.
                let reach = depth * self.cone_tan[1];
                let range = |axis: &Axis, x: f64| {
                    if axis.n == 1 {
                        return 0..1;
                    }
                    let lo = ((x - reach) / axis.h).floor().max(0.0) as usize;
                    let hi = ((x + reach) / axis.h).ceil().max(0.0) as usize;
                    lo.min(axis.n)..(hi + 1).min(axis.n)
                };
                let (r0, r1) = (range(&self.axes[0], o[0]), range(&self.axes[1], o[1]));
                for l in r1 {
                    let dy = if n1 > 1 {
                        l as f64 * self.axes[1].h - o[1]
                    } else {
                        0.0
                    };
                    for m in r0.clone() {
                        let at = l * n0 + m;
                        let t = self.taper[at];
                        if t == 0.0 {
                            continue;
                        }
                        let dx = m as f64 * self.axes[0].h - o[0];
                        let lateral = (dx * dx + dy * dy).sqrt();
                        let c = self.aperture_weight(lateral, depth);
                        if c > 0.0 {
                            let r = (lateral * lateral + depth * depth).sqrt();
                            u[at] += a * (t * c) * kernel.green(r);
                        }
                    }
                }
                lit = true;
            }
            pending.retain(|&q| boundary[q] > s + 1);
        }
        Some((psi, u))
    }
}
