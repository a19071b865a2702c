//! X-Y charts rendered to SVG text with `plotters`' SVG backend.

use plotters::prelude::*;

use crate::ReportError;

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mark {
    /// A polyline through the points (non-finite points break it).
    Line,
    /// A small dot per point.
    Dots,
    /// A larger hollow marker per point (end points, landmarks).
    Markers,
    /// A vertical bar from 0 to y per point, 0.8 wide in x.
    Bars,
}

/// One named set of points of a chart.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend text; empty = no legend entry.
    pub label: String,
    /// Points in chart units (non-finite points are skipped).
    pub points: Vec<(f64, f64)>,
    /// How the points are drawn.
    pub mark: Mark,
    /// Palette index (see [`PALETTE`]).
    pub color: usize,
}

impl Series {
    /// A series with the given label, points, mark and palette colour.
    pub fn new(label: &str, points: Vec<(f64, f64)>, mark: Mark, color: usize) -> Self {
        Self {
            label: label.to_string(),
            points,
            mark,
            color,
        }
    }
}

/// A titled X-Y chart with labelled axes (labels carry the units).
#[derive(Debug, Clone, PartialEq)]
pub struct Chart {
    /// Title drawn above the plot.
    pub title: String,
    /// X axis label with unit, e.g. "x (m)".
    pub x_label: String,
    /// Y axis label with unit.
    pub y_label: String,
    /// The data.
    pub series: Vec<Series>,
    /// Y grows downwards (image coordinates).
    pub y_down: bool,
    /// Same scale on both axes (maps, trajectories).
    pub equal_aspect: bool,
    /// Fixed x range instead of the data's.
    pub x_range: Option<(f64, f64)>,
    /// Fixed y range instead of the data's.
    pub y_range: Option<(f64, f64)>,
    /// Size in pixels (width, height).
    pub size_px: (u32, u32),
    /// A heat map drawn under the series, if any.
    pub cells: Option<Cells>,
}

/// A grid of values drawn as coloured cells (a heat map) in chart units.
#[derive(Debug, Clone, PartialEq)]
pub struct Cells {
    /// Left and top edge of the first cell (top = smallest y).
    pub origin: (f64, f64),
    /// Width and height of a cell.
    pub cell: (f64, f64),
    /// Cells across.
    pub cols: usize,
    /// The values row by row (`None`: the cell is left grey).
    pub values: Vec<Option<f64>>,
    /// Legend text for the grey cells.
    pub missing_label: String,
    /// Unit written after the values in the legend, e.g. "mm".
    pub unit: String,
}

impl Cells {
    /// The largest finite value.
    pub fn max(&self) -> f64 {
        self.values
            .iter()
            .flatten()
            .copied()
            .filter(|v| v.is_finite())
            .fold(0.0, f64::max)
    }

    /// The colour of `v` on a viridis scale from 0 to `max`.
    fn colour(v: f64, max: f64) -> RGBColor {
        use plotters::style::colors::colormaps::{ColorMap, ViridisRGB};
        let t = if max > 0.0 {
            (v / max).clamp(0.0, 1.0)
        } else {
            0.0
        };
        ViridisRGB.get_color_normalized(t, 0.0, 1.0)
    }
}

/// Colour-blind-safe palette (Okabe–Ito) plus grey.
pub const PALETTE: [RGBColor; 8] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(0, 0, 0),
    RGBColor(150, 150, 150),
];

impl Chart {
    /// An empty 760x420 chart with the given title and axis labels.
    pub fn new(title: &str, x_label: &str, y_label: &str) -> Self {
        Self {
            title: title.to_string(),
            x_label: x_label.to_string(),
            y_label: y_label.to_string(),
            series: Vec::new(),
            y_down: false,
            equal_aspect: false,
            x_range: None,
            y_range: None,
            size_px: (760, 420),
            cells: None,
        }
    }

    /// Adds a series (builder style).
    pub fn with(mut self, s: Series) -> Self {
        self.series.push(s);
        self
    }

