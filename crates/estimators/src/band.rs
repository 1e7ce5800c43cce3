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
//! A band splits into **tiles** of whole image rows ([`ImageBand::new_tile`], `speckle covariance
//! --band R --tile I/N`): a tile keeps the entries `(p, q)` whose pixel `p` lies in its rows. Every
//! kept entry is summed on its own (a general-diagonal batch sum, element by element, and batch
//! means element by element), from pair values that do not depend on which entries are kept, so
//! a tile's entries are bitwise the whole band's (`tiles_are_bitwise_the_whole_band`).
//!
//! **Single scattering alone beyond `R1`** ([`ImageBand::with_single_beyond`], `speckle
//! covariance --band R --single-beyond R1`): beyond the memory-effect range the multiple-
//! scattering part of the covariance vanishes while single scattering keeps a correlation
//! (Bar et al. 2019, Sec. 7 and Fig. 14). The entries whose pixel offset `max(|dx|, |dy|)`
//! exceeds `R1` then receive only the first vertex of each path (the one-vertex sub-path `x1`,
//! `B = 1`: the `single` part of [`crate::render_covariance`] and of
//! [`crate::render_single_scattering`]'s definition), the others every vertex: the later
//! vertices' products are formed for the inner entries only. Outer entries are bitwise the
//! single-scattering part of the full band render, inner ones bitwise its entries
//! (`single_beyond_keeps_inner_entries_and_single_part_outside`); what the outer entries lose
//! is the multiple-scattering part there, the option's bias.
//!
//! What is dropped is reported, not hidden: [`BandEstimate::edge_correlation`] is the largest
//! normalised magnitude `|C| / sqrt(I I)` on the band's outermost ring (offset `radius` along
//! one axis), the level the correlation has fallen to where the band stops.

