//! Pictures a calibration engineer reads at a glance (SVG, plotters):
//!
//! * [`per_pose`]: per-pose errors as markers (no lines joining unrelated poses) on an
//!   integer pose axis, an optional noise-floor band, the legend in its own strip above
//!   the panels (never over the data);
//! * [`predicted_vs_measured`]: one marker per campaign, the identity and factor-1.5
//!   lines;
//! * [`plan_map`]: projections of the plans' poses, marker area by the number of poses
//!   that project onto the same point.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use m2ctl::kinematics::Pose;

/// Figure width (px).
const WIDTH_PX: u32 = 1100;
/// Height of one panel (px).
const PANEL_HEIGHT_PX: u32 = 380;
/// Height of the title and legend strip (px): the title and two rows of entries.
const LEGEND_STRIP_PX: u32 = 92;
/// Approximate width of one legend character (px, 15 px sans-serif).
const LEGEND_CHAR_PX: i32 = 7;
/// Marker half-size (px).
const MARKER_PX: i32 = 4;
/// Series colours, in order.
const COLOURS: [RGBColor; 6] = [
    RGBColor(200, 30, 30),
    RGBColor(30, 110, 200),
    RGBColor(20, 150, 60),
    RGBColor(230, 140, 0),
    RGBColor(120, 60, 160),
    RGBColor(0, 0, 0),
];
/// Colour of the many small per-campaign dots.
const LIGHT_BLUE: RGBColor = RGBColor(140, 180, 225);
/// Colour of the noise-floor band.
const BAND_COLOUR: RGBColor = RGBColor(150, 150, 150);
/// Smallest value drawn on a log axis.
const LOG_FLOOR: f64 = 1.0e-4;

/// Marker shapes, in series order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Marker {
    /// Filled circle.
    Dot,
    /// Diagonal cross.
    Cross,
    /// Filled triangle.
    Triangle,
    /// Open circle (ring).
    Square,
}

/// Marker of series `k`.
pub fn marker_of(k: usize) -> Marker {
    [Marker::Dot, Marker::Cross, Marker::Triangle, Marker::Square][k % 4]
}

/// Draws markers of shape `m` at `points` into `chart`.
fn draw_markers<'a, DB: DrawingBackend + 'a>(
    chart: &mut ChartContext<
        'a,
        DB,
        Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
    >,
    m: Marker,
    points: &[(f64, f64)],
    c: RGBColor,
    size: i32,
) -> Result<(), String> {
    let e = |x: &dyn std::fmt::Display| format!("plot: {x}");
    let pts = points.iter().copied();
    match m {
        Marker::Dot => chart
            .draw_series(pts.map(|p| Circle::new(p, size, c.filled())))
            .map(|_| ()),
        Marker::Cross => chart
            .draw_series(pts.map(|p| Cross::new(p, size, c.stroke_width(2))))
            .map(|_| ()),
        Marker::Triangle => chart
            .draw_series(pts.map(|p| TriangleMarker::new(p, size + 1, c.mix(0.7).filled())))
            .map(|_| ()),
        Marker::Square => chart
            .draw_series(pts.map(|p| Circle::new(p, size + 1, c.stroke_width(2))))
            .map(|_| ()),
    }
    .map_err(|x| e(&x))
}

/// What a legend entry shows before its label.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Swatch {
    /// A marker.
    Marker(Marker),
    /// A filled band.
    Band,
    /// A solid line.
    Line,
    /// A dashed line.
    Dashed,
    /// Nothing (a note).
    None,
}

/// One legend entry.
#[derive(Clone, Debug)]
pub struct LegendEntry {
    /// Label.
    pub label: String,
    /// Swatch.
    pub swatch: Swatch,
    /// Colour.
    pub colour: RGBColor,
}

