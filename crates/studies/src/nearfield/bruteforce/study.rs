//! The comparison's renders: the near field twice, the brute force with its contractions,
//! the biased reference, the timing render.

use super::*;

/// One near-field render of the comparison.
#[derive(Debug, Clone)]
pub struct NearRender {
    /// Its label.
    pub label: &'static str,
    /// `render.beams` of the render.
    pub strategy: BeamStrategy,
    /// The estimate.
    pub estimate: CovarianceEstimate,
    /// Wall time per path, seconds.
    pub time_per_path: f64,
    /// The per-path variance summed over the diagonal (real parts).
    pub variance: f64,
    /// Against the apodized brute force, with the Eq. 25 model error in the band.
    pub apodized: Comparison,
    /// Against the biased reference (no model band: it makes the closed forms' approximation).
    pub biased: Comparison,
    /// Against the binary-aperture brute force (no band: a measured model difference).
    pub binary: Comparison,
}

/// The result of a brute-force comparison.
#[derive(Debug, Clone)]
pub struct BruteForce {
    /// The quadrature's largest deviations from the beams' fields on a unit grid over the box.
    pub quadrature_error: QuadratureError,
    /// The binary mask's half-width `a`, radians.
    pub binary_half_width: f64,
    /// Per diagonal entry, the binary over the apodized intensity to single scattering
    /// ([`BruteForceStudy::single_scattering_ratios`]).
    pub single_scattering_ratio: Vec<f64>,
    /// Source plane waves `Q`.
    pub q: usize,
    /// Sensor plane waves `P` (both apertures).
    pub p: usize,
    /// The near-field renders: importance sampling around the beams, then uniform.
    pub near: Vec<NearRender>,
    /// The brute force with the apodized (vMF) apertures.
    pub brute: Estimate,
    /// The brute force with binary apertures (the same paths).
    pub binary: Estimate,
    /// The biased reference: the apodized brute force with every plane wave attenuated along
    /// its aperture's axis (the first `render.biased_paths` of the same paths).
    pub biased: Estimate,
    /// Binary minus apodized, path by path (paired standard errors).
    pub binary_minus_apodized: Estimate,
    /// Biased minus apodized, path by path over the biased reference's paths.
    pub biased_minus_apodized: Estimate,
    /// Wall time of the brute-force render with its contractions, seconds.
    pub brute_seconds: f64,
    /// Wall time of the biased reference's render with its contraction, seconds.
    pub biased_seconds: f64,
    /// The brute force's time per path, from the timing render.
    pub brute_time_per_path: f64,
    /// The brute force's per-path variance summed over the diagonal.
    pub brute_variance: f64,
    /// Wall time of the whole study, seconds.
    pub wall: f64,
}

impl BruteForceStudy {
    /// Wavenumber `2 pi` (lengths in wavelengths).
    pub fn k(&self) -> f64 {
        TAU
    }

    /// The box.
    pub(super) fn medium(&self) -> Result<HomogeneousBox, EstimatorError> {
        let [lat, depth] = self.file.size;
        let bounds = Aabb::flat(
            glam::DVec2::new(-0.5 * lat, -0.5 * depth),
            glam::DVec2::new(0.5 * lat, 0.5 * depth),
        )
        .map_err(|e| invalid("size")(e.to_string()))?;
        HomogeneousBox::from_mean_free_path(bounds, self.file.mean_free_path, 1.0)
            .map_err(|e| invalid("mean_free_path")(e.to_string()))
    }

    pub(super) fn focus(&self, x: f64) -> DVec3 {
        DVec3::new(x, self.file.focus_depth, 0.0)
    }

