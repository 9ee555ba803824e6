//! PNG charts for benchmark results: line charts (optionally log-scaled) and bar charts.
//!
//! Rendering goes through plotters' bitmap backend into an RGB buffer that is written with
//! `image`. Text needs a TrueType font, loaded once at runtime from `$KDRAY_PLOT_FONT` or a
//! common system location (DejaVu Sans, Liberation Sans).

use std::ops::Range;
use std::path::Path;
use std::sync::OnceLock;

use anyhow::{anyhow, bail, Context, Result};
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::{register_font, FontStyle, FontTransform};

const WIDTH: u32 = 1200;
const HEIGHT: u32 = 800;
const MARGIN: u32 = 20;
const CAPTION_PX: u32 = 50;
const X_LABEL_AREA: u32 = 70; // line charts; bar charts size it to the category names
const Y_LABEL_AREA: u32 = 100;
const FONT: &str = "sans-serif";

/// Okabe–Ito colour-blind-friendly palette (yellow last: weakest contrast on white).
const PALETTE: [RGBColor; 8] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(230, 159, 0),
    RGBColor(204, 121, 167),
    RGBColor(86, 180, 233),
    RGBColor(0, 0, 0),
    RGBColor(240, 228, 66),
];

type Root<'a> = DrawingArea<BitMapBackend<'a>, Shift>;

/// One line of a [`LineChart`].
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend entry.
    pub name: String,
    /// `(x, y)` samples in drawing order; NaN/inf (and non-positive values on log axes) are
    /// skipped, and a series left with no points is omitted from the chart and its legend.
    pub points: Vec<(f64, f64)>,
    /// Draw dashed and without point markers (meant for fits and reference curves).
    pub dashed: bool,
}

/// Description of a line chart; see [`line_chart`].
#[derive(Debug, Clone)]
pub struct LineChart {
    /// Caption above the plot.
    pub title: String,
    /// X axis description.
    pub x_label: String,
    /// Y axis description.
    pub y_label: String,
    /// Logarithmic x axis.
    pub x_log: bool,
    /// Logarithmic y axis.
    pub y_log: bool,
    /// The lines, coloured in order from a fixed colour-blind-friendly palette.
    pub series: Vec<Series>,
}

/// Lines with point markers, legend, axis labels, title; 1200x800 px; handles log axes (skip
/// non-positive values there), a single point, empty series (error), NaN/inf (skipped).
pub fn line_chart(path: &Path, chart: &LineChart) -> Result<()> {
    ensure_font()?;
    let ctx = || format!("line chart {:?}", chart.title);
    if chart.series.is_empty() {
        bail!("{}: no series", ctx());
    }
    if let Some(s) = chart.series.iter().find(|s| s.points.is_empty()) {
        bail!("{}: series {:?} has no points", ctx(), s.name);
    }
    let usable = |v: f64, log: bool| v.is_finite() && (!log || v > 0.0);
    let data: Vec<(&Series, Vec<(f64, f64)>)> = chart
        .series
        .iter()
        .map(|s| {
            let pts = s.points.iter().copied();
            (s, pts.filter(|&(x, y)| usable(x, chart.x_log) && usable(y, chart.y_log)).collect())
        })
        .collect();
    let all = || data.iter().flat_map(|(_, pts)| pts.iter().copied());
    let (Some(xs), Some(ys)) = (min_max(all().map(|p| p.0)), min_max(all().map(|p| p.1))) else {
        let what = if chart.x_log || chart.y_log { "finite positive" } else { "finite" };
        bail!("{}: no {what} points to plot", ctx());
    };
    let plot_h = HEIGHT - 2 * MARGIN - CAPTION_PX - X_LABEL_AREA;
    let x = padded(xs, chart.x_log, false, 0.0);
    let y = padded(ys, chart.y_log, true, legend_fraction(data.len(), plot_h));
    render(path, |root| match (chart.x_log, chart.y_log) {
        (false, false) => draw_lines(root, chart, &data, x, y),
        (true, false) => draw_lines(root, chart, &data, x.log_scale(), y),
        (false, true) => draw_lines(root, chart, &data, x, y.log_scale()),
        (true, true) => draw_lines(root, chart, &data, x.log_scale(), y.log_scale()),
    })
    .with_context(ctx)
}

