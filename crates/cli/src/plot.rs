//! SVG line plots (plotters, SVG backend) with an embedded font, so no system fonts are needed.

use miette::{miette, Result};
use physid_ident::RankedParam;
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;

static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
static REGISTER: Once = Once::new();

fn register_font() {
    REGISTER.call_once(|| {
        // The bytes are a valid TTF shipped with the binary; failure would show as missing text.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

/// One curve.
pub struct Series<'a> {
    /// Legend text.
    pub name: String,
    /// Abscissa.
    pub x: &'a [f64],
    /// Ordinate.
    pub y: &'a [f64],
    /// Colour.
    pub color: RGBColor,
    /// Drawn thicker and lighter, for reference curves such as the truth.
    pub reference: bool,
}

/// One panel: a y-axis label, its curves and marks.
#[derive(Default)]
pub struct Panel<'a> {
    /// Y-axis label.
    pub ylabel: String,
    /// Curves.
    pub series: Vec<Series<'a>>,
    /// Dashed lines across the panel: reference values and instants, in the legend.
    pub marks: Vec<Mark>,
    /// The y-axis range, when the data's own would be set by something a reader should not
    /// look at (a start-up transient); data beyond it is clipped at the frame.
    pub y_range: Option<(f64, f64)>,
}

/// A dashed line across a panel: a value (horizontal) or an instant (vertical).
pub struct Mark {
    /// Legend text (marks with the same text and colour share one legend entry).
    pub name: String,
    /// The value or the instant.
    pub at: f64,
    /// An instant (a vertical line) rather than a value.
    pub vertical: bool,
    /// Colour.
    pub color: RGBColor,
}

impl Mark {
    /// A horizontal line at the value `at`.
    pub fn value(name: impl Into<String>, at: f64, color: RGBColor) -> Self {
        Self {
            name: name.into(),
            at,
            vertical: false,
            color,
        }
    }

    /// A vertical line at the instant `at`.
    pub fn instant(name: impl Into<String>, at: f64, color: RGBColor) -> Self {
        Self {
            name: name.into(),
            at,
            vertical: true,
            color,
        }
    }
}

/// Tick labels for an axis over `lo..hi` that differ from one another: plotters places about
/// ten labels at a step of 1, 2 or 5 × 10^k no smaller than a tenth of the span, so the labels
/// carry the digits down to that decade (in scientific notation for very small or large
/// values).
pub fn tick_labels(lo: f64, hi: f64) -> impl Fn(&f64) -> String {
    let span = (hi - lo).abs().max(f64::MIN_POSITIVE);
    let finest = (span / 10.0).log10().floor();
    let mag = lo.abs().max(hi.abs());
    let sci = mag > 0.0 && !(1e-3..1e6).contains(&mag);
    move |v: &f64| {
        // A label at zero computed as a tiny residue reads 0.
        let v = if v.abs() < span * 1e-9 { 0.0 } else { *v };
        if sci && v == 0.0 {
            "0".into()
        } else if sci {
            let exp = v.abs().log10().floor();
            let digits = (exp - finest).clamp(0.0, 15.0) as usize;
            format!("{v:.digits$e}")
        } else {
            let digits = (-finest).clamp(0.0, 15.0) as usize;
            format!("{v:.digits$}")
        }
    }
}

/// Width of the legend column to the right of every panel: legends never cover data.
const LEGEND_WIDTH: u32 = 200;

/// Colours for successive estimators (colour-blind-safe Okabe–Ito palette).
pub const PALETTE: [RGBColor; 5] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
];

/// A ±3σ band (Okabe–Ito sky blue: apart from the estimate's blue and the truth's orange).
pub const BAND: RGBColor = RGBColor(86, 180, 233);
/// A reference value (dark grey).
pub const REFERENCE: RGBColor = RGBColor(60, 60, 60);
/// An alarm (red).
pub const ALARM: RGBColor = RGBColor(200, 0, 0);

