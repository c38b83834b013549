//! Figures as SVG and PNG, with plotters' pure-Rust backends only.
//!
//! Text in bitmaps is drawn by plotters' `ab_glyph` feature with DejaVu Sans, embedded with
//! `include_bytes!` and registered as the `sans-serif` family (no system fonts, no C). PNG
//! files are encoded here with the `image` crate from the RGB buffer of
//! `BitMapBackend::with_buffer`, so no plotters image feature is needed.
//!
//! A figure is a stack of [`Panel`]s sharing the time axis; the dual-UKF figures
//! ([`fig12_panels`], [`fig13_panels`]) follow the paper's Figs. 12 and 13.

use std::path::Path;
use std::sync::OnceLock;

use plotters::backend::RGBPixel;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};

use crate::reproduce::StepRecord;

/// The font embedded in the binary for bitmap text.
static DEJAVU_SANS: &[u8] = include_bytes!("../assets/fonts/DejaVuSans.ttf");

/// Errors while drawing or writing a figure.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// The embedded font could not be parsed.
    #[error("the embedded DejaVu Sans font could not be registered")]
    Font,
    /// plotters failed while drawing.
    #[error("drawing {figure} failed: {message}")]
    Drawing {
        /// Which figure.
        figure: String,
        /// plotters' message.
        message: String,
    },
    /// A figure has no data to draw.
    #[error("figure {figure} has no data to draw")]
    Empty {
        /// Which figure.
        figure: String,
    },
    /// Writing a file failed.
    #[error("writing {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The cause.
        source: std::io::Error,
    },
    /// PNG encoding failed.
    #[error("encoding {path}: {source}")]
    Png {
        /// The file.
        path: String,
        /// The cause.
        source: image::ImageError,
    },
}

/// Registers the embedded font once; later calls return the first outcome.
fn ensure_font() -> Result<(), PlotError> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED
        .get_or_init(|| register_font("sans-serif", FontStyle::Normal, DEJAVU_SANS).is_ok());
    if ok { Ok(()) } else { Err(PlotError::Font) }
}

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Mark {
    /// A solid line of the given width in pixels.
    Line(u32),
    /// Filled dots of the given radius in pixels.
    Dots(u32),
}

/// One labelled series of `(t, value)` points.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend label.
    pub label: String,
    /// The points, `(time in s, value)`.
    pub points: Vec<(f64, f64)>,
    /// Colour.
    pub color: RGBColor,
    /// Line or dots.
    pub mark: Mark,
}

/// One panel: a title, a y-axis label (with units) and its series, over time in seconds.
#[derive(Debug, Clone, PartialEq)]
pub struct Panel {
    /// Caption above the panel.
    pub title: String,
    /// Label of the y axis, with its unit.
    pub y_label: String,
    /// The series to draw, in drawing order (the legend follows it).
    pub series: Vec<Series>,
    /// A time window `[from, to)` in seconds to shade (e.g. an occlusion), if any.
    pub shade: Option<(f64, f64)>,
}

/// Colours shared by the figures.
const REAL: RGBColor = RGBColor(0, 0, 0);
const MEASURED: RGBColor = RGBColor(150, 150, 150);
const ESTIMATED: RGBColor = RGBColor(200, 30, 30);
/// Background of a shaded time window (an occlusion).
const SHADE: RGBColor = RGBColor(225, 225, 240);

fn bounds(panel: &Panel) -> Option<(f64, f64, f64, f64)> {
    let mut it = panel
        .series
        .iter()
        .flat_map(|s| s.points.iter())
        .filter(|p| p.0.is_finite() && p.1.is_finite());
    let first = it.next()?;
    let (mut t0, mut t1, mut y0, mut y1) = (first.0, first.0, first.1, first.1);
    for &(t, y) in it {
        t0 = t0.min(t);
        t1 = t1.max(t);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    if t1 <= t0 {
        t1 = t0 + 1.0;
    }
    let pad = ((y1 - y0) * 0.08).max(1e-6);
    Some((t0, t1, y0 - pad, y1 + pad))
}

/// Decimals that tell apart the ticks of an axis spanning `range` (plotters puts 5 to 10
/// ticks on it, at steps of 1, 2 or 5 times a power of ten).
fn decimals_for(range: f64) -> usize {
    let step = range / 10.0;
    if !(step.is_finite() && step > 0.0) {
        return 3;
    }
    (-step.log10()).ceil().clamp(0.0, 9.0) as usize
}

/// A tick label with `decimals` decimals, trailing zeros dropped, never "-0".
fn tick(v: f64, decimals: usize) -> String {
    let s = format!("{v:.decimals$}");
    let s = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_owned()
    } else {
        s
    };
    if s == "-0" { "0".to_owned() } else { s }
}