    /// Number of finite points over all series.
    pub fn n_points(&self) -> usize {
        self.series
            .iter()
            .flat_map(|s| &s.points)
            .filter(|p| p.0.is_finite() && p.1.is_finite())
            .count()
    }

    /// Renders the chart to SVG text. An axis far from 0 for its span (surveyed coordinates,
    /// epoch times) is drawn from a round origin its label states: its ticks would otherwise
    /// all read "5.4e6".
    pub fn to_svg(&self) -> Result<String, ReportError> {
        let (xr, yr) = self.ranges();
        let (ox, oy) = (axis_origin(xr), axis_origin(yr));
        if ox == 0.0 && oy == 0.0 {
            return self.render();
        }
        let mut c = self.clone();
        for s in &mut c.series {
            for p in &mut s.points {
                *p = (p.0 - ox, p.1 - oy);
            }
        }
        c.x_range = c.x_range.map(|r| (r.0 - ox, r.1 - ox));
        c.y_range = c.y_range.map(|r| (r.0 - oy, r.1 - oy));
        if let Some(cells) = &mut c.cells {
            cells.origin = (cells.origin.0 - ox, cells.origin.1 - oy);
        }
        c.x_label = label_from(&c.x_label, ox);
        c.y_label = label_from(&c.y_label, oy);
        c.render()
    }

