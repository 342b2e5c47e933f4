//! The report's plots, drawn with plotters into SVG strings (text as SVG `<text>`, no system
//! fonts needed).

use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

/// Okabe and Ito's colour-blind-safe palette: blue, vermillion, orange, bluish green.
pub const BLUE_CB: RGBColor = RGBColor(0, 114, 178);
/// Vermillion.
pub const VERMILLION: RGBColor = RGBColor(213, 94, 0);
/// Orange.
pub const ORANGE: RGBColor = RGBColor(230, 159, 0);
/// Bluish green.
pub const BLUISH_GREEN: RGBColor = RGBColor(0, 158, 115);

/// A legend entry's mark.
#[derive(Clone, Copy)]
enum Mark {
    Dot(RGBColor),
    Cross(RGBColor),
    Line(RGBColor),
    Band(RGBColor),
}

/// The legend in its own strip under the plot, never over the data.
fn legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    entries: &[(Mark, String)],
) -> Result<(), String> {
    let mut x = 80i32;
    for (mark, text) in entries {
        let y = 10i32;
        match *mark {
            Mark::Dot(c) => area.draw(&Circle::new((x + 6, y), 3, c.filled())),
            Mark::Cross(c) => area.draw(&Cross::new((x + 6, y), 4, c.stroke_width(2))),
            Mark::Line(c) => area.draw(&PathElement::new([(x, y), (x + 16, y)], c.stroke_width(2))),
            Mark::Band(c) => area.draw(&Rectangle::new(
                [(x, y - 5), (x + 16, y + 5)],
                c.mix(0.25).filled(),
            )),
        }
        .map_err(|e| e.to_string())?;
        area.draw(&Text::new(
            text.clone(),
            (x + 22, y - 7),
            ("sans-serif", 13),
        ))
        .map_err(|e| e.to_string())?;
        x += 30 + 7 * text.chars().count() as i32;
    }
    Ok(())
}

/// The chart every framed plot draws on: f64 on both axes, into an SVG string.
type Chart<'a, 'b> = ChartContext<'a, SVGBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// A plot's frame: its size, title, axes, and the legend's strip of 24 pixels under it.
struct Frame<'a> {
    size: (u32, u32),
    title: &'a str,
    /// The x and y axis labels.
    axes: (&'a str, &'a str),
    /// The width of the y labels' area, pixels.
    y_label_area: u32,
    x: (f64, f64),
    y: (f64, f64),
}

/// Draws a plot in `frame`, its y ticks labelled by `ticks` (plotters' own when None):
/// `draw` puts the data on the chart and returns the legend's entries.
fn framed(
    frame: &Frame<'_>,
    ticks: Option<&dyn Fn(&f64) -> String>,
    draw: impl FnOnce(&mut Chart<'_, '_>) -> Result<Vec<(Mark, String)>, String>,
) -> Result<String, String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, frame.size).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let (plot, strip) = root.split_vertically(frame.size.1 - 24);
        let mut chart = ChartBuilder::on(&plot)
            .caption(frame.title, ("sans-serif", 16))
            .margin(12)
            .x_label_area_size(42)
            .y_label_area_size(frame.y_label_area)
            .build_cartesian_2d(frame.x.0..frame.x.1, frame.y.0..frame.y.1)
            .map_err(|e| e.to_string())?;
        {
            let mut mesh = chart.configure_mesh();
            mesh.x_desc(frame.axes.0)
                .y_desc(frame.axes.1)
                .light_line_style(WHITE.mix(0.0));
            if let Some(ticks) = ticks {
                mesh.y_label_formatter(ticks);
            }
            mesh.draw().map_err(|e| e.to_string())?;
        }
        let entries = draw(&mut chart)?;
        legend(&strip, &entries)?;
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(svg)
}