/// Draws the title and the legend entries in a strip of their own.
fn legend_strip(
    area: &DrawingArea<SVGBackend<'_>, Shift>,
    title: &str,
    entries: &[LegendEntry],
) -> Result<(), String> {
    let e = |x: &dyn std::fmt::Display| format!("plot: {x}");
    area.draw(&Text::new(
        title.to_string(),
        (12, 8),
        ("sans-serif", 20).into_font(),
    ))
    .map_err(|x| e(&x))?;
    let mut x = 20i32;
    let mut y = 44i32;
    let right = area.dim_in_pixel().0 as i32 - 10;
    for en in entries {
        let w = 40 + LEGEND_CHAR_PX * en.label.len() as i32;
        if x > 20 && x + w > right {
            x = 20;
            y += 26;
        }
        let s = MARKER_PX;
        let c = en.colour;
        let r = match en.swatch {
            Swatch::Marker(Marker::Dot) => area.draw(&Circle::new((x, y), s, c.filled())),
            Swatch::Marker(Marker::Cross) => area.draw(&Cross::new((x, y), s, c.stroke_width(2))),
            Swatch::Marker(Marker::Triangle) => {
                area.draw(&TriangleMarker::new((x, y), s + 1, c.mix(0.7).filled()))
            }
            Swatch::Marker(Marker::Square) => {
                area.draw(&Circle::new((x, y), s + 1, c.stroke_width(2)))
            }
            Swatch::Band => area.draw(&Rectangle::new(
                [(x - 8, y - 6), (x + 8, y + 6)],
                c.mix(0.35).filled(),
            )),
            Swatch::Line => area.draw(&PathElement::new(
                vec![(x - 10, y), (x + 10, y)],
                c.stroke_width(2),
            )),
            Swatch::Dashed => area
                .draw(&PathElement::new(
                    vec![(x - 10, y), (x - 4, y)],
                    c.stroke_width(2),
                ))
                .and_then(|_| {
                    area.draw(&PathElement::new(
                        vec![(x + 2, y), (x + 8, y)],
                        c.stroke_width(2),
                    ))
                }),
            Swatch::None => Ok(()),
        };
        r.map_err(|x| e(&x))?;
        area.draw(&Text::new(
            en.label.clone(),
            (x + 14, y - 8),
            ("sans-serif", 15).into_font(),
        ))
        .map_err(|x| e(&x))?;
        x += w;
    }
    Ok(())
}

/// One series of per-pose values.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend label.
    pub label: String,
    /// Value per pose (pose k + 1 at index k).
    pub values: Vec<f64>,
}

/// A band across the panel (e.g. where pure tracker noise lands).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Band {
    /// Lower edge.
    pub lo: f64,
    /// Upper edge.
    pub hi: f64,
}

/// One panel of [`per_pose`].
#[derive(Clone, Debug)]
pub struct Panel {
    /// Caption.
    pub caption: String,
    /// Y axis label (with unit).
    pub y_label: String,
    /// Series, one marker shape and colour each (same order in every panel).
    pub series: Vec<Series>,
    /// Noise-floor band, if any.
    pub band: Option<Band>,
    /// Log y axis.
    pub log: bool,
}

