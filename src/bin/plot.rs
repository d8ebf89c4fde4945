//! `eval --plot`: estimated vs ground-truth trajectory (top view, the
//! estimate mapped by the ATE alignment) beside the position error over
//! time, as SVG or PNG.

use anyhow::{anyhow, bail, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::{Path, PathBuf};
use surfel_slam::eval::AteReport;

/// Plot size, pixels.
pub const WIDTH: u32 = 1200;
/// Plot size, pixels.
pub const HEIGHT: u32 = 600;

const FONT: &str = "sans-serif";
const GT: RGBColor = RGBColor(150, 150, 150);
const GRID: RGBColor = RGBColor(236, 236, 236);

/// What the error plot's horizontal axis counts.
#[derive(Clone, Copy)]
pub enum TimeAxis {
    /// Seconds since the first matched pose.
    Seconds,
    /// Frame numbers (files stamped with whole frame ids).
    Frame,
    /// Row of the estimate file (row-order association).
    Row,
}

enum Format {
    Svg,
    Png,
}

fn format_of(path: &Path) -> Option<Format> {
    let ext = path.extension()?.to_str()?.to_ascii_lowercase();
    match ext.as_str() {
        "svg" => Some(Format::Svg),
        "png" => Some(Format::Png),
        _ => None,
    }
}

/// Command-line check: the plot's file name ends in `.svg` or `.png`.
pub fn parse_path(s: &str) -> Result<PathBuf, String> {
    let path = PathBuf::from(s);
    match format_of(&path) {
        Some(_) => Ok(path),
        None => Err("the plot file must end in .svg or .png".to_owned()),
    }
}

/// Text needs a font that plotters can measure and (for PNG) rasterise: the
/// embedded DejaVu Sans, so nothing depends on the machine's fonts.
fn register_font() -> Result<()> {
    plotters::style::register_font(FONT, FontStyle::Normal, dejavu::sans::regular())
        .map_err(|_| anyhow!("the embedded font could not be loaded"))
}

/// Writes the plot of `report` to `path` (`.svg` or `.png`).
pub fn write(path: &Path, report: &AteReport, axis: TimeAxis) -> Result<()> {
    register_font()?;
    match format_of(path) {
        Some(Format::Svg) => {
            let mut svg = String::new();
            {
                let root = SVGBackend::with_string(&mut svg, (WIDTH, HEIGHT)).into_drawing_area();
                draw(&root, report, axis)?;
                root.present()?;
            }
            std::fs::write(path, svg)?;
        }
        Some(Format::Png) => {
            let mut rgb = vec![0u8; WIDTH as usize * HEIGHT as usize * 3];
            {
                let root =
                    BitMapBackend::with_buffer(&mut rgb, (WIDTH, HEIGHT)).into_drawing_area();
                draw(&root, report, axis)?;
                root.present()?;
            }
            let image = image::RgbImage::from_raw(WIDTH, HEIGHT, rgb)
                .ok_or_else(|| anyhow!("plot buffer has the wrong size"))?;
            image.save_with_format(path, image::ImageFormat::Png)?;
        }
        None => bail!("the plot file must end in .svg or .png"),
    }
    Ok(())
}

/// A range around `values` with a margin; never empty.
fn padded(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    if !(lo.is_finite() && hi.is_finite()) {
        return (0.0, 1.0);
    }
    let margin = ((hi - lo) * 0.05).max(1e-6);
    (lo - margin, hi + margin)
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    report: &AteReport,
    axis: TimeAxis,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    let root = root.titled(
        &format!(
            "ATE rmse {} over {} poses (max {})",
            crate::evaluate::cm(report.summary.rmse_m),
            report.summary.pairs,
            crate::evaluate::cm(report.summary.max_m)
        ),
        (FONT, 22),
    )?;
    let (left, right) = root.split_horizontally(HEIGHT);
    top_view(&left, report)?;
    error_over_time(&right, report, axis)?;
    Ok(())
}

/// The two world axes the trajectory spreads over most, as indices and
/// names: looking along the axis of least ground-truth motion (usually
/// the vertical for a hand-held camera) gives a top view whatever the
/// dataset's up axis. The pair keeps the cyclic order x, y, z.
fn view_axes(report: &AteReport) -> [(usize, &'static str); 2] {
    let n = report.errors.len().max(1) as f64;
    let mean = report
        .errors
        .iter()
        .map(|e| e.ground_truth_position)
        .sum::<glam::DVec3>()
        / n;
    let var = report
        .errors
        .iter()
        .map(|e| (e.ground_truth_position - mean).powf(2.0))
        .sum::<glam::DVec3>();
    let flat = (0..3)
        .min_by(|&a, &b| var[a].total_cmp(&var[b]))
        .unwrap_or(2);
    const NAMES: [&str; 3] = ["x", "y", "z"];
    let (a, b) = ((flat + 1) % 3, (flat + 2) % 3);
    [(a, NAMES[a]), (b, NAMES[b])]
}

fn top_view<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, report: &AteReport) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let [(a, a_name), (b, b_name)] = view_axes(report);
    let points = |f: fn(&surfel_slam::eval::PoseError) -> glam::DVec3| -> Vec<(f64, f64)> {
        report.errors.iter().map(|e| (f(e)[a], f(e)[b])).collect()
    };
    let truth = points(|e| e.ground_truth_position);
    let estimate = points(|e| e.aligned_position);
    // Equal scale on both axes: a square range around both paths.
    let (x0, x1) = padded(truth.iter().chain(&estimate).map(|p| p.0));
    let (y0, y1) = padded(truth.iter().chain(&estimate).map(|p| p.1));
    let half = 0.5 * (x1 - x0).max(y1 - y0);
    let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
    let mut chart = ChartBuilder::on(area)
        .caption("top view (along the least-moving axis)", (FONT, 16))
        .margin(12)
        .x_label_area_size(36)
        .y_label_area_size(52)
        .build_cartesian_2d(cx - half..cx + half, cy - half..cy + half)?;
    chart
        .configure_mesh()
        .light_line_style(GRID)
        .x_desc(format!("{a_name} (m)"))
        .y_desc(format!("{b_name} (m)"))
        .label_style((FONT, 13))
        .draw()?;
    chart
        // Wide and light under the estimate: both stay visible where they agree.
        .draw_series(LineSeries::new(truth.clone(), GT.stroke_width(6)))?
        .label("ground truth")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], GT.stroke_width(6)));
    let red = RGBColor(220, 40, 30);
    chart
        .draw_series(LineSeries::new(estimate, red.stroke_width(2)))?
        .label("estimate (aligned)")
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], red.stroke_width(2)));
    if let Some(&start) = truth.first() {
        chart
            .draw_series(std::iter::once(Circle::new(start, 5, BLACK.filled())))?
            .label("start")
            .legend(|(x, y)| Circle::new((x + 10, y), 4, BLACK.filled()));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font((FONT, 13))
        .position(SeriesLabelPosition::UpperLeft)
        .draw()?;
    Ok(())
}

