//! The report's figures with plotters: error against time per view with its Pareto front, and
//! validation PSNR against training time. Each is written as SVG and PNG; text is drawn with the
//! bundled DejaVu Sans Mono, so no system font is needed.

use std::path::Path;
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};

use crate::report::pareto_front;

static FONT: &[u8] = include_bytes!("../assets/DejaVuSansMono.ttf");
static REGISTER: Once = Once::new();

fn fonts() {
    REGISTER.call_once(|| {
        // The bundled font is valid; registration cannot fail for it.
        let _ = register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

/// Why a figure could not be drawn or written.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {message}")]
pub struct PlotError {
    /// The file being written.
    pub path: String,
    /// What went wrong.
    pub message: String,
}

/// A point of the error-vs-time figure.
#[derive(Debug, Clone)]
pub struct TimePoint {
    /// Method and configuration.
    pub label: String,
    /// Milliseconds per novel view.
    pub ms: f64,
    /// Quality (PSNR dB, higher is better).
    pub psnr: f64,
    /// Its 95 % interval, drawn as a vertical bar through the point (`None`: no bar).
    pub psnr_ci: Option<[f64; 2]>,
}

/// A curve of the training figure.
#[derive(Debug, Clone)]
pub struct Curve {
    /// Legend.
    pub label: String,
    /// (seconds of training, validation PSNR dB).
    pub points: Vec<(f64, f64)>,
}

const SIZE: (u32, u32) = (960, 640);
const COLORS: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
];

fn err(path: &Path, e: impl std::fmt::Display) -> PlotError {
    PlotError {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}

fn write_png(path: &Path, buf: Vec<u8>) -> Result<(), PlotError> {
    let img = image::RgbImage::from_raw(SIZE.0, SIZE.1, buf)
        .ok_or_else(|| err(path, "bitmap of the wrong size"))?;
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .map_err(|e| err(path, e))?;
    mhi_data::write_atomic(path, &bytes).map_err(|e| err(path, e))
}

/// Draw with `draw` into `stem.svg` and `stem.png` (each written atomically).
macro_rules! svg_and_png {
    ($stem:expr, $draw:ident, $($arg:expr),*) => {{
        let stem: &Path = $stem;
        let svg_path = stem.with_extension("svg");
        let png_path = stem.with_extension("png");
        fonts();
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
            $draw(&root, $($arg),*).map_err(|e| err(&svg_path, e))?;
            root.present().map_err(|e| err(&svg_path, e))?;
        }
        mhi_data::write_atomic(&svg_path, svg.as_bytes()).map_err(|e| err(&svg_path, e))?;
        let mut buf = vec![0u8; (SIZE.0 * SIZE.1 * 3) as usize];
        {
            let root = BitMapBackend::with_buffer(&mut buf, SIZE).into_drawing_area();
            $draw(&root, $($arg),*).map_err(|e| err(&png_path, e))?;
            root.present().map_err(|e| err(&png_path, e))?;
        }
        write_png(&png_path, buf)
    }};
}

fn range(v: impl Iterator<Item = f64> + Clone, pad: f64) -> (f64, f64) {
    let lo = v.clone().fold(f64::INFINITY, f64::min);
    let hi = v.fold(f64::NEG_INFINITY, f64::max);
    if !lo.is_finite() || !hi.is_finite() {
        return (0.0, 1.0);
    }
    let span = (hi - lo).max(1e-6);
    (lo - pad * span, hi + pad * span)
}

fn draw_error_vs_time<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    points: &[TimePoint],
    title: &str,
) -> Result<(), String> {
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(e)?;
    // The y range holds every point and every interval.
    let ys = points.iter().flat_map(|p| {
        let [lo, hi] = p.psnr_ci.unwrap_or([p.psnr, p.psnr]);
        [p.psnr, lo, hi]
    });
    let (ylo, yhi) = range(ys.filter(|v| v.is_finite()), 0.12);
    let xs = points.iter().map(|p| p.ms.max(1e-3));
    let xlo = xs.clone().fold(f64::INFINITY, f64::min);
    let xhi = xs.fold(f64::NEG_INFINITY, f64::max);
    let (xlo, xhi) = if xlo.is_finite() && xhi.is_finite() {
        (xlo / 2.0, xhi * 3.0)
    } else {
        (0.1, 10.0)
    };
    let mut chart = ChartBuilder::on(root)
        .caption(title, ("sans-serif", 22))
        .margin(16)
        .x_label_area_size(44)
        .y_label_area_size(64)
        .build_cartesian_2d((xlo..xhi).log_scale(), ylo..yhi)
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc("time per novel view (ms, log scale)")
        .y_desc("PSNR (dB)")
        .label_style(("sans-serif", 15))
        .draw()
        .map_err(e)?;
    let pts: Vec<(f64, f64)> = points.iter().map(|p| (p.ms.max(1e-3), p.psnr)).collect();
    let front = pareto_front(&pts, true);
    chart
        .draw_series(LineSeries::new(
            front.iter().map(|&i| pts[i]),
            ShapeStyle::from(&RGBColor(200, 60, 60)).stroke_width(2),
        ))
        .map_err(e)?
        .label("Pareto front (ringed: no other point is both faster and better)")
        .legend(|(x, y)| {
            PathElement::new(
                vec![(x, y), (x + 20, y)],
                ShapeStyle::from(&RGBColor(200, 60, 60)).stroke_width(2),
            )
        });
    // Front points get a red ring, so a front of one point is still visible.
    chart
        .draw_series(front.iter().map(|&i| {
            Circle::new(
                pts[i],
                11,
                ShapeStyle::from(&RGBColor(200, 60, 60)).stroke_width(2),
            )
        }))
        .map_err(e)?;
    // 95 % intervals: a bar with short caps, under the points.
    for (i, (p, &(x, _))) in points.iter().zip(&pts).enumerate() {
        let Some([lo, hi]) = p.psnr_ci.filter(|c| c.iter().all(|v| v.is_finite())) else {
            continue;
        };
        let style = ShapeStyle::from(&COLORS[i % COLORS.len()]).stroke_width(1);
        let (xl, xr) = (x / 1.04, x * 1.04);
        chart
            .draw_series([
                PathElement::new(vec![(x, lo), (x, hi)], style),
                PathElement::new(vec![(xl, lo), (xr, lo)], style),
                PathElement::new(vec![(xl, hi), (xr, hi)], style),
            ])
            .map_err(e)?;
    }
    // Points at nearly the same place (an MHI rendered pruned and exactly) would print their
    // labels over each other: each such label moves down a line per earlier neighbour.
    let near = |a: (f64, f64), b: (f64, f64)| {
        (a.0.ln() - b.0.ln()).abs() < 0.3 && (a.1 - b.1).abs() < 0.04 * (yhi - ylo)
    };
    for (i, (p, xy)) in points.iter().zip(&pts).enumerate() {
        let color = COLORS[i % COLORS.len()];
        let on_front = front.contains(&i);
        let below = pts[..i].iter().filter(|q| near(**q, *xy)).count() as i32;
        // The label sits level with its point, to its right, or to its left near the right edge.
        let right_half = xy.0.ln() > (xlo.ln() + xhi.ln()) / 2.0;
        let dx = if right_half {
            -10 - 8 * p.label.chars().count() as i32
        } else {
            10
        };
        chart
            .draw_series(std::iter::once(
                EmptyElement::at(*xy)
                    + Circle::new((0, 0), if on_front { 7 } else { 5 }, color.filled())
                    + Text::new(
                        p.label.clone(),
                        (dx, -7 + 16 * below),
                        ("sans-serif", 14).into_font().color(&color),
                    ),
            ))
            .map_err(e)?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .position(SeriesLabelPosition::LowerRight)
        .draw()
        .map_err(e)?;
    Ok(())
}

/// Axis titles of a line figure, and whether both axes are logarithmic.
#[derive(Debug, Clone, Copy)]
pub struct Axes<'a> {
    /// Title of the x axis.
    pub x: &'a str,
    /// Title of the y axis.
    pub y: &'a str,
    /// Both axes on a log scale (for power laws: a slope is an exponent).
    pub log: bool,
}

fn draw_curves<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    curves: &[Curve],
    title: &str,
    axes: &Axes<'_>,
) -> Result<(), String> {
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(e)?;
    let all = curves.iter().flat_map(|c| c.points.iter().copied());
    let builder = |root| {
        let mut b = ChartBuilder::on(root);
        b.caption(title, ("sans-serif", 22))
            .margin(16)
            .x_label_area_size(44)
            .y_label_area_size(72);
        b
    };
    if axes.log {
        let pos = |v: f64| v.is_finite() && v > 0.0;
        let xs = all.clone().map(|p| p.0).filter(|v| pos(*v));
        let ys = all.clone().map(|p| p.1).filter(|v| pos(*v));
        let lo_hi = |v: &mut dyn Iterator<Item = f64>| {
            let (lo, hi) = v.fold((f64::INFINITY, 0.0_f64), |(l, h), x| (l.min(x), h.max(x)));
            if lo.is_finite() && hi > 0.0 {
                (lo / 1.5, hi * 1.5)
            } else {
                (0.1, 10.0)
            }
        };
        let (xlo, xhi) = lo_hi(&mut xs.clone());
        let (ylo, yhi) = lo_hi(&mut ys.clone());
        let mut chart = builder(root)
            .build_cartesian_2d((xlo..xhi).log_scale(), (ylo..yhi).log_scale())
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc(axes.x)
            .y_desc(axes.y)
            .label_style(("sans-serif", 15))
            .draw()
            .map_err(e)?;
        draw_series(&mut chart, curves).map_err(e)?;
        let corner = emptiest_corner(curves, f64::ln, (xlo, xhi), (ylo, yhi));
        legend(&mut chart, corner).map_err(e)?;
    } else {
        // From zero (a time, a step), unless every x lies far from it (a speed-up near 1).
        let (xlo, xhi) = range(all.clone().map(|p| p.0), 0.05);
        let xlo = if xlo > 0.25 * xhi { xlo } else { 0.0 };
        let xhi = xhi.max(xlo + 1.0);
        let (ylo, yhi) = range(all.clone().map(|p| p.1), 0.1);
        let mut chart = builder(root)
            .build_cartesian_2d(xlo..xhi, ylo..yhi)
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc(axes.x)
            .y_desc(axes.y)
            .label_style(("sans-serif", 15))
            .draw()
            .map_err(e)?;
        draw_series(&mut chart, curves).map_err(e)?;
        let corner = emptiest_corner(curves, |v| v, (xlo, xhi), (ylo, yhi));
        legend(&mut chart, corner).map_err(e)?;
    }
    Ok(())
}

