//! A figure of curves with error bars against one axis (SVG, `plotters`): plain data in, a
//! document out. Used for temporal correlations (`speckle g1`: `|g1(t)|` of each pair) and
//! meant for any render whose result a person reads as curves.

use crate::plot::{COLOURS, PlotError, font, svg_document};
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

/// The unit of a figure's x values, for its tick labels ([`Figure::x_unit`]).
#[derive(Debug, Clone, PartialEq)]
pub enum AxisUnit {
    /// An SI unit: `base` (`"s"`, `"m"`) and the value in it of one unit of the data (`1e-2`
    /// for data in cm with base `"m"`); ticks carry SI prefixes (`20 us`).
    Si {
        /// The SI base symbol.
        base: String,
        /// One data unit in the base unit.
        scale: f64,
    },
    /// A unit known only by a description (`"the scene's time unit"`); ticks are scaled by a
    /// power of ten the label states.
    Described(String),
}

/// A figure: title, subtitle, axis labels and its curves (at most [`MAX_CURVES`] are drawn,
/// the figure says how many were left out). With [`Figure::x_log`], an x axis whose positive
/// values span two decades or more is logarithmic (non-positive abscissae are then left out);
/// tick labels are distinct numbers, with SI prefixes when the unit is known.
#[derive(Debug, Clone, PartialEq)]
pub struct Figure {
    /// Title (first line).
    pub title: String,
    /// Subtitle (second line).
    pub subtitle: String,
    /// Label of the x axis, without its unit (see [`Figure::x_unit`]).
    pub x_label: String,
    /// The unit of the x values, when they have one.
    pub x_unit: Option<AxisUnit>,
    /// Whether the x axis turns logarithmic when its positive values span two decades or more
    /// (time lags).
    pub x_log: bool,
    /// Label of the y axis.
    pub y_label: String,
    /// The curves.
    pub curves: Vec<Curve>,
}