/// Per-pose markers, one panel per quantity, x = pose number 1..n. `band_label` names
/// the band in the legend.
pub fn per_pose(
    path: &Path,
    title: &str,
    x_label: &str,
    panels: &[Panel],
    band_label: Option<&str>,
) -> Result<(), String> {
    let e = |x: &dyn std::fmt::Display| format!("{}: plot: {x}", path.display());
    let height = LEGEND_STRIP_PX + PANEL_HEIGHT_PX * panels.len().max(1) as u32;
    let root = SVGBackend::new(path, (WIDTH_PX, height)).into_drawing_area();
    root.fill(&WHITE).map_err(|x| e(&x))?;
    let (strip, body) = root.split_vertically(LEGEND_STRIP_PX);
    let mut entries: Vec<LegendEntry> = panels
        .first()
        .map(|p| {
            p.series
                .iter()
                .enumerate()
                .map(|(k, s)| LegendEntry {
                    label: s.label.clone(),
                    swatch: Swatch::Marker(marker_of(k)),
                    colour: COLOURS[k % COLOURS.len()],
                })
                .collect()
        })
        .unwrap_or_default();
    if let Some(l) = band_label {
        entries.push(LegendEntry {
            label: l.to_string(),
            swatch: Swatch::Band,
            colour: BAND_COLOUR,
        });
    }
    legend_strip(&strip, title, &entries)?;
    let areas = body.split_evenly((panels.len().max(1), 1));
    for (area, p) in areas.iter().zip(panels) {
        let n = p
            .series
            .iter()
            .map(|s| s.values.len())
            .max()
            .unwrap_or(1)
            .max(1);
        let tr = |v: f64| if p.log { v.max(LOG_FLOOR).log10() } else { v };
        let mut lo = f64::INFINITY;
        let mut hi = f64::NEG_INFINITY;
        for v in p
            .series
            .iter()
            .flat_map(|s| s.values.iter())
            .copied()
            .chain(p.band.iter().flat_map(|b| [b.lo, b.hi]))
        {
            lo = lo.min(tr(v));
            hi = hi.max(tr(v));
        }
        if !lo.is_finite() {
            (lo, hi) = (0.0, 1.0);
        }
        let (y0, y1) = if p.log {
            (lo.floor(), hi.ceil().max(lo.floor() + 1.0))
        } else {
            (0.0, hi * 1.08 + f64::MIN_POSITIVE)
        };
        let mut chart = ChartBuilder::on(area)
            .caption(p.caption.clone(), ("sans-serif", 17))
            .margin(12)
            .x_label_area_size(38)
            .y_label_area_size(70)
            .build_cartesian_2d(0.5f64..n as f64 + 0.5, y0..y1)
            .map_err(|x| e(&x))?;
        let log = p.log;
        let y_fmt = move |v: &f64| {
            if log {
                let x = 10f64.powf(*v);
                if x >= 1.0 {
                    format!("{x:.0}")
                } else {
                    format!("{x}")
                }
            } else {
                format!("{v:.1}")
            }
        };
        let x_step = ((n as f64 / 20.0).ceil() as usize).max(1);
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(p.y_label.clone())
            .x_labels(n.div_ceil(x_step) + 1)
            .x_label_formatter(&|v: &f64| {
                if (v - v.round()).abs() < 1e-9 && *v >= 1.0 {
                    format!("{:.0}", v)
                } else {
                    String::new()
                }
            })
            .y_labels(if log { (y1 - y0) as usize + 1 } else { 8 })
            .y_label_formatter(&y_fmt)
            .light_line_style(WHITE.mix(0.0))
            .draw()
            .map_err(|x| e(&x))?;
        if let Some(b) = p.band {
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(0.5, tr(b.lo)), (n as f64 + 0.5, tr(b.hi))],
                    BAND_COLOUR.mix(0.3).filled(),
                )))
                .map_err(|x| e(&x))?;
        }
        for (k, s) in p.series.iter().enumerate() {
            let c = COLOURS[k % COLOURS.len()];
            let m = marker_of(k);
            let pts: Vec<(f64, f64)> = s
                .values
                .iter()
                .enumerate()
                .filter(|(_, v)| v.is_finite())
                .map(|(i, v)| ((i + 1) as f64, tr(*v)))
                .collect();
            draw_markers(&mut chart, m, &pts, c, MARKER_PX)?;
        }
    }
    root.present().map_err(|x| e(&x))?;
    Ok(())
}

/// One group of [`predicted_vs_measured`]: a label, per-campaign `(predicted,
/// measured)` points and their mean.
#[derive(Clone, Debug)]
pub struct PredictionGroup {
    /// Label (e.g. the tracker noise scale).
    pub label: String,
    /// Per campaign.
    pub points: Vec<(f64, f64)>,
}

