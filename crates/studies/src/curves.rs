//! A figure of curves with error bars against one axis (SVG, `plotters`): plain data in, a
//! document out. Used for temporal correlations (`speckle g1`: `|g1(t)|` of each pair) and
//! meant for any render whose result a person reads as curves.

use crate::plot::{COLOURS, PlotError, font, plot_error};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

/// One curve: its legend, abscissae, ordinates and (optionally) one standard error per point.
#[derive(Debug, Clone, PartialEq)]
pub struct Curve {
    /// Legend text.
    pub label: String,
    /// Abscissae.
    pub x: Vec<f64>,
    /// Ordinates (one per abscissa).
    pub y: Vec<f64>,
    /// Error bars of `y` (one per point), or empty.
    pub err: Vec<f64>,
}

/// A figure: title, subtitle, axis labels and its curves (at most [`MAX_CURVES`] are drawn,
/// the figure says how many were left out).
#[derive(Debug, Clone, PartialEq)]
pub struct Figure {
    /// Title (first line).
    pub title: String,
    /// Subtitle (second line).
    pub subtitle: String,
    /// Label of the x axis.
    pub x_label: String,
    /// Label of the y axis.
    pub y_label: String,
    /// The curves.
    pub curves: Vec<Curve>,
}

/// Curves drawn at most (more would not be told apart).
pub const MAX_CURVES: usize = 8;

/// Canvas size, pixels.
const SIZE: (u32, u32) = (1000, 540);
/// Width of the plot's part of the canvas; the legend takes the rest.
const PLOT_WIDTH: u32 = 700;

impl Figure {
    /// The figure as an SVG document. Non-finite points are skipped.
    pub fn svg(&self) -> Result<String, PlotError> {
        let mut out = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
        let mut body = String::new();
        {
            let root = SVGBackend::with_string(&mut body, SIZE).into_drawing_area();
            self.draw(&root).map_err(plot_error)?;
            root.present().map_err(plot_error)?;
        }
        out.push_str(&body);
        if !out.ends_with('\n') {
            out.push('\n');
        }
        Ok(out)
    }

    /// The ranges of the finite points (with their error bars), padded; `[0, 1]` when empty.
    fn ranges(&self) -> ((f64, f64), (f64, f64)) {
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for c in self.curves.iter().take(MAX_CURVES) {
            for (i, (&x, &y)) in c.x.iter().zip(&c.y).enumerate() {
                let e = c.err.get(i).copied().unwrap_or(0.0);
                if !(x.is_finite() && y.is_finite() && e.is_finite()) {
                    continue;
                }
                (x0, x1) = (x0.min(x), x1.max(x));
                (y0, y1) = (y0.min(y - e), y1.max(y + e));
            }
        }
        let pad = |a: f64, b: f64| {
            if a > b {
                (0.0, 1.0)
            } else if a == b {
                (a - 0.5, b + 0.5)
            } else {
                (a, b)
            }
        };
        let (x0, x1) = pad(x0, x1);
        let (y0, y1) = pad(y0, y1);
        let h = 0.04 * (y1 - y0);
        ((x0, x1), (y0 - h, y1 + h))
    }

    fn draw(
        &self,
        root: &DrawingArea<SVGBackend<'_>, Shift>,
    ) -> Result<(), Box<dyn std::error::Error + '_>> {
        root.fill(&WHITE)?;
        root.draw(&Text::new(self.title.clone(), (80, 12), font(16.0)))?;
        root.draw(&Text::new(
            self.subtitle.clone(),
            (80, 36),
            font(12.0).color(&RGBColor(0x44, 0x44, 0x44)),
        ))?;
        let (plot, legend) = root.split_horizontally(PLOT_WIDTH);
        let ((x0, x1), (y0, y1)) = self.ranges();
        let mut chart = ChartBuilder::on(&plot)
            .margin_top(60)
            .margin_right(20)
            .margin_bottom(10)
            .margin_left(10)
            .x_label_area_size(50)
            .y_label_area_size(80)
            .build_cartesian_2d(x0..x1, y0..y1)?;
        chart
            .configure_mesh()
            .x_desc(self.x_label.clone())
            .y_desc(self.y_label.clone())
            .x_labels(7)
            .y_labels(8)
            .disable_x_mesh()
            .bold_line_style(RGBColor(0xe4, 0xe4, 0xe4))
            .light_line_style(TRANSPARENT)
            .label_style(font(13.0))
            .axis_desc_style(font(14.0))
            .draw()?;
        chart
            .plotting_area()
            .draw(&Rectangle::new([(x0, y0), (x1, y1)], BLACK.stroke_width(1)))?;
        let text = TextStyle::from(font(13.0)).pos(Pos::new(HPos::Left, VPos::Center));
        let mut y = 80;
        for (i, c) in self.curves.iter().take(MAX_CURVES).enumerate() {
            let colour = COLOURS[i % COLOURS.len()];
            let points: Vec<(f64, f64, f64)> =
                c.x.iter()
                    .zip(&c.y)
                    .enumerate()
                    .map(|(k, (&x, &y))| (x, y, c.err.get(k).copied().unwrap_or(0.0)))
                    .filter(|(x, y, e)| x.is_finite() && y.is_finite() && e.is_finite())
                    .collect();
            chart.draw_series(LineSeries::new(
                points.iter().map(|&(x, y, _)| (x, y)),
                colour.stroke_width(2),
            ))?;
            if !c.err.is_empty() {
                chart.draw_series(points.iter().map(|&(x, y, e)| {
                    ErrorBar::new_vertical(x, y - e, y, y + e, colour.stroke_width(1), 5)
                }))?;
            }
            legend.draw(&PathElement::new(
                vec![(5, y), (35, y)],
                colour.stroke_width(2),
            ))?;
            legend.draw(&Text::new(c.label.clone(), (43, y), text.clone()))?;
            y += 22;
        }
        if self.curves.len() > MAX_CURVES {
            legend.draw(&Text::new(
                format!("({} more not drawn)", self.curves.len() - MAX_CURVES),
                (5, y),
                text.clone(),
            ))?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_every_curve_and_skips_non_finite_points() {
        let curve = |i: usize| Curve {
            label: format!("pair {i}"),
            x: vec![0.0, 1.0, 2.0, 3.0],
            y: vec![1.0, 0.5, f64::NAN, 0.1 * i as f64],
            err: vec![0.0, 0.05, 0.05, 0.05],
        };
        let f = Figure {
            title: "g1".into(),
            subtitle: "test".into(),
            x_label: "t".into(),
            y_label: "|g1|".into(),
            curves: (0..10).map(curve).collect(),
        };
        let svg = f.svg().unwrap();
        assert!(svg.starts_with("<?xml"));
        for i in 0..MAX_CURVES {
            assert!(svg.contains(&format!("pair {i}")), "legend of curve {i}");
        }
        assert!(!svg.contains("pair 9"));
        assert!(svg.contains("2 more not drawn"));
        assert!(!svg.contains("NaN"));
        // An empty figure still draws.
        let empty = Figure {
            curves: vec![],
            ..f
        };
        assert!(empty.svg().unwrap().contains("</svg>"));
    }
}
