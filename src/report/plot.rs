//! Plots as PNG and SVG (plotters, with an embedded DejaVu Sans so they render on machines without
//! system fonts). Files are written atomically.

use crate::error::{Error, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;

static FONT: Once = Once::new();

/// Registers the embedded font as "sans-serif" (once): every drawing's text uses it.
pub(crate) fn ensure_font() {
    FONT.call_once(|| {
        let bytes: &'static [u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");
        for style in [FontStyle::Normal, FontStyle::Bold] {
            // The font is compiled in and known to be valid.
            let _ = plotters::style::register_font("sans-serif", style, bytes);
        }
    });
}

/// Pixel size of every PNG (and SVG) we draw.
pub const SIZE: (u32, u32) = (900, 560);

/// One line of a line chart, optionally with a shaded band (e.g. a 95 % interval).
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend label.
    pub label: String,
    /// (x, y) points.
    pub points: Vec<(f64, f64)>,
    /// (x, low, high) band around the line.
    pub band: Vec<(f64, f64, f64)>,
    /// Palette index.
    pub color: usize,
    /// Drawn wide and pale, under the other lines (so a line that coincides with it stays visible).
    pub wide: bool,
}

/// Colour `i` of the plots' palette (cycling).
pub(crate) fn color(i: usize) -> RGBColor {
    const P: [RGBColor; 6] = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(148, 103, 189),
        RGBColor(255, 127, 14),
        RGBColor(127, 127, 127),
    ];
    P[i % P.len()]
}

/// A writer that keeps the first error of the writer under it: the PNG encoder turns I/O errors
/// into text of kind `Other`, and the kind decides the exit code (a full disk is 1, not 2).
struct Watched<'a, W: std::io::Write> {
    inner: &'a mut W,
    first: Option<std::io::Error>,
}

impl<W: std::io::Write> Watched<'_, W> {
    fn keep(&mut self, e: std::io::Error) -> std::io::Error {
        if self.first.is_none() {
            self.first = Some(match e.raw_os_error() {
                Some(code) => std::io::Error::from_raw_os_error(code),
                None => std::io::Error::new(e.kind(), e.to_string()),
            });
        }
        e
    }
}

impl<W: std::io::Write> std::io::Write for Watched<'_, W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.inner.write(buf).map_err(|e| self.keep(e))
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush().map_err(|e| self.keep(e))
    }
}

fn plot_err(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::File { path: path.to_path_buf(), message: format!("plotting failed: {e}") }
}

/// Renders `draw` into `<base>.png` and `<base>.svg`, atomically.
pub fn render(
    base: &Path,
    draw: &dyn Fn(&DrawingArea<BitMapBackend<'_>, Shift>) -> Result<()>,
    draw_svg: &dyn Fn(&DrawingArea<SVGBackend<'_>, Shift>) -> Result<()>,
) -> Result<()> {
    render_sized(base, SIZE, draw, draw_svg)
}

/// [`render`] at `size` pixels.
pub(crate) fn render_sized(
    base: &Path,
    size: (u32, u32),
    draw: &dyn Fn(&DrawingArea<BitMapBackend<'_>, Shift>) -> Result<()>,
    draw_svg: &dyn Fn(&DrawingArea<SVGBackend<'_>, Shift>) -> Result<()>,
) -> Result<()> {
    ensure_font();
    let png = base.with_extension("png");
    let tmp =
        base.with_file_name(format!(".{}.tmp.png", base.file_name().map_or("plot".into(), |n| n.to_string_lossy())));
    // Drawn in memory and written by us, not by the backend: its file errors print as a debug
    // dump and leave the temporary file behind, where ours name the file, keep the OS's error (a
    // full disk is exit 1) and remove it.
    let mut pixels = vec![0u8; size.0 as usize * size.1 as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut pixels, size).into_drawing_area();
        root.fill(&WHITE).map_err(|e| plot_err(&png, e))?;
        draw(&root)?;
        root.present().map_err(|e| plot_err(&png, e))?;
    }
    crate::store::write_atomic_via(&png, &tmp, |w| {
        use image::ImageEncoder;
        let mut watched = Watched { inner: w, first: None };
        let encoded = image::codecs::png::PngEncoder::new(&mut watched).write_image(
            &pixels,
            size.0,
            size.1,
            image::ColorType::Rgb8,
        );
        match (encoded, watched.first) {
            (Ok(()), _) => Ok(()),
            (Err(_), Some(io)) => Err(io),
            (Err(image::ImageError::IoError(e)), None) => Err(e),
            (Err(e), None) => Err(std::io::Error::other(e.to_string())),
        }
    })?;
    let svg_path = base.with_extension("svg");
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        root.fill(&WHITE).map_err(|e| plot_err(&svg_path, e))?;
        draw_svg(&root)?;
        root.present().map_err(|e| plot_err(&svg_path, e))?;
    }
    crate::store::write_atomic(&svg_path, |w| std::io::Write::write_all(w, svg.as_bytes()))
}

/// x and y ranges covering every point and band of `series` (y padded by 6 %), never empty.
pub(crate) fn bounds(series: &[Series]) -> (f64, f64, f64, f64) {
    let xs = series.iter().flat_map(|s| s.points.iter().map(|p| p.0).chain(s.band.iter().map(|b| b.0)));
    let ys = series.iter().flat_map(|s| s.points.iter().map(|p| p.1).chain(s.band.iter().flat_map(|b| [b.1, b.2])));
    let (mut x0, mut x1) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| (a.min(x), b.max(x)));
    let (mut y0, mut y1) =
        ys.filter(|y| y.is_finite()).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), y| (a.min(y), b.max(y)));
    if !x0.is_finite() {
        (x0, x1) = (0.0, 1.0);
    }
    if !y0.is_finite() {
        (y0, y1) = (0.0, 1.0);
    }
    if x1 <= x0 {
        x1 = x0 + 1.0;
    }
    let pad = if y1 > y0 { (y1 - y0) * 0.06 } else { y0.abs().max(1.0) * 0.1 };
    (x0, x1, y0 - pad, y1 + pad)
}