fn draw_series<'a, DB: DrawingBackend + 'a, X, Y>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<X, Y>>,
    curves: &[Curve],
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>>
where
    X: Ranged<ValueType = f64>,
    Y: Ranged<ValueType = f64>,
{
    for (i, c) in curves.iter().enumerate() {
        let color = COLORS[i % COLORS.len()];
        chart
            .draw_series(LineSeries::new(
                c.points.iter().copied(),
                ShapeStyle::from(&color).stroke_width(2),
            ))?
            .label(c.label.clone())
            .legend(move |(x, y)| {
                PathElement::new(
                    vec![(x, y), (x + 20, y)],
                    ShapeStyle::from(&color).stroke_width(2),
                )
            });
        chart.draw_series(c.points.iter().map(|&p| Circle::new(p, 3, color.filled())))?;
    }
    Ok(())
}

fn legend<'a, DB: DrawingBackend + 'a, X, Y>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<X, Y>>,
    corner: SeriesLabelPosition,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>>
where
    X: Ranged<ValueType = f64>,
    Y: Ranged<ValueType = f64>,
{
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .position(corner)
        .draw()
}

/// The corner of the plot whose quarter (the outer 40 % of each axis, after `scale`) the
/// curves pass through least (their points, and samples along each segment a hundredth of the
/// plot apart), for the legend; lower right on a tie.
fn emptiest_corner(
    curves: &[Curve],
    scale: impl Fn(f64) -> f64,
    (x0, x1): (f64, f64),
    (y0, y1): (f64, f64),
) -> SeriesLabelPosition {
    let at = |(x, y): (f64, f64)| {
        (
            (scale(x) - scale(x0)) / (scale(x1) - scale(x0)),
            (scale(y) - scale(y0)) / (scale(y1) - scale(y0)),
        )
    };
    let samples = curves.iter().flat_map(|c| {
        let pts: Vec<(f64, f64)> = c.points.iter().map(|p| at(*p)).collect();
        let along: Vec<(f64, f64)> = pts
            .windows(2)
            .flat_map(|w| {
                // A sample every hundredth of the plot's size along the segment.
                let (dx, dy) = (w[1].0 - w[0].0, w[1].1 - w[0].1);
                let steps = ((dx * dx + dy * dy).sqrt() * 100.0).clamp(1.0, 1e4) as u32;
                (1..steps).map(move |k| {
                    let t = f64::from(k) / f64::from(steps);
                    (w[0].0 + t * dx, w[0].1 + t * dy)
                })
            })
            .collect();
        pts.into_iter().chain(along)
    });
    // Lower right, lower left, upper right, upper left.
    let corners = [(true, false), (false, false), (true, true), (false, true)];
    let mut count = [0_usize; 4];
    for (fx, fy) in samples {
        for (k, (right, upper)) in corners.into_iter().enumerate() {
            let in_x = if right { fx > 0.6 } else { fx < 0.4 };
            let in_y = if upper { fy > 0.6 } else { fy < 0.4 };
            count[k] += usize::from(in_x && in_y);
        }
    }
    let best = (0..4).min_by_key(|k| count[*k]).unwrap_or(0);
    [
        SeriesLabelPosition::LowerRight,
        SeriesLabelPosition::LowerLeft,
        SeriesLabelPosition::UpperRight,
        SeriesLabelPosition::UpperLeft,
    ][best]
        .clone()
}

