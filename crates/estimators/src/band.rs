//! Covariances of whole images in bounded memory: the entries of a band around the diagonal of
//! an image's covariance (issue 29, item 3).
//!
//! A covariance of a `256 x 256`-pixel image (`J = 65 536` pairs) holds `J^2 = 4.3e9` entries,
//! 69 GB, but the speckle grain and the memory effect make almost all of them zero: the field
//! at one pixel correlates only with pixels within a few grains of it (`speckle plan` predicts
//! the grain and the memory-effect range before rendering). [`render_covariance_band`] renders
//! only the entries whose sensors lie within `radius` pixels of each other along both image
//! axes, for every pair of sources: `S^2 (2 r + 1)^2` entries per pixel, accumulated entry by
//! entry (`O(E)` per vertex, `E` the number of kept entries) by the same estimator, paths and
//! batches as [`crate::render_covariance`]; each kept entry equals the dense render's to
//! rounding (the dense one sums through rank-`K` blocks).
//!
//! What is dropped is reported, not hidden: [`BandEstimate::edge_correlation`] is the largest
//! normalised magnitude `|C| / sqrt(I I)` on the band's outermost ring (offset `radius` along
//! one axis), the level the correlation has fallen to where the band stops.

use crate::covariance::{Target, render_target};
use crate::{CovarianceOptions, EstimatorError, Scene};
use num_complex::Complex64;
use speckle_medium::Medium;
use speckle_paths::NoFactor;
use speckle_phase::PhaseFunction;
use speckle_stats::Progress;

/// At most this many kept entries (`2^25`: about 3 GB of sums and moments while rendering).
pub const MAX_BAND_ENTRIES: usize = 1 << 25;

/// The band of an image's covariance: a scene of `sources` sources and an `ny x nx` image of
/// sensors (row-major) whose pairs are every combination, source-major (`Pair::all`), and the
/// kept entries `C[(s1, (y, x)), (s2, (y + dy, x + dx))]` with `|dx|, |dy| <= radius`.
///
/// Its arrays have the shape [`ImageBand::shape`], `(S, ny, nx, S, 2r + 1, 2r + 1)`, indexed
/// `[s1, y, x, s2, dy + r, dx + r]`; offsets that leave the image hold NaN.
///
/// ```
/// use speckle_estimators::ImageBand;
/// let b = ImageBand::new(1, 4, 3, 1).unwrap();
/// assert_eq!(b.shape(), [1, 3, 4, 1, 3, 3]);
/// // Pixel (0, 0) keeps itself, its right, lower and lower-right neighbours.
/// assert_eq!(b.entries().iter().filter(|(p, _)| *p == 0).count(), 4);
/// assert!(ImageBand::new(1, 4, 3, 4).is_err());
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageBand {
    sources: usize,
    nx: usize,
    ny: usize,
    radius: usize,
}

impl ImageBand {
    /// A band of half-width `radius` pixels over `sources` sources and an `ny x nx` image.
    /// Errors name `band` (a radius reaching across the whole image, which a dense covariance
    /// renders, or more than [`MAX_BAND_ENTRIES`] entries) or `sensors` (an empty image).
    pub fn new(
        sources: usize,
        nx: usize,
        ny: usize,
        radius: usize,
    ) -> Result<Self, EstimatorError> {
        let invalid = |field: &str, reason: String| EstimatorError::InvalidInput {
            field: field.into(),
            reason,
        };
        if sources == 0 || nx == 0 || ny == 0 {
            return Err(invalid(
                "sensors",
                format!("a band needs sources and an image (got {sources} sources, {nx} x {ny})"),
            ));
        }
        if radius >= nx.max(ny) {
            return Err(invalid(
                "band",
                format!(
                    "the radius {radius} reaches across the {nx} x {ny} image: render the dense \
                     covariance instead"
                ),
            ));
        }
        let w = 2 * radius + 1;
        let len = [sources, nx, ny, sources, w, w]
            .iter()
            .try_fold(1usize, |a, &b| a.checked_mul(b));
        match len {
            Some(n) if n <= MAX_BAND_ENTRIES => Ok(Self {
                sources,
                nx,
                ny,
                radius,
            }),
            _ => Err(invalid(
                "band",
                format!(
                    "{sources}^2 sources x {nx} x {ny} pixels x {w} x {w} offsets exceed \
                     {MAX_BAND_ENTRIES} entries: a smaller radius or image"
                ),
            )),
        }
    }

