//! The figure of a memory-spectrum study, drawn with `plotters` (SVG backend only): `C(theta)`
//! of every wavelength (solid, with error bars of one standard error and markers) and Eq. 39
//! with the thickness `L` (dashed) and with `L + 2 z_e` (dotted), in one colour per wavelength,
//! against `theta` in degrees (scaled by a power of ten when small), with a legend that gives
//! each wavelength's optical depths.

use crate::memory::{MILNE_ZE, MemorySpectrum, Study, eq39};
use plotters::coord::Shift;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

/// Curve colours, one per wavelength or curve (cycled).
pub(crate) const COLOURS: [RGBColor; 8] = [
    RGBColor(0x1f, 0x77, 0xb4),
    RGBColor(0x2c, 0xa0, 0x2c),
    RGBColor(0xd6, 0x27, 0x28),
    RGBColor(0x94, 0x67, 0xbd),
    RGBColor(0xff, 0x7f, 0x0e),
    RGBColor(0x8c, 0x56, 0x4b),
    RGBColor(0xe3, 0x77, 0xc2),
    RGBColor(0x17, 0xbe, 0xcf),
];

/// Canvas size, pixels.
const SIZE: (u32, u32) = (1000, 540);
/// Width of the plot's part of the canvas; the legend takes the rest.
const PLOT_WIDTH: u32 = 660;
/// Samples of each Eq. 39 curve.
const CURVE_SAMPLES: usize = 200;
/// Dash and gap of the Eq. 39 curve with `L` (pixels).
const DASHED: (u32, u32) = (6, 4);
/// Dash and gap of the Eq. 39 curve with `L + 2 z_e` (pixels).
const DOTTED: (u32, u32) = (2, 3);
const FONT: &str = "sans-serif";

/// A font of `px` pixels (`plotters` writes font sizes as `size / 1.24`).
pub(crate) fn font(px: f64) -> FontDesc<'static> {
    (FONT, px * 1.24).into_font()
}

/// `10` to the power `e` in Unicode superscripts (`10⁻³`).
pub fn power_of_ten(e: i32) -> String {
    const SUP: [char; 10] = ['⁰', '¹', '²', '³', '⁴', '⁵', '⁶', '⁷', '⁸', '⁹'];
    let mut s = String::from("10");
    if e < 0 {
        s.push('⁻');
    }
    for c in e.unsigned_abs().to_string().chars() {
        s.push(SUP[c.to_digit(10).unwrap_or(0) as usize]);
    }
    s
}

/// Errors of drawing (the SVG backend writes to a string; errors are not expected).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("drawing the plot failed: {0}")]
pub struct PlotError(String);

pub(crate) fn plot_error(e: impl std::fmt::Display) -> PlotError {
    PlotError(e.to_string())
}

/// The study's figure as an SVG document.
pub fn svg(s: &Study, m: &MemorySpectrum) -> Result<String, PlotError> {
    svg_document(SIZE, |root| draw(root, s, m))
}