fn draw_lines<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    log_x: bool,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let (x0, x1, y0, y1) = bounds(series);
    if log_x && x0 > 0.0 {
        draw_lines_on(area, title, x_label, y_label, series, (x0..x1).log_scale(), y0..y1)
    } else {
        draw_lines_on(area, title, x_label, y_label, series, x0..x1, y0..y1)
    }
}

fn draw_lines_on<DB: DrawingBackend, X: plotters::coord::ranged1d::AsRangedCoord<Value = f64>>(
    area: &DrawingArea<DB, Shift>,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    x: X,
    y: std::ops::Range<f64>,
) -> Result<()>
where
    DB::ErrorType: 'static,
    X::CoordDescType: plotters::coord::ranged1d::ValueFormatter<f64>,
{
    let e = |err: &dyn std::fmt::Display| Error::Data(format!("plot '{title}': {err}"));
    let mut chart = ChartBuilder::on(area)
        .caption(title, ("sans-serif", 22))
        .margin(14)
        .x_label_area_size(44)
        .y_label_area_size(70)
        .build_cartesian_2d(x, y)
        .map_err(|x| e(&x))?;
    // Iterations, depths, units and sizes are whole numbers: label them so.
    let integer_x = series.iter().flat_map(|s| &s.points).all(|p| p.0.fract() == 0.0);
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .x_label_formatter(&|v| match integer_x {
            true if (v - v.round()).abs() < 1e-6 => format!("{:.0}", v.round()),
            true => String::new(),
            false => format!("{v}"),
        })
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 17))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(|x| e(&x))?;
    for s in series {
        let c = color(s.color);
        if !s.band.is_empty() {
            let mut poly: Vec<(f64, f64)> = s.band.iter().map(|b| (b.0, b.2)).collect();
            poly.extend(s.band.iter().rev().map(|b| (b.0, b.1)));
            chart.draw_series(std::iter::once(Polygon::new(poly, c.mix(0.18).filled()))).map_err(|x| e(&x))?;
        }
        let line = if s.wide { c.mix(0.35).stroke_width(7) } else { c.stroke_width(2) };
        chart
            .draw_series(LineSeries::new(s.points.iter().copied(), line))
            .map_err(|x| e(&x))?
            .label(s.label.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 22, y)], line));
        if !s.wide {
            chart.draw_series(s.points.iter().map(|&p| Circle::new(p, 3, c.filled()))).map_err(|x| e(&x))?;
        }
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK.mix(0.3))
        .label_font(("sans-serif", 15))
        .draw()
        .map_err(|x| e(&x))?;
    Ok(())
}

/// A line chart with optional bands, as `<base>.png` and `<base>.svg`.
pub fn lines(base: &Path, title: &str, x_label: &str, y_label: &str, series: &[Series]) -> Result<()> {
    lines_scaled(base, title, x_label, y_label, series, false)
}

/// [`lines`], with a logarithmic x axis if `log_x` (dataset sizes from 10 to 2000 episodes would
/// otherwise crowd the small sizes, where the algorithms differ, into the first few pixels).
pub fn lines_scaled(
    base: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    log_x: bool,
) -> Result<()> {
    render(base, &|a| draw_lines(a, title, x_label, y_label, series, log_x), &|a| {
        draw_lines(a, title, x_label, y_label, series, log_x)
    })
}