    fn render(&self) -> Result<String, ReportError> {
        if self.n_points() == 0 {
            return Err(ReportError::Plot(format!(
                "'{}': no finite data to plot",
                self.title
            )));
        }
        let flip = if self.y_down { -1.0 } else { 1.0 };
        let (mut xr, mut yr) = self.ranges();
        if self.y_down {
            yr = (-yr.1, -yr.0);
        }
        if self.equal_aspect {
            // Plot area is roughly the figure less the label areas and margins.
            let aw = f64::from(self.size_px.0.saturating_sub(110).max(50));
            let ah = f64::from(self.size_px.1.saturating_sub(110).max(50));
            let sx = (xr.1 - xr.0) / aw;
            let sy = (yr.1 - yr.0) / ah;
            let s = sx.max(sy);
            let cx = 0.5 * (xr.0 + xr.1);
            let cy = 0.5 * (yr.0 + yr.1);
            xr = (cx - 0.5 * s * aw, cx + 0.5 * s * aw);
            yr = (cy - 0.5 * s * ah, cy + 0.5 * s * ah);
        }
        let err = |e: &dyn std::fmt::Display| ReportError::Plot(format!("'{}': {e}", self.title));
        let mut buf = String::new();
        {
            let root = SVGBackend::with_string(&mut buf, self.size_px).into_drawing_area();
            root.fill(&WHITE).map_err(|e| err(&e))?;
            let mut chart = ChartBuilder::on(&root)
                .caption(&self.title, ("sans-serif", 18))
                .margin(12)
                .x_label_area_size(44)
                .y_label_area_size(70)
                .build_cartesian_2d(xr.0..xr.1, yr.0..yr.1)
                .map_err(|e| err(&e))?;
            let y_fmt = move |v: &f64| fmt_tick(flip * *v);
            chart
                .configure_mesh()
                .x_desc(&self.x_label)
                .y_desc(&self.y_label)
                .x_label_formatter(&|v: &f64| fmt_tick(*v))
                .y_label_formatter(&y_fmt)
                .light_line_style(RGBColor(238, 238, 238))
                .max_light_lines(4)
                .axis_desc_style(("sans-serif", 15))
                .label_style(("sans-serif", 13))
                .draw()
                .map_err(|e| err(&e))?;
            let mut any_label = false;
            if let Some(c) = &self.cells {
                let max = c.max();
                let grey = RGBColor(200, 200, 200);
                let rects = c.values.iter().enumerate().map(|(i, v)| {
                    let (col, row) = ((i % c.cols.max(1)) as f64, (i / c.cols.max(1)) as f64);
                    let x0 = c.origin.0 + col * c.cell.0;
                    let y0 = c.origin.1 + row * c.cell.1;
                    let colour = v
                        .filter(|v| v.is_finite())
                        .map_or(grey, |v| Cells::colour(v, max));
                    Rectangle::new(
                        [(x0, flip * y0), (x0 + c.cell.0, flip * (y0 + c.cell.1))],
                        colour.filled(),
                    )
                });
                chart.draw_series(rects).map_err(|e| err(&e))?;
                // The scale as legend entries: five levels from 0 to the largest value.
                let mut levels: Vec<(String, RGBColor)> = (0..5)
                    .map(|k| {
                        let v = max * k as f64 / 4.0;
                        (format!("{} {}", fmt_tick(v), c.unit), Cells::colour(v, max))
                    })
                    .collect();
                if c.values.iter().any(|v| v.is_none()) {
                    levels.push((c.missing_label.clone(), grey));
                }
                for (label, colour) in levels {
                    any_label = true;
                    chart
                        .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
                        .map_err(|e| err(&e))?
                        .label(label)
                        .legend(move |(x, y)| {
                            Rectangle::new([(x, y - 5), (x + 18, y + 5)], colour.filled())
                        });
                }
            }
            for s in &self.series {
                let color = PALETTE[s.color % PALETTE.len()];
                let pts: Vec<(f64, f64)> = s.points.iter().map(|&(x, y)| (x, flip * y)).collect();
                let finite = |p: &&(f64, f64)| p.0.is_finite() && p.1.is_finite();
                let legend_mark = s.mark;
                let anno = match s.mark {
                    Mark::Line => {
                        let mut segments: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
                        for p in &pts {
                            if p.0.is_finite() && p.1.is_finite() {
                                if let Some(last) = segments.last_mut() {
                                    last.push(*p);
                                }
                            } else if segments.last().is_some_and(|l| !l.is_empty()) {
                                segments.push(Vec::new());
                            }
                        }
                        segments.retain(|s| !s.is_empty());
                        // Later pieces first: the first piece's annotation (legend) is kept.
                        for seg in segments.iter().skip(1) {
                            chart
                                .draw_series(LineSeries::new(seg.clone(), color.stroke_width(2)))
                                .map_err(|e| err(&e))?;
                        }
                        match segments.into_iter().next() {
                            Some(first) => Some(
                                chart
                                    .draw_series(LineSeries::new(first, color.stroke_width(2)))
                                    .map_err(|e| err(&e))?,
                            ),
                            None => None,
                        }
                    }
                    Mark::Dots => Some(
                        chart
                            .draw_series(
                                pts.iter()
                                    .filter(finite)
                                    .map(|&p| Circle::new(p, 2, color.filled())),
                            )
                            .map_err(|e| err(&e))?,
                    ),
                    Mark::Markers => Some(
                        chart
                            .draw_series(
                                pts.iter()
                                    .filter(finite)
                                    .map(|&p| Circle::new(p, 6, color.stroke_width(2))),
                            )
                            .map_err(|e| err(&e))?,
                    ),
                    Mark::Bars => Some(
                        chart
                            .draw_series(pts.iter().filter(finite).map(|&(x, y)| {
                                Rectangle::new([(x - 0.4, 0.0), (x + 0.4, y)], color.filled())
                            }))
                            .map_err(|e| err(&e))?,
                    ),
                };
                if let (Some(a), false) = (anno, s.label.is_empty()) {
                    any_label = true;
                    a.label(&s.label).legend(move |(x, y)| {
                        let h = if legend_mark == Mark::Line { 1 } else { 5 };
                        Rectangle::new([(x, y - h), (x + 18, y + h)], color.filled())
                    });
                }
            }
            if any_label {
                chart
                    .configure_series_labels()
                    .background_style(WHITE.mix(0.85))
                    .border_style(RGBColor(120, 120, 120))
                    .label_font(("sans-serif", 13))
                    .position(SeriesLabelPosition::UpperRight)
                    .draw()
                    .map_err(|e| err(&e))?;
            }
            root.present().map_err(|e| err(&e))?;
        }
        Ok(buf)
    }