/// How [`Figure::svg_styled`] draws a figure beyond its data; the default is [`Figure::svg`]'s
/// (a linear y axis, solid curves).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Style {
    /// A logarithmic y axis: non-positive values are left out, and an error bar reaching zero
    /// or below is cut a decade under its point.
    pub y_log: bool,
    /// Indices of the curves drawn dashed (references, closed forms).
    pub dashed: Vec<usize>,
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
        self.svg_styled(&Style::default())
    }

    /// The figure as an SVG document drawn in `style`. Non-finite points are skipped.
    pub fn svg_styled(&self, style: &Style) -> Result<String, PlotError> {
        svg_document(SIZE, |root| self.draw(root, style))
    }

    /// Whether the x axis is logarithmic: [`Figure::x_log`] and the positive abscissae span
    /// two decades or more.
    pub fn log_axis(&self) -> bool {
        if !self.x_log {
            return false;
        }
        let (mut lo, mut hi) = (f64::MAX, 0.0f64);
        for c in self.curves.iter().take(MAX_CURVES) {
            for &x in c.x.iter().filter(|x| x.is_finite() && **x > 0.0) {
                (lo, hi) = (lo.min(x), hi.max(x));
            }
        }
        hi >= 100.0 * lo
    }

    /// The plotted abscissa of `x`: `log10(x)` on a logarithmic axis (NaN for `x <= 0`).
    fn plotted(x: f64, log: bool) -> f64 {
        match (log, x > 0.0) {
            (false, _) => x,
            (true, true) => x.log10(),
            (true, false) => f64::NAN,
        }
    }

    /// The plotted ordinate of `y` and its error bar's ends `(y, low, high)`: on a logarithmic
    /// axis their `log10`, the low end cut a decade under `y` (NaN for `y <= 0`).
    fn plotted_y(y: f64, e: f64, log: bool) -> (f64, f64, f64) {
        if !log {
            return (y, y - e, y + e);
        }
        if y <= 0.0 {
            return (f64::NAN, f64::NAN, f64::NAN);
        }
        let low = if y - e > 0.1 * y { y - e } else { 0.1 * y };
        (y.log10(), low.log10(), (y + e).log10())
    }

    /// The ranges of the finite points (with their error bars), padded; `[0, 1]` when empty;
    /// the y values on a logarithmic axis when `y_log`.
    fn ranges(&self, log: bool, y_log: bool) -> ((f64, f64), (f64, f64)) {
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for c in self.curves.iter().take(MAX_CURVES) {
            for (i, (&x, &y)) in c.x.iter().zip(&c.y).enumerate() {
                let e = c.err.get(i).copied().unwrap_or(0.0);
                let x = Self::plotted(x, log);
                let (y, lo, hi) = Self::plotted_y(y, e, y_log);
                if !(x.is_finite() && y.is_finite() && lo.is_finite() && hi.is_finite()) {
                    continue;
                }
                (x0, x1) = (x0.min(x), x1.max(x));
                (y0, y1) = (y0.min(lo), y1.max(hi));
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
        style: &Style,
    ) -> Result<(), Box<dyn std::error::Error + '_>> {
        root.fill(&WHITE)?;
        root.draw(&Text::new(self.title.clone(), (80, 12), font(16.0)))?;
        root.draw(&Text::new(
            self.subtitle.clone(),
            (80, 36),
            font(12.0).color(&RGBColor(0x44, 0x44, 0x44)),
        ))?;
        let (plot, legend) = root.split_horizontally(PLOT_WIDTH);
        let log = self.log_axis();
        let y_log = style.y_log;
        let ((x0, x1), (y0, y1)) = self.ranges(log, y_log);
        let ticks = Ticks::new(self, log, (x0, x1));
        let mut chart = ChartBuilder::on(&plot)
            .margin_top(60)
            .margin_right(20)
            .margin_bottom(10)
            .margin_left(10)
            .x_label_area_size(50)
            .y_label_area_size(80)
            .build_cartesian_2d(x0..x1, y0..y1)?;
        let y_desc = if y_log {
            format!("{} (log scale)", self.y_label)
        } else {
            self.y_label.clone()
        };
        let power = |y: &f64| power_label(*y);
        let x_format = |x: &f64| ticks.format(*x);
        let mut mesh = chart.configure_mesh();
        mesh.x_desc(ticks.label.clone())
            .y_desc(y_desc)
            .x_label_formatter(&x_format)
            .x_labels(TICKS)
            .y_labels(8)
            .disable_x_mesh()
            .bold_line_style(RGBColor(0xe4, 0xe4, 0xe4))
            .light_line_style(TRANSPARENT)
            .label_style(font(13.0))
            .axis_desc_style(font(14.0));
        if y_log {
            mesh.y_label_formatter(&power);
        }
        mesh.draw()?;
        chart
            .plotting_area()
            .draw(&Rectangle::new([(x0, y0), (x1, y1)], BLACK.stroke_width(1)))?;
        let text = TextStyle::from(font(13.0)).pos(Pos::new(HPos::Left, VPos::Center));
        let mut y = 80;
        for (i, c) in self.curves.iter().take(MAX_CURVES).enumerate() {
            let colour = COLOURS[i % COLOURS.len()];
            let points: Vec<(f64, f64, f64, f64)> =
                c.x.iter()
                    .zip(&c.y)
                    .enumerate()
                    .map(|(k, (&x, &y))| {
                        let e = c.err.get(k).copied().unwrap_or(0.0);
                        let (y, lo, hi) = Self::plotted_y(y, e, y_log);
                        (Self::plotted(x, log), y, lo, hi)
                    })
                    .filter(|p| [p.0, p.1, p.2, p.3].iter().all(|v| v.is_finite()))
                    .collect();
            let dashed = style.dashed.contains(&i);
            let line = points.iter().map(|&(x, y, _, _)| (x, y));
            if dashed {
                chart.draw_series(DashedLineSeries::new(line, 8, 5, colour.stroke_width(2)))?;
            } else {
                chart.draw_series(LineSeries::new(line, colour.stroke_width(2)))?;
            }
            if !c.err.is_empty() {
                chart.draw_series(points.iter().map(|&(x, y, lo, hi)| {
                    ErrorBar::new_vertical(x, lo, y, hi, colour.stroke_width(1), 5)
                }))?;
            }
            if dashed {
                for (a, b) in [(5, 14), (21, 30)] {
                    legend.draw(&PathElement::new(
                        vec![(a, y), (b, y)],
                        colour.stroke_width(2),
                    ))?;
                }
            } else {
                legend.draw(&PathElement::new(
                    vec![(5, y), (35, y)],
                    colour.stroke_width(2),
                ))?;
            }
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

/// Tick labels requested on the x axis.
const TICKS: usize = 7;

/// The x axis's label and tick format (see [`Figure`]).
struct Ticks {
    /// The axis label with its unit.
    label: String,
    /// On a logarithmic axis, the unit's SI base and scale (ticks are `10^x` data units).
    log: Option<(String, f64)>,
    /// On a linear axis, the factor from data to tick values and the decimals shown.
    factor: f64,
    decimals: usize,
}

/// SI prefixes from 1e-15 to 1e9.
const PREFIXES: [(&str, i32); 9] = [
    ("f", -15),
    ("p", -12),
    ("n", -9),
    ("u", -6),
    ("m", -3),
    ("", 0),
    ("k", 3),
    ("M", 6),
    ("G", 9),
];

/// The SI prefix (and its exponent) for values of magnitude `m` (1 to 1000 of the prefix).
fn prefix(m: f64) -> (&'static str, i32) {
    let e = if m > 0.0 && m.is_finite() {
        (m.log10() / 3.0).floor() as i32 * 3
    } else {
        0
    };
    let e = e.clamp(-15, 9);
    PREFIXES
        .iter()
        .find(|p| p.1 == e)
        .copied()
        .unwrap_or(("", 0))
}

/// The tick label of `10^v` on a logarithmic y axis, two significant digits (`0.032`, `1e-5`).
fn power_label(v: f64) -> String {
    let x = 10f64.powf(v);
    if (1e-3..1e4).contains(&x) {
        let digits = (1.0 - x.log10().floor()).max(0.0) as usize;
        let text = format!("{x:.digits$}");
        if text.contains('.') {
            text.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            text
        }
    } else {
        let text = format!("{x:.1e}");
        match text.split_once('e') {
            Some((m, e)) => format!("{}e{e}", m.trim_end_matches('0').trim_end_matches('.')),
            None => text,
        }
    }
}

/// `v` with three significant digits and an SI prefix on `base` (`31.6 us`).
pub fn si(v: f64, base: &str) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v} {base}");
    }
    let (p, e) = prefix(v.abs());
    let x = v / 10f64.powi(e);
    let digits = 2usize.saturating_sub(x.abs().log10().floor().max(0.0) as usize);
    let text = format!("{x:.digits$}");
    let text = if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        text
    };
    format!("{text} {p}{base}")
}

