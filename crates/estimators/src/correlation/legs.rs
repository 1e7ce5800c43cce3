//! [`LegSet`]: the connections of a set of directional endpoints along the drift line of one
//! end vertex, at the lags of the exponential drift ([`super::linear`]).

use glam::DVec3;
use num_complex::Complex64;
use speckle_endpoints::Endpoints;
use speckle_medium::Medium;

/// A leg's factors over one step or at one lag: copy 1's `leg(x - s U) / leg(x)` and copy 2's
/// conjugated `conj(leg(x + s U) / leg(x))`.
pub(super) type Factors = (Complex64, Complex64);

/// The legs of every endpoint of a set at one end vertex `x`, moving with drift `U`, relative to
/// their values at `x`: a leg that is an exponential `exp(beta s)` along the copies' line
/// (leaving the box through one face all along) by its factors over one step `delta` of the
/// lags (copy 1 at `-delta / 2`, copy 2 at `+delta / 2`), a *bent* one (changing face) by its
/// factors at each lag (`Endpoints::drift_log_ratio`).
#[derive(Debug, Default)]
pub(super) struct LegSet {
    rates: Vec<Option<Complex64>>,
    /// Per leg: the step factors where it is exponential (ones where bent).
    steps: Vec<Factors>,
    /// Per leg: its slot in `table` where bent, else `usize::MAX`.
    slot: Vec<usize>,
    /// Per bent leg, the factors at each of the first `stride` lags (`[slot * stride + k]`).
    table: Vec<Factors>,
    stride: usize,
    /// Whether any leg is bent.
    any_bent: bool,
    /// Per leg, the last rate and step it had and its step factors: with a uniform drift a
    /// leg keeps its rate from vertex to vertex (while it leaves through the same face), and its
    /// factors need no exponential.
    last: Vec<(Complex64, f64, Factors)>,
}

impl LegSet {
    /// The legs of `set` at `x` moving with `u`, for the lags `times` (increasing, non-zero;
    /// every copy `x -/+ t u / 2` inside the box) with step `delta`. False where `set` is not
    /// directional in a box or a copy is outside it (the legs are then unset).
    pub fn fill<M: Medium>(
        &mut self,
        set: &Endpoints<M>,
        x: DVec3,
        u: DVec3,
        delta: f64,
        times: &[f64],
    ) -> bool {
        let n = set.len();
        let reach = 0.5 * times.last().copied().unwrap_or(0.0);
        self.rates.resize(n, None);
        if !set.drift_rates(x, u, reach, &mut self.rates) {
            return false;
        }
        self.steps.clear();
        self.slot.clear();
        self.table.clear();
        self.stride = times.len();
        self.any_bent = false;
        self.last
            .resize(n, (Complex64::new(f64::NAN, 0.0), 0.0, Default::default()));
        for (i, rate) in self.rates.iter().enumerate() {
            match rate {
                Some(beta) => {
                    let last = &mut self.last[i];
                    if (last.0, last.1) != (*beta, delta) {
                        *last = (*beta, delta, factors(*beta, delta));
                    }
                    self.steps.push(last.2);
                    self.slot.push(usize::MAX);
                }
                None => {
                    self.any_bent = true;
                    self.steps.push((Complex64::ONE, Complex64::ONE));
                    self.slot.push(self.table.len() / self.stride.max(1));
                    for &t in times {
                        let (Some(a), Some(b)) = (
                            set.drift_log_ratio(i, x, u, -0.5 * t),
                            set.drift_log_ratio(i, x, u, 0.5 * t),
                        ) else {
                            return false;
                        };
                        self.table.push((a.exp(), b.exp().conj()));
                    }
                }
            }
        }
        true
    }

    /// Whether leg `i` is bent.
    #[inline]
    pub fn bent(&self, i: usize) -> bool {
        self.any_bent && self.slot[i] != usize::MAX
    }

    /// Leg `i`'s factors over one step (exponential legs).
    #[inline]
    pub fn step(&self, i: usize) -> Factors {
        self.steps[i]
    }

    /// Whether any leg is bent.
    #[inline]
    pub fn any_bent(&self) -> bool {
        self.any_bent
    }

    /// Bent leg `i`'s factors at lag number `k` (ones for an exponential leg, whose factors
    /// are its steps').
    #[inline]
    pub fn at(&self, i: usize, k: usize) -> Factors {
        match self.slot[i] {
            usize::MAX => (Complex64::ONE, Complex64::ONE),
            s => self.table[s * self.stride + k],
        }
    }
}

/// The factors of a leg of rate `beta` over the lag `t`: `exp(-beta t / 2)` for copy 1, and for
/// copy 2 `conj(exp(beta t / 2))`, the conjugate of the first's inverse.
#[inline]
fn factors(beta: Complex64, t: f64) -> Factors {
    let f = (-0.5 * t * beta).exp();
    (f, f / f.norm_sqr())
}