use crate::covariance::{Target, render_target};
use crate::{CovarianceEstimate, CovarianceOptions, EstimatorError, Scene};
use num_complex::Complex64;
use speckle_medium::Medium;
use speckle_paths::NoFactor;
use speckle_phase::PhaseFunction;
use speckle_stats::Progress;
use std::ops::Range;

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
    /// The image rows `y0..y1` whose pixels `p` are kept (`0..ny` for the whole band).
    y0: usize,
    y1: usize,
    /// Entries whose pixel offset `max(|dx|, |dy|)` exceeds this receive single scattering
    /// only ([`ImageBand::with_single_beyond`]).
    single_beyond: Option<usize>,
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
        Self::new_tile(sources, nx, ny, radius, 0..ny)
    }

    /// The tile of the band of [`ImageBand::new`] that keeps the entries of the pixels in image
    /// rows `rows` (with every partner `q` within the radius, in any row): its arrays have
    /// the shape `(S, rows.len(), nx, S, 2r + 1, 2r + 1)`, rows `rows` of the whole band's.
    /// Errors as [`ImageBand::new`] ([`MAX_BAND_ENTRIES`] counts the tile's entries), and
    /// naming `tile` for rows empty or outside `0..ny`.
    pub fn new_tile(
        sources: usize,
        nx: usize,
        ny: usize,
        radius: usize,
        rows: Range<usize>,
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
        if rows.is_empty() || rows.end > ny {
            return Err(invalid(
                "tile",
                format!("rows {rows:?} are not a tile of an image of {ny} rows"),
            ));
        }
        let w = 2 * radius + 1;
        let len = [sources, nx, rows.len(), sources, w, w]
            .iter()
            .try_fold(1usize, |a, &b| a.checked_mul(b));
        match len {
            Some(n) if n <= MAX_BAND_ENTRIES => Ok(Self {
                sources,
                nx,
                ny,
                radius,
                y0: rows.start,
                y1: rows.end,
                single_beyond: None,
            }),
            _ => Err(invalid(
                "band",
                format!(
                    "{sources}^2 sources x {nx} x {} pixels x {w} x {w} offsets exceed \
                     {MAX_BAND_ENTRIES} entries: a smaller radius or image{}",
                    rows.len(),
                    if rows.len() == ny {
                        ", or tiles (--tile)"
                    } else {
                        ", or more tiles"
                    }
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
        Self::of_tile(scene, nx, ny, radius, 0..ny)
    }

    /// The tile of rows `rows` ([`ImageBand::new_tile`]) of the band of [`ImageBand::of`].
    pub fn of_tile<M: Medium, P: PhaseFunction>(
        scene: &Scene<M, P>,
        nx: usize,
        ny: usize,
        radius: usize,
        rows: Range<usize>,
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
        Self::new_tile(s, nx, ny, radius, rows)
    }

    /// `(S, rows, nx, S, 2r + 1, 2r + 1)`: `rows = ny` for the whole band, the tile's rows for
    /// a tile.
    pub fn shape(&self) -> [usize; 6] {
        let w = 2 * self.radius + 1;
        [self.sources, self.y1 - self.y0, self.nx, self.sources, w, w]
    }

    /// The whole band's shape `(S, ny, nx, S, 2r + 1, 2r + 1)` (of a tile: the band it is a
    /// tile of).
    pub fn whole_shape(&self) -> [usize; 6] {
        let w = 2 * self.radius + 1;
        [self.sources, self.ny, self.nx, self.sources, w, w]
    }

    /// The image rows whose pixels' entries are kept (`0..ny` for the whole band).
    pub fn rows(&self) -> Range<usize> {
        self.y0..self.y1
    }

    /// Whether the band keeps every row (not a proper tile).
    pub fn is_whole(&self) -> bool {
        self.y0 == 0 && self.y1 == self.ny
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

    /// This band with single scattering alone (the first vertex of every path, `B = 1`) in the
    /// entries whose pixel offset `max(|dx|, |dy|)` exceeds `r1` pixels, the full estimator
    /// within (module docs). An error names `--single-beyond` unless `r1 < radius`.
    ///
    /// ```
    /// use speckle_estimators::ImageBand;
    /// let b = ImageBand::new(1, 8, 8, 3).unwrap().with_single_beyond(1).unwrap();
    /// assert_eq!(b.single_beyond(), Some(1));
    /// // 3 x 3 offsets within 1 pixel of the 7 x 7: the other 40 are single-only.
    /// let within = ImageBand::new(1, 8, 8, 1).unwrap().entries().len();
    /// assert_eq!(b.single_only_entries(), b.entries().len() - within);
    /// assert!(ImageBand::new(1, 8, 8, 3).unwrap().with_single_beyond(3).is_err());
    /// ```
    pub fn with_single_beyond(self, r1: usize) -> Result<Self, EstimatorError> {
        if r1 >= self.radius {
            return Err(EstimatorError::InvalidInput {
                field: "--single-beyond".into(),
                reason: format!(
                    "{r1} pixels must be less than the band's radius {} (entries beyond it \
                     receive single scattering only)",
                    self.radius
                ),
            });
        }
        Ok(Self {
            single_beyond: Some(r1),
            ..self
        })
    }

    /// The offset in pixels beyond which entries receive single scattering only, if any
    /// ([`ImageBand::with_single_beyond`]).
    pub fn single_beyond(&self) -> Option<usize> {
        self.single_beyond
    }

    /// The entries of the whole band (inside the image) whose offset `max(|dx|, |dy|)` is at
    /// most `r` pixels (`r <= radius`): `S^2` times the offsets summed over the pixels that
    /// keep them in the image.
    pub fn whole_entries_within(&self, r: usize) -> usize {
        let r = r.min(self.radius);
        let along =
            |n: usize| (0..=r).map(move |d| if d == 0 { n } else { 2 * n.saturating_sub(d) });
        self.sources * self.sources * along(self.ny).sum::<usize>() * along(self.nx).sum::<usize>()
    }

    /// The entries of the whole band that receive single scattering only (0 without
    /// [`ImageBand::with_single_beyond`]).
    pub fn single_only_entries(&self) -> usize {
        self.single_beyond.map_or(0, |r1| {
            self.whole_entries_within(self.radius) - self.whole_entries_within(r1)
        })
    }

    /// Calls `f(element, p, q, offset)` for every array element inside the image: its index
    /// in the flattened array, its pair indices and its pixel offset `max(|dx|, |dy|)`.
    fn each(&self, mut f: impl FnMut(usize, usize, usize, usize)) {
        let r = self.radius as isize;
        let (nx, ny, v) = (self.nx as isize, self.ny as isize, self.nx * self.ny);
        let mut element = 0;
        for s1 in 0..self.sources {
            for y in self.y0 as isize..self.y1 as isize {
                for x in 0..nx {
                    let p = s1 * v + (y * nx + x) as usize;
                    for s2 in 0..self.sources {
                        for dy in -r..=r {
                            for dx in -r..=r {
                                let (yy, xx) = (y + dy, x + dx);
                                if (0..ny).contains(&yy) && (0..nx).contains(&xx) {
                                    let q = s2 * v + (yy * nx + xx) as usize;
                                    f(element, p, q, dy.unsigned_abs().max(dx.unsigned_abs()));
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
        self.each(|_, p, q, _| e.push((p as u32, q as u32)));
        e
    }

    /// The kept entries in render order, the full estimator's first (all of them, in array
    /// order, without [`ImageBand::with_single_beyond`]; else those within `R1` in array order,
    /// then the single-only ones in array order), with each one's position in array order
    /// and the number of full ones.
    fn render_entries(&self) -> (Vec<(u32, u32)>, Vec<usize>, usize) {
        let r1 = self.single_beyond.unwrap_or(self.radius);
        let (mut inner, mut outer) = (vec![], vec![]);
        let mut k = 0;
        self.each(|_, p, q, off| {
            let e = (k, (p as u32, q as u32));
            if off <= r1 {
                inner.push(e)
            } else {
                outer.push(e)
            }
            k += 1;
        });
        let full = inner.len();
        let (position, entries) = inner.into_iter().chain(outer).unzip();
        (entries, position, full)
    }

    /// `values` of the kept entries (in [`ImageBand::entries`] order) laid out in the band's
    /// array, NaN outside the image.
    fn scatter(&self, values: impl Iterator<Item = Complex64>) -> Vec<Complex64> {
        let mut out = vec![Complex64::new(f64::NAN, f64::NAN); self.len()];
        let mut values = values;
        self.each(|i, _, _, _| out[i] = values.next().expect("one value per kept entry"));
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
    /// The correlation summaries of a whole band (`None` for a proper tile, which lacks the
    /// intensities of the rows beyond it).
    pub fn correlation(&self) -> Option<BandCorrelation> {
        if !self.band.is_whole() {
            return None;
        }
        let [s, ny, nx, _, w, _] = self.band.shape();
        let r = self.band.radius;
        let pixel = s * w * w;
        let centre = |s1: usize| s1 * w * w + r * w + r;
        let intensity = (0..s * ny * nx)
            .map(|k| self.value[k * pixel + centre(k / (ny * nx))].re)
            .collect();
        let mut c = BandCorrelation::new(&self.band, intensity);
        for (k, values) in self.value.chunks_exact(pixel).enumerate() {
            c.add_pixel(k / (ny * nx), (k / nx) % ny, k % nx, values);
        }
        Some(c)
    }

    /// The largest `|C[p, q]| / sqrt(C[p, p] C[q, q])` over the band's outermost ring (an
    /// offset of exactly `radius` pixels along one axis, at most along the other): where the
    /// correlation has fallen to when the band stops. `0` for a radius of 0; NaN for a tile
    /// ([`BandCorrelation`] of the merged tiles).
    pub fn edge_correlation(&self) -> f64 {
        self.correlation()
            .map_or(f64::NAN, |c| c.edge_correlation())
    }

    /// The mean correlation `|C| / sqrt(I I)` at each offset `(dy, dx)` (row-major,
    /// `(2r + 1)^2` values), over the pixels and sources whose offset stays in the image
    /// (`s2 = s1`): the shape of the speckle grain, which the band cuts at `radius`. Empty for
    /// a tile.
    pub fn mean_correlation(&self) -> Vec<f64> {
        self.correlation()
            .map_or_else(Vec::new, |c| c.mean_correlation())
    }
}

/// The summaries of a whole band's correlation `rho = |C| / sqrt(I I)` (edge correlation, mean
/// by offset), accumulated pixel by pixel in array order from the image's intensities: a whole
/// render and a merge of tiles that streams them pixel by pixel get bitwise the same.
#[derive(Debug, Clone, PartialEq)]
pub struct BandCorrelation {
    band: ImageBand,
    /// `C[p, p]` of every pixel `p = (s, y, x)`, row-major.
    intensity: Vec<f64>,
    edge: f64,
    sum: Vec<f64>,
    count: Vec<usize>,
}

impl BandCorrelation {
    /// Nothing accumulated yet, for the whole band of `band` (which may be a tile of it) and
    /// the intensities `C[p, p]` of its `S ny nx` pixels (the real parts of the elements
    /// `[s, y, x, s, r, r]`).
    pub fn new(band: &ImageBand, intensity: Vec<f64>) -> Self {
        let w = 2 * band.radius + 1;
        assert_eq!(intensity.len(), band.sources * band.ny * band.nx);
        Self {
            band: *band,
            intensity,
            edge: 0.0,
            sum: vec![0.0; w * w],
            count: vec![0; w * w],
        }
    }

    /// Adds pixel `(s1, y, x)`'s elements `values` (`S (2r + 1)^2`, `[s2, dy, dx]`); pixels must
    /// come in array order (`s1`, then `y`, then `x`) for bitwise reproducible means.
    pub fn add_pixel(&mut self, s1: usize, y: usize, x: usize, values: &[Complex64]) {
        let b = &self.band;
        let (r, w, nx, ny) = (b.radius, 2 * b.radius + 1, b.nx, b.ny);
        let last = 2 * r;
        let at = |s: usize, y: usize, x: usize| self.intensity[(s * ny + y) * nx + x];
        let i1 = at(s1, y, x);
        for s2 in 0..b.sources {
            for dy in 0..w {
                for dx in 0..w {
                    let c = values[(s2 * w + dy) * w + dx];
                    if c.re.is_nan() {
                        continue;
                    }
                    let i2 = at(s2, y + dy - r, x + dx - r);
                    let rho = c.norm() / (i1 * i2).sqrt();
                    if !rho.is_finite() {
                        continue;
                    }
                    if last > 0 && (dy == 0 || dx == 0 || dy == last || dx == last) {
                        self.edge = self.edge.max(rho);
                    }
                    if s1 == s2 {
                        self.sum[dy * w + dx] += rho;
                        self.count[dy * w + dx] += 1;
                    }
                }
            }
        }
    }

    /// See [`BandEstimate::edge_correlation`].
    pub fn edge_correlation(&self) -> f64 {
        self.edge
    }

    /// See [`BandEstimate::mean_correlation`].
    pub fn mean_correlation(&self) -> Vec<f64> {
        self.sum
            .iter()
            .zip(&self.count)
            .map(|(&a, &n)| if n > 0 { a / n as f64 } else { f64::NAN })
            .collect()
    }
}

/// Renders the band `band` of the covariance of `scene` (an image of sensors, see
/// [`ImageBand::of`]): the estimator of [`crate::render_covariance`] with the same paths for
/// the same seed, its kept entries only (module docs); with [`ImageBand::with_single_beyond`],
/// single scattering alone beyond `R1`. Memory: the kept entries' sums, not `J^2`.
pub fn render_covariance_band<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    options: &CovarianceOptions,
    band: &ImageBand,
    progress: &dyn Progress,
) -> Result<BandEstimate, EstimatorError> {
    let (est, position) = render_parts(scene, options, band, progress)?;
    Ok(BandEstimate {
        band: *band,
        value: band.scatter(in_array_order(&est.total.value, &position)),
        std_error: band.scatter(in_array_order(&est.total.std_error, &position)),
        paths: est.paths,
    })
}

/// The band's parts (single, multiple, total) as `E x 1` columns in render order, and each
/// entry's position in array order ([`ImageBand::render_entries`]).
fn render_parts<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    options: &CovarianceOptions,
    band: &ImageBand,
    progress: &dyn Progress,
) -> Result<(CovarianceEstimate, Vec<usize>), EstimatorError> {
    if scene.len() != band.sources * band.nx * band.ny || !crate::connect::is_grid(scene) {
        return Err(EstimatorError::InvalidInput {
            field: "band".into(),
            reason: "the band is not of this scene's pairs (ImageBand::of)".into(),
        });
    }
    let (entries, position, multiple) = band.render_entries();
    let target = Target::Entries {
        entries: &entries,
        multiple,
    };
    let est = render_target(scene, options, &NoFactor, target, progress)?;
    Ok((est, position))
}

/// The `E x 1` column `m` in render order, rearranged into array order by `position`.
fn in_array_order(m: &speckle_stats::CMatrix, position: &[usize]) -> std::vec::IntoIter<Complex64> {
    let mut out = vec![Complex64::ZERO; position.len()];
    for (i, &k) in position.iter().enumerate() {
        out[k] = m.get(i, 0);
    }
    out.into_iter()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{NoProgress, Pair, Sensor, Source};
    use glam::DVec3;
    use speckle_medium::{Aabb, HomogeneousBox};
    use speckle_phase::Phase;

    /// A slab lit by two plane waves, a 5 x 4 far-field image (`J = 40`).
    fn scene() -> Scene<HomogeneousBox, Phase> {
        let b = Aabb::centered(DVec3::ZERO, DVec3::new(10.0, 10.0, 2.0)).unwrap();
        let m = HomogeneousBox::from_mean_free_path(b, 3.0, 1.0).unwrap();
        let step = 2f64.to_radians();
        let (nx, ny) = (5, 4);
        let sensors = (0..nx * ny)
            .map(|i| {
                let (y, x) = ((i / nx) as f64 - 1.5, (i % nx) as f64 - 2.0);
                Sensor::far_field(DVec3::new((x * step).tan(), (y * step).tan(), 1.0)).unwrap()
            })
            .collect();
        let sources = vec![
            Source::plane_wave(DVec3::Z).unwrap(),
            Source::plane_wave(DVec3::new(0.05, 0.0, 1.0)).unwrap(),
        ];
        Scene::new(
            m,
            Phase::hg(0.5).unwrap(),
            1.0,
            sources,
            sensors,
            Pair::all(2, nx * ny),
        )
        .unwrap()
    }

    /// Every tile's elements (values and standard errors, NaN offsets included) are bitwise
    /// the whole band's in the tile's rows, for any split of the rows, with two sources (the
    /// tiles interleave per `s1`); the correlation summaries of the whole band are those of
    /// its pixels streamed in order.
    #[test]
    fn tiles_are_bitwise_the_whole_band() {
        let s = scene();
        let opts = CovarianceOptions {
            paths: 600,
            seed: 7,
            ..Default::default()
        };
        let whole = ImageBand::of(&s, 5, 4, 1).unwrap();
        let w = render_covariance_band(&s, &opts, &whole, &NoProgress).unwrap();
        let bits = |v: &[Complex64]| -> Vec<(u64, u64)> {
            v.iter().map(|z| (z.re.to_bits(), z.im.to_bits())).collect()
        };
        let [ns, ny, nx, _, k, _] = whole.shape();
        let pixel = ns * k * k;
        for splits in [&[0, 1, 4][..], &[0, 2, 3, 4], &[0, 1, 2, 3, 4]] {
            for t in splits.windows(2) {
                let tile = ImageBand::of_tile(&s, 5, 4, 1, t[0]..t[1]).unwrap();
                assert_eq!(tile.shape(), [ns, t[1] - t[0], nx, ns, k, k]);
                let e = render_covariance_band(&s, &opts, &tile, &NoProgress).unwrap();
                assert_eq!(e.paths, w.paths);
                assert!(e.edge_correlation().is_nan() && e.mean_correlation().is_empty());
                for s1 in 0..ns {
                    let rows = |v: &[Complex64], y0: usize, y1: usize, n: usize| {
                        bits(&v[(s1 * n + y0) * nx * pixel..(s1 * n + y1) * nx * pixel])
                    };
                    let n = t[1] - t[0];
                    assert_eq!(rows(&e.value, 0, n, n), rows(&w.value, t[0], t[1], ny));
                    assert_eq!(
                        rows(&e.std_error, 0, n, n),
                        rows(&w.std_error, t[0], t[1], ny)
                    );
                }
            }
        }
        assert!(w.edge_correlation() > 0.0);
        assert_eq!(w.mean_correlation().len(), k * k);
        let e = ImageBand::of_tile(&s, 5, 4, 1, 2..5)
            .unwrap_err()
            .to_string();
        assert!(e.contains("tile"), "{e}");
    }

    /// `--single-beyond R1`: the entries beyond `R1` pixels hold bitwise the single-scattering
    /// part of the full band render on the same paths (values and standard errors, which are
    /// the single part's since the multiple part is zero there), the entries within `R1`
    /// bitwise the full band's; tiles of it are bitwise its rows; `R1 >= R` is refused naming
    /// the flag.
    #[test]
    fn single_beyond_keeps_inner_entries_and_single_part_outside() {
        let s = scene();
        let opts = CovarianceOptions {
            paths: 600,
            seed: 3,
            ..Default::default()
        };
        let full = ImageBand::of(&s, 5, 4, 2).unwrap();
        let (parts, position) = render_parts(&s, &opts, &full, &NoProgress).unwrap();
        let whole = |m: &speckle_stats::CMatrix| full.scatter(in_array_order(m, &position));
        let (single, single_se) = (whole(&parts.single.value), whole(&parts.single.std_error));
        let (total, total_se) = (whole(&parts.total.value), whole(&parts.total.std_error));
        let same = |a: Complex64, b: Complex64| {
            a.re.to_bits() == b.re.to_bits() && a.im.to_bits() == b.im.to_bits()
        };
        let r = full.radius() as isize;
        let k = 2 * full.radius() + 1;
        for r1 in [0, 1] {
            let band = full.with_single_beyond(r1).unwrap();
            let e = render_covariance_band(&s, &opts, &band, &NoProgress).unwrap();
            let (mut inner, mut outer, mut dropped) = (0, 0, 0.0f64);
            for (i, (&v, &se)) in e.value.iter().zip(&e.std_error).enumerate() {
                let (dy, dx) = ((i / k) % k, i % k);
                let off = (dy as isize - r)
                    .unsigned_abs()
                    .max((dx as isize - r).unsigned_abs());
                if v.re.is_nan() {
                    assert!(total[i].re.is_nan());
                } else if off <= r1 {
                    assert!(same(v, total[i]) && same(se, total_se[i]), "inner {i}");
                    inner += 1;
                } else {
                    // x + 0.0 is x: the total of a zero multiple part is the single part.
                    assert!(v == single[i] && se == single_se[i], "outer {i}");
                    dropped = dropped.max((total[i] - v).norm());
                    outer += 1;
                }
            }
            assert_eq!(outer, band.single_only_entries());
            assert_eq!(inner + outer, full.entries().len());
            assert!(
                dropped > 0.0,
                "the full render has multiple scattering beyond {r1}"
            );
            // Tiles with the option are bitwise its rows.
            let [ns, _, nx, _, _, _] = band.shape();
            let pixel = ns * k * k;
            for t in [0..1, 1..4] {
                let tile = ImageBand::of_tile(&s, 5, 4, 2, t.clone())
                    .unwrap()
                    .with_single_beyond(r1)
                    .unwrap();
                let te = render_covariance_band(&s, &opts, &tile, &NoProgress).unwrap();
                for s1 in 0..ns {
                    let n = t.len();
                    let a = &te.value[s1 * n * nx * pixel..(s1 + 1) * n * nx * pixel];
                    let b =
                        &e.value[(s1 * 4 + t.start) * nx * pixel..(s1 * 4 + t.end) * nx * pixel];
                    assert!(a.iter().zip(b).all(|(&a, &b)| same(a, b)), "tile {t:?}");
                }
            }
        }
        let err = full.with_single_beyond(2).unwrap_err().to_string();
        assert!(err.contains("--single-beyond"), "{err}");
    }
}