/// An SVG document of `size` pixels drawn by `draw`: the XML declaration, the drawing, a final
/// newline (every study figure is written this way).
pub(crate) fn svg_document<E: std::fmt::Display>(
    size: (u32, u32),
    draw: impl FnOnce(&Area<'_>) -> Result<(), E>,
) -> Result<String, PlotError> {
    let mut out = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    let mut body = String::new();
    {
        let root = SVGBackend::with_string(&mut body, size).into_drawing_area();
        draw(&root).map_err(plot_error)?;
        root.present().map_err(plot_error)?;
    }
    out.push_str(&body);
    if !out.ends_with('\n') {
        out.push('\n');
    }
    Ok(out)
}

/// The drawing area of a study figure, and what drawing on it returns.
pub(crate) type Area<'a> = DrawingArea<SVGBackend<'a>, Shift>;
pub(crate) type DrawResult = Result<(), DrawingAreaErrorKind<std::io::Error>>;

fn draw(root: &Area<'_>, s: &Study, m: &MemorySpectrum) -> DrawResult {
    root.fill(&WHITE)?;
    let index = if s.m.im == 0.0 {
        format!("{:.4}", s.m.re)
    } else {
        format!("{:.4}{:+.4}i", s.m.re, s.m.im)
    };
    root.draw(&Text::new(
        format!(
            "{}: memory effect versus wavelength (Bar et al. 2019, Fig. 11)",
            s.name
        ),
        (80, 12),
        font(16.0),
    ))?;
    root.draw(&Text::new(
        format!(
            "spheres of radius {} µm (m = {index}), slab L = {} µm, {} L wide; {} paths per \
             wavelength",
            s.radius, s.thickness, s.file.lateral_factor, s.file.render.paths
        ),
        (80, 36),
        font(12.0).color(&RGBColor(0x44, 0x44, 0x44)),
    ))?;
    let (plot_area, legend_area) = root.split_horizontally(PLOT_WIDTH);
    draw_curves(&plot_area, s, m)?;
    draw_legend(&legend_area, s, m)
}

/// The axes and the curves.
fn draw_curves(area: &Area<'_>, s: &Study, m: &MemorySpectrum) -> DrawResult {
    let theta_max = s.angles.last().copied().unwrap_or(1.0).to_degrees();
    // Below 0.1 degrees, show theta in units of 10^-p degrees, p a multiple of 3, so that the
    // tick labels read 1 to 999.
    let p = if theta_max >= 0.1 {
        0
    } else {
        (-(theta_max.log10().floor() as i32) + 2) / 3 * 3
    };
    let unit = 10f64.powi(p);
    let ymax = m
        .rows
        .iter()
        .flat_map(|r| r.curve.c.iter().zip(&r.curve.se).map(|(c, e)| c + e))
        .fold(1.0, f64::max)
        .min(1.5)
        * 1.04;
    let mut chart = ChartBuilder::on(area)
        .margin_top(60)
        .margin_right(20)
        .margin_bottom(10)
        .margin_left(10)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..theta_max * unit, 0.0..ymax)?;
    let x_desc = if p == 0 {
        "θ (degrees)".to_string()
    } else {
        format!("θ ({} degrees)", power_of_ten(-p))
    };
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc("C(θ) = |C₀θ|² / (C₀₀ Cθθ)")
        .x_labels(7)
        .x_label_formatter(&|v| format!("{}", (v * 1e6).round() / 1e6))
        .y_labels(8)
        .disable_x_mesh()
        .bold_line_style(RGBColor(0xe4, 0xe4, 0xe4))
        .light_line_style(TRANSPARENT)
        .label_style(font(13.0))
        .axis_desc_style(font(14.0))
        .draw()?;
    let (x_range, y_range) = (chart.x_range(), chart.y_range());
    chart.plotting_area().draw(&Rectangle::new(
        [(x_range.start, y_range.start), (x_range.end, y_range.end)],
        BLACK.stroke_width(1),
    ))?;
    let clamp = |y: f64| y.clamp(0.0, ymax);
    for (i, row) in m.rows.iter().enumerate() {
        let colour = COLOURS[i % COLOURS.len()];
        let k = row.band.k();
        let leff = s.thickness + 2.0 * MILNE_ZE * row.band.transport_mfp();
        for (length, (dash, gap), width) in [(s.thickness, DASHED, 2), (leff, DOTTED, 1)] {
            let curve = (0..=CURVE_SAMPLES).map(move |j| {
                let theta = theta_max * j as f64 / CURVE_SAMPLES as f64;
                (theta * unit, eq39(k * theta.to_radians() * length))
            });
            chart.draw_series(DashedLineSeries::new(
                curve,
                dash,
                gap,
                colour.stroke_width(width),
            ))?;
        }
        let points: Vec<(f64, f64, f64)> = s
            .angles
            .iter()
            .zip(row.curve.c.iter().zip(&row.curve.se))
            .map(|(t, (c, e))| (t.to_degrees() * unit, *c, *e))
            .collect();
        chart.draw_series(LineSeries::new(
            points.iter().map(|&(x, c, _)| (x, clamp(c))),
            colour.stroke_width(2),
        ))?;
        chart.draw_series(points.iter().map(|&(x, c, e)| {
            ErrorBar::new_vertical(
                x,
                clamp(c - e),
                clamp(c),
                clamp(c + e),
                colour.stroke_width(1),
                6,
            )
        }))?;
        chart.draw_series(
            points
                .iter()
                .map(|&(x, c, _)| Circle::new((x, clamp(c)), 3, colour.filled())),
        )?;
    }
    Ok(())
}