/// Predicted (x) vs measured (y) on log-log axes, one panel per quantity
/// (`caption, unit, groups`): each campaign a small dot, each group's mean a large
/// marker; the identity and the factor-1.5 lines.
pub fn predicted_vs_measured(
    path: &Path,
    title: &str,
    panels: &[(String, String, Vec<PredictionGroup>)],
) -> Result<(), String> {
    let e = |x: &dyn std::fmt::Display| format!("{}: plot: {x}", path.display());
    let height = LEGEND_STRIP_PX + 540;
    let root = SVGBackend::new(path, (WIDTH_PX, height)).into_drawing_area();
    root.fill(&WHITE).map_err(|x| e(&x))?;
    let (strip, body) = root.split_vertically(LEGEND_STRIP_PX);
    legend_strip(
        &strip,
        title,
        &[
            LegendEntry {
                label: "one campaign".into(),
                swatch: Swatch::Marker(Marker::Dot),
                colour: LIGHT_BLUE,
            },
            LegendEntry {
                label: "mean of the campaigns of one tracker noise scale".into(),
                swatch: Swatch::Marker(Marker::Cross),
                colour: COLOURS[0],
            },
            LegendEntry {
                label: "measured = predicted".into(),
                swatch: Swatch::Line,
                colour: BLACK,
            },
            LegendEntry {
                label: "factor 1.5".into(),
                swatch: Swatch::Dashed,
                colour: COLOURS[2],
            },
        ],
    )?;
    let areas = body.split_evenly((1, panels.len().max(1)));
    for (area, (caption, unit, groups)) in areas.iter().zip(panels) {
        let all = groups
            .iter()
            .flat_map(|g| g.points.iter())
            .flat_map(|(a, b)| [*a, *b]);
        let (lo, hi) = all.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
            (l.min(v), h.max(v))
        });
        let (lo, hi) = if lo.is_finite() && lo > 0.0 {
            (lo.log10().floor(), hi.log10().ceil())
        } else {
            (-1.0, 1.0)
        };
        let mut chart = ChartBuilder::on(area)
            .caption(caption.clone(), ("sans-serif", 17))
            .margin(14)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(lo..hi, lo..hi)
            .map_err(|x| e(&x))?;
        let fmt = |v: &f64| {
            let x = 10f64.powf(*v);
            if x >= 1.0 {
                format!("{x:.0}")
            } else {
                format!("{x}")
            }
        };
        let n_labels = (hi - lo) as usize + 1;
        chart
            .configure_mesh()
            .x_desc(format!("predicted RMS, 1 sigma ({unit}, log scale)"))
            .y_desc(format!("measured held-out RMS ({unit}, log scale)"))
            .x_labels(n_labels)
            .y_labels(n_labels)
            .x_label_formatter(&fmt)
            .y_label_formatter(&fmt)
            .light_line_style(WHITE.mix(0.0))
            .draw()
            .map_err(|x| e(&x))?;
        chart
            .draw_series(std::iter::once(PathElement::new(
                vec![(lo, lo), (hi, hi)],
                BLACK.stroke_width(1),
            )))
            .map_err(|x| e(&x))?;
        let f = 1.5f64.log10();
        for d in [f, -f] {
            chart
                .draw_series(DashedLineSeries::new(
                    vec![(lo, lo + d), (hi, hi + d)],
                    6,
                    4,
                    COLOURS[2].stroke_width(1),
                ))
                .map_err(|x| e(&x))?;
        }
        for g in groups {
            let pts: Vec<(f64, f64)> = g
                .points
                .iter()
                .map(|(p, m)| (p.log10(), m.log10()))
                .collect();
            draw_markers(&mut chart, Marker::Dot, &pts, LIGHT_BLUE, 2)?;
        }
        for (gi, g) in groups.iter().enumerate() {
            let n = g.points.len().max(1) as f64;
            let mp = g.points.iter().map(|(p, _)| p * p).sum::<f64>() / n;
            let mm = g.points.iter().map(|(_, m)| m * m).sum::<f64>() / n;
            let at = (mp.sqrt().log10(), mm.sqrt().log10());
            draw_markers(&mut chart, Marker::Cross, &[at], COLOURS[0], 7)?;
            // Labels alternate: right and below, left and above their cross.
            let d = 0.03 * (hi - lo);
            let (pos, dx, dy) = if gi % 2 == 0 {
                (Pos::new(HPos::Left, VPos::Top), d, -d)
            } else {
                (Pos::new(HPos::Right, VPos::Bottom), -d, d)
            };
            let style = TextStyle::from(("sans-serif", 14).into_font()).pos(pos);
            chart
                .draw_series(std::iter::once(Text::new(
                    g.label.clone(),
                    (at.0 + dx, at.1 + dy),
                    style,
                )))
                .map_err(|x| e(&x))?;
        }
    }
    root.present().map_err(|x| e(&x))?;
    Ok(())
}