    /// Data ranges with 5 % padding (bars include 0), or the fixed ranges.
    fn ranges(&self) -> ((f64, f64), (f64, f64)) {
        let (mut x0, mut x1, mut y0, mut y1) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        for s in &self.series {
            for &(x, y) in s
                .points
                .iter()
                .filter(|p| p.0.is_finite() && p.1.is_finite())
            {
                let (xa, xb) = if s.mark == Mark::Bars {
                    (x - 0.5, x + 0.5)
                } else {
                    (x, x)
                };
                x0 = x0.min(xa);
                x1 = x1.max(xb);
                y0 = y0.min(y);
                y1 = y1.max(y);
                if s.mark == Mark::Bars {
                    y0 = y0.min(0.0);
                    y1 = y1.max(0.0);
                }
            }
        }
        let pad = |a: f64, b: f64| {
            let span = b - a;
            if span > 1e-12 * (a.abs() + b.abs()).max(1e-300) && span > 0.0 {
                (a - 0.05 * span, b + 0.05 * span)
            } else {
                let d = (a.abs() * 0.1).max(1e-3);
                (a - d, b + d)
            }
        };
        let mut yr = pad(y0, y1);
        if !self.y_down && self.series.iter().any(|s| !s.label.is_empty()) {
            // Head room for the legend box in the upper right corner.
            yr.1 += 0.25 * (yr.1 - yr.0);
        }
        (
            self.x_range.unwrap_or_else(|| pad(x0, x1)),
            self.y_range.unwrap_or(yr),
        )
    }
}

/// A round origin for an axis spanning `r` whose ticks would need more digits than they
/// show (values of 10 000 and more, spanning less than a tenth of their size), else 0: the
/// span's power of ten below the axis' start, so the ticks count up from it.
fn axis_origin(r: (f64, f64)) -> f64 {
    let (lo, hi) = r;
    let size = lo.abs().max(hi.abs());
    let span = hi - lo;
    if !(size.is_finite() && span.is_finite()) || size < 1e4 || span * 10.0 >= size {
        return 0.0;
    }
    let unit = 10f64.powf(span.max(1e-9).log10().ceil());
    (lo / unit).floor() * unit
}

/// `label` of an axis drawn from `origin`: "x (m) − 512300" reads as the tick plus 512300.
fn label_from(label: &str, origin: f64) -> String {
    if origin == 0.0 {
        label.to_string()
    } else if origin > 0.0 {
        format!("{label} − {origin}")
    } else {
        format!("{label} + {}", -origin)
    }
}