impl Ticks {
    fn new(f: &Figure, log: bool, (x0, x1): (f64, f64)) -> Self {
        if log {
            let (log, label) = match &f.x_unit {
                Some(AxisUnit::Si { base, scale }) => (
                    Some((base.clone(), *scale)),
                    format!("{} (log scale)", f.x_label),
                ),
                Some(AxisUnit::Described(d)) => (None, format!("{} ({d}, log scale)", f.x_label)),
                None => (None, format!("{} (log scale)", f.x_label)),
            };
            return Self {
                label,
                log: log.or(Some((String::new(), f64::NAN))),
                factor: 1.0,
                decimals: 0,
            };
        }
        let scale = match &f.x_unit {
            Some(AxisUnit::Si { scale, .. }) => *scale,
            _ => 1.0,
        };
        let m = x0.abs().max(x1.abs()) * scale;
        let (p, e) = prefix(m);
        let factor = scale / 10f64.powi(e);
        // Enough decimals for ticks a seventh of the range apart to differ.
        let step = (x1 - x0) * factor / TICKS as f64;
        let decimals = if step > 0.0 && step.is_finite() {
            (-step.log10().floor()).clamp(0.0, 8.0) as usize + 1
        } else {
            1
        };
        let label = match (&f.x_unit, e) {
            (Some(AxisUnit::Si { base, .. }), _) => format!("{} ({p}{base})", f.x_label),
            (Some(AxisUnit::Described(d)), 0) => format!("{} ({d})", f.x_label),
            (Some(AxisUnit::Described(d)), e) => format!("{} (1e{e} x {d})", f.x_label),
            (None, 0) => f.x_label.clone(),
            (None, e) => format!("{} (x 1e{e})", f.x_label),
        };
        Self {
            label,
            log: None,
            factor,
            decimals,
        }
    }