/// Description of a bar chart; see [`bar_chart`].
#[derive(Debug, Clone)]
pub struct BarChart {
    /// Caption above the plot.
    pub title: String,
    /// Y axis description.
    pub y_label: String,
    /// One group of bars per category, labelled on the x axis.
    pub categories: Vec<String>,
    /// `(legend name, one value per category)`; values must be >= 0, NaN/inf mark a missing bar.
    pub series: Vec<(String, Vec<f64>)>,
    /// Stack the series on top of each other instead of placing them side by side.
    pub stacked: bool,
}

/// Grouped (side by side per category) or stacked bars with legend; category names on the x
/// axis (shrunk, then turned vertical when they do not fit side by side); values >= 0.
pub fn bar_chart(path: &Path, chart: &BarChart) -> Result<()> {
    ensure_font()?;
    let ctx = || format!("bar chart {:?}", chart.title);
    let n = chart.categories.len();
    if n == 0 || chart.series.is_empty() {
        bail!("{}: needs at least one category and one series", ctx());
    }
    for (name, values) in &chart.series {
        if values.len() != n {
            bail!("{}: series {name:?} has {} values for {n} categories", ctx(), values.len());
        }
        if let Some(v) = values.iter().find(|v| **v < 0.0) {
            bail!("{}: series {name:?} has negative value {v}", ctx());
        }
    }
    let value = |s: usize, c: usize| Some(chart.series[s].1[c]).filter(|v| v.is_finite());
    let top = (0..n)
        .map(|c| {
            let vals = (0..chart.series.len()).filter_map(|s| value(s, c));
            if chart.stacked {
                vals.sum()
            } else {
                vals.fold(0.0, f64::max)
            }
        })
        .fold(0.0, f64::max);
    let top = if top > 0.0 { top } else { 1.0 };
    render(path, |root| {
        let (label_style, label_area) = category_labels(root, &chart.categories)?;
        let plot_h = HEIGHT - 2 * MARGIN - CAPTION_PX - label_area;
        let y = padded((0.0, top), false, true, legend_fraction(chart.series.len(), plot_h));
        let mut cc = ChartBuilder::on(root)
            .caption(&chart.title, (FONT, 28))
            .margin(MARGIN)
            .x_label_area_size(label_area)
            .y_label_area_size(Y_LABEL_AREA)
            .build_cartesian_2d(0.0..n as f64, y)
            .context("building chart")?;
        cc.configure_mesh()
            .disable_x_mesh()
            .x_labels(0)
            .y_desc(&chart.y_label)
            .y_label_formatter(&|v| fmt_num(*v))
            .label_style((FONT, 16))
            .axis_desc_style((FONT, 20))
            .bold_line_style(BLACK.mix(0.15))
            .light_line_style(BLACK.mix(0.05))
            .draw()
            .context("drawing axes")?;
        let m = chart.series.len();
        for (s, (name, _)) in chart.series.iter().enumerate() {
            let color = PALETTE[s % PALETTE.len()];
            let bars = (0..n).filter_map(|c| {
                let v = value(s, c)?;
                let (x0, x1, base) = if chart.stacked {
                    let below: f64 = (0..s).filter_map(|k| value(k, c)).sum();
                    (c as f64 + 0.15, c as f64 + 0.85, below)
                } else {
                    let w = 0.8 / m as f64;
                    (c as f64 + 0.1 + s as f64 * w, c as f64 + 0.1 + (s + 1) as f64 * w, 0.0)
                };
                Some(Rectangle::new([(x0, base), (x1, base + v)], color.filled()))
            });
            cc.draw_series(bars)
                .with_context(|| format!("drawing series {name:?}"))?
                .label(name)
                .legend(move |(x, y)| {
                    Rectangle::new([(x, y - 7), (x + 18, y + 7)], color.filled())
                });
        }
        draw_legend(&mut cc)?;
        for (c, name) in chart.categories.iter().enumerate() {
            let (px, py) = cc.backend_coord(&(c as f64 + 0.5, 0.0));
            root.draw_text(name, &label_style, (px, py + 8))
                .with_context(|| format!("drawing category label {name:?}"))?;
        }
        Ok(())
    })
    .with_context(ctx)
}