/// A legend line: its style, dash and gap (`None`: solid), and text (empty: a gap).
type LegendEntry = (ShapeStyle, Option<(u32, u32)>, String);

/// The legend: one line per wavelength (its optical depths), then the three line kinds.
fn draw_legend(area: &Area<'_>, s: &Study, m: &MemorySpectrum) -> DrawResult {
    let font = TextStyle::from(font(13.0)).pos(Pos::new(HPos::Left, VPos::Center));
    let (x0, x1, xt) = (5, 35, 43);
    let mut entries: Vec<LegendEntry> = m
        .rows
        .iter()
        .enumerate()
        .map(|(i, row)| {
            let text = format!(
                "λ = {:.0} nm: OD {:.2}, (1-g) OD {:.2}",
                row.band.lambda * 1e3,
                row.od(s),
                row.transport_od(s)
            );
            (COLOURS[i % COLOURS.len()].stroke_width(2), None, text)
        })
        .collect();
    let black = BLACK.stroke_width(2);
    entries.push((black, None, String::new()));
    entries.push((black, None, "Monte Carlo ± 1 SE (jackknife)".into()));
    entries.push((black, Some(DASHED), "Eq. 39, thickness L".into()));
    entries.push((
        BLACK.stroke_width(1),
        Some(DOTTED),
        "Eq. 39, L + 2 z_e (z_e = 0.7104 l*)".into(),
    ));
    let mut y = 80;
    for (style, dash, text) in entries {
        if text.is_empty() {
            y += 8;
            continue;
        }
        let line = vec![(x0, y), (x1, y)];
        match dash {
            None => area.draw(&PathElement::new(line, style))?,
            Some((d, g)) => area.draw(&DashedPathElement::new(line, d, g, style))?,
        }
        area.draw(&Text::new(text, (xt, y), font.clone()))?;
        y += 22;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::memory::{Curve, StudyOverrides, Wavelength, load_str};

    /// A study of two wavelengths with made-up curves (no render): every part of the figure is
    /// drawn. The dashed curves are drawn dash by dash, so the wavelength's colour appears on
    /// many more elements than a solid curve would give.
    #[test]
    fn the_figure_has_its_curves_axes_and_legend() {
        let text = "radius_um = 0.01\nparticle_index = 1.59\nhost_index = 1.33\n\
                    wavelengths_um = [0.4, 0.65]\nthickness_um = 1000.0\noptical_depth = 6.0\n\
                    optical_depth_at_um = 0.4\nk_theta_l = [0.0, 1.0, 2.0]\n";
        let s = load_str(text, "t.toml", "t", &StudyOverrides::default()).unwrap();
        let rows = s
            .prepare()
            .unwrap()
            .into_iter()
            .map(|band| Wavelength {
                band,
                curve: Curve {
                    c: vec![1.0, 0.7, 0.3],
                    se: vec![0.0, 0.02, 0.02],
                    left_out: vec![],
                    single_fraction: 0.1,
                    intensity: 1.0,
                    wall: 0.0,
                },
                diffusion: vec![1.0, 0.72, 0.3],
                extrapolated: vec![1.0, 0.69, 0.26],
                k_theta_l: vec![0.0, 1.0, 2.0],
            })
            .collect();
        let m = MemorySpectrum {
            rows,
            volume_fraction: 0.01,
            wall: 0.0,
        };
        let svg = svg(&s, &m).unwrap();
        assert!(svg.starts_with("<?xml") && svg.trim_end().ends_with("</svg>"));
        for text in [
            "t: memory effect versus wavelength",
            "λ = 400 nm: OD 6.00",
            "λ = 650 nm: OD",
            "Monte Carlo ± 1 SE (jackknife)",
            "Eq. 39, thickness L",
            "Eq. 39, L + 2 z_e",
            "θ (10⁻³ degrees)",
            "C(θ)",
        ] {
            assert!(svg.contains(text), "{text}");
        }
        let blue = svg.matches("#1F77B4").count();
        assert!(
            blue > 50,
            "{blue} elements of the first wavelength's colour"
        );
    }

    #[test]
    fn powers_of_ten_use_superscripts() {
        assert_eq!(power_of_ten(-3), "10⁻³");
        assert_eq!(power_of_ten(12), "10¹²");
        assert_eq!(power_of_ten(0), "10⁰");
    }
}