    /// The band of a scene whose pairs are every (source, sensor) combination of an `ny x nx`
    /// image of sensors. Errors name `pairs` or `sensors` when the scene is not one, `band`
    /// as [`ImageBand::new`].
    pub fn of<M: Medium, P: PhaseFunction>(
        scene: &Scene<M, P>,
        nx: usize,
        ny: usize,
        radius: usize,
    ) -> Result<Self, EstimatorError> {
        let (s, v) = (scene.sources().len(), scene.sensors().len());
        if nx.checked_mul(ny) != Some(v) {
            return Err(EstimatorError::InvalidInput {
                field: "sensors".into(),
                reason: format!("{v} sensors are not an image of {nx} x {ny}"),
            });
        }
        if !crate::connect::is_grid(scene) || scene.len() != s * v {
            return Err(EstimatorError::InvalidInput {
                field: "pairs".into(),
                reason: "a band needs every (source, sensor) pair, source-major (no `pairs`)"
                    .into(),
            });
        }
        Self::new(s, nx, ny, radius)
    }

    /// `(S, ny, nx, S, 2r + 1, 2r + 1)`.
    pub fn shape(&self) -> [usize; 6] {
        let w = 2 * self.radius + 1;
        [self.sources, self.ny, self.nx, self.sources, w, w]
    }

    /// The number of array elements (kept entries and NaN offsets outside the image).
    pub fn len(&self) -> usize {
        self.shape().iter().product()
    }

    /// Whether the band is empty (never: [`ImageBand::new`] refuses empty images).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The half-width in pixels.
    pub fn radius(&self) -> usize {
        self.radius
    }

    /// Calls `f(element, p, q)` for every array element inside the image: its index in the
    /// flattened array and its pair indices.
    fn each(&self, mut f: impl FnMut(usize, usize, usize)) {
        let r = self.radius as isize;
        let (nx, ny, v) = (self.nx as isize, self.ny as isize, self.nx * self.ny);
        let mut element = 0;
        for s1 in 0..self.sources {
            for y in 0..ny {
                for x in 0..nx {
                    let p = s1 * v + (y * nx + x) as usize;
                    for s2 in 0..self.sources {
                        for dy in -r..=r {
                            for dx in -r..=r {
                                let (yy, xx) = (y + dy, x + dx);
                                if (0..ny).contains(&yy) && (0..nx).contains(&xx) {
                                    f(element, p, s2 * v + (yy * nx + xx) as usize);
                                }
                                element += 1;
                            }
                        }
                    }
                }
            }
        }
        debug_assert_eq!(element, self.len());
    }

    /// The kept entries `(p, q)` in array order (those inside the image).
    pub fn entries(&self) -> Vec<(u32, u32)> {
        let mut e = vec![];
        self.each(|_, p, q| e.push((p as u32, q as u32)));
        e
    }

    /// `values` of the kept entries (in [`ImageBand::entries`] order) laid out in the band's
    /// array, NaN outside the image.
    fn scatter(&self, values: impl Iterator<Item = Complex64>) -> Vec<Complex64> {
        let mut out = vec![Complex64::new(f64::NAN, f64::NAN); self.len()];
        let mut values = values;
        self.each(|i, _, _| out[i] = values.next().expect("one value per kept entry"));
        out
    }
}

/// A band of an image's covariance ([`render_covariance_band`]).
#[derive(Debug, Clone, PartialEq)]
pub struct BandEstimate {
    /// The band.
    pub band: ImageBand,
    /// The covariance at every element of the band's array ([`ImageBand::shape`]; NaN outside
    /// the image).
    pub value: Vec<Complex64>,
    /// Standard errors: real part of `Re C`'s, imaginary part of `Im C`'s.
    pub std_error: Vec<Complex64>,
    /// Number of sampled sub-paths.
    pub paths: u64,
}