    /// The source beams and the sensor beams with their viewing axes.
    pub fn beams(&self) -> Result<Beams, EstimatorError> {
        let f = &self.file;
        let axis = DVec3::Y;
        let beam = |x: f64, a: DVec3| {
            GaussianBeam::new("beam", self.focus(x), a, f.concentration)
                .map_err(|e| invalid("concentration")(e.to_string()))
        };
        let (delta, tau) = (f.source_offset, f.sensor_shift);
        let sources = vec![beam(0.0, axis)?, beam(delta, axis)?];
        let sensors = vec![
            (beam(tau, axis)?, axis),
            (beam(tau + delta, axis)?, axis),
            (beam(0.0, -axis)?, -axis),
        ];
        Ok((sources, sensors))
    }

    /// The binary mask's half-width `a` (radians; see [`binary_half_width`]).
    pub fn binary_half_width(&self) -> f64 {
        binary_half_width(self.file.concentration, self.file.theta_max)
    }

    /// The quadrature nodes of the aperture about `axis`: Gauss-Legendre in the angle `t` from
    /// the axis on three pieces, `binary_nodes` on `[-a, a]` and half the rest on each of
    /// `[-theta_max, -a]` and `[a, theta_max]` (so that the binary mask, discontinuous at
    /// `+-a`, is integrated by the middle piece alone, exactly for its smooth integrand, and the
    /// apodized mask by all three). Each node carries both masks' weights `W_q m(w_q)`, each
    /// normalised so that its sum is 1 (`u(f) = 1` in free space; `C_2 = 1 / (2 pi I_0(gamma))`
    /// for the apodized mask, the rest of the circle neglected).
    pub fn aperture(&self, axis: DVec3) -> Vec<Node> {
        let f = &self.file;
        let (gamma, tm, a) = (f.concentration, f.theta_max, self.binary_half_width());
        let tail = (f.nodes - f.binary_nodes) / 2;
        let piece = |n: usize, lo: f64, hi: f64, inside: bool| {
            gauss_legendre(n).into_iter().map(move |(x, w)| {
                let h = 0.5 * (hi - lo);
                (0.5 * (hi + lo) + h * x, h * w, inside)
            })
        };
        let raw: Vec<(f64, f64, bool)> = piece(tail, -tm, -a, false)
            .chain(piece(f.binary_nodes, -a, a, true))
            .chain(piece(tail, a, tm, false))
            .collect();
        let apo = |t: f64, w: f64| w * (gamma * (t.cos() - 1.0)).exp();
        let total_apo: f64 = raw.iter().map(|&(t, w, _)| apo(t, w)).sum();
        let total_bin: f64 = raw.iter().filter(|n| n.2).map(|n| n.1).sum();
        raw.into_iter()
            .map(|(t, w, inside)| Node {
                dir: rotate(axis, t),
                apodized: apo(t, w) / total_apo,
                binary: if inside { w / total_bin } else { 0.0 },
            })
            .collect()
    }

    /// The near-field scene: the beams, all pairs source-major.
    pub fn near_scene(&self) -> Result<Scene<HomogeneousBox, Phase>, EstimatorError> {
        let (src, sen) = self.beams()?;
        Ok(Scene::new(
            self.medium()?,
            Phase::isotropic(Dimension::Two),
            1.0,
            src.iter().map(|b| Source::GaussianBeam(*b)).collect(),
            sen.iter().map(|(b, _)| Sensor::GaussianBeam(*b)).collect(),
            Pair::all(2, 3),
        )?)
    }

