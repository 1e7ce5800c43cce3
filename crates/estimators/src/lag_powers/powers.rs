//! Lag grids as powers of one step: whole multiples, multiples to within their rounding, and
//! sparse (multi-tau) grids split into runs.

/// Lags `|t_l| = m_l delta` (whole `m_l`, the largest at most [`Powers::MAX_STEPS`] times the
/// number of lags): `delta` is the smallest non-zero `|t|` divided by a whole number up to
/// [`Powers::MAX_DIVISOR`], so log-spaced DCS grids such as `2, 5, 10, 20, ... 200` times
/// `1e-7` qualify (`delta = 1e-7`).
///
/// Lags written to a few significant digits (`3.174603e-07, 6.349206e-07, ...`, as a file or a
/// correlator gives them) are whole multiples only to within their rounding:
/// `|t_l| = m_l delta (1 + eps_l)`, `|eps_l| <=` [`Powers::ROUNDING`]. Their factor
/// `exp(-x m_l (1 + eps_l))` is then interpolated, linearly in `eps`, between the powers at the
/// step (`s = 0`) and at the step stretched by `1 + eta` (`s = eta`, the largest `|eps_l|` with
/// its sign): two sums of powers, weighted `1 - eps_l / eta` and `eps_l / eta` at each lag.
/// (The chunked powers, [`super::PowerSums`], do so; the slot sums of diagonal entries,
/// [`super::SlotSums`], take each lag's gap from the one before as its own multiplier instead,
/// exact to rounding, and interpolate only where a grid has many distinct gaps.) The
/// interpolation's error is at most `(x m)^2 e^{-x m} |eps (eps - eta)| / 2 <= 0.54 eta^2`
/// relative to the term's weight: below `2e-13` for seven significant digits (`eta` up to about
/// `6e-7`, the step itself being a rounded lag) and `6e-11` at the largest rounding accepted.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Powers {
    /// The step `delta`.
    pub delta: f64,
    /// The non-zero lags `(l, m_l)`, by increasing `m_l`.
    pub order: Vec<(usize, usize)>,
    /// Each lag's relative rounding `eps_l` (in the order of `order`); all zero for whole
    /// multiples.
    pub rounding: Vec<f64>,
    /// The stretch `eta` of the second sums (zero for whole multiples: no second sums).
    pub eta: f64,
}

impl Powers {
    /// Steps allowed per lag: beyond, forming the powers (one product per eight steps) costs
    /// more than the exponentials it replaces.
    const MAX_STEPS: usize = 32;
    /// The largest divisor of the smallest lag tried as the step.
    const MAX_DIVISOR: usize = 16;
    /// The largest relative rounding `|eps_l|` of a lag taken as a multiple of the step (six
    /// significant digits).
    pub const ROUNDING: f64 = 1e-5;

    /// The powers of `lags` when they are whole multiples of one step, exactly (to `1e-12`) or
    /// else to within [`Self::ROUNDING`].
    pub fn of(lags: &[f64]) -> Option<Self> {
        Self::within(lags, 1e-12).or_else(|| Self::within(lags, Self::ROUNDING))
    }

    /// The powers of `lags` when they are whole multiples of one step to within `tolerance`
    /// (relative); roundings below `1e-12` are taken as exact.
    fn within(lags: &[f64], tolerance: f64) -> Option<Self> {
        let smallest = lags
            .iter()
            .map(|t| t.abs())
            .filter(|t| *t > 0.0)
            .fold(f64::INFINITY, f64::min);
        if !smallest.is_finite() {
            return None;
        }
        let most = (Self::MAX_STEPS * lags.len()) as f64;
        (1..=Self::MAX_DIVISOR).find_map(|d| {
            let delta = smallest / d as f64;
            let mut order = Vec::new();
            for (l, t) in lags.iter().enumerate() {
                if *t == 0.0 {
                    continue;
                }
                let m = (t.abs() / delta).round();
                if (m * delta - t.abs()).abs() > tolerance * t.abs() || m < 1.0 || m > most {
                    return None;
                }
                let eps = t.abs() / (m * delta) - 1.0;
                let eps = if eps.abs() <= 1e-12 { 0.0 } else { eps };
                order.push((l, m as usize, eps));
            }
            order.sort_by_key(|&(l, m, _)| (m, l));
            let eta = order
                .iter()
                .map(|o| o.2)
                .fold(0.0, |a: f64, e| if e.abs() > a.abs() { e } else { a });
            Some(Self {
                delta,
                order: order.iter().map(|&(l, m, _)| (l, m)).collect(),
                rounding: order.iter().map(|o| o.2).collect(),
                eta,
            })
        })
    }