/// Projections of plans (label, poses): x-y (mm), z (mm) - gamma ("), alpha - beta ("). A
/// marker's area grows with the number of the plan's poses projecting onto it; plans are
/// drawn side by side (a small offset) so that equal points stay visible.
pub fn plan_map(
    path: &Path,
    title: &str,
    plans: &[(String, Vec<Pose<f64>>)],
) -> Result<(), String> {
    let e = |x: &dyn std::fmt::Display| format!("{}: plot: {x}", path.display());
    let height = LEGEND_STRIP_PX + 420;
    let root = SVGBackend::new(path, (WIDTH_PX + 200, height)).into_drawing_area();
    root.fill(&WHITE).map_err(|x| e(&x))?;
    let (strip, body) = root.split_vertically(LEGEND_STRIP_PX);
    let mut entries: Vec<LegendEntry> = plans
        .iter()
        .enumerate()
        .map(|(k, (l, _))| LegendEntry {
            label: l.clone(),
            swatch: Swatch::Marker(marker_of(k)),
            colour: COLOURS[k % COLOURS.len()],
        })
        .collect();
    entries.push(LegendEntry {
        label: "(marker size and number: poses at that point)".into(),
        swatch: Swatch::None,
        colour: WHITE,
    });
    legend_strip(&strip, title, &entries)?;
    let areas = body.split_evenly((1, 3));
    type Proj = fn(&Pose<f64>) -> (f64, f64);
    let projections: [(&str, &str, &str, Proj, f64, f64); 3] = [
        (
            "translation x-y",
            "x (mm)",
            "y (mm)",
            |p| (p.translation_mm[0], p.translation_mm[1]),
            1.0,
            1.0,
        ),
        (
            "z and gamma",
            "z (mm)",
            "gamma (arcsec)",
            |p| (p.translation_mm[2], p.rotation_arcsec()[2]),
            1.0,
            60.0,
        ),
        (
            "rotation alpha-beta",
            "alpha (arcsec)",
            "beta (arcsec)",
            |p| (p.rotation_arcsec()[0], p.rotation_arcsec()[1]),
            60.0,
            60.0,
        ),
    ];
    for (area, (caption, xl, yl, proj, sx, sy)) in areas.iter().zip(projections.iter()) {
        let mut chart = ChartBuilder::on(area)
            .caption(*caption, ("sans-serif", 17))
            .margin(14)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(-1.3 * sx..1.3 * sx, -1.3 * sy..1.3 * sy)
            .map_err(|x| e(&x))?;
        chart
            .configure_mesh()
            .x_desc(*xl)
            .y_desc(*yl)
            .light_line_style(WHITE.mix(0.0))
            .draw()
            .map_err(|x| e(&x))?;
        let np = plans.len().max(1) as f64;
        for (k, (_, poses)) in plans.iter().enumerate() {
            let mut counts: Vec<((f64, f64), usize)> = Vec::new();
            for p in poses {
                let q = proj(p);
                match counts
                    .iter_mut()
                    .find(|(c, _)| (c.0 - q.0).abs() < 1e-9 * sx && (c.1 - q.1).abs() < 1e-9 * sy)
                {
                    Some((_, n)) => *n += 1,
                    None => counts.push((q, 1)),
                }
            }
            let off = (k as f64 - (np - 1.0) / 2.0) * 0.09 * sx;
            let c = COLOURS[k % COLOURS.len()];
            for ((x, y), n) in &counts {
                let size = MARKER_PX + (2.0 * ((*n as f64).sqrt() - 1.0)).round() as i32;
                draw_markers(&mut chart, marker_of(k), &[(x + off, *y)], c, size)?;
                if *n > 1 {
                    chart
                        .draw_series(std::iter::once(Text::new(
                            format!("{n}"),
                            (x + off + 0.08 * sx, y + 0.16 * sy),
                            ("sans-serif", 11).into_font().color(&c),
                        )))
                        .map_err(|x| e(&x))?;
                }
            }
        }
    }
    root.present().map_err(|x| e(&x))?;
    Ok(())
}