    /// The largest deviations of the source apertures' plane-wave superpositions from the
    /// beams' fields on the unit grid over the box (spacing `ceil(size / 64)` beyond 64
    /// wavelengths): the apodized one against the Gaussian beam's closed form, the binary one
    /// against a direct integral of its mask, `u(x) = (1 / 2a) int_{-a}^{a} e^(i k w(t) . (x -
    /// f)) dt`, by the composite Simpson rule on `N` even panels of width `h = 2 a / N`, `N`
    /// the least with `h k r <= 0.01` (`r` the box's diagonal, the largest `|x - f|`), at least
    /// 4000 and at most 40 000: its error is below `h^4 max |d^4 u / dt^4| / 180`, and that
    /// derivative is `(k r)^4 (1 + O(1 / (k r)))`, so below `6e-11` (where the cap does not
    /// bind: `2 a k r <= 400`).
    pub fn quadrature_error(&self) -> Result<QuadratureError, EstimatorError> {
        let (src, _) = self.beams()?;
        let nodes = self.aperture(DVec3::Y);
        let [lat, depth] = self.file.size;
        let k = self.k();
        let a = self.binary_half_width();
        let r = lat.hypot(depth);
        let panels = (((2.0 * a * k * r / 0.01).ceil() as usize).clamp(4000, 40_000) + 1) & !1;
        let h = 2.0 * a / panels as f64;
        let simpson: Vec<(DVec3, f64)> = (0..=panels)
            .map(|i| {
                let c = if i == 0 || i == panels {
                    1.0
                } else if i % 2 == 1 {
                    4.0
                } else {
                    2.0
                };
                (rotate(DVec3::Y, -a + h * i as f64), c * h / 3.0 / (2.0 * a))
            })
            .collect();
        let sum = |x: DVec3, w: &mut dyn Iterator<Item = (DVec3, f64)>| -> Complex64 {
            w.map(|(w, m)| m * Complex64::from_polar(1.0, k * w.dot(x)))
                .sum()
        };
        // A unit grid, coarser in a box over 64 wavelengths.
        let (sx, sy) = ((lat / 64.0).ceil().max(1.0), (depth / 64.0).ceil().max(1.0));
        let mut worst = QuadratureError {
            apodized: 0.0,
            binary: 0.0,
        };
        for b in &src {
            for ix in 0..=((lat / sx).floor() as usize) {
                for iy in 0..=((depth / sy).floor() as usize) {
                    let x = DVec3::new(
                        -0.5 * lat + sx * ix as f64,
                        -0.5 * depth + sy * iy as f64,
                        0.0,
                    );
                    let d = x - b.focus;
                    let apo = sum(d, &mut nodes.iter().map(|n| (n.dir, n.apodized)));
                    let bin = sum(d, &mut nodes.iter().map(|n| (n.dir, n.binary)));
                    let direct = sum(d, &mut simpson.iter().copied());
                    worst.apodized = worst
                        .apodized
                        .max((apo - b.field(Dimension::Two, k, x)).norm());
                    worst.binary = worst.binary.max((bin - direct).norm());
                }
            }
        }
        Ok(worst)
    }

    /// A single-scattering estimate of the binary over the apodized brute force, per diagonal
    /// entry `3 i + v` (an independent check of their difference, reported): to single
    /// scattering off isotropic scatterers an intensity is `sigma_s |f|^2 int |u_i(x)|^2
    /// |u_v(x)|^2 e^(-sigma_t (d_i + d_v)) dx` over the box, with `u` the beams' free-space
    /// fields (here their quadratures) and `d` the distances to the boundary along the axes,
    /// so the ratio depends on the two masks' focal spots alone (midpoint rule on a grid of
    /// spacing 0.1 wavelength, at most 400 x 400 points). Multiple scattering, whose ratio is
    /// near the beams' power ratio (`int m^2 dt`, 2.6% apart here), pulls the measured ratio
    /// towards 1.
    pub fn single_scattering_ratios(&self) -> Result<Vec<f64>, EstimatorError> {
        let (src, sen) = self.beams()?;
        let k = self.k();
        let [lat, depth] = self.file.size;
        let st = 1.0 / self.file.mean_free_path;
        let (nx, ny) = (
            ((lat / 0.1).ceil() as usize).min(400),
            ((depth / 0.1).ceil() as usize).min(400),
        );
        let (hx, hy) = (lat / nx as f64, depth / ny as f64);
        // |u|^2 e^(-sigma_t d) of a beam on the grid, for both masks.
        let map = |b: &GaussianBeam, sensor: bool| -> [Vec<f64>; 2] {
            let nodes = self.aperture(b.axis);
            let mut out = [vec![0.0; nx * ny], vec![0.0; nx * ny]];
            for ix in 0..nx {
                for iy in 0..ny {
                    let x = DVec3::new(
                        -0.5 * lat + hx * (ix as f64 + 0.5),
                        -0.5 * depth + hy * (iy as f64 + 0.5),
                        0.0,
                    );
                    // A source's light enters from the side its axis comes from; a sensor
                    // (source form: the axis reversed) reads towards the side its axis points.
                    let along = if sensor { b.axis } else { -b.axis };
                    let d = if along.y > 0.0 {
                        0.5 * depth - x.y
                    } else {
                        x.y + 0.5 * depth
                    };
                    let att = (-st * d).exp();
                    for (m, o) in out.iter_mut().enumerate() {
                        let u: Complex64 = nodes
                            .iter()
                            .map(|n| {
                                let w = if m == 0 { n.apodized } else { n.binary };
                                w * Complex64::from_polar(1.0, k * n.dir.dot(x - b.focus))
                            })
                            .sum();
                        o[ix * ny + iy] = u.norm_sqr() * att;
                    }
                }
            }
            out
        };
        let src_maps: Vec<[Vec<f64>; 2]> = src.iter().map(|b| map(b, false)).collect();
        let sen_maps: Vec<[Vec<f64>; 2]> = sen.iter().map(|(b, _)| map(b, true)).collect();
        let mut ratios = Vec::with_capacity(J);
        for si in &src_maps {
            for sv in &sen_maps {
                let overlap =
                    |m: usize| -> f64 { si[m].iter().zip(&sv[m]).map(|(a, b)| a * b).sum() };
                ratios.push(overlap(1) / overlap(0));
            }
        }
        Ok(ratios)
    }