/// Text style for the category names under a bar chart and the height of their area: the
/// largest horizontal size that fits each category's slot, else vertical text.
fn category_labels(root: &Root, names: &[String]) -> Result<(TextStyle<'static>, u32)> {
    let slot = f64::from(WIDTH - 2 * MARGIN - Y_LABEL_AREA) / names.len() as f64;
    let widest = |size: u32| -> Result<u32> {
        let style = TextStyle::from((FONT, size).into_font());
        names.iter().try_fold(0, |w, t| {
            let (tw, _) = root.estimate_text_size(t, &style).context("measuring label")?;
            Ok(w.max(tw))
        })
    };
    for size in [18, 16, 14, 12] {
        if f64::from(widest(size)?) <= 0.95 * slot {
            let style = (FONT, size).into_font().into_text_style(root);
            return Ok((style.pos(Pos::new(HPos::Center, VPos::Top)), size + 24));
        }
    }
    // Vertical, reading bottom-to-top and ending just below the axis; at most a third of the
    // image tall (longer names are cut off at the bottom edge).
    let max_len = HEIGHT / 3 - 24;
    let mut size = 10;
    for s in [16, 14, 12] {
        if f64::from(s) <= 0.9 * slot && widest(s)? <= max_len {
            size = s;
            break;
        }
    }
    let style = (FONT, size).into_font().transform(FontTransform::Rotate270).into_text_style(root);
    Ok((style.pos(Pos::new(HPos::Right, VPos::Center)), widest(size)?.min(max_len) + 24))
}

/// Draws the line chart once the axis coordinate types (linear or log) are fixed.
fn draw_lines<X, Y>(
    root: &Root,
    chart: &LineChart,
    data: &[(&Series, Vec<(f64, f64)>)],
    x: impl AsRangedCoord<CoordDescType = X, Value = f64>,
    y: impl AsRangedCoord<CoordDescType = Y, Value = f64>,
) -> Result<()>
where
    X: Ranged<ValueType = f64> + ValueFormatter<f64>,
    Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
{
    let mut cc = ChartBuilder::on(root)
        .caption(&chart.title, (FONT, 28))
        .margin(MARGIN)
        .margin_right(2 * MARGIN)
        .x_label_area_size(X_LABEL_AREA)
        .y_label_area_size(Y_LABEL_AREA)
        .build_cartesian_2d(x, y)
        .context("building chart")?;
    cc.configure_mesh()
        .x_desc(&chart.x_label)
        .y_desc(&chart.y_label)
        .x_label_formatter(&|v| fmt_num(*v))
        .y_label_formatter(&|v| fmt_num(*v))
        .label_style((FONT, 16))
        .axis_desc_style((FONT, 20))
        .bold_line_style(BLACK.mix(0.15))
        .light_line_style(BLACK.mix(0.05))
        .draw()
        .context("drawing axes")?;
    for (i, (s, pts)) in data.iter().enumerate().filter(|(_, (_, pts))| !pts.is_empty()) {
        let color = PALETTE[i % PALETTE.len()];
        let style = color.stroke_width(2);
        let dashed = s.dashed && pts.len() > 1; // a lone point is shown as a marker
        let drawn = if dashed {
            cc.draw_series(DashedLineSeries::new(pts.iter().copied(), 12, 8, style))
        } else {
            cc.draw_series(LineSeries::new(pts.iter().copied(), style).point_size(4))
        };
        // Legend sample: two line pieces (with a gap when dashed) and a marker for solid lines.
        let (gap, marker) = if dashed { (4, TRANSPARENT.into()) } else { (0, style) };
        drawn.with_context(|| format!("drawing series {:?}", s.name))?.label(&s.name).legend(
            move |(x, y)| {
                EmptyElement::at((x, y))
                    + PathElement::new([(0, 0), (10 - gap, 0)], style)
                    + PathElement::new([(10 + gap, 0), (20, 0)], style)
                    + Circle::new((10, 0), 4, marker)
            },
        );
    }
    draw_legend(&mut cc)
}