    /// Steps beyond which the lags are split into runs ([`Self::runs`]).
    const DENSE: usize = 256;
    /// Most distinct steps of a run.
    const RUN: usize = 32;

    /// Lags whose largest step count exceeds [`Self::DENSE`] (a multi-tau grid: eight lags per
    /// level, the step doubling per level), split into runs of equally spaced step counts
    /// `m = o + s m'`, `m' = 1, 2, ...` (up to [`Self::RUN`] distinct ones), each with the
    /// powers of its own step `s` from offset `o`: `exp(-x m) = exp(-x o) (exp(-x s))^m'`. A
    /// lag's rounding becomes `eps m / (m - o)` within its run. `None` for denser grids.
    ///
    /// Such a grid is *sparse*: [`super::PowerSums`] takes it segment by segment (up to eight
    /// equally spaced lags, one vector product each) and [`super::SlotSums`] lag by lag, both
    /// with the multiplier of each gap formed by squaring, rather than step by step.
    pub(super) fn runs(&self) -> Option<Vec<(usize, usize, Powers)>> {
        let n = self.order.len();
        if self.order.last()?.1 <= Self::DENSE {
            return None;
        }
        let mut out = Vec::new();
        let mut i = 0;
        while i < n {
            let m0 = self.order[i].1;
            let after =
                |from: usize, m: usize| (from..n).find(|&j| self.order[j].1 != m).unwrap_or(n);
            let j = after(i, m0);
            let (stride, offset) = match self.order.get(j) {
                Some(&(_, m1)) if m1 - m0 <= m0 => (m1 - m0, m0 - (m1 - m0)),
                _ => (m0, 0),
            };
            let (mut end, mut next, mut count) = (j, m0 + stride, 1);
            while end < n && self.order[end].1 == next && count < Self::RUN {
                end = after(end, next);
                next += stride;
                count += 1;
            }
            let order: Vec<(usize, usize)> = self.order[i..end]
                .iter()
                .map(|&(l, m)| (l, (m - offset) / stride))
                .collect();
            let rounding: Vec<f64> = (i..end)
                .map(|k| {
                    let m = self.order[k].1 as f64;
                    self.rounding[k] * m / (m - offset as f64)
                })
                .collect();
            let eta = rounding
                .iter()
                .fold(0.0, |a: f64, &e| if e.abs() > a.abs() { e } else { a });
            let delta = self.delta * stride as f64;
            out.push((
                offset,
                stride,
                Powers {
                    delta,
                    order,
                    rounding,
                    eta,
                },
            ));
            i = end;
        }
        Some(out)
    }

    /// The weights of the sums at the step (`stretched` false) or at the stretched step, in
    /// the order of `order`.
    pub(super) fn weights(&self, stretched: bool) -> Vec<f64> {
        self.rounding
            .iter()
            .map(|&e| {
                let f = if self.eta == 0.0 { 0.0 } else { e / self.eta };
                if stretched { f } else { 1.0 - f }
            })
            .collect()
    }

    /// The non-zero lags' indices `l` and their step counts `m_l`, apart, in `order`.
    pub(super) fn lags_and_steps(&self) -> (Vec<usize>, Vec<usize>) {
        self.order.iter().copied().unzip()
    }
}
