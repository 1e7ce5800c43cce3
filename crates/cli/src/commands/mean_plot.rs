//! `speckle wave --mean-plot`: the speckle mean against the distance between a point source
//! and point sensors (Bar et al. 2019, Sec. 4.1 and Fig. 4b): the closed form of Eq. 20 (the
//! attenuated direct path `e^{-sigma_t d / 2} G0(d)`), the wave solver's empirical mean over its
//! configurations with one standard error, and the free-space field `G0(d)` (no scattering) as
//! a dashed reference, as an SVG on a logarithmic y axis, `.npy` arrays and a JSON sidecar.
//!
//! A flag of `speckle wave` rather than a command of its own: the wave solver is the costly
//! part and `wave` already plans it (cost estimate, `render.configurations`, progress,
//! cancellation) and writes its mean (`<name>.wave_mean.npy`); the closed forms are
//! `speckle mean`'s, cheap, computed here on the same scene.

use super::*;
use speckle::estimators::{Sensor, Source};
use speckle::phase::Dimension;
use speckle::scene::npy::{encode_c16, encode_f8};
use speckle::studies::curves::{AxisUnit, Curve, Figure, Style};
use speckle::wave::WaveEstimate;

/// The distance `|sensor - source|` of every pair of `p`, in pair order; an error naming
/// `sources` or `sensors` unless every pair joins a point source to a point sensor at distinct
/// positions.
pub fn distances(p: &Problem) -> anyhow::Result<Vec<f64>> {
    let (sources, sensors) = (p.scene.sources(), p.scene.sensors());
    let mut d = Vec::with_capacity(p.pairs());
    for pair in p.scene.pairs() {
        let Source::Point { position: a } = sources[pair.source] else {
            return Err(input(format!(
                "{}: sources: source {} (after expanding tilts) is not a point source; \
                 --mean-plot plots the mean against the distance from point sources to point \
                 sensors",
                p.origin, pair.source
            )));
        };
        let Sensor::Point { position: b } = sensors[pair.sensor] else {
            return Err(input(format!(
                "{}: sensors: sensor {} (after expanding grids) is not a point sensor; \
                 --mean-plot plots the mean against the distance from point sources to point \
                 sensors",
                p.origin, pair.sensor
            )));
        };
        let r = (b - a).length();
        if r <= 0.0 {
            return Err(input(format!(
                "{}: sensors: sensor {} sits on source {}; --mean-plot needs a distance > 0",
                p.origin, pair.sensor, pair.source
            )));
        }
        d.push(r);
    }
    Ok(d)
}

/// The free-space field of a unit point source at distance `r`: `e^{ikr} / r` (3D),
/// `e^{ikr} / sqrt(r)` (flatland, the far zone of the Hankel function).
pub fn free_space(dimension: Dimension, k: f64, r: f64) -> Complex64 {
    let spread = match dimension {
        Dimension::Three => 1.0 / r,
        Dimension::Two => 1.0 / r.sqrt(),
    };
    Complex64::from_polar(spread, k * r)
}

/// The deviation of `w +- se` from `m` in standard errors, real and imaginary parts
/// (`se` holds the standard errors of the parts).
fn z(w: Complex64, se: Complex64, m: Complex64) -> (f64, f64) {
    ((w.re - m.re) / se.re, (w.im - m.im) / se.im)
}

/// The standard error of `|w|` from those of its parts (first order).
fn magnitude_stderr(w: Complex64, se: Complex64) -> f64 {
    let n = w.norm();
    if n == 0.0 {
        return se.norm();
    }
    ((w.re * se.re).powi(2) + (w.im * se.im).powi(2)).sqrt() / n
}

/// The unit of a length axis: the scene's declared length unit, else a description.
fn length_axis(p: &Problem) -> AxisUnit {
    match p.units.length {
        Some(u) => AxisUnit::Si {
            base: u.base.into(),
            scale: u.scale,
        },
        None => AxisUnit::Described("the scene's length unit".into()),
    }
}