impl BandEstimate {
    /// Calls `f(s1, s2, dy, dx, rho)` with `rho = |C| / sqrt(I I)` for every element inside the
    /// image whose `rho` is finite (`dy`, `dx` the array's offset indices, `0..2r + 1`).
    fn each_correlation(&self, mut f: impl FnMut(usize, usize, usize, usize, f64)) {
        let [s, ny, nx, _, w, _] = self.band.shape();
        let r = self.band.radius;
        let at = |s1: usize, y: usize, x: usize, s2: usize, dy: usize, dx: usize| {
            self.value[((((s1 * ny + y) * nx + x) * s + s2) * w + dy) * w + dx]
        };
        for s1 in 0..s {
            for y in 0..ny {
                for x in 0..nx {
                    let i1 = at(s1, y, x, s1, r, r).re;
                    for s2 in 0..s {
                        for dy in 0..w {
                            for dx in 0..w {
                                let c = at(s1, y, x, s2, dy, dx);
                                if c.re.is_nan() {
                                    continue;
                                }
                                let i2 = at(s2, y + dy - r, x + dx - r, s2, r, r).re;
                                let rho = c.norm() / (i1 * i2).sqrt();
                                if rho.is_finite() {
                                    f(s1, s2, dy, dx, rho);
                                }
                            }
                        }
                    }
                }
            }
        }
    }

    /// The largest `|C[p, q]| / sqrt(C[p, p] C[q, q])` over the band's outermost ring (an
    /// offset of exactly `radius` pixels along one axis, at most along the other): where the
    /// correlation has fallen to when the band stops. `0` for a radius of 0.
    pub fn edge_correlation(&self) -> f64 {
        let last = 2 * self.band.radius;
        let mut max: f64 = 0.0;
        if last > 0 {
            self.each_correlation(|_, _, dy, dx, rho| {
                if dy == 0 || dx == 0 || dy == last || dx == last {
                    max = max.max(rho);
                }
            });
        }
        max
    }

    /// The mean correlation `|C| / sqrt(I I)` at each offset `(dy, dx)` (row-major,
    /// `(2r + 1)^2` values), over the pixels and sources whose offset stays in the image
    /// (`s2 = s1`): the shape of the speckle grain, which the band cuts at `radius`.
    pub fn mean_correlation(&self) -> Vec<f64> {
        let w = 2 * self.band.radius + 1;
        let (mut sum, mut count) = (vec![0.0; w * w], vec![0usize; w * w]);
        self.each_correlation(|s1, s2, dy, dx, rho| {
            if s1 == s2 {
                sum[dy * w + dx] += rho;
                count[dy * w + dx] += 1;
            }
        });
        sum.iter()
            .zip(&count)
            .map(|(&a, &n)| if n > 0 { a / n as f64 } else { f64::NAN })
            .collect()
    }
}

/// Renders the band `band` of the covariance of `scene` (an image of sensors, see
/// [`ImageBand::of`]): the estimator of [`crate::render_covariance`] with the same paths for
/// the same seed, its kept entries only (module docs). Memory: the kept entries' sums, not
/// `J^2`.
pub fn render_covariance_band<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    options: &CovarianceOptions,
    band: &ImageBand,
    progress: &dyn Progress,
) -> Result<BandEstimate, EstimatorError> {
    if scene.len() != band.sources * band.nx * band.ny || !crate::connect::is_grid(scene) {
        return Err(EstimatorError::InvalidInput {
            field: "band".into(),
            reason: "the band is not of this scene's pairs (ImageBand::of)".into(),
        });
    }
    let entries = band.entries();
    let est = render_target(
        scene,
        options,
        &NoFactor,
        Target::Entries(&entries),
        progress,
    )?;
    let column =
        |m: &speckle_stats::CMatrix| (0..m.rows()).map(|i| m.get(i, 0)).collect::<Vec<_>>();
    Ok(BandEstimate {
        band: *band,
        value: band.scatter(column(&est.total.value).into_iter()),
        std_error: band.scatter(column(&est.total.std_error).into_iter()),
        paths: est.paths,
    })
}