/// The corner of the panel whose box (35 % of the width, 30 % of the height) holds the
/// fewest data points, so that the legend covers as little data as possible.
fn legend_corner(panel: &Panel, (t0, t1, y0, y1): (f64, f64, f64, f64)) -> SeriesLabelPosition {
    let (tw, yh) = (0.35 * (t1 - t0), 0.30 * (y1 - y0));
    let corners = [
        (SeriesLabelPosition::UpperRight, t1 - tw, t1, y1 - yh, y1),
        (SeriesLabelPosition::UpperLeft, t0, t0 + tw, y1 - yh, y1),
        (SeriesLabelPosition::LowerRight, t1 - tw, t1, y0, y0 + yh),
        (SeriesLabelPosition::LowerLeft, t0, t0 + tw, y0, y0 + yh),
    ];
    let count = |&(_, a, b, c, d): &(SeriesLabelPosition, f64, f64, f64, f64)| {
        panel
            .series
            .iter()
            .flat_map(|s| s.points.iter())
            .filter(|p| p.0 >= a && p.0 <= b && p.1 >= c && p.1 <= d)
            .count()
    };
    // The first corner with the fewest points (upper right wins ties).
    let mut best = (usize::MAX, SeriesLabelPosition::UpperRight);
    for c in &corners {
        let n = count(c);
        if n < best.0 {
            best = (n, c.0.clone());
        }
    }
    best.1
}

fn draw_err<E: std::fmt::Debug>(figure: &str) -> impl Fn(E) -> PlotError + '_ {
    move |e| PlotError::Drawing {
        figure: figure.to_owned(),
        message: format!("{e:?}"),
    }
}

/// Draws the panels stacked vertically on `root`.
fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    name: &str,
    panels: &[Panel],
) -> Result<(), PlotError>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(draw_err(name))?;
    let cols = panels.len().clamp(1, 2);
    let rows = panels.len().div_ceil(cols);
    let areas = root.split_evenly((rows, cols));
    for (area, panel) in areas.iter().zip(panels) {
        let Some((t0, t1, y0, y1)) = bounds(panel) else {
            return Err(PlotError::Empty {
                figure: name.to_owned(),
            });
        };
        let mut chart = ChartBuilder::on(area)
            .caption(&panel.title, ("sans-serif", 16))
            .margin(6)
            .x_label_area_size(34)
            .y_label_area_size(62)
            .build_cartesian_2d(t0..t1, y0..y1)
            .map_err(draw_err(name))?;
        let (xd, yd) = (decimals_for(t1 - t0), decimals_for(y1 - y0));
        if let Some((a, b)) = panel.shade {
            let (a, b) = (a.max(t0), b.min(t1));
            if b > a {
                chart
                    .draw_series(std::iter::once(Rectangle::new(
                        [(a, y0), (b, y1)],
                        SHADE.filled(),
                    )))
                    .map_err(draw_err(name))?;
            }
        }
        chart
            .configure_mesh()
            .x_desc("time t [s]")
            .y_desc(panel.y_label.as_str())
            .label_style(("sans-serif", 12))
            .axis_desc_style(("sans-serif", 13))
            .light_line_style(RGBColor(240, 240, 240))
            .x_max_light_lines(2)
            .y_max_light_lines(2)
            .x_label_formatter(&|v| tick(*v, xd))
            .y_label_formatter(&|v| tick(*v, yd))
            .draw()
            .map_err(draw_err(name))?;
        for s in &panel.series {
            let color = s.color;
            let pts = s
                .points
                .iter()
                .copied()
                .filter(|p| p.0.is_finite() && p.1.is_finite());
            let anno = match s.mark {
                Mark::Line(w) => chart
                    .draw_series(LineSeries::new(pts, color.stroke_width(w)))
                    .map_err(draw_err(name))?,
                Mark::Dots(r) => chart
                    .draw_series(pts.map(|p| Circle::new(p, r, color.filled())))
                    .map_err(draw_err(name))?,
            };
            anno.label(s.label.as_str()).legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(3))
            });
        }
        chart
            .configure_series_labels()
            .position(legend_corner(panel, (t0, t1, y0, y1)))
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(180, 180, 180))
            .label_font(("sans-serif", 12))
            .draw()
            .map_err(draw_err(name))?;
    }
    root.present().map_err(draw_err(name))?;
    Ok(())
}