/// Stages the figure of `est` against the closed forms `closed` of `p` at the pairs'
/// distances `d`: `<name>.mean_distance.npy`, `.mean_closed.npy`, `.mean_free.npy`,
/// `.mean_z.npy`, `.mean_plot.svg` and `.mean_plot.json`; prints its table.
pub fn stage(
    p: &Problem,
    staged: &mut Staged,
    est: &WaveEstimate,
    closed: &[Complex64],
    d: &[f64],
) -> anyhow::Result<()> {
    let n = &p.name;
    let k = p.scene.wavenumber();
    let free: Vec<Complex64> = d.iter().map(|&r| free_space(p.dimension(), k, r)).collect();
    let mut zs = Vec::with_capacity(2 * d.len());
    let mut rows = Vec::with_capacity(d.len());
    let (mut worst, mut worst_free): (f64, f64) = (0.0, f64::INFINITY);
    for j in 0..d.len() {
        let (w, se, m) = (est.mean[j], est.mean_std_error[j], closed[j]);
        let (zr, zi) = z(w, se, m);
        let (fr, fi) = z(w, se, free[j]);
        zs.extend([zr, zi]);
        let zf = fr.abs().max(fi.abs());
        worst = worst.max(zr.abs().max(zi.abs()));
        worst_free = worst_free.min(zf);
        let phase = (w / m).arg();
        rows.push(json!({
            "pair": j,
            "distance": d[j],
            "closed_form": [m.re, m.im],
            "closed_form_abs": m.norm(),
            "wave_mean": [w.re, w.im],
            "wave_mean_stderr": [se.re, se.im],
            "wave_mean_abs": w.norm(),
            "wave_mean_abs_stderr": magnitude_stderr(w, se),
            "phase_wave_minus_closed_rad": phase,
            "free_space_abs": free[j].norm(),
            "attenuation_closed": m.norm() / free[j].norm(),
            "z": [zr, zi],
            "z_from_free_space": zf,
        }));
        say!(
            "  d = {:>8.3}: closed form {:+.5e} {:+.5e}i, wave {:+.5e} {:+.5e}i +- {:.1e} \
             {:.1e} (z {zr:+.2} {zi:+.2}); |G0| {:.5e} ({zf:.0} SE away)",
            d[j],
            m.re,
            m.im,
            w.re,
            w.im,
            se.re,
            se.im,
            free[j].norm()
        );
    }
    let mut files = json!({});
    stage_arrays(
        staged,
        &mut files,
        n,
        [
            ("mean_distance", encode_f8(&[d.len()], d)),
            ("mean_closed", encode_c16(&[d.len()], closed)),
            ("mean_free", encode_c16(&[d.len()], &free)),
            ("mean_z", encode_f8(&[d.len(), 2], &zs)),
        ],
    );
    files["wave_mean"] = json!(format!("{n}.wave_mean.npy"));
    files["wave_mean_stderr"] = json!(format!("{n}.wave_mean_stderr.npy"));
    let svg = format!("{n}.mean_plot.svg");
    let (figure, style) = figure(p, est, closed, &free, d);
    staged.add(svg.clone(), figure.svg_styled(&style)?.into_bytes());
    files["svg"] = json!(svg);
    files["layout"] = json!(
        "mean_distance: float64 (J,), |sensor - source| of each pair (scene units); \
         mean_closed: complex128 (J,), the closed-form speckle mean (Eq. 20, as speckle mean); \
         mean_free: complex128 (J,), the free-space field of the source at the sensor (no \
         scattering); mean_z: float64 (J, 2), (wave - closed) / stderr of the real and \
         imaginary parts; wave_mean, wave_mean_stderr: the wave solver's empirical mean"
    );
    let meta = json!({
        "figure": "Bar et al. 2019, Fig. 4b: the speckle mean against the distance",
        "scene": p.origin,
        "units": {"length": p.units.length.map(|u| u.symbol)},
        "wavelength": p.scene.wavelength(),
        "dimension": match p.dimension() {
            Dimension::Two => 2,
            Dimension::Three => 3,
        },
        "configurations": p.render.configurations,
        "seed": p.render.seed,
        "closed_form": "e^{-sigma_t d / 2} G0(d), the attenuated direct path (Eq. 20); G0 = \
                        e^{ikd} / d (3D), e^{ikd} / sqrt(d) (flatland)",
        "wave": "speckle wave: the mean of the Foldy-Lax fields over the configurations, with \
                 the standard errors of its real and imaginary parts",
        "files": files,
        "summary": {
            "max_abs_z": worst,
            "min_z_from_free_space": worst_free,
        },
        "rows": rows,
    });
    stage_json(staged, format!("{n}.mean_plot.json"), &meta)?;
    say!(
        "{n}: mean against distance: largest |z| from the closed form {worst:.2}; the wave \
         mean at least {worst_free:.0} SE from the free-space field"
    );
    Ok(())
}

/// The figure: `|closed|`, `|wave| +- SE` and the dashed `|G0|` against the distance, sorted
/// by distance, on a logarithmic y axis.
fn figure(
    p: &Problem,
    est: &WaveEstimate,
    closed: &[Complex64],
    free: &[Complex64],
    d: &[f64],
) -> (Figure, Style) {
    let mut order: Vec<usize> = (0..d.len()).collect();
    order.sort_by(|&a, &b| d[a].total_cmp(&d[b]));
    let x: Vec<f64> = order.iter().map(|&j| d[j]).collect();
    let pick = |v: &dyn Fn(usize) -> f64| order.iter().map(|&j| v(j)).collect::<Vec<f64>>();
    let curves = vec![
        Curve {
            label: "closed form, Eq. 20".into(),
            x: x.clone(),
            y: pick(&|j| closed[j].norm()),
            err: vec![],
        },
        Curve {
            label: "wave solver, mean +- SE".into(),
            x: x.clone(),
            y: pick(&|j| est.mean[j].norm()),
            err: pick(&|j| magnitude_stderr(est.mean[j], est.mean_std_error[j])),
        },
        Curve {
            label: "free space |G0|".into(),
            x,
            y: pick(&|j| free[j].norm()),
            err: vec![],
        },
    ];
    let figure = Figure {
        title: format!(
            "{}: the speckle mean against distance (Bar et al. 2019, Fig. 4)",
            p.name
        ),
        subtitle: format!(
            "|E[u(x2)]|, point source x1: closed form e^(-sigma_t d/2) |G0(d)|, wave solver over \
             {} configurations (+- 1 SE); dashed: no scattering",
            p.render.configurations
        ),
        x_label: "distance d = |x2 - x1|".into(),
        x_unit: Some(length_axis(p)),
        x_log: false,
        y_label: "|speckle mean|".into(),
        curves,
    };
    let style = Style {
        y_log: true,
        dashed: vec![2],
    };
    (figure, style)
}