/// Legend box in the upper right corner (the y range leaves headroom for it).
fn draw_legend<'a, X: Ranged, Y: Ranged>(
    cc: &mut ChartContext<'a, BitMapBackend<'a>, Cartesian2d<X, Y>>,
) -> Result<()> {
    cc.configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .label_font((FONT, 18))
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK.mix(0.5))
        .draw()
        .context("drawing legend")
}

/// Renders a 1200x800 chart into memory and writes it as PNG (after [`ensure_font`]).
fn render(path: &Path, draw: impl FnOnce(&Root) -> Result<()>) -> Result<()> {
    let mut buf = vec![0u8; WIDTH as usize * HEIGHT as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (WIDTH, HEIGHT)).into_drawing_area();
        root.fill(&WHITE).context("clearing canvas")?;
        draw(&root)?;
        root.present().context("finishing drawing")?;
    }
    let img = image::RgbImage::from_raw(WIDTH, HEIGHT, buf)
        .ok_or_else(|| anyhow!("internal error: pixel buffer has the wrong size"))?;
    Ok(kdray::image_out::write_rgb8(&img, path)?)
}

/// Loads and registers the plot font as "sans-serif" once per process: `$KDRAY_PLOT_FONT`
/// if set, else the first existing common system font. Its error is a complete message.
fn ensure_font() -> Result<()> {
    static FONT_STATE: OnceLock<Result<(), String>> = OnceLock::new();
    let load = || -> Result<()> {
        let path = match std::env::var_os("KDRAY_PLOT_FONT") {
            Some(p) => p.into(),
            None => [
                "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
                "/usr/share/fonts/TTF/DejaVuSans.ttf",
                "/usr/share/fonts/dejavu/DejaVuSans.ttf",
                "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
                "/usr/share/fonts/liberation/LiberationSans-Regular.ttf",
            ]
            .into_iter()
            .map(std::path::PathBuf::from)
            .find(|p| p.is_file())
            .context(
                "no TrueType font for plots (install fonts-dejavu-core or set KDRAY_PLOT_FONT)",
            )?,
        };
        let bytes = std::fs::read(&path)
            .with_context(|| format!("reading plot font {}", path.display()))?;
        register_font(FONT, FontStyle::Normal, Box::leak(bytes.into_boxed_slice()))
            .map_err(|_| anyhow!("{} is not a usable TrueType font", path.display()))
    };
    FONT_STATE.get_or_init(|| load().map_err(|e| format!("{e:#}"))).clone().map_err(|e| anyhow!(e))
}

/// Minimum and maximum of a sequence, `None` if it is empty.
fn min_max(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    values.fold(None, |acc, v| match acc {
        None => Some((v, v)),
        Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
    })
}

/// Axis range around `(lo, hi)`: a little padding (a linear y axis starts at 0 when the data
/// allow it), plus `headroom` (fraction of the axis) at the top for the legend.
fn padded((lo, hi): (f64, f64), log: bool, is_y: bool, headroom: f64) -> Range<f64> {
    let stretch = |lo: f64, hi: f64| lo + (hi - lo) / (1.0 - headroom);
    if log {
        let (lo, hi) = if hi / lo < 1.01 { (lo / 2.0, hi * 2.0) } else { (lo, hi) };
        let pad = (hi / lo).powf(0.03);
        let (mut l, mut h) = ((lo / pad).log10(), (hi * pad).log10());
        // plotters only labels powers of ten and steps above them: use whole decades if narrow.
        if h - l < 2.0 {
            (l, h) = (l.floor(), h.ceil());
        }
        return 10f64.powf(l)..10f64.powf(stretch(l, h));
    }
    let span = hi - lo;
    let pad = if span > 0.0 { 0.04 * span } else { (0.1 * lo.abs()).max(1.0) };
    let lo = if is_y && lo >= 0.0 { 0.0 } else { lo - pad };
    lo..stretch(lo, hi + pad)
}

/// Fraction of the plot height to keep free at the top for a legend of `entries` rows.
fn legend_fraction(entries: usize, plot_h: u32) -> f64 {
    ((entries as f64 * 26.0 + 30.0) / f64::from(plot_h)).min(0.5)
}