/// `stem.svg` and `stem.png`: PSNR against milliseconds per view (log scale), one labelled point
/// per method and configuration with its 95 % interval as a bar, the Pareto front drawn.
pub fn error_vs_time(stem: &Path, points: &[TimePoint], title: &str) -> Result<(), PlotError> {
    svg_and_png!(stem, draw_error_vs_time, points, title)
}

/// The points of [`error_vs_time`] from report rows: every timed configuration over all
/// triplets, its covered PSNR (the whole image's where there is no covered score) with its
/// interval, against its time per view.
pub fn time_points(rows: &[crate::report::Row]) -> Vec<TimePoint> {
    rows.iter()
        .filter(|r| r.bin == "all" && r.kind == "all" && r.timed)
        .map(|r| TimePoint {
            label: crate::report::config_label(&r.method, r.normals, r.planes),
            ms: r.ms_per_view,
            psnr: r.psnr_covered.unwrap_or(r.psnr),
            psnr_ci: if r.psnr_covered.is_some() {
                r.psnr_covered_ci
            } else {
                Some(r.psnr_ci)
            },
        })
        .collect()
}

/// `stem.svg` and `stem.png`: validation PSNR against wall-clock training time, one line per
/// curve.
pub fn training_curve(stem: &Path, curves: &[Curve], title: &str) -> Result<(), PlotError> {
    let axes = Axes {
        x: "wall-clock training time (s)",
        y: "validation PSNR (dB)",
        log: false,
    };
    svg_and_png!(stem, draw_curves, curves, title, &axes)
}