/// Writes the panels as an SVG file of `size` pixels (text as SVG text, laid out with the
/// embedded font's metrics).
///
/// # Errors
/// [`PlotError`] if the font cannot be registered, drawing or writing fails, or a panel is
/// empty.
pub fn write_svg(path: &Path, panels: &[Panel], size: (u32, u32)) -> Result<(), PlotError> {
    ensure_font()?;
    let name = path.display().to_string();
    let mut text = String::new();
    {
        let root = SVGBackend::with_string(&mut text, size).into_drawing_area();
        draw(&root, &name, panels)?;
    }
    std::fs::write(path, text).map_err(|source| PlotError::Io { path: name, source })
}

/// Renders the panels into an RGB buffer of `size` pixels (row-major, 3 bytes a pixel).
///
/// # Errors
/// [`PlotError`] if the font cannot be registered, drawing fails, or a panel is empty.
pub fn render_rgb(panels: &[Panel], size: (u32, u32)) -> Result<Vec<u8>, PlotError> {
    ensure_font()?;
    let mut buf = vec![0u8; size.0 as usize * size.1 as usize * 3];
    {
        let backend = BitMapBackend::<RGBPixel>::with_buffer_and_format(&mut buf, size)
            .map_err(draw_err("bitmap"))?;
        let root = backend.into_drawing_area();
        draw(&root, "bitmap", panels)?;
    }
    Ok(buf)
}

/// Writes the panels as a PNG file of `size` pixels.
///
/// # Errors
/// As [`render_rgb`], plus encoding or writing failures.
pub fn write_png(path: &Path, panels: &[Panel], size: (u32, u32)) -> Result<(), PlotError> {
    let name = path.display().to_string();
    let buf = render_rgb(panels, size)?;
    image::save_buffer_with_format(
        path,
        &buf,
        size.0,
        size.1,
        image::ColorType::Rgb8,
        image::ImageFormat::Png,
    )
    .map_err(|source| PlotError::Png { path: name, source })
}

fn series(label: &str, color: RGBColor, mark: Mark, points: Vec<(f64, f64)>) -> Series {
    Series {
        label: label.to_owned(),
        points,
        color,
        mark,
    }
}

fn collect(records: &[StepRecord], f: impl Fn(&StepRecord) -> f64) -> Vec<(f64, f64)> {
    records.iter().map(|r| (r.t, f(r))).collect()
}

/// Shades the time window `[from, to)` (seconds) in every panel, e.g. an occlusion.
pub fn shade(panels: &mut [Panel], window: Option<(f64, f64)>) {
    for p in panels {
        p.shade = window;
    }
}

/// The paper's Fig. 12: `l12` and `alpha12`, real / measured / estimated, and their errors.
pub fn fig12_panels(records: &[StepRecord]) -> Vec<Panel> {
    let value_panel = |title: &str, unit: &str, i: usize| Panel {
        title: title.to_owned(),
        shade: None,
        y_label: unit.to_owned(),
        series: vec![
            series(
                "measured",
                MEASURED,
                Mark::Dots(2),
                collect(records, |r| r.measured[i]),
            ),
            series(
                "real",
                REAL,
                Mark::Line(2),
                collect(records, |r| r.truth[i]),
            ),
            series(
                "estimated",
                ESTIMATED,
                Mark::Line(2),
                collect(records, |r| r.estimated[i]),
            ),
        ],
    };
    let error_panel = |title: &str, unit: &str, i: usize| Panel {
        title: title.to_owned(),
        shade: None,
        y_label: unit.to_owned(),
        series: vec![
            series(
                "measurement error",
                MEASURED,
                Mark::Dots(2),
                collect(records, |r| r.measurement_error()[i]),
            ),
            series(
                "estimation error",
                ESTIMATED,
                Mark::Line(2),
                collect(records, |r| r.estimation_error()[i]),
            ),
        ],
    };
    vec![
        value_panel("separation l12", "l12 [m]", 0),
        value_panel("bearing alpha12", "alpha12 [rad]", 1),
        error_panel("error in l12", "error [m]", 0),
        error_panel("error in alpha12", "error [rad]", 1),
    ]
}