/// One generation's fitness figures (`None` = every individual diverged).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitnessRow {
    /// Generation (0-based, as in generations.jsonl and best.json).
    pub generation: usize,
    /// Best fitness of the generation.
    pub best: Option<f64>,
    /// Mean finite fitness of the generation.
    pub mean: Option<f64>,
    /// Best fitness so far.
    pub best_so_far: Option<f64>,
    /// Lowest finite fitness of the generation.
    pub min: Option<f64>,
}

/// `fitness.png` / `fitness.svg` of a search, in two panels. Above, the whole population: the best
/// so far (wide, underneath), the best and the mean of each generation with its spread (min–max of
/// the finite fitnesses). Below, the best so far alone on its own scale, since its gains are tiny
/// beside the population's spread. Both show `reference` (a known config's fitness under this
/// search's fitness, e.g. the thesis optimum) as a flat line.
pub fn fitness(dir: &Path, title: &str, rows: &[FitnessRow], reference: Option<(&str, f64)>) -> Result<()> {
    let pick = |f: fn(&FitnessRow) -> Option<f64>| -> Vec<(f64, f64)> {
        rows.iter().filter_map(|r| f(r).map(|v| (r.generation as f64, v))).collect()
    };
    let spread: Vec<(f64, f64, f64)> =
        rows.iter().filter_map(|r| Some((r.generation as f64, r.min?, r.best?))).collect();
    let mut series = vec![
        Series { label: "best so far".into(), points: pick(|r| r.best_so_far), band: vec![], color: 1, wide: true },
        Series { label: "best of generation".into(), points: pick(|r| r.best), band: vec![], color: 0, wide: false },
        Series {
            label: "mean of generation (band: min–max)".into(),
            points: pick(|r| r.mean),
            band: spread,
            color: 5,
            wide: false,
        },
    ];
    if let (Some((label, f)), Some(first), Some(last)) = (reference, rows.first(), rows.last()) {
        let (x0, x1) = (first.generation as f64, last.generation.max(first.generation + 1) as f64);
        series.push(Series {
            label: format!("{label}: {f:.2}"),
            points: vec![(x0, f), (x1, f)],
            band: vec![],
            color: 2,
            wide: false,
        });
    }
    // The reference joins the zoom only when it is near the best so far (within a tenth of the
    // population's spread); otherwise it would squash the zoom back to the full scale.
    let (_, _, y0, y1) = bounds(&series);
    let near = |f: f64| rows.iter().filter_map(|r| r.best_so_far).all(|b| (b - f).abs() <= 0.1 * (y1 - y0));
    let reference_near = reference.is_some_and(|(_, f)| near(f));
    let zoom: Vec<Series> = series
        .iter()
        .filter(|s| s.wide || (s.color == 2 && reference_near))
        .map(|s| Series { wide: false, ..s.clone() })
        .collect();
    let zoom_title = match reference {
        Some((label, f)) if !reference_near => format!("best so far, zoomed ({label}, {f:.2}, off this scale)"),
        _ => "best so far, zoomed".to_string(),
    };
    let y = "fitness (mean score)";
    const TALL: (u32, u32) = (SIZE.0, SIZE.1 + 300);
    let split = SIZE.1 as i32 - 40;
    render_sized(
        &dir.join("fitness"),
        TALL,
        &|a| {
            let (top, bottom) = a.split_vertically(split);
            draw_lines(&top, title, "generation", y, &series, false)?;
            draw_lines(&bottom, &zoom_title, "generation", y, &zoom, false)
        },
        &|a| {
            let (top, bottom) = a.split_vertically(split);
            draw_lines(&top, title, "generation", y, &series, false)?;
            draw_lines(&bottom, &zoom_title, "generation", y, &zoom, false)
        },
    )
}

/// Colour of `t ∈ [0, 1]`: viridis for magnitudes, or blue–white–red for signed differences.
fn cell_color(t: f64, diverging: bool) -> RGBColor {
    let t = t.clamp(0.0, 1.0);
    if diverging {
        // 0 → blue, 0.5 → white, 1 → red.
        let (r, g, b) = if t < 0.5 {
            let u = t / 0.5;
            (40.0 + 215.0 * u, 90.0 + 165.0 * u, 200.0 + 55.0 * u)
        } else {
            let u = (t - 0.5) / 0.5;
            (255.0 - 40.0 * u, 255.0 - 200.0 * u, 255.0 - 215.0 * u)
        };
        RGBColor(r as u8, g as u8, b as u8)
    } else {
        use plotters::style::colors::colormaps::ViridisRGB;
        ViridisRGB::get_color(t)
    }
}