    /// The rough cost on `threads` threads.
    pub fn estimate(&self, threads: usize) -> speckle_scene::cost::Estimate {
        use speckle_scene::cost::{covariance_seconds, expected_vertices, gaussian_legs};
        let f = &self.file;
        let r = &f.render;
        let t = 1.0 / f.mean_free_path;
        let v = expected_vertices(
            &[t * f.size[0], t * f.size[1]],
            1.0,
            0.0,
            Dimension::Two,
            u32::MAX,
        );
        let (q, p) = (f.nodes as f64, 2.0 * f.nodes as f64);
        let near =
            2.0 * covariance_seconds(r.near_paths as f64, v, gaussian_legs(5.0, 1), J as f64);
        // The brute force: Q + P legs and Q P pair products per vertex, then the contraction.
        let biased = r.biased_paths.unwrap_or(r.paths);
        let far = covariance_seconds(
            (r.paths + biased + r.timing_paths) as f64,
            v,
            q + p + q * p,
            0.0,
        ) + (2 * r.paths + biased) as f64 * 2.0 * q * p * 8.0 / 6e10;
        let chunk = r.chunk.min(r.paths) as f64;
        speckle_scene::cost::Estimate {
            bytes: chunk * q * p * 16.0 * 2.0 + 1e6,
            memory_field: "render.chunk".into(),
            seconds: (near + far) / threads.max(1) as f64,
            time_field: "render.paths".into(),
            vertices_per_path: v,
        }
    }

    /// The brute-force seed of chunk `c`.
    pub(super) fn chunk_seed(&self, c: u64) -> u64 {
        let r = &self.file.render;
        r.brute_force_seed.unwrap_or_else(|| derive_seed(r.seed, 1)) + c
    }

