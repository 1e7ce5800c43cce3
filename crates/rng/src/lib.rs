//! Counter-based random streams (Philox4x32-10) and the one way every render derives them.
//!
//! Its own crate, with no dependencies, so that the building blocks an embedder picks first
//! (`speckle-vmf`, `speckle-phase`) need no more than these streams; `speckle_stats::rng`
//! re-exports it.
//!
//! # Stream layout (value-stable; a change is a breaking change, see `CHANGELOG.md`)
//!
//! Every random number of a render comes from [`PathRng::new`]`(key, stream)`:
//!
//! | render | key | stream |
//! |---|---|---|
//! | covariance, intensity, single scattering | `seed` | global path index `n` |
//! | fields | `seed` | `r N + n` for path `n` of realization `r` (`N` paths each) |
//! | field sequences (scatterer displacements; paths and phases as fields) | [`derive_seed`]`(seed, 0x4d6f74696f6e)` | `r N + n` |
//! | temporal correlation of a scene with Gaussian beams (the end vertices' Brownian displacements; paths as the covariance) | [`derive_seed`]`(seed, 0x42726f776e)` | global path index `n` |
//! | the exact attenuation of Gaussian beams (`render.nearfield = "exact"`: two directions per beam and vertex; paths as the covariance) | [`derive_seed`]`(seed, 0x4e65_6172_4669)` | global path index `n` |
//! | wave solver | `seed` | configuration index `r` |
//! | a sub-render `g` of a study (e.g. group `g` of a wavelength sweep), render `g` of `speckle g1 --reference` | [`derive_seed`]`(seed, g)` | as its estimator |
//! | tracking (`speckle tracking`): the `U = 0` render, the tracked render of lag `l` | [`derive_seed`]`(seed, 0x747261636b00)`, [`derive_seed`]`(seed, 0x747261636b00 + 1 + l)` | as its estimator |
//!
//! Work is cut into batches that depend only on these counts, so a stream never depends on the
//! thread (or, for sharded runs, the machine) that draws it.

/// A random stream that is a pure function of `(seed, stream)`: Philox4x32-10 (Salmon et al.,
/// "Parallel random numbers: as easy as 1, 2, 3", SC 2011) keyed by the seed, with the stream
/// index in the upper half of the counter and the draw index in the lower half.
///
/// Each path of a render owns the stream of its global path index, so the numbers a path sees do
/// not depend on the thread that runs it. Portable and value-stable across platforms.
///
/// ```
/// use speckle_rng::PathRng;
/// let mut a = PathRng::new(7, 42);
/// let mut b = PathRng::new(7, 42);
/// assert_eq!(a.next_f64(), b.next_f64());
/// assert!((0.0..1.0).contains(&a.next_f64()));
/// ```
#[derive(Debug, Clone)]
pub struct PathRng {
    key: [u32; 2],
    counter: [u32; 4],
    block: [u32; 4],
    used: usize,
}

const M0: u32 = 0xD251_1F53;
const M1: u32 = 0xCD9E_8D57;
const W0: u32 = 0x9E37_79B9;
const W1: u32 = 0xBB67_AE85;

#[inline]
fn mulhilo(a: u32, b: u32) -> (u32, u32) {
    let p = u64::from(a) * u64::from(b);
    ((p >> 32) as u32, p as u32)
}

/// The Philox4x32 bijection with 10 rounds.
#[inline]
pub(crate) fn philox4x32_10(mut c: [u32; 4], mut k: [u32; 2]) -> [u32; 4] {
    for round in 0..10 {
        if round > 0 {
            k[0] = k[0].wrapping_add(W0);
            k[1] = k[1].wrapping_add(W1);
        }
        let (hi0, lo0) = mulhilo(M0, c[0]);
        let (hi1, lo1) = mulhilo(M1, c[2]);
        c = [hi1 ^ c[1] ^ k[0], lo1, hi0 ^ c[3] ^ k[1], lo0];
    }
    c
}

/// The SplitMix64 increment, `2^64 / phi`.
pub const GOLDEN_GAMMA: u64 = 0x9E37_79B9_7F4A_7C15;

/// The SplitMix64 output function (Steele, Lea and Flood, *Fast splittable pseudorandom number
/// generators*, OOPSLA 2014): a bijective 64-bit mixer.
#[inline]
pub fn splitmix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The key of sub-render `index` of a render seeded with `seed`: output `index + 1` of the
/// SplitMix64 sequence seeded with `seed`, so that every sub-render (every group of every
/// wavelength of a study, say) draws from its own Philox key, and nearby seeds or indices give
/// unrelated keys.
///
/// ```
/// use speckle_rng::derive_seed;
/// assert_ne!(derive_seed(1, 0), derive_seed(1, 1));
/// assert_ne!(derive_seed(1, 0), derive_seed(2, 0));
/// ```
#[inline]
pub fn derive_seed(seed: u64, index: u64) -> u64 {
    splitmix64(seed.wrapping_add(GOLDEN_GAMMA.wrapping_mul(index.wrapping_add(1))))
}