/// The paper's Fig. 13: the leader's `v1` and `w1`, real / estimated, and their errors.
pub fn fig13_panels(records: &[StepRecord]) -> Vec<Panel> {
    let value_panel = |title: &str,
                       unit: &str,
                       real: fn(&StepRecord) -> f64,
                       est: fn(&StepRecord) -> f64| Panel {
        title: title.to_owned(),
        shade: None,
        y_label: unit.to_owned(),
        series: vec![
            series("real", REAL, Mark::Line(2), collect(records, real)),
            series("estimated", ESTIMATED, Mark::Line(2), collect(records, est)),
        ],
    };
    let error_panel = |title: &str, unit: &str, err: fn(&StepRecord) -> f64| Panel {
        title: title.to_owned(),
        shade: None,
        y_label: unit.to_owned(),
        series: vec![series(
            "estimation error",
            ESTIMATED,
            Mark::Line(2),
            collect(records, err),
        )],
    };
    vec![
        value_panel(
            "leader linear velocity v1",
            "v1 [m/s]",
            |r| r.v1_true,
            |r| r.v1_estimated,
        ),
        value_panel(
            "leader angular velocity w1",
            "w1 [rad/s]",
            |r| r.w1_true,
            |r| r.w1_estimated,
        ),
        error_panel("error in v1", "error [m/s]", |r| r.v1_estimated - r.v1_true),
        error_panel("error in w1", "error [rad/s]", |r| {
            r.w1_estimated - r.w1_true
        }),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reproduce::reproduce;

    #[test]
    fn figures_draw_into_svg_and_bitmap() {
        let run = reproduce(1, false).unwrap();
        let panels = fig12_panels(&run.records);
        let dir = std::env::temp_dir().join(format!("ft-plot-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let svg = dir.join("fig12.svg");
        write_svg(&svg, &panels, (800, 600)).unwrap();
        let text = std::fs::read_to_string(&svg).unwrap();
        assert!(text.contains("l12 [m]") && text.contains("estimated"));
        let rgb = render_rgb(&fig13_panels(&run.records), (800, 600)).unwrap();
        assert_eq!(rgb.len(), 800 * 600 * 3);
        // Mostly white background, with black (real), red (estimated) and text pixels.
        let px = |i: usize| (rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2]);
        let red = (0..800 * 600).filter(|&i| px(i) == (200, 30, 30)).count();
        let dark = (0..800 * 600)
            .filter(|&i| px(i).0 < 60 && px(i).1 < 60)
            .count();
        assert!(red > 500, "{red} red pixels");
        assert!(dark > 500, "{dark} dark pixels");
        let png = dir.join("fig13.png");
        write_png(&png, &fig13_panels(&run.records), (800, 600)).unwrap();
        let img = image::open(&png).unwrap();
        assert_eq!((img.width(), img.height()), (800, 600));
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// Regression (#11): the alpha12 error panel's ticks read `-0.001, -0.001, 0, 0.001,
    /// 0.001`.
    #[test]
    fn tick_labels_tell_the_ticks_apart() {
        let d = decimals_for(0.004);
        let labels: Vec<String> = [-0.001, -0.0005, 0.0, 0.0005, 0.001]
            .iter()
            .map(|&v| tick(v, d))
            .collect();
        assert_eq!(labels, ["-0.001", "-0.0005", "0", "0.0005", "0.001"]);
        assert_eq!(tick(1.25, decimals_for(2.0)), "1.2");
        assert_eq!(tick(-0.0, 3), "0");
        assert_eq!(tick(8.0, decimals_for(8.0)), "8");
        assert_eq!(decimals_for(f64::NAN), 3);
    }

    #[test]
    fn the_legend_goes_where_the_data_is_not() {
        let points = |pts: &[(f64, f64)]| Panel {
            title: "t".into(),
            y_label: "y".into(),
            series: vec![series("s", REAL, Mark::Line(1), pts.to_vec())],
            shade: None,
        };
        let b = (0.0, 10.0, 0.0, 10.0);
        // Data along the top: the legend goes below.
        let top: Vec<(f64, f64)> = (0..=10).map(|t| (f64::from(t), 9.5)).collect();
        assert!(matches!(
            legend_corner(&points(&top), b),
            SeriesLabelPosition::LowerRight
        ));
        // Data in the upper right only: the upper left is free.
        assert!(matches!(
            legend_corner(&points(&[(9.0, 9.0), (9.5, 9.5)]), b),
            SeriesLabelPosition::UpperLeft
        ));
    }

    #[test]
    fn a_shaded_window_is_drawn() {
        let run = reproduce(1, false).unwrap();
        let mut panels = fig12_panels(&run.records);
        let plain = render_rgb(&panels, (400, 300)).unwrap();
        shade(&mut panels, Some((3.5, 4.5)));
        let shaded = render_rgb(&panels, (400, 300)).unwrap();
        let count = |rgb: &[u8]| {
            rgb.chunks_exact(3)
                .filter(|p| (p[0], p[1], p[2]) == (SHADE.0, SHADE.1, SHADE.2))
                .count()
        };
        assert_eq!(count(&plain), 0);
        assert!(count(&shaded) > 200, "{} shaded pixels", count(&shaded));
    }

    #[test]
    fn an_empty_panel_is_an_error() {
        let panels = vec![Panel {
            title: "nothing".into(),
            shade: None,
            y_label: "y [m]".into(),
            series: vec![],
        }];
        assert!(matches!(
            render_rgb(&panels, (200, 100)),
            Err(PlotError::Empty { .. })
        ));
    }
}