    fn format(&self, x: f64) -> String {
        match &self.log {
            Some((base, scale)) if scale.is_finite() => si(10f64.powf(x) * scale, base),
            Some(_) => {
                let v = 10f64.powf(x);
                let text = format!("{v:.2e}");
                // 3.16e-5, 1e-5 (trailing zeros of the mantissa dropped).
                match text.split_once('e') {
                    Some((m, e)) if m.contains('.') => {
                        format!("{}e{e}", m.trim_end_matches('0').trim_end_matches('.'))
                    }
                    _ => text,
                }
            }
            None => {
                let text = format!("{:.*}", self.decimals, x * self.factor);
                // A tick at zero computed as -1e-21 prints as zero, unsigned.
                match text.strip_prefix('-') {
                    Some(t) if t.chars().all(|c| c == '0' || c == '.') => t.to_string(),
                    _ => text,
                }
            }
        }
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
            x_unit: None,
            x_log: false,
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

    #[test]
    fn ticks_carry_si_prefixes_and_differ() {
        assert_eq!(si(2e-5, "s"), "20 us");
        assert_eq!(si(3.1623e-7, "s"), "316 ns");
        assert_eq!(si(1.0, "m"), "1 m");
        assert_eq!(si(0.0125, "m"), "12.5 mm");
        let figure = |x: Vec<f64>, unit: Option<AxisUnit>, log: bool| Figure {
            title: String::new(),
            subtitle: String::new(),
            x_label: "lag t".into(),
            x_unit: unit,
            x_log: log,
            y_label: "|g1|".into(),
            curves: vec![Curve {
                label: "a".into(),
                y: vec![1.0; x.len()],
                x,
                err: vec![],
            }],
        };
        let seconds = || {
            Some(AxisUnit::Si {
                base: "s".into(),
                scale: 1.0,
            })
        };
        // Linear, in us: the axis names the prefix, ticks are numbers in it.
        let f = figure(vec![0.0, 1e-5, 2e-5], seconds(), true);
        assert!(!f.log_axis());
        let (x0, x1) = f.ranges(false, false).0;
        let t = Ticks::new(&f, false, (x0, x1));
        assert_eq!(t.label, "lag t (us)");
        assert_eq!(t.format(1.5e-5), "15.0");
        assert_eq!(t.format(-1e-21), "0.0");
        // Logarithmic over three decades, ticks with prefixes.
        let f = figure(vec![0.0, 1e-7, 1e-6, 1e-4], seconds(), true);
        assert!(f.log_axis());
        let t = Ticks::new(&f, true, f.ranges(true, false).0);
        assert_eq!(t.label, "lag t (log scale)");
        assert_eq!(t.format(-6.5), "316 ns");
        // Not with x_log off; a described unit is scaled by a stated power of ten.
        let f = figure(
            vec![0.0, 1e-7, 1e-4],
            Some(AxisUnit::Described("the scene's time unit".into())),
            false,
        );
        assert!(!f.log_axis());
        let t = Ticks::new(&f, false, f.ranges(false, false).0);
        assert_eq!(t.label, "lag t (1e-6 x the scene's time unit)");
        assert_eq!(t.format(5e-5), "50.0");
    }

    #[test]
    fn a_log_y_axis_labels_powers_and_draws_dashed_curves() {
        assert_eq!(power_label(-2.0), "0.01");
        assert_eq!(power_label(-1.5), "0.032");
        assert_eq!(power_label(0.0), "1");
        assert_eq!(power_label(-5.0), "1e-5");
        let curve = |label: &str, y: Vec<f64>, err: Vec<f64>| Curve {
            label: label.into(),
            x: vec![1.0, 2.0, 3.0],
            y,
            err,
        };
        let f = Figure {
            title: "mean".into(),
            subtitle: String::new(),
            x_label: "d".into(),
            x_unit: None,
            x_log: false,
            y_label: "|m|".into(),
            curves: vec![
                curve("a", vec![1.0, 0.1, 0.001], vec![]),
                curve("b", vec![1.0, 0.1, 0.0], vec![0.5, 0.2, 0.1]),
            ],
        };
        // The second curve's bar below zero is cut a decade under its point; its zero is left out.
        let (_, (y0, y1)) = f.ranges(false, true);
        assert!(y0 < -3.0 && y0 > -3.5 && y1 > 0.17 && y1 < 0.4, "{y0} {y1}");
        let style = Style {
            y_log: true,
            dashed: vec![0],
        };
        let svg = f.svg_styled(&style).unwrap();
        assert!(svg.contains("|m| (log scale)"));
        assert!(!svg.contains("NaN"));
        assert_ne!(svg, f.svg().unwrap());
    }
}