    /// Renders the near field twice (importance sampling around the beams, then uniform; both
    /// with `render.seed`), the brute force in chunks, and its timing render.
    pub fn render(&self, progress: &dyn Progress) -> Result<BruteForce, StudyError> {
        let start = Instant::now();
        let f = &self.file;
        let r = &f.render;
        let k = self.k();
        let quadrature_error = self.quadrature_error()?;
        let scene_near = self.near_scene()?;
        let near_with = |beams| -> Result<(CovarianceEstimate, f64), StudyError> {
            let t0 = Instant::now();
            let c = render_covariance(
                &scene_near,
                &CovarianceOptions {
                    paths: r.near_paths,
                    seed: r.seed,
                    coherence: Coherence::ForwardAndReversed,
                    sampling: TracerConfig {
                        beams,
                        ..Default::default()
                    },
                },
                progress,
            )?;
            Ok((c, t0.elapsed().as_secs_f64() / r.near_paths as f64))
        };
        let nears = [
            (
                "importance sampling",
                BeamStrategy::PositionAndDirection,
                near_with(BeamStrategy::PositionAndDirection)?,
            ),
            ("uniform", BeamStrategy::Off, near_with(BeamStrategy::Off)?),
        ];

        // Brute force: every plane wave of the source aperture to every far-field direction of
        // the sensor apertures (transmission about +axis, reflection about -axis).
        let axis = DVec3::Y;
        let (src_beams, sen_beams) = self.beams()?;
        let src_nodes = self.aperture(axis);
        let sen_nodes: Vec<Vec<Node>> = [axis, -axis].iter().map(|a| self.aperture(*a)).collect();
        let sen_dirs: Vec<DVec3> = sen_nodes.iter().flatten().map(|n| n.dir).collect();
        let (q, p) = (src_nodes.len(), sen_dirs.len());
        let plane = |e: speckle_endpoints::EndpointError| invalid("nodes")(e.to_string());
        let far_scene = |medium| -> Result<Scene<_, Phase>, EstimatorError> {
            Ok(Scene::new(
                medium,
                Phase::isotropic(Dimension::Two),
                1.0,
                src_nodes
                    .iter()
                    .map(|n| Source::plane_wave(n.dir).map_err(plane))
                    .collect::<Result<_, _>>()?,
                sen_dirs
                    .iter()
                    .map(|w| Sensor::far_field(*w).map_err(plane))
                    .collect::<Result<_, _>>()?,
                Pair::all(q, p),
            )?)
        };
        let scene_far = far_scene(self.medium()?)?;
        let scene_biased = Scene::new(
            AxialAttenuation {
                inner: self.medium()?,
                axis,
            },
            Phase::isotropic(Dimension::Two),
            1.0,
            scene_far.sources().to_vec(),
            scene_far.sensors().to_vec(),
            Pair::all(q, p),
        )
        .map_err(EstimatorError::from)?;
        // Contraction weights of each mask: S[i][q] and V[v][p] (zero on the other aperture's
        // directions).
        let weights = |mask: fn(&Node) -> f64| {
            let s_w: Vec<Vec<Complex64>> = src_beams
                .iter()
                .map(|b| {
                    src_nodes
                        .iter()
                        .map(|n| mask(n) * Complex64::from_polar(1.0, -k * n.dir.dot(b.focus)))
                        .collect()
                })
                .collect();
            let v_w: Vec<Vec<Complex64>> = sen_beams
                .iter()
                .map(|(b, look)| {
                    let side = usize::from(*look != axis);
                    let mut row = vec![Complex64::ZERO; p];
                    for (j, n) in sen_nodes[side].iter().enumerate() {
                        row[side * q + j] =
                            mask(n) * Complex64::from_polar(1.0, k * n.dir.dot(b.focus));
                    }
                    row
                })
                .collect();
            (s_w, v_w)
        };
        let (s_apo, v_apo) = weights(|n| n.apodized);
        let (s_bin, v_bin) = weights(|n| n.binary);
        let outer = |u: &[Complex64; J]| {
            let u = *u;
            move |a: usize, b: usize| u[a] * u[b].conj()
        };
        let diff = |x: &[Complex64; J], y: &[Complex64; J]| {
            let (x, y) = (*x, *y);
            move |a: usize, b: usize| x[a] * x[b].conj() - y[a] * y[b].conj()
        };
        let options = |realizations: usize, seed: u64| FieldOptions {
            realizations,
            paths_per_realization: 1,
            seed,
            coherence: Coherence::ForwardAndReversed,
            add_mean: false,
            ..Default::default()
        };
        let (mut apo, mut bin, mut bias) = (Sums::new(), Sums::new(), Sums::new());
        let (mut bin_apo, mut bias_apo) = (Sums::new(), Sums::new());
        let (mut brute_seconds, mut biased_seconds) = (0.0, 0.0);
        let biased_paths = r.biased_paths.unwrap_or(r.paths);
        let mut done = 0;
        let mut c = 0;
        while done < r.paths {
            let per_chunk = r.chunk.min(r.paths - done) as usize;
            let t0 = Instant::now();
            let fields = render_fields(
                &scene_far,
                &options(per_chunk, self.chunk_seed(c)),
                progress,
            )?;
            let mut u_apo = Vec::with_capacity(per_chunk);
            for u_far in fields.fields.as_slice().chunks_exact(q * p) {
                let ua = contract(u_far, &s_apo, &v_apo);
                let ub = contract(u_far, &s_bin, &v_bin);
                apo.add(outer(&ua));
                bin.add(outer(&ub));
                bin_apo.add(diff(&ub, &ua));
                u_apo.push(ua);
            }
            drop(fields);
            brute_seconds += t0.elapsed().as_secs_f64();
            // The biased reference: the same paths (the same chunk seeds, realization r of a
            // chunk is path r whatever the chunk's length), up to `biased_paths`.
            let per_biased = biased_paths.saturating_sub(done).min(per_chunk as u64) as usize;
            if per_biased > 0 {
                let t0 = Instant::now();
                let fields = render_fields(
                    &scene_biased,
                    &options(per_biased, self.chunk_seed(c)),
                    progress,
                )?;
                for (u_far, ua) in fields.fields.as_slice().chunks_exact(q * p).zip(&u_apo) {
                    let uc = contract(u_far, &s_apo, &v_apo);
                    bias.add(outer(&uc));
                    bias_apo.add(diff(&uc, ua));
                }
                biased_seconds += t0.elapsed().as_secs_f64();
            }
            done += per_chunk as u64;
            c += 1;
        }
        // Its cost per path in a render of many paths per realization.
        let t0 = Instant::now();
        render_fields(
            &scene_far,
            &FieldOptions {
                paths_per_realization: r.timing_paths.div_ceil(8),
                ..options(8, derive_seed(r.seed, 2))
            },
            progress,
        )?;
        let brute_time_per_path =
            t0.elapsed().as_secs_f64() / (8 * r.timing_paths.div_ceil(8)) as f64;

        let (brute, binary, biased) = (apo.estimate(), bin.estimate(), bias.estimate());
        let n = r.paths as f64;
        let brute_variance: f64 = (0..J).map(|a| brute.se[a * J + a].re.powi(2) * n).sum();
        // Eq. 25's model error, relative (see the module documentation).
        let model = (f.size[1] / f.mean_free_path) / (2.0 * f.concentration);
        let near = nears
            .into_iter()
            .map(|(label, strategy, (estimate, time_per_path))| {
                let get = |a: usize, b: usize| estimate.total.get(a, b);
                let variance = (0..J)
                    .map(|a| get(a, a).1.re.powi(2) * r.near_paths as f64)
                    .sum();
                NearRender {
                    label,
                    strategy,
                    time_per_path,
                    variance,
                    apodized: Comparison::of(&get, &brute, model),
                    biased: Comparison::of(&get, &biased, 0.0),
                    binary: Comparison::of(&get, &binary, 0.0),
                    estimate,
                }
            })
            .collect();
        Ok(BruteForce {
            quadrature_error,
            binary_half_width: self.binary_half_width(),
            single_scattering_ratio: self.single_scattering_ratios()?,
            q,
            p,
            near,
            brute,
            binary,
            biased,
            binary_minus_apodized: bin_apo.estimate(),
            biased_minus_apodized: bias_apo.estimate(),
            brute_seconds,
            biased_seconds,
            brute_time_per_path,
            brute_variance,
            wall: start.elapsed().as_secs_f64(),
        })
    }
}