/// A line through (x, value) with its 1-sigma band (x, value +/- sigma) under it.
fn line_with_band(
    chart: &mut Chart<'_, '_>,
    points: &[(f64, f64, f64)],
    colour: RGBColor,
) -> Result<(), String> {
    let band: Vec<(f64, f64)> = points
        .iter()
        .map(|q| (q.0, q.1 + q.2))
        .chain(points.iter().rev().map(|q| (q.0, q.1 - q.2)))
        .collect();
    chart
        .draw_series(std::iter::once(Polygon::new(
            band,
            colour.mix(0.25).filled(),
        )))
        .map_err(|e| e.to_string())?;
    chart
        .draw_series(LineSeries::new(
            points.iter().map(|q| (q.0, q.1)),
            colour.stroke_width(2),
        ))
        .map_err(|e| e.to_string())?;
    Ok(())
}

/// A scatter plot: used points, removed points (marked), optional line.
pub struct Scatter<'a> {
    /// Title.
    pub title: &'a str,
    /// x axis label with unit.
    pub x_label: &'a str,
    /// y axis label with unit.
    pub y_label: &'a str,
    /// Points used in the adjustment.
    pub used: &'a [(f64, f64)],
    /// Points removed by data snooping.
    pub removed: &'a [(f64, f64)],
    /// A line to draw through the points (e.g. the calibration function).
    pub line: &'a [(f64, f64)],
    /// Draw y = 0.
    pub zero_line: bool,
    /// Legend of the points (their count follows) and of the line.
    pub labels: (&'a str, &'a str),
    /// The y range to draw, shared by small multiples; None: from the points.
    pub y_range: Option<(f64, f64)>,
}

/// The legend of a residual or calibration plot: the points used, the calibration function.
pub const ADJUSTMENT_LABELS: (&str, &str) = ("used", "calibration function");

/// The range of `values` with a 5 % margin ((-1, 1) when there are none).
pub fn range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    });
    if !lo.is_finite() {
        return (-1.0, 1.0);
    }
    let pad = if hi > lo {
        0.05 * (hi - lo)
    } else {
        1.0_f64.max(lo.abs() * 1e-6)
    };
    (lo - pad, hi + pad)
}

/// Draws `s` as an SVG document.
pub fn scatter(s: &Scatter<'_>) -> Result<String, String> {
    let ((x0, x1), (y0, y1)) = scatter_ranges(s);
    let frame = Frame {
        size: (560, 360),
        title: s.title,
        axes: (s.x_label, s.y_label),
        y_label_area: 72,
        x: (x0, x1),
        y: (y0, y1),
    };
    framed(&frame, None, |chart| {
        let mut entries = Vec::new();
        if s.zero_line {
            chart
                .draw_series(LineSeries::new([(x0, 0.0), (x1, 0.0)], BLACK.mix(0.4)))
                .map_err(|e| e.to_string())?;
        }
        if !s.line.is_empty() {
            chart
                .draw_series(LineSeries::new(
                    s.line.iter().copied(),
                    ORANGE.stroke_width(2),
                ))
                .map_err(|e| e.to_string())?;
            entries.push((Mark::Line(ORANGE), s.labels.1.to_owned()));
        }
        chart
            .draw_series(s.used.iter().map(|&p| Circle::new(p, 2, BLUE_CB.filled())))
            .map_err(|e| e.to_string())?;
        entries.push((
            Mark::Dot(BLUE_CB),
            format!("{} ({})", s.labels.0, s.used.len()),
        ));
        if !s.removed.is_empty() {
            let off_scale = s.removed.iter().filter(|p| p.1 < y0 || p.1 > y1).count();
            let label = if off_scale > 0 {
                format!(
                    "removed by data snooping ({}, {off_scale} off scale, drawn at the edge)",
                    s.removed.len()
                )
            } else {
                format!("removed by data snooping ({})", s.removed.len())
            };
            chart
                .draw_series(
                    s.removed.iter().map(|&(x, y)| {
                        Cross::new((x, y.clamp(y0, y1)), 5, VERMILLION.stroke_width(2))
                    }),
                )
                .map_err(|e| e.to_string())?;
            entries.push((Mark::Cross(VERMILLION), label));
        }
        Ok(entries)
    })
}