/// Keep at most ~2·`buckets` points: the min and max of each bucket, in order, so that short
/// spikes survive decimation.
fn decimate(x: &[f64], y: &[f64], buckets: usize) -> Vec<(f64, f64)> {
    let n = x.len().min(y.len());
    if n <= 2 * buckets {
        return x.iter().zip(y).map(|(&a, &b)| (a, b)).collect();
    }
    let size = n.div_ceil(buckets);
    let mut out = Vec::with_capacity(2 * buckets + 1);
    for start in (0..n).step_by(size) {
        let end = (start + size).min(n);
        let (mut lo, mut hi) = (start, start);
        for i in start..end {
            if y[i] < y[lo] {
                lo = i;
            }
            if y[i] > y[hi] {
                hi = i;
            }
        }
        let (a, b) = if lo <= hi { (lo, hi) } else { (hi, lo) };
        out.push((x[a], y[a]));
        if b != a {
            out.push((x[b], y[b]));
        }
    }
    out
}

fn range(panel: &Panel) -> (f64, f64, f64, f64) {
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for m in panel.marks.iter().filter(|m| m.at.is_finite()) {
        if m.vertical {
            x0 = x0.min(m.at);
            x1 = x1.max(m.at);
        } else {
            y0 = y0.min(m.at);
            y1 = y1.max(m.at);
        }
    }
    for s in &panel.series {
        for (&a, &b) in s.x.iter().zip(s.y) {
            if a.is_finite() && b.is_finite() {
                x0 = x0.min(a);
                x1 = x1.max(a);
                y0 = y0.min(b);
                y1 = y1.max(b);
            }
        }
    }
    if x0 > x1 || y0 > y1 {
        return (0.0, 1.0, 0.0, 1.0);
    }
    if let Some((lo, hi)) = panel.y_range {
        (y0, y1) = (lo, hi);
    }
    let pad = ((y1 - y0) * 0.05).max(1e-9 * y1.abs().max(1.0));
    (x0, x1.max(x0 + 1e-12), y0 - pad, y1 + pad)
}