fn error_over_time<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    report: &AteReport,
    axis: TimeAxis,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let t0 = report.errors.first().map_or(0.0, |e| e.timestamp);
    let series: Vec<(f64, f64)> = report
        .errors
        .iter()
        .map(|e| {
            let x = match axis {
                TimeAxis::Seconds => e.timestamp - t0,
                TimeAxis::Frame => e.timestamp,
                TimeAxis::Row => e.estimate_index as f64,
            };
            (x, e.position_error_m * 100.0)
        })
        .collect();
    let (x0, x1) = padded(series.iter().map(|p| p.0));
    // Headroom above the curve for the legend.
    let y1 = 1.25 * padded(series.iter().map(|p| p.1)).1.max(1e-6);
    let x_desc = match axis {
        TimeAxis::Seconds => "time since the first pose (s)",
        TimeAxis::Frame => "frame",
        TimeAxis::Row => "pose (row of the estimate file)",
    };
    let mut chart = ChartBuilder::on(area)
        .caption("position error after alignment", (FONT, 16))
        .margin(12)
        .x_label_area_size(36)
        .y_label_area_size(60)
        .build_cartesian_2d(x0..x1, 0.0..y1)?;
    chart
        .configure_mesh()
        .light_line_style(GRID)
        .x_label_formatter(&|v| match axis {
            TimeAxis::Seconds => format!("{v}"),
            TimeAxis::Frame | TimeAxis::Row => format!("{v:.0}"),
        })
        .x_desc(x_desc)
        .y_desc("error (cm)")
        .label_style((FONT, 13))
        .draw()?;
    let blue = RGBColor(30, 90, 200);
    chart
        .draw_series(LineSeries::new(series, blue.stroke_width(2)))?
        .label("position error")
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], blue.stroke_width(2)));
    let rmse = report.summary.rmse_m * 100.0;
    let grey = RGBColor(120, 120, 120);
    chart
        .draw_series(LineSeries::new(vec![(x0, rmse), (x1, rmse)], grey))?
        .label("rmse")
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], grey));
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font((FONT, 13))
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    Ok(())
}