/// A scatter plot's x and y ranges: x over every point and the line; y over the used
/// points and the line (a blunder of hundreds of mGal must not squash the residuals;
/// removed points beyond it sit on the frame's edge), or as given, with 0 when drawn.
fn scatter_ranges(s: &Scatter<'_>) -> ((f64, f64), (f64, f64)) {
    let all = || s.used.iter().chain(s.removed).chain(s.line);
    let x = range(all().map(|p| p.0));
    let (mut y0, mut y1) = if let Some(r) = s.y_range {
        r
    } else if s.used.is_empty() {
        range(all().map(|p| p.1))
    } else {
        range(s.used.iter().chain(s.line).map(|p| p.1))
    };
    if s.zero_line {
        y0 = y0.min(0.0);
        y1 = y1.max(0.0);
    }
    (x, (y0, y1))
}

/// A parameter of per-session fits against temperature (points with 1-sigma bars) and a
/// temperature model's line with its 1-sigma band.
pub struct Trend<'a> {
    /// Title.
    pub title: &'a str,
    /// y axis label with unit.
    pub y_label: &'a str,
    /// (temperature degC, value, sigma) per session fit.
    pub points: &'a [(f64, f64, f64)],
    /// (temperature, value, sigma) along the model's line.
    pub line: &'a [(f64, f64, f64)],
    /// Legends of the points and of the line.
    pub labels: (&'a str, &'a str),
}

/// Draws `t` as an SVG document.
pub fn trend(t: &Trend<'_>) -> Result<String, String> {
    let xs = t.points.iter().chain(t.line).map(|p| p.0);
    let ys = t
        .points
        .iter()
        .chain(t.line)
        .flat_map(|p| [p.1 - p.2, p.1 + p.2]);
    let frame = Frame {
        size: (560, 360),
        title: t.title,
        axes: ("temperature (degC)", t.y_label),
        y_label_area: 90,
        x: range(xs),
        y: range(ys),
    };
    let fine = (frame.y.1 - frame.y.0).abs() < 0.1;
    let ticks = move |v: &f64| {
        if fine {
            format!("{v:.1e}")
        } else {
            format!("{v:.1}")
        }
    };
    framed(&frame, Some(&ticks), |chart| {
        let mut entries = Vec::new();
        if !t.line.is_empty() {
            line_with_band(chart, t.line, ORANGE)?;
            entries.push((Mark::Line(ORANGE), t.labels.1.to_owned()));
            entries.push((Mark::Band(ORANGE), "its 1-sigma band".to_owned()));
        }
        chart
            .draw_series(t.points.iter().map(|&(x, y, e)| {
                PathElement::new([(x, y - e), (x, y + e)], BLUE_CB.stroke_width(2))
            }))
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(
                t.points
                    .iter()
                    .map(|&(x, y, _)| Circle::new((x, y), 3, BLUE_CB.filled())),
            )
            .map_err(|e| e.to_string())?;
        entries.push((Mark::Dot(BLUE_CB), format!("{} (1-sigma bars)", t.labels.0)));
        Ok(entries)
    })
}

/// A misalignment vector in the block's frame: the estimate (theta_x, theta_y), the line
/// from the origin to it, and its error ellipse, on equal axes through the origin.
pub struct Polar<'a> {
    /// Title.
    pub title: &'a str,
    /// The estimate, mrad.
    pub point: (f64, f64),
    /// The error ellipse, mrad, as a closed polyline.
    pub ellipse: &'a [(f64, f64)],
    /// Legend of the ellipse.
    pub ellipse_label: &'a str,
}