/// The label of the cell at coordinate `v`, if `v` is (close to) a cell centre.
fn label_at(labels: &[usize], v: f64) -> String {
    let i = v.round();
    if (v - i).abs() > 0.01 || i < 0.0 {
        return String::new();
    }
    labels.get(i as usize).map_or(String::new(), |c| c.to_string())
}

/// A short number for a colour-bar tick.
fn compact(v: f64) -> String {
    match v.abs() {
        a if a >= 100.0 => format!("{v:.0}"),
        a if a >= 1.0 => format!("{v:.2}"),
        _ => format!("{v:.3}"),
    }
}

/// A heatmap grid: `values[i][j]` is row `rows[i]` (y) at column `cols[j]` (x); `None` cells are grey.
#[derive(Debug, Clone)]
pub struct Grid {
    /// Column labels (x), e.g. iterations.
    pub cols: Vec<usize>,
    /// Row labels (y), e.g. complexities.
    pub rows: Vec<usize>,
    /// Values, row-major.
    pub values: Vec<Vec<Option<f64>>>,
}

fn draw_heatmap<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    title: &str,
    x_label: &str,
    y_label: &str,
    grid: &Grid,
    diverging: bool,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let e = |err: &dyn std::fmt::Display| Error::Data(format!("plot '{title}': {err}"));
    let finite: Vec<f64> = grid.values.iter().flatten().flatten().copied().filter(|v| v.is_finite()).collect();
    let (mut lo, mut hi) = finite.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)));
    if diverging {
        let m = lo.abs().max(hi.abs()).max(1e-12);
        (lo, hi) = (-m, m);
    }
    if !lo.is_finite() || hi <= lo {
        (lo, hi) = (if lo.is_finite() { lo - 1.0 } else { 0.0 }, if hi.is_finite() { hi + 1.0 } else { 1.0 });
    }
    let (main, bar) = area.split_horizontally(SIZE.0 - 110);
    let (nx, ny) = (grid.cols.len(), grid.rows.len());
    let mut chart = ChartBuilder::on(&main)
        .caption(title, ("sans-serif", 22))
        .margin(14)
        .x_label_area_size(44)
        .y_label_area_size(60)
        // Cells are centred on integer coordinates so the axis labels sit in the middle of them.
        .build_cartesian_2d(-0.5..nx as f64 - 0.5, -0.5..ny as f64 - 0.5)
        .map_err(|x| e(&x))?;
    let (cols, rows) = (grid.cols.clone(), grid.rows.clone());
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .x_labels(nx.min(20))
        .y_labels(ny.min(20))
        .x_label_formatter(&|v| label_at(&cols, *v))
        .y_label_formatter(&|v| label_at(&rows, *v))
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 17))
        .draw()
        .map_err(|x| e(&x))?;
    let cells = grid.values.iter().enumerate().flat_map(|(i, row)| {
        row.iter().enumerate().map(move |(j, v)| {
            let c = match v {
                Some(v) if v.is_finite() => cell_color((v - lo) / (hi - lo), diverging),
                _ => RGBColor(200, 200, 200),
            };
            Rectangle::new([(j as f64 - 0.5, i as f64 - 0.5), (j as f64 + 0.5, i as f64 + 0.5)], c.filled())
        })
    });
    chart.draw_series(cells).map_err(|x| e(&x))?;
    // Colour bar with its scale.
    let mut cb = ChartBuilder::on(&bar)
        .margin_top(50)
        .margin_bottom(58)
        .margin_right(10)
        .y_label_area_size(62)
        .build_cartesian_2d(0.0..1.0, lo..hi)
        .map_err(|x| e(&x))?;
    cb.configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_labels(6)
        .y_label_formatter(&|v| compact(*v))
        .label_style(("sans-serif", 13))
        .draw()
        .map_err(|x| e(&x))?;
    let steps = 60;
    cb.draw_series((0..steps).map(|k| {
        let (a, b) = (lo + (hi - lo) * k as f64 / steps as f64, lo + (hi - lo) * (k + 1) as f64 / steps as f64);
        Rectangle::new([(0.0, a), (1.0, b)], cell_color(k as f64 / (steps - 1) as f64, diverging).filled())
    }))
    .map_err(|x| e(&x))?;
    Ok(())
}

/// A heatmap as `<base>.png` and `<base>.svg`; `diverging` centres the scale on 0 (for differences).
pub fn heatmap(base: &Path, title: &str, x_label: &str, y_label: &str, grid: &Grid, diverging: bool) -> Result<()> {
    render(base, &|a| draw_heatmap(a, title, x_label, y_label, grid, diverging), &|a| {
        draw_heatmap(a, title, x_label, y_label, grid, diverging)
    })
}