/// Compact tick label: plain decimals for moderate magnitudes, scientific otherwise.
fn fmt_num(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if !(1e-3..1e6).contains(&a) {
        format!("{v:.1e}").replace(".0e", "e")
    } else {
        let s = format!("{v:.4}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Draws into a fresh temp file, then checks the PNG decodes, is 1200x800 and is not flat.
    fn check(name: &str, draw: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
        let dir = std::env::temp_dir().join(format!("kdray_bench_plot_{}", std::process::id()));
        std::fs::create_dir_all(&dir)?;
        let path = dir.join(format!("{name}.png"));
        draw(&path)?;
        let img = image::open(&path)?.to_rgb8();
        assert_eq!(img.dimensions(), (WIDTH, HEIGHT));
        assert!(img.pixels().any(|p| p != img.get_pixel(0, 0)), "{name}: single colour");
        Ok(())
    }

    fn line(name: &str, points: Vec<(f64, f64)>, dashed: bool) -> Series {
        Series { name: name.into(), points, dashed }
    }

    fn lines(log: bool, series: Vec<Series>) -> LineChart {
        let (x_label, y_label) = ("Triangles".into(), "Time (ms)".into());
        LineChart { title: "Build time".into(), x_label, y_label, x_log: log, y_log: log, series }
    }

    fn bars(n: usize, stacked: bool) -> BarChart {
        let values = |k: usize| (0..n).map(|c| ((c * 7 + k * 3) % 11) as f64 * 1.5).collect();
        let mut series: Vec<(String, Vec<f64>)> = ["build", "trace", "shade"]
            .iter()
            .enumerate()
            .map(|(k, s)| (s.to_string(), values(k)))
            .collect();
        series[1].1[0] = f64::NAN; // a missing measurement
        BarChart {
            title: "Frame time".into(),
            y_label: "Time (ms)".into(),
            categories: (0..n).map(|i| format!("scene_{i:02}_sponza_crytek")).collect(),
            series,
            stacked,
        }
    }

    #[test]
    fn linear_line_chart() -> Result<()> {
        let cpu = (1..=10).map(|i| (i as f64, 3.0 * i as f64 + 1.0)).collect();
        let gpu = vec![(1.0, 2.0), (2.0, f64::NAN), (5.0, 4.5), (10.0, f64::INFINITY)];
        let one = vec![(6.0, 20.0)];
        let chart = lines(
            false,
            vec![line("CPU", cpu, false), line("GPU", gpu, false), line("one", one, false)],
        );
        check("linear", |p| line_chart(p, &chart))
    }

    #[test]
    fn log_log_line_chart_with_dashed_fit() -> Result<()> {
        let model = |n: f64| 2e-4 * n * n.ln();
        let mut measured: Vec<_> = (0..=8)
            .map(|i| 1e3 * 10f64.powf(i as f64 * 0.5))
            .map(|n| (n, model(n) * 1.1))
            .collect();
        measured.push((0.0, 1.0)); // not representable on a log axis: skipped
        let fit = (0..=80).map(|i| 1e3 * 10f64.powf(i as f64 * 0.05)).map(|n| (n, model(n)));
        let chart =
            lines(true, vec![line("SAH build", measured, false), line("fit", fit.collect(), true)]);
        check("loglog", |p| line_chart(p, &chart))
    }

    #[test]
    fn grouped_bar_chart() -> Result<()> {
        check("grouped", |p| bar_chart(p, &bars(12, false)))
    }

    #[test]
    fn stacked_bar_chart() -> Result<()> {
        check("stacked", |p| bar_chart(p, &bars(5, true)))
    }

    #[test]
    fn empty_series_is_an_error() {
        let path =
            std::env::temp_dir().join(format!("kdray_bench_plot_empty_{}.png", std::process::id()));
        let err =
            line_chart(&path, &lines(false, vec![line("nothing", vec![], false)])).unwrap_err();
        assert!(format!("{err:#}").contains("has no points"), "{err:#}");
        assert!(!path.exists());
    }
}