/// The SplitMix64 sequence seeded with `seed` as uniform variates in `[0, 1)` (53 bits): a
/// cheap fixed stream for tests and deterministic initialisations, which need no Philox key.
pub fn uniform_stream(seed: u64) -> impl FnMut() -> f64 {
    let mut state = seed;
    move || {
        state = state.wrapping_add(GOLDEN_GAMMA);
        (splitmix64(state) >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

impl PathRng {
    /// The stream `stream` of the generator keyed by `seed`.
    pub fn new(seed: u64, stream: u64) -> Self {
        Self {
            key: [seed as u32, (seed >> 32) as u32],
            counter: [0, 0, stream as u32, (stream >> 32) as u32],
            block: [0; 4],
            used: 4,
        }
    }

    /// The next 32 random bits.
    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        if self.used == 4 {
            self.block = philox4x32_10(self.counter, self.key);
            let (lo, carry) = self.counter[0].overflowing_add(1);
            self.counter[0] = lo;
            self.counter[1] = self.counter[1].wrapping_add(u32::from(carry));
            self.used = 0;
        }
        let v = self.block[self.used];
        self.used += 1;
        v
    }

    /// The next 64 random bits.
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        let lo = u64::from(self.next_u32());
        (u64::from(self.next_u32()) << 32) | lo
    }

    /// A uniform variate in `[0, 1)` with 53 random bits.
    #[inline]
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Two uniform variates.
    #[inline]
    pub fn next_2(&mut self) -> [f64; 2] {
        [self.next_f64(), self.next_f64()]
    }

    /// A standard normal variate (Box-Muller on the next two uniforms, its cosine branch).
    #[inline]
    pub fn standard_normal(&mut self) -> f64 {
        let [u, v] = self.next_2();
        (-2.0 * (1.0 - u).ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }

    /// Three uniform variates.
    #[inline]
    pub fn next_3(&mut self) -> [f64; 3] {
        [self.next_f64(), self.next_f64(), self.next_f64()]
    }
}

/// The examples of the crate's README.md, compiled and run as doctests.
#[doc = include_str!("../README.md")]
#[cfg(doctest)]
pub struct ReadmeDoctests;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn random123_known_answers() {
        // Random123 kat_vectors for philox4x32_10.
        assert_eq!(
            philox4x32_10([0; 4], [0; 2]),
            [0x6627e8d5, 0xe169c58d, 0xbc57ac4c, 0x9b00dbd8]
        );
        assert_eq!(
            philox4x32_10([u32::MAX; 4], [u32::MAX; 2]),
            [0x408f276d, 0x41c83b0e, 0xa20bc7c6, 0x6d5451fd]
        );
        assert_eq!(
            philox4x32_10(
                [0x243f6a88, 0x85a308d3, 0x13198a2e, 0x03707344],
                [0xa4093822, 0x299f31d0]
            ),
            [0xd16cfe09, 0x94fdcceb, 0x5001e420, 0x24126ea1]
        );
    }

    #[test]
    fn value_stability() {
        // Pinned so that a change of the stream layout is noticed (it changes every seeded result).
        let mut r = PathRng::new(1, 2);
        let v: Vec<u64> = (0..3).map(|_| r.next_u64()).collect();
        let mut again = PathRng::new(1, 2);
        assert_eq!(v, (0..3).map(|_| again.next_u64()).collect::<Vec<_>>());
        assert_ne!(PathRng::new(1, 3).next_u64(), v[0]);
        assert_ne!(PathRng::new(2, 2).next_u64(), v[0]);
    }

    #[test]
    fn uniform_moments() {
        let mut r = PathRng::new(3, 0);
        let n = 200_000;
        let (mut s, mut s2) = (0.0, 0.0);
        for _ in 0..n {
            let u = r.next_f64();
            assert!((0.0..1.0).contains(&u));
            s += u;
            s2 += u * u;
        }
        let mean = s / n as f64;
        // Standard error of the mean of U(0,1) is sqrt(1/12/n).
        assert!((mean - 0.5).abs() < 5.0 * (1.0 / 12.0 / n as f64).sqrt());
        assert!((s2 / n as f64 - 1.0 / 3.0).abs() < 5.0 * (4.0 / 45.0 / n as f64).sqrt());
    }
}