/// Stacked panels sharing the x label, written as one SVG file; each panel's legend in a
/// column to its right, so that it never covers data.
pub fn panels(path: &Path, title: &str, xlabel: &str, panels: &[Panel]) -> Result<()> {
    register_font();
    let err = |e: &dyn std::fmt::Display| miette!("writing {}: {e}", path.display());
    let height = 60 + 300 * panels.len() as u32;
    let width = 960 + LEGEND_WIDTH;
    let root = SVGBackend::new(path, (width, height)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let (top, body) = root.split_vertically(50);
    top.titled(title, ("sans-serif", 22)).map_err(|e| err(&e))?;
    let areas = body.split_evenly((panels.len(), 1));
    for (area, panel) in areas.iter().zip(panels) {
        let (plot_area, legend_area) = area.split_horizontally(width - LEGEND_WIDTH);
        let (x0, x1, y0, y1) = range(panel);
        let mut chart = ChartBuilder::on(&plot_area)
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(80)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(|e| err(&e))?;
        let (fx, fy) = (tick_labels(x0, x1), tick_labels(y0, y1));
        chart
            .configure_mesh()
            .x_desc(xlabel)
            .y_desc(panel.ylabel.as_str())
            .x_label_formatter(&fx)
            .y_label_formatter(&fy)
            .label_style(("sans-serif", 14))
            .draw()
            .map_err(|e| err(&e))?;
        // Legend entries: a name, its line's style and whether it is dashed.
        let mut legend: Vec<(String, ShapeStyle, bool)> = Vec::new();
        for s in &panel.series {
            let style = if s.reference {
                ShapeStyle::from(&s.color.mix(0.55)).stroke_width(3)
            } else {
                ShapeStyle::from(&s.color).stroke_width(1)
            };
            // Points beyond a fixed y range are clipped to the frame.
            let points = decimate(s.x, s.y, 1500)
                .into_iter()
                .map(|(x, y)| (x, y.clamp(y0, y1)));
            chart
                .draw_series(LineSeries::new(points, style))
                .map_err(|e| err(&e))?;
            // A series without a name (the second line of a band) stays out of the legend.
            if !s.name.is_empty() {
                legend.push((s.name.clone(), style, false));
            }
        }
        for m in panel.marks.iter().filter(|m| m.at.is_finite()) {
            let style = ShapeStyle::from(&m.color).stroke_width(2);
            let line = if m.vertical {
                [(m.at, y0), (m.at, y1)]
            } else {
                [(x0, m.at), (x1, m.at)]
            };
            chart
                .draw_series(DashedLineSeries::new(line, 8, 5, style))
                .map_err(|e| err(&e))?;
            if !legend
                .iter()
                .any(|(n, s, _)| *n == m.name && s.color == style.color)
            {
                legend.push((m.name.clone(), style, true));
            }
        }
        for (i, (name, style, dashed)) in legend.iter().enumerate() {
            let y = 30 + 22 * i as i32;
            let sample = [(4, y), (34, y)];
            if *dashed {
                legend_area
                    .draw(&plotters::element::DashedPathElement::new(
                        sample, 6, 4, *style,
                    ))
                    .map_err(|e| err(&e))?;
            } else {
                legend_area
                    .draw(&PathElement::new(sample.to_vec(), *style))
                    .map_err(|e| err(&e))?;
            }
            legend_area
                .draw(&Text::new(
                    name.clone(),
                    (42, y - 8),
                    ("sans-serif", 14).into_font(),
                ))
                .map_err(|e| err(&e))?;
        }
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

/// A heat map of ranks (1 = darkest), one row per test and one column per parameter, with
/// the rank written in each cell — the layout of the thesis's Fig. 7.1.
pub fn rank_heatmap(
    path: &Path,
    title: &str,
    rows: &[String],
    columns: &[String],
    ranks: &[Vec<usize>],
) -> Result<()> {
    register_font();
    let err = |e: &dyn std::fmt::Display| miette!("writing {}: {e}", path.display());
    let (cell_w, cell_h, left, top) = (64u32, 22u32, 230u32, 90u32);
    let width = left + cell_w * columns.len() as u32 + 20;
    let height = top + cell_h * rows.len() as u32 + 20;
    let root = SVGBackend::new(path, (width, height)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let text = |s: &str, x: u32, y: u32, size: u32, color: &RGBColor| {
        Text::new(
            s.to_string(),
            (x as i32, y as i32),
            ("sans-serif", size).into_font().color(color),
        )
    };
    root.draw(&text(title, 10, 12, 20, &BLACK))
        .map_err(|e| err(&e))?;
    let max_rank = columns.len().max(2) as f64;
    for (j, c) in columns.iter().enumerate() {
        let x = left + cell_w * j as u32 + cell_w / 2 - 4 * c.len() as u32;
        root.draw(&text(c, x, top - 24, 15, &BLACK))
            .map_err(|e| err(&e))?;
    }
    for (i, (label, row)) in rows.iter().zip(ranks).enumerate() {
        let y = top + cell_h * i as u32;
        root.draw(&text(label, 10, y + 4, 13, &BLACK))
            .map_err(|e| err(&e))?;
        for (j, &rank) in row.iter().enumerate() {
            // Rank 1 dark blue, the last rank near white.
            let f = (rank as f64 - 1.0) / (max_rank - 1.0);
            let shade = |dark: f64| (dark + (250.0 - dark) * f) as u8;
            let fill = RGBColor(shade(8.0), shade(48.0), shade(107.0));
            let x = left + cell_w * j as u32;
            root.draw(&Rectangle::new(
                [
                    (x as i32, y as i32),
                    ((x + cell_w) as i32, (y + cell_h) as i32),
                ],
                ShapeStyle::from(&fill).filled(),
            ))
            .map_err(|e| err(&e))?;
            let ink = if f < 0.5 { WHITE } else { BLACK };
            root.draw(&text(
                &rank.to_string(),
                x + cell_w / 2 - 4,
                y + 4,
                13,
                &ink,
            ))
            .map_err(|e| err(&e))?;
        }
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

/// The residual profile of an identifiability ranking: one bar per parameter in selection
/// order, its height `log10` of the residual sum of squares relative to the first (Alg. 5.1),
/// estimable parameters dark, the rest light; the parameter's name under its bar.
pub fn residual_profile(path: &Path, title: &str, ranked: &[RankedParam]) -> Result<()> {
    register_font();
    let err = |e: &dyn std::fmt::Display| miette!("writing {}: {e}", path.display());
    // Rounding-level residuals (exactly 0 or below 1e-40) sit on the floor.
    let floor = -40.0;
    let heights: Vec<f64> = ranked
        .iter()
        .map(|r| {
            if r.relative_residual > 0.0 {
                r.relative_residual.log10().max(floor)
            } else {
                floor
            }
        })
        .collect();
    let low = heights.iter().cloned().fold(0.0, f64::min).floor() - 1.0;
    let n = ranked.len().max(1);
    let root = SVGBackend::new(path, (960, 380)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let (top, body) = root.split_vertically(40);
    top.titled(title, ("sans-serif", 20)).map_err(|e| err(&e))?;
    let mut chart = ChartBuilder::on(&body)
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..n as f64, low..3.0)
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .disable_x_mesh()
        .x_labels(0)
        .y_desc("log10 relative residual")
        .x_desc("selection order (estimable dark)")
        .label_style(("sans-serif", 13))
        .draw()
        .map_err(|e| err(&e))?;
    for (i, (r, h)) in ranked.iter().zip(&heights).enumerate() {
        let color = if r.estimable {
            PALETTE[0]
        } else {
            RGBColor(170, 190, 210)
        };
        chart
            .draw_series(std::iter::once(Rectangle::new(
                [(i as f64 + 0.15, low), (i as f64 + 0.85, *h)],
                ShapeStyle::from(&color).filled(),
            )))
            .map_err(|e| err(&e))?;
        // The name just above the bar.
        let label_y = h + (1.0 - low) * 0.06;
        chart
            .draw_series(std::iter::once(Text::new(
                r.param.clone(),
                (i as f64 + 0.2, label_y),
                ("sans-serif", 13).into_font(),
            )))
            .map_err(|e| err(&e))?;
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

/// A cycle-by-crank-angle surface (thesis Fig. 4.8) as a heat map: one row per cycle, one
/// column per crank-angle bin (1° bins over 0–720°), colour by value (dark blue low, yellow
/// high), with a colour bar.
pub fn surface(
    path: &Path,
    title: &str,
    cycle: &[f64],
    crank_deg: &[f64],
    x: &[f64],
) -> Result<()> {
    register_font();
    let err = |e: &dyn std::fmt::Display| miette!("writing {}: {e}", path.display());
    let c0 = cycle
        .iter()
        .cloned()
        .filter(|c| *c >= 0.0)
        .fold(f64::MAX, f64::min);
    let c1 = cycle.iter().cloned().fold(f64::MIN, f64::max);
    if c0 > c1 || c1.is_nan() {
        return Err(miette!("no cycles to draw in {}", path.display()));
    }
    let rows = (c1 - c0) as usize + 1;
    let mut grid = vec![f64::NAN; rows * 720];
    for ((&c, &d), &v) in cycle.iter().zip(crank_deg).zip(x) {
        if c >= c0 && v.is_finite() {
            let (r, k) = ((c - c0) as usize, (d.floor() as usize).min(719));
            grid[r * 720 + k] = v;
        }
    }
    let (lo, hi) = grid
        .iter()
        .filter(|v| v.is_finite())
        .fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
    let span = if hi > lo { hi - lo } else { 1.0 };
    // A perceptually ordered ramp (viridis end points and middle).
    let colour = |v: f64| {
        let f = ((v - lo) / span).clamp(0.0, 1.0);
        let stops = [
            (68.0, 1.0, 84.0),
            (33.0, 145.0, 140.0),
            (253.0, 231.0, 37.0),
        ];
        let (a, b, g) = if f < 0.5 {
            (stops[0], stops[1], f * 2.0)
        } else {
            (stops[1], stops[2], (f - 0.5) * 2.0)
        };
        RGBColor(
            (a.0 + (b.0 - a.0) * g) as u8,
            (a.1 + (b.1 - a.1) * g) as u8,
            (a.2 + (b.2 - a.2) * g) as u8,
        )
    };
    let root = SVGBackend::new(path, (960, 540)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let (main, bar) = root.split_horizontally(860);
    let mut chart = ChartBuilder::on(&main)
        .caption(title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..720.0, c0..(c1 + 1.0))
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .x_desc("crank angle [deg]")
        .y_desc("cycle")
        .label_style(("sans-serif", 14))
        .disable_mesh()
        .draw()
        .map_err(|e| err(&e))?;
    // Bins of 4° keep the SVG small (180 rectangles per cycle).
    let bin = 4;
    let mut rects = Vec::new();
    for r in 0..rows {
        for k in (0..720).step_by(bin) {
            let vals: Vec<f64> = grid[r * 720 + k..r * 720 + k + bin]
                .iter()
                .cloned()
                .filter(|v| v.is_finite())
                .collect();
            if vals.is_empty() {
                continue;
            }
            let m = vals.iter().sum::<f64>() / vals.len() as f64;
            let y = c0 + r as f64;
            rects.push(Rectangle::new(
                [(k as f64, y), ((k + bin) as f64, y + 1.0)],
                ShapeStyle::from(&colour(m)).filled(),
            ));
        }
    }
    chart.draw_series(rects).map_err(|e| err(&e))?;
    // Colour bar.
    let steps = 50;
    let (_, h) = bar.dim_in_pixel();
    let top = 60i32;
    let height = h as i32 - 120;
    for s in 0..steps {
        let f = s as f64 / steps as f64;
        let y0 = top + height - ((s + 1) as f64 / steps as f64 * height as f64) as i32;
        let y1 = top + height - (f * height as f64) as i32;
        bar.draw(&Rectangle::new(
            [(10, y0), (35, y1)],
            ShapeStyle::from(&colour(lo + f * span)).filled(),
        ))
        .map_err(|e| err(&e))?;
    }
    for (v, y) in [(hi, top), (lo, top + height)] {
        bar.draw(&Text::new(
            format!("{v:.3e}"),
            (38, y - 6),
            ("sans-serif", 12).into_font(),
        ))
        .map_err(|e| err(&e))?;
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decimation_keeps_spikes_and_order() {
        let x: Vec<f64> = (0..10_000).map(|i| i as f64).collect();
        let mut y = vec![0.0; 10_000];
        y[5003] = 7.0;
        y[7001] = -3.0;
        let d = decimate(&x, &y, 100);
        assert!(d.len() <= 201);
        assert!(d.contains(&(5003.0, 7.0)) && d.contains(&(7001.0, -3.0)));
        assert!(d.windows(2).all(|w| w[0].0 < w[1].0));
    }

    /// Tick labels differ from one another for every step plotters may choose (1, 2 or 5 ×
    /// 10^k, at least a tenth of the span), over spans from 1e-9 to 1e9 and offsets far from
    /// zero — the duplicated `0.0001, 0.0001, 0.00008` of c4's axis cannot come back.
    #[test]
    fn tick_labels_differ() {
        let mut checked = 0;
        for lo_exp in -9..=9 {
            for offset in [0.0, 1.0, -3.7, 1250.0, 2.5e-4] {
                for span_mul in [1.0, 1.7, 3.3, 7.9] {
                    let span = span_mul * 10f64.powi(lo_exp);
                    let lo = offset * 10f64.powi(lo_exp.max(0)) + span * 0.123;
                    let hi = lo + span;
                    let label = tick_labels(lo, hi);
                    let decade = 10f64.powf((span / 10.0).log10().floor());
                    for mult in [1.0, 2.0, 5.0, 10.0] {
                        let step = mult * decade;
                        if step < span / 10.0 {
                            continue;
                        }
                        let first = (lo / step).ceil() as i64;
                        let last = (hi / step).floor() as i64;
                        let labels: Vec<String> =
                            (first..=last).map(|i| label(&(i as f64 * step))).collect();
                        let mut unique = labels.clone();
                        unique.dedup();
                        assert_eq!(unique, labels, "{lo}..{hi}, step {step}: {labels:?}");
                        checked += 1;
                    }
                }
            }
        }
        assert!(checked > 500);
        // The reported case: c4 between 8e-5 and 1e-4.
        let l = tick_labels(8e-5, 1e-4);
        assert_ne!(l(&1e-4), l(&9e-5));
        assert_eq!(l(&0.0), "0");
        assert_eq!(tick_labels(-1.0, 1.0)(&-2.7755575615628914e-17), "0.0");
    }
}
