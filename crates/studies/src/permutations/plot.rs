//! The Fig. 16 figure of a permutations study, drawn with `plotters` (SVG backend only):
//! `|I_P / I_id|` per permutation as bars on a logarithmic axis, one colour per viewing
//! direction, with error bars of one standard error.

use super::{NAMES, Permutations, PermutationsStudy};
use crate::plot::{Area, COLOURS, DrawResult, PlotError, font, power_of_ten, svg_document};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

/// Canvas size, pixels.
const SIZE: (u32, u32) = (900, 560);

/// A tick label of the logarithmic axis: `10⁻²`, or `2·10⁻²` between powers of ten.
fn log_label(v: f64) -> String {
    let e = v.log10().floor();
    let m = v / 10f64.powf(e);
    if (m - 1.0).abs() < 1e-6 {
        power_of_ten(e as i32)
    } else if (m - 10.0).abs() < 1e-5 {
        power_of_ten(e as i32 + 1)
    } else {
        format!("{}·{}", (m * 10.0).round() / 10.0, power_of_ten(e as i32))
    }
}

/// The study's Fig. 16 as an SVG document.
pub fn svg(s: &PermutationsStudy, r: &Permutations) -> Result<String, PlotError> {
    svg_document(SIZE, |root| draw(root, s, r))
}

fn draw(root: &Area<'_>, s: &PermutationsStudy, r: &Permutations) -> DrawResult {
    root.fill(&WHITE)?;
    let f = &s.file;
    root.draw(&Text::new(
        format!(
            "{}: contributions of path permutations (Bar et al. 2019, Fig. 16)",
            s.name
        ),
        (80, 12),
        font(16.0),
    ))?;
    root.draw(&Text::new(
        format!(
            "|∬ μ(x) μ(x_P)* dx₂ dx₃| / ∬ |μ(x)|² dx₂ dx₃ over a {} λ square, x₁ = ({}, {}) λ; \
             flatland, {} samples",
            f.side, f.x1[0], f.x1[1], f.render.samples
        ),
        (80, 36),
        font(12.0).color(&RGBColor(0x44, 0x44, 0x44)),
    ))?;
    let low = r
        .views
        .iter()
        .flat_map(|v| v.magnitude.iter().zip(&v.magnitude_se))
        .map(|(&m, &e)| if m - e > 0.0 { m - e } else { 0.5 * m })
        .filter(|&m| m > 0.0)
        .fold(1.0, f64::min);
    let floor = 10f64.powf(low.log10().floor()).max(1e-8);
    let mut chart = ChartBuilder::on(root)
        .margin_top(60)
        .margin_right(220)
        .margin_bottom(10)
        .margin_left(10)
        .x_label_area_size(60)
        .y_label_area_size(80)
        .build_cartesian_2d(0.0..6.0, (floor..3.0).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("vertex order of the second path, P")
        .y_desc("|I_P / I_id| (dimensionless)")
        .x_labels(0)
        .y_label_formatter(&|v| log_label(*v))
        .disable_x_mesh()
        .bold_line_style(RGBColor(0xe4, 0xe4, 0xe4))
        .light_line_style(TRANSPARENT)
        .label_style(font(13.0))
        .axis_desc_style(font(14.0))
        .draw()?;
    let names = TextStyle::from(font(13.0)).pos(Pos::new(HPos::Center, VPos::Top));
    for (j, name) in NAMES.iter().enumerate() {
        let (x, y) = chart.backend_coord(&(j as f64 + 0.5, floor));
        root.draw(&Text::new(name.to_string(), (x, y + 8), names.clone()))?;
    }
    let nv = r.views.len();
    let width = 0.8 / nv as f64;
    for (w, v) in r.views.iter().enumerate() {
        let colour = COLOURS[w % COLOURS.len()];
        for p in 0..6 {
            let x0 = p as f64 + 0.1 + w as f64 * width;
            let (m, e) = (v.magnitude[p], v.magnitude_se[p]);
            let top = m.max(floor);
            chart.draw_series(std::iter::once(Rectangle::new(
                [(x0, floor), (x0 + width, top)],
                colour.mix(0.75).filled(),
            )))?;
            let xc = x0 + 0.5 * width;
            chart.draw_series(std::iter::once(ErrorBar::new_vertical(
                xc,
                (m - e).max(floor),
                top,
                (m + e).max(floor),
                BLACK.stroke_width(1),
                6,
            )))?;
        }
        let y = 90 + 24 * w as i32;
        let x = SIZE.0 as i32 - 200;
        root.draw(&Rectangle::new(
            [(x, y - 7), (x + 24, y + 7)],
            colour.mix(0.75).filled(),
        ))?;
        let label = if v.offset_deg == 0.0 {
            "v = -i (backscattering)".to_string()
        } else {
            format!("v = -i turned {}°", v.offset_deg)
        };
        root.draw(&Text::new(
            label,
            (x + 32, y),
            TextStyle::from(font(13.0)).pos(Pos::new(HPos::Left, VPos::Center)),
        ))?;
    }
    let y = 90 + 24 * nv as i32 + 10;
    root.draw(&Text::new(
        "bars ± 1 SE (jackknife)",
        (SIZE.0 as i32 - 200, y),
        TextStyle::from(font(13.0)).pos(Pos::new(HPos::Left, VPos::Center)),
    ))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_labels_are_distinct_powers() {
        assert_eq!(log_label(0.01), "10⁻²");
        assert_eq!(log_label(1.0), "10⁰");
        assert_eq!(log_label(0.02), "2·10⁻²");
        assert_ne!(log_label(0.2), log_label(0.3));
    }
}
