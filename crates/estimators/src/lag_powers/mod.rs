//! Regular time lags as powers of one exponential (the spatio-temporal estimator without drift).
//!
//! Without drift every factor of a contribution at lag `t` is `exp(-k^2 |t| a)` for an exponent
//! `a` of the term (the interior sum plus the end vertices' Brownian transfers). When the lags
//! are whole multiples `|t_l| = m_l delta` of one step, the factor is `r^(m_l)` with
//! `r = exp(-k^2 delta a)`: one exponential per term (a polynomial of its own, [`exp_neg`],
//! vectorised over a vertex's terms), and the powers by products instead of one `exp` per term
//! and lag.
//!
//! [`PowerSums`] adds `z r^(m_l)` for every lag into sums of its own (entry-major, real and
//! imaginary parts apart, so that the loops over the lags are contiguous and vectorise); the
//! render adds them to its batch sums once per batch ([`PowerSums::flush`]) rather than once per
//! vertex and lag. The powers are formed in chunks of eight, `r^(8 j + i) = r^i r^(8 j)`, with
//! the chunks' multipliers `r^(8 j)` themselves formed eight at a time ([`multipliers`]), so
//! that no chunk waits on the one before: at regular lags chunk `j` of an entry's sums takes
//! `(z q) r^(8 j)`, `q = (r, ..., r^8)`, one vector product and sum per term. A power differs
//! from `exp(-k^2 |t| a)` by rounding only (a few ulps), and they stop where they underflow
//! (below [`PowerSums::TINY`] the rest are zero), which keeps subnormal numbers out of the
//! loops.
//!
//! Lags that are multiples of the step only to within their rounding (a grid written to seven
//! digits) are interpolated between the sums at two steps ([`Powers`]), or, in the slot sums of
//! diagonal entries, taken lag by lag with each distinct gap's multiplier ([`SlotSums`]).
//!
//! The loops are compiled for the instruction sets the CPU has (AVX-512, AVX2, detected at run
//! time through `pulp`); they use no fused multiply-adds, so every instruction set gives bitwise
//! the same sums.

mod drift;
pub(crate) mod kernels;
mod powers;
mod slots;
mod sums;

pub(crate) use drift::DriftSums;
pub(crate) use powers::Powers;
pub(crate) use slots::SlotSums;
pub(crate) use sums::PowerSums;

#[cfg(test)]
mod tests;
