//! How a connector's pair values enter the batch sums: `w a a^H`, or with two independent
//! estimates of every Gaussian connection (the exact near-field attenuation,
//! `speckle_endpoints::NearField::Exact`) the unbiased `w (a b^H + b a^H) / 2`; and the second
//! draw set that provides `b`.

use super::{Connector, Cvec, Ends};
use num_complex::Complex64;
use speckle_endpoints::Endpoints;
use speckle_medium::Medium;
use speckle_paths::PathRng;
use speckle_phase::PhaseFunction;

/// The second draw set of a path's connections with the exact attenuation of Gaussian beams
/// (see `speckle_endpoints::NearField`): two independent estimates of every Gaussian connection,
/// whose products `a b^H` are unbiased where `a a^H` would add the correction's variance.
pub(crate) struct Exact {
    /// The key of the draws' streams (stream = global path index).
    key: u64,
    pub(super) rng: PathRng,
    /// Set 1's `fwd_src`, `rev_sens`, `fwd_sens`, `rev_src`.
    pub fwd_src: Cvec,
    pub rev_sens: Cvec,
    pub fwd_sens: Cvec,
    pub rev_src: Cvec,
}

/// The index given to [`speckle_stats::rng::derive_seed`] for the key of the draws of the exact
/// attenuation of Gaussian beams (`speckle_endpoints::NearField::Exact`): path `n` draws from
/// stream `n` of `derive_seed(seed, NEAR_FIELD_KEY)`, apart from its path's stream.
pub const NEAR_FIELD_KEY: u64 = 0x4e65_6172_4669; // "NearFi"

/// `out` (set 0's value, already the closed form) copied to `set1`, then each corrected by its
/// draw set: `correct(set, values)`.
pub(super) fn two_sets(out: &mut Cvec, set1: &mut Cvec, mut correct: impl FnMut(usize, &mut Cvec)) {
    set1.re.clone_from(&out.re);
    set1.im.clone_from(&out.im);
    correct(0, out);
    correct(1, set1);
}

impl Ends {
    /// Enables the exact attenuation of Gaussian beams with draws keyed by `key` (see
    /// [`Exact`]); no effect when neither set has a Gaussian beam.
    pub fn enable_exact<M: Medium>(&mut self, src: &Endpoints<M>, sen: &Endpoints<M>, key: u64) {
        if src.has_gaussian() || sen.has_gaussian() {
            self.exact = Some(Exact {
                key,
                rng: PathRng::new(key, 0),
                fwd_src: Cvec::zeros(src.len()),
                rev_sens: Cvec::zeros(sen.len()),
                fwd_sens: Cvec::zeros(sen.len()),
                rev_src: Cvec::zeros(src.len()),
            });
        }
    }

    /// Starts the draws of global path `n` (with the exact attenuation; else nothing).
    pub fn begin_path(&mut self, n: u64) {
        if let Some(e) = &mut self.exact {
            e.rng = PathRng::new(e.key, n);
        }
    }
}

impl<M: Medium, P: PhaseFunction> Connector<'_, M, P> {
    /// Makes the connections of the scene's Gaussian beams exact when the scene asks for it
    /// (`speckle_endpoints::NearField::Exact`, not the default): every Gaussian connection is then
    /// estimated twice, from independent draws keyed by `seed` ([`NEAR_FIELD_KEY`]), and
    /// [`Connector::first`] and [`Connector::vertex`] fill `b` with set 1's pair values as well
    /// as `a` with set 0's. Only the estimators of second moments call it (covariance,
    /// intensity, single scattering); call [`Connector::begin_path`] before each path. Other
    /// estimators (fields, temporal correlations) take the control variate alone
    /// (`NearField::Fitted`) for a scene that asks for `Exact`. No effect without Gaussian beams
    /// or with another model.
    pub(crate) fn with_exact_attenuation(mut self, seed: u64) -> Self {
        let exact = speckle_endpoints::NearField::Exact;
        if self.scene.near_field() == exact {
            // `for_tile` gave the endpoints the control variate alone.
            self.sources.set_near_field(exact);
            self.sensors.set_near_field(exact);
            let key = speckle_stats::rng::derive_seed(seed, NEAR_FIELD_KEY);
            self.ends.enable_exact(&self.sources, &self.sensors, key);
            if self.ends.exact.is_some() {
                self.b = vec![Complex64::new(0.0, 0.0); self.a.len()];
            }
        }
        self
    }

    /// Adds the products of the current pair values at the listed entries `(p, q)`, times
    /// `w`, to the general-diagonal sum `sum`: `a_p conj(a_q)`, or with two independent
    /// estimates `(a_p conj(b_q) + b_p conj(a_q)) / 2` (see [`Connector::push_moment`]).
    pub(crate) fn push_entries(
        &mut self,
        sum: &mut speckle_stats::BatchSum,
        entries: &[(u32, u32)],
        w: f64,
    ) {
        let v = &mut self.halves.0;
        v.clear();
        let (a, b) = (&self.a, &self.b);
        if self.ends.exact.is_some() {
            v.extend(entries.iter().map(|&(p, q)| {
                let (p, q) = (p as usize, q as usize);
                0.5 * (a[p] * b[q].conj() + b[p] * a[q].conj())
            }));
        } else {
            v.extend(
                entries
                    .iter()
                    .map(|&(p, q)| a[p as usize] * a[q as usize].conj()),
            );
        }
        sum.push_values(v, Complex64::new(w, 0.0));
    }

    /// Whether `b` holds a second, independent estimate of the pair values (exact attenuation
    /// of Gaussian beams).
    pub(crate) fn two_sets(&self) -> bool {
        self.ends.exact.is_some()
    }

    /// Starts the draws of global path `n` (exact attenuation; else nothing).
    pub(crate) fn begin_path(&mut self, n: u64) {
        self.ends.begin_path(n);
    }

    /// Adds the current pair values' second moment times `w` to `sum`: `w a a^H`, or with two
    /// independent estimates ([`Connector::two_sets`]) the unbiased `w (a b^H + b a^H) / 2`,
    /// Hermitian as `w p p^H - w q q^H` with `p, q = (a +- b) / 2` (real `w`; a complex `w`
    /// takes the general layout's `a b^H` and `b a^H`).
    pub(crate) fn push_moment<V: speckle_paths::FactorValue>(
        &mut self,
        sum: &mut speckle_stats::BatchSum,
        w: f64,
        f: V,
    ) {
        if !self.two_sets() {
            if V::REAL {
                sum.push_hermitian(&self.a, w * f.real());
            } else {
                sum.push(&self.a, &self.a, f.complex() * w);
            }
            return;
        }
        if V::REAL {
            let (p, q) = &mut self.halves;
            p.clear();
            q.clear();
            for (x, y) in self.a.iter().zip(&self.b) {
                p.push(0.5 * (x + y));
                q.push(0.5 * (x - y));
            }
            let w = w * f.real();
            sum.push_hermitian(p, w);
            sum.push_hermitian(q, -w);
        } else {
            let h = 0.5 * f.complex() * w;
            sum.push(&self.a, &self.b, h);
            sum.push(&self.b, &self.a, h);
        }
    }
}