/// Tick label: few significant digits, no trailing noise.
fn fmt_tick(v: f64) -> String {
    let a = v.abs();
    if a != 0.0 && !(1e-3..1e5).contains(&a) {
        format!("{v:.1e}")
    } else {
        let s = format!("{v:.4}");
        let s = s.trim_end_matches('0').trim_end_matches('.').to_string();
        if s == "-0" {
            "0".into()
        } else {
            s
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn svg_has_title_labels_and_data() {
        let c = Chart::new("Test plot", "x (m)", "y (m)")
            .with(Series::new(
                "line",
                vec![
                    (0.0, 0.0),
                    (1.0, 2.0),
                    (f64::NAN, 0.0),
                    (2.0, 1.0),
                    (3.0, 3.0),
                ],
                Mark::Line,
                0,
            ))
            .with(Series::new("dots", vec![(0.5, 1.0)], Mark::Dots, 1))
            .with(Series::new("", vec![(1.0, 0.5)], Mark::Bars, 2));
        let svg = c.to_svg().unwrap();
        assert!(svg.starts_with("<svg"), "{}", &svg[..40]);
        for s in [
            "Test plot",
            "x (m)",
            "y (m)",
            "<polyline",
            "<circle",
            "line",
            "dots",
        ] {
            assert!(svg.contains(s), "missing {s}");
        }
        // The NaN splits the line into two polylines (plus legend path).
        assert!(svg.matches("<polyline").count() >= 2);
    }

    #[test]
    fn empty_chart_is_an_error_and_y_down_flips_labels() {
        assert!(Chart::new("e", "x", "y").to_svg().is_err());
        let mut c = Chart::new("img", "u (px)", "v (px)").with(Series::new(
            "",
            vec![(0.0, 0.0), (1280.0, 720.0)],
            Mark::Dots,
            0,
        ));
        c.y_down = true;
        c.x_range = Some((0.0, 1280.0));
        c.y_range = Some((0.0, 720.0));
        let svg = c.to_svg().unwrap();
        assert!(
            !svg.contains(">-"),
            "negative tick labels in a y-down chart"
        );
    }

    /// Surveyed coordinates (512 345 m east) and epoch times (1.7e9 s) gave every tick one
    /// label ("5.1e5"); the axis is drawn from a round origin its label states.
    #[test]
    fn far_axes_are_drawn_from_a_stated_origin() {
        let c = Chart::new("Far", "x (m)", "t (s)").with(Series::new(
            "",
            vec![(512_345.0, 1.7e9 + 3.0), (512_355.0, 1.7e9 + 40.0)],
            Mark::Dots,
            0,
        ));
        let svg = c.to_svg().unwrap();
        assert!(svg.contains("x (m) − 512300"), "no origin in the x label");
        assert!(
            svg.contains("t (s) − 1700000000"),
            "no origin in the y label"
        );
        // The texts of the SVG: tick labels, axis labels, title.
        let texts: Vec<&str> = svg
            .split("<text")
            .skip(1)
            .filter_map(|t| Some(t.split_once('>')?.1.split_once("</text>")?.0.trim()))
            .collect();
        assert!(
            !texts.iter().any(|t| t.contains("e5") || t.contains("e9")),
            "{texts:?}"
        );
        // Ticks count up from the origin: 50 m past it is labelled, as is 37 s past it.
        assert!(texts.contains(&"50"), "no tick at 512350 m: {texts:?}");
        assert!(texts.contains(&"40"), "no tick at 1.7e9 + 40 s: {texts:?}");
        assert_eq!(axis_origin((0.0, 20.0)), 0.0);
        assert_eq!(axis_origin((9000.0, 9010.0)), 0.0);
        assert_eq!(axis_origin((5_412_340.0, 5_412_352.0)), 5_412_300.0);
        assert_eq!(axis_origin((-512_352.0, -512_340.0)), -512_400.0);
    }

    #[test]
    fn ticks_are_short() {
        assert_eq!(fmt_tick(0.25), "0.25");
        assert_eq!(fmt_tick(-0.0), "0");
        assert_eq!(fmt_tick(1500.0), "1500");
        assert_eq!(fmt_tick(2e-5), "2.0e-5");
    }

    /// A heat map draws one cell per value, the missing ones grey, the scale in the legend
    /// from 0 to the largest value.
    #[test]
    fn cells_are_drawn_with_their_scale() {
        let mut c = Chart::new("Heat", "u (px)", "v (px)").with(Series::new(
            "",
            vec![(0.0, 0.0), (30.0, 20.0)],
            Mark::Line,
            7,
        ));
        c.cells = Some(Cells {
            origin: (0.0, 0.0),
            cell: (10.0, 10.0),
            cols: 3,
            values: vec![Some(0.0), Some(1.0), Some(2.0), None, Some(4.0), Some(2.0)],
            missing_label: "no floor".into(),
            unit: "mm".into(),
        });
        let svg = c.to_svg().unwrap();
        for s in ["0 mm", "4 mm", "no floor", "#C8C8C8"] {
            assert!(svg.contains(s), "missing {s}");
        }
        // The largest value takes viridis' top colour, 0 its bottom.
        let top = Cells::colour(4.0, 4.0);
        let bottom = Cells::colour(0.0, 4.0);
        for col in [top, bottom] {
            let css = format!("#{:02X}{:02X}{:02X}", col.0, col.1, col.2);
            assert!(svg.contains(&css), "missing {css}");
        }
        assert_ne!(top, bottom);
    }
}