/// `stem.svg` and `stem.png`: curves on given axes (log-log for power laws).
pub fn lines(stem: &Path, curves: &[Curve], title: &str, axes: &Axes<'_>) -> Result<(), PlotError> {
    svg_and_png!(stem, draw_curves, curves, title, axes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn figures_are_written_as_svg_and_png() {
        let d = tempfile::tempdir().unwrap();
        let pts = vec![
            TimePoint {
                label: "a N=5 D=8".into(),
                ms: 10.0,
                psnr: 20.0,
                psnr_ci: None,
            },
            TimePoint {
                label: "b".into(),
                ms: 1.0,
                psnr: 15.0,
                psnr_ci: None,
            },
            TimePoint {
                label: "c".into(),
                ms: 30.0,
                psnr: 18.0,
                psnr_ci: None,
            },
        ];
        error_vs_time(&d.path().join("e"), &pts, "test").unwrap();
        let svg = std::fs::read_to_string(d.path().join("e.svg")).unwrap();
        assert!(svg.contains("a N=5 D=8") && svg.contains("Pareto"));
        // With intervals: a bar of three thin lines in the point's colour per point, and the
        // y axis reaching the intervals' ends (a bar outside it would leave the drawing area).
        let bars = |svg: &str| -> Vec<Vec<(f64, f64)>> {
            svg.split("<polyline")
                .skip(1)
                .map(|p| &p[..p.find("/>").unwrap_or(p.len())])
                .filter(|t| t.contains("stroke-width=\"1\"") && !t.contains("#000000"))
                .map(|t| {
                    let pts = t.split("points=\"").nth(1).unwrap_or("");
                    pts.split_whitespace()
                        .filter_map(|xy| {
                            let (x, y) = xy.trim_end_matches('"').split_once(',')?;
                            Some((x.parse().ok()?, y.parse().ok()?))
                        })
                        .collect()
                })
                .collect()
        };
        assert!(bars(&svg).is_empty());
        let with_ci: Vec<TimePoint> = pts
            .iter()
            .map(|p| TimePoint {
                psnr_ci: Some([p.psnr - 1.0, p.psnr + 9.0]),
                ..p.clone()
            })
            .collect();
        error_vs_time(&d.path().join("f"), &with_ci, "test").unwrap();
        let svg_ci = std::fs::read_to_string(d.path().join("f.svg")).unwrap();
        let b = bars(&svg_ci);
        assert_eq!(b.len(), 9, "three lines a bar");
        // The plot area starts 43 px from the top (margin and caption); a bar the y range left
        // out is clipped there, one inside it ends below the range's padding.
        for (x, y) in b.iter().flatten() {
            assert!(
                *x > 0.0 && *y > 60.0 && *y < f64::from(SIZE.1) - 44.0,
                "bar at ({x}, {y}) clipped or outside the plot"
            );
        }
        let png = image::open(d.path().join("e.png")).unwrap().to_rgb8();
        assert_eq!(png.dimensions(), SIZE);
        // Something besides the white background was drawn, including text pixels.
        let dark = png.pixels().filter(|p| p.0.iter().all(|&c| c < 80)).count();
        assert!(dark > 500, "{dark} dark pixels");
        let curves = vec![Curve {
            label: "learned".into(),
            points: vec![(0.0, 10.0), (50.0, 12.0), (100.0, 13.0)],
        }];
        training_curve(&d.path().join("t"), &curves, "curve").unwrap();
        let axes = Axes {
            x: "pixels",
            y: "ms",
            log: true,
        };
        lines(&d.path().join("l"), &curves[..], "log-log", &axes).unwrap();
        assert!(
            std::fs::read_to_string(d.path().join("l.svg"))
                .unwrap()
                .contains("learned")
        );
        assert!(d.path().join("t.png").is_file() && d.path().join("t.svg").is_file());
    }

    #[test]
    fn the_legend_goes_where_no_curve_passes() {
        let curve = |points: Vec<(f64, f64)>| Curve {
            label: "c".into(),
            points,
        };
        let unit = ((0.0, 1.0), (0.0, 1.0));
        let corner = |c: &[Curve]| emptiest_corner(c, |v| v, unit.0, unit.1);
        // A level line along the bottom with only its two ends as points, and a curve rising
        // through the upper right: only the upper left is free.
        let level = curve(vec![(0.0, 0.05), (1.0, 0.05)]);
        let rising = curve(vec![(0.0, 0.05), (0.5, 0.5), (0.95, 0.95)]);
        assert!(matches!(
            corner(&[level, rising]),
            SeriesLabelPosition::UpperLeft
        ));
        // Lines falling to the right from the upper left (what each budget buys): lower left.
        let falling = curve(vec![(0.0, 0.95), (0.6, 0.7), (0.95, 0.05)]);
        let upper = curve(vec![(0.0, 0.95), (0.9, 0.9)]);
        assert!(matches!(
            corner(&[falling, upper]),
            SeriesLabelPosition::LowerLeft
        ));
        // Nothing anywhere: lower right.
        assert!(matches!(corner(&[]), SeriesLabelPosition::LowerRight));
    }
}