/// Draws `p` as an SVG document.
pub fn polar(p: &Polar<'_>) -> Result<String, String> {
    let mut svg = String::new();
    {
        let reach = p
            .ellipse
            .iter()
            .chain(std::iter::once(&p.point))
            .map(|q| q.0.abs().max(q.1.abs()))
            .fold(0.0, f64::max)
            .max(1e-6)
            * 1.25;
        let root = SVGBackend::with_string(&mut svg, (380, 380)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let mut chart = ChartBuilder::on(&root)
            .caption(p.title, ("sans-serif", 14))
            .margin(10)
            .x_label_area_size(36)
            .y_label_area_size(48)
            .build_cartesian_2d(-reach..reach, -reach..reach)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_desc("theta_x (mrad)")
            .y_desc("theta_y (mrad)")
            .light_line_style(WHITE.mix(0.0))
            .draw()
            .map_err(|e| e.to_string())?;
        for axis in [[(-reach, 0.0), (reach, 0.0)], [(0.0, -reach), (0.0, reach)]] {
            chart
                .draw_series(LineSeries::new(axis, BLACK.mix(0.3)))
                .map_err(|e| e.to_string())?;
        }
        chart
            .draw_series(LineSeries::new(
                [(0.0, 0.0), p.point],
                BLUE_CB.stroke_width(1),
            ))
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(LineSeries::new(
                p.ellipse.iter().copied(),
                VERMILLION.stroke_width(2),
            ))
            .map_err(|e| e.to_string())?
            .label(p.ellipse_label)
            .legend(|(x, y)| PathElement::new([(x, y), (x + 16, y)], VERMILLION.stroke_width(2)));
        chart
            .draw_series(std::iter::once(Circle::new(p.point, 3, BLUE_CB.filled())))
            .map_err(|e| e.to_string())?
            .label("estimate")
            .legend(|(x, y)| Circle::new((x + 8, y), 3, BLUE_CB.filled()));
        // The legend in the quadrant opposite the estimate.
        let corner = match (p.point.0 >= 0.0, p.point.1 >= 0.0) {
            (true, true) => SeriesLabelPosition::LowerLeft,
            (true, false) => SeriesLabelPosition::UpperLeft,
            (false, true) => SeriesLabelPosition::LowerRight,
            (false, false) => SeriesLabelPosition::UpperRight,
        };
        chart
            .configure_series_labels()
            .position(corner)
            .border_style(BLACK.mix(0.3))
            .background_style(WHITE.mix(0.85))
            .draw()
            .map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(svg)
}

/// A survey's track on a local map (east, north in km from its first point), each epoch
/// coloured by a value on a diverging scale symmetric about zero.
pub struct TrackMap<'a> {
    /// Title.
    pub title: &'a str,
    /// (east km, north km, value) per point drawn.
    pub points: &'a [(f64, f64, f64)],
    /// What the colour is, with its unit.
    pub value_label: &'a str,
}

/// Blue (negative) through white to vermillion (positive), `v` in [-1, 1].
fn diverging(v: f64) -> RGBColor {
    let v = v.clamp(-1.0, 1.0);
    let mix = |a: u8, b: u8, t: f64| (f64::from(a) + (f64::from(b) - f64::from(a)) * t) as u8;
    let (end, t) = if v < 0.0 {
        (BLUE_CB, -v)
    } else {
        (VERMILLION, v)
    };
    RGBColor(mix(235, end.0, t), mix(235, end.1, t), mix(235, end.2, t))
}

/// Draws `m` as an SVG document, on equal axes.
pub fn track_map(m: &TrackMap<'_>) -> Result<String, String> {
    let (mut x0, mut x1) = range(m.points.iter().map(|p| p.0));
    let (mut y0, mut y1) = range(m.points.iter().map(|p| p.1));
    // Equal scales: widen the narrower range about its centre (the plot is 520 x 300).
    let (w, h) = (x1 - x0, y1 - y0);
    if w / 520.0 > h / 300.0 {
        let c = 0.5 * (y0 + y1);
        (y0, y1) = (c - w * 300.0 / 1040.0, c + w * 300.0 / 1040.0);
    } else {
        let c = 0.5 * (x0 + x1);
        (x0, x1) = (c - h * 520.0 / 600.0, c + h * 520.0 / 600.0);
    }
    let scale = m
        .points
        .iter()
        .fold(0.0_f64, |a, p| a.max(p.2.abs()))
        .max(1e-9);
    let frame = Frame {
        size: (600, 400),
        title: m.title,
        axes: ("east (km)", "north (km)"),
        y_label_area: 60,
        x: (x0, x1),
        y: (y0, y1),
    };
    framed(&frame, None, |chart| {
        chart
            .draw_series(
                m.points
                    .iter()
                    .map(|&(x, y, v)| Circle::new((x, y), 3, diverging(v / scale).filled())),
            )
            .map_err(|e| e.to_string())?;
        Ok(vec![
            (
                Mark::Dot(diverging(-1.0)),
                format!("{:.2} {}", -scale, m.value_label),
            ),
            (Mark::Dot(diverging(0.0)), "0".to_owned()),
            (
                Mark::Dot(diverging(1.0)),
                format!("+{scale:.2} {}", m.value_label),
            ),
        ])
    })
}

/// A value along a track or in time (x, value, sigma) drawn as a line with its 1-sigma
/// band, one piece per stretch (no line across a gap).
pub struct Profile<'a> {
    /// Title.
    pub title: &'a str,
    /// x axis label with unit.
    pub x_label: &'a str,
    /// y axis label with unit.
    pub y_label: &'a str,
    /// The line's name in the legend.
    pub legend: &'a str,
    /// Per stretch, (x, value, sigma).
    pub stretches: &'a [Vec<(f64, f64, f64)>],
}

/// Draws `p` as an SVG document.
pub fn profile(p: &Profile<'_>) -> Result<String, String> {
    let all = || p.stretches.iter().flatten();
    let frame = Frame {
        size: (600, 360),
        title: p.title,
        axes: (p.x_label, p.y_label),
        y_label_area: 72,
        x: range(all().map(|q| q.0)),
        y: range(all().flat_map(|q| [q.1 - q.2, q.1 + q.2])),
    };
    framed(&frame, None, |chart| {
        for s in p.stretches.iter().filter(|s| !s.is_empty()) {
            line_with_band(chart, s, BLUE_CB)?;
        }
        Ok(vec![
            (Mark::Line(BLUE_CB), p.legend.to_owned()),
            (Mark::Band(BLUE_CB), "its 1-sigma band".to_owned()),
        ])
    })
}

/// A stream's norm over time with the still intervals found shaded: what a person looking
/// at the recording would call positions, beside what the detector used.
pub struct Stillness<'a> {
    /// Title.
    pub title: &'a str,
    /// y axis label with unit.
    pub y_label: &'a str,
    /// Per time bin (s from the first sample), the least and greatest norm in it.
    pub envelope: &'a [(f64, f64, f64)],
    /// The intervals used as positions, (start, end) s.
    pub used: &'a [(f64, f64)],
}

/// Draws `p` as an SVG document.
pub fn stillness(p: &Stillness<'_>) -> Result<String, String> {
    let frame = Frame {
        size: (720, 320),
        title: p.title,
        axes: ("time from the session's first sample (s)", p.y_label),
        y_label_area: 72,
        x: range(p.envelope.iter().map(|q| q.0)),
        y: range(p.envelope.iter().flat_map(|q| [q.1, q.2])),
    };
    let (y0, y1) = frame.y;
    framed(&frame, None, |chart| {
        chart
            .draw_series(
                p.used.iter().map(|&(a, b)| {
                    Rectangle::new([(a, y0), (b, y1)], BLUISH_GREEN.mix(0.25).filled())
                }),
            )
            .map_err(|e| e.to_string())?;
        let band: Vec<(f64, f64)> = p
            .envelope
            .iter()
            .map(|q| (q.0, q.2))
            .chain(p.envelope.iter().rev().map(|q| (q.0, q.1)))
            .collect();
        chart
            .draw_series(std::iter::once(Polygon::new(band, BLUE_CB.filled())))
            .map_err(|e| e.to_string())?;
        // A still bin's least and greatest nearly meet: its line keeps it in sight.
        for edge in [
            |q: &(f64, f64, f64)| (q.0, q.1),
            |q: &(f64, f64, f64)| (q.0, q.2),
        ] {
            chart
                .draw_series(LineSeries::new(
                    p.envelope.iter().map(edge),
                    BLUE_CB.stroke_width(2),
                ))
                .map_err(|e| e.to_string())?;
        }
        Ok(vec![
            (
                Mark::Line(BLUE_CB),
                "the norm (least to greatest per bin)".to_owned(),
            ),
            (
                Mark::Band(BLUISH_GREEN),
                format!("{} positions used", p.used.len()),
            ),
        ])
    })
}
